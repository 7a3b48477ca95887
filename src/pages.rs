//! Large allocations on transparent huge pages.
//!
//! The vectors and operators of a mesh of millions of vertices take tens to hundreds of
//! megabytes each. Above glibc's largest mmap threshold (32 MiB) every such allocation is mapped
//! afresh, and the kernel zeroes and maps it one 4 KiB page at a time as it is first written: at
//! 16.8M vertices, where each CG vector is 134 MB, a large part of a solve (README, Speed).
//! [`HugePages`] asks the kernel (`madvise(MADV_HUGEPAGE)`) to back those allocations, of at
//! least [`THRESHOLD`], with 2 MiB pages where it can: 512 times fewer faults, and as many fewer
//! TLB entries for the sweeps. Smaller blocks are left alone: glibc reuses them from its heap, and
//! advised, the sparse Cholesky factorization's were slower (huge pages are zeroed whole). The
//! numbers computed are the same; where the kernel's huge pages are off
//! (`/sys/kernel/mm/transparent_hugepage/enabled` = never) the advice changes nothing.
//!
//! It also keeps glibc to one heap arena for all threads: by default each thread that allocates
//! gets an arena of its own, and the blocks the threads of the pool free stay in theirs, so that
//! the resident memory grows with the threads (measured in docs/performance.md).
//!
//! The program and `make bench` use it as their global allocator:
//!
//! ```ignore
//! #[global_allocator]
//! static ALLOCATOR: membrane_contact::pages::HugePages = membrane_contact::pages::HugePages;
//! ```

use std::alloc::{GlobalAlloc, Layout, System};
use std::sync::Once;

/// The system allocator, with the allocations of at least [`THRESHOLD`] bytes advised onto huge
/// pages.
pub struct HugePages;

/// The allocations advised: from glibc's largest mmap threshold on (32 MiB on 64-bit systems),
/// above which every allocation is a fresh mapping.
pub const THRESHOLD: usize = 32 << 20;

/// The base page size that `madvise` needs its start aligned to (on other page sizes the call
/// fails, harmlessly).
const PAGE: usize = 4096;

// SAFETY: every call is forwarded to `System` with its own arguments; the advice only changes
// how the kernel backs the pages of an allocation, never its address, size or contents.
unsafe impl GlobalAlloc for HugePages {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        one_arena();
        advised(unsafe { System.alloc(layout) }, layout.size())
    }

    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        one_arena();
        advised(unsafe { System.alloc_zeroed(layout) }, layout.size())
    }

    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        unsafe { System.dealloc(ptr, layout) }
    }

    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        advised(unsafe { System.realloc(ptr, layout, new_size) }, new_size)
    }
}

/// The peak resident memory of this process so far (`VmHWM` of /proc/self/status, Linux), in
/// bytes.
pub fn peak_resident_bytes() -> Option<u64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with("VmHWM:"))?;
    let kb: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kb << 10)
}

/// Sets glibc's arenas to one, at the first allocation (before any thread but the first exists).
fn one_arena() {
    static ONCE: Once = Once::new();
    // SAFETY: mallopt only sets a parameter of the allocator; it neither allocates nor frees.
    ONCE.call_once(|| unsafe {
        libc::mallopt(libc::M_ARENA_MAX, 1);
    });
}

/// `ptr`, with the whole pages of its `size` bytes advised onto huge pages when it is large.
fn advised(ptr: *mut u8, size: usize) -> *mut u8 {
    if size >= THRESHOLD && !ptr.is_null() {
        let start = (ptr as usize).next_multiple_of(PAGE);
        let end = (ptr as usize + size) / PAGE * PAGE;
        if end > start {
            // SAFETY: the range lies inside the allocation just made; MADV_HUGEPAGE neither
            // frees nor moves memory. A failure (no huge pages here) leaves the pages as they are.
            unsafe { libc::madvise(start as *mut libc::c_void, end - start, libc::MADV_HUGEPAGE) };
        }
    }
    ptr
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Whether the mapping that holds `address` is advised onto huge pages (`hg` among its
    /// `VmFlags` in /proc/self/smaps), with the flags to show.
    fn advised_at(address: usize) -> (bool, String) {
        let smaps = std::fs::read_to_string("/proc/self/smaps").expect("/proc/self/smaps");
        let mut inside = false;
        for line in smaps.lines() {
            let range = line.split_whitespace().next().and_then(|r| r.split_once('-'));
            if let Some((start, end)) = range.filter(|_| !line.starts_with("VmFlags")) {
                if let (Ok(start), Ok(end)) =
                    (usize::from_str_radix(start, 16), usize::from_str_radix(end, 16))
                {
                    inside = (start..end).contains(&address);
                    continue;
                }
            }
            if inside && line.starts_with("VmFlags:") {
                return (line.split_whitespace().any(|f| f == "hg"), line.to_string());
            }
        }
        panic!("no mapping holds {address:#x}")
    }

    /// Whether this kernel has transparent huge pages at all (else `madvise` refuses the advice).
    fn kernel_has_huge_pages() -> bool {
        std::path::Path::new("/sys/kernel/mm/transparent_hugepage/enabled").exists()
    }

    #[test]
    fn large_allocations_are_advised_onto_huge_pages_and_keep_their_contents() {
        if !kernel_has_huge_pages() {
            return;
        }
        let layout = Layout::from_size_align(64 << 20, 8).unwrap();
        unsafe {
            let p = HugePages.alloc_zeroed(layout);
            assert!(!p.is_null());
            let middle = p as usize + (32 << 20);
            let (advised, flags) = advised_at(middle);
            assert!(advised, "{flags}");
            assert_eq!(*p.add(12345), 0);
            *p.add(12345) = 7;
            // Grown (mremap moves the mapping), still advised, the contents kept.
            let q = HugePages.realloc(p, layout, 128 << 20);
            assert_eq!(*q.add(12345), 7);
            let middle = q as usize + (96 << 20);
            let (advised, flags) = advised_at(middle);
            assert!(advised, "{flags}");
            HugePages.dealloc(q, Layout::from_size_align(128 << 20, 8).unwrap());
        }
    }

    #[test]
    fn smaller_allocations_are_left_to_the_heap_as_they_are() {
        let layout = Layout::from_size_align(THRESHOLD / 2, 8).unwrap();
        unsafe {
            let p = HugePages.alloc(layout);
            assert!(!p.is_null());
            p.write_bytes(1, layout.size());
            let middle = p as usize + THRESHOLD / 4;
            let (advised, flags) = advised_at(middle);
            assert!(!advised, "{flags}");
            HugePages.dealloc(p, layout);
        }
    }

    #[test]
    fn the_advice_stays_inside_the_block() {
        if !kernel_has_huge_pages() {
            return;
        }
        // Three blocks of 64 MiB in one mapping of our own; the middle one advised as if it
        // had been allocated there, one byte off a page boundary at both ends.
        let block = 64 << 20;
        unsafe {
            let base = libc::mmap(
                std::ptr::null_mut(),
                3 * block,
                libc::PROT_READ | libc::PROT_WRITE,
                libc::MAP_PRIVATE | libc::MAP_ANONYMOUS,
                -1,
                0,
            );
            assert_ne!(base, libc::MAP_FAILED);
            let base = base as usize;
            advised((base + block + 1) as *mut u8, block - 2);
            for (at, expected) in [
                (base + block / 2, false),
                (base + 3 * block / 2, true),
                (base + 5 * block / 2, false),
            ] {
                let (advised, flags) = advised_at(at);
                assert_eq!(advised, expected, "{:#x} into the mapping: {flags}", at - base);
            }
            // The pages holding the block's first and last bytes are shared with its neighbours:
            // they are not advised.
            assert!(!advised_at(base + block).0 && !advised_at(base + 2 * block - 1).0);
            libc::munmap(base as *mut libc::c_void, 3 * block);
        }
    }
}
