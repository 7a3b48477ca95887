//! Data parallelism on rayon's thread pool, with results that do not depend on the number of
//! threads: the work is cut into pieces fixed by the size of the data, never by the thread
//! count, and a reduction combines the pieces' partial results in their order. So every number
//! the program computes is the same bit for bit on 1 thread or 64; only the time changes.
//!
//! The pool is rayon's global one: as many threads as the machine has cores, or
//! `RAYON_NUM_THREADS`, or what [`use_threads`] sets (the `--threads` option).

use rayon::prelude::*;
use std::ops::Range;

/// Items per piece of the loops over vertices, rows or cells: large enough that a piece costs
/// far more than handing it to a thread (a few microseconds of work), small enough that a mesh
/// of 10⁵ vertices gives every core of a large machine some.
pub const PIECE: usize = 1 << 12;

/// Sorts `v` in parallel. Its items are to be distinct (a total order), so that the result does
/// not depend on the threads.
pub fn sort<T: Ord + Send>(v: &mut [T]) {
    v.par_sort_unstable();
}

/// The pieces of 0..n of `size` items each (the last one shorter).
fn pieces(n: usize, size: usize) -> impl IndexedParallelIterator<Item = Range<usize>> {
    let size = size.max(1);
    (0..n.div_ceil(size))
        .into_par_iter()
        .map(move |k| k * size..((k + 1) * size).min(n))
}

/// `part` of each piece of 0..n (of `size` items), in parallel; the results in the pieces' order.
/// One piece runs on the calling thread.
pub fn map<T: Send>(n: usize, size: usize, part: impl Fn(Range<usize>) -> T + Sync + Send) -> Vec<T> {
    if n <= size {
        return vec![part(0..n)];
    }
    pieces(n, size).map(part).collect()
}

/// As [`map`], with scratch room made by `room` once per thread's run of pieces (not per piece)
/// and handed to `part` with each piece: for results that do not depend on what the room held
/// before.
pub fn map_with<T: Send, S>(
    n: usize,
    size: usize,
    room: impl Fn() -> S + Sync + Send,
    part: impl Fn(&mut S, Range<usize>) -> T + Sync + Send,
) -> Vec<T> {
    if n <= size {
        return vec![part(&mut room(), 0..n)];
    }
    pieces(n, size).map_init(room, part).collect()
}

/// Σ `part`(piece) over the pieces of 0..n (of `size` items), added in the pieces' order.
pub fn sum(n: usize, size: usize, part: impl Fn(Range<usize>) -> f64 + Sync + Send) -> f64 {
    map(n, size, part).into_iter().sum()
}

/// `part`(first index, chunk) on the chunks of `x` of `size` items, in parallel; the results in
/// the chunks' order.
pub fn map_mut<T: Send, R: Send>(
    x: &mut [T],
    size: usize,
    part: impl Fn(usize, &mut [T]) -> R + Sync + Send,
) -> Vec<R> {
    let size = size.max(1);
    if x.len() <= size {
        return vec![part(0, x)];
    }
    (x.par_chunks_mut(size).enumerate())
        .map(|(k, chunk)| part(k * size, chunk))
        .collect()
}

/// `part`(first index, chunk of x, chunk of y) on the chunks of `size` items of two slices of
/// one length, in parallel; the results in the chunks' order.
pub fn map_mut2<T: Send, U: Send, R: Send>(
    x: &mut [T],
    y: &mut [U],
    size: usize,
    part: impl Fn(usize, &mut [T], &mut [U]) -> R + Sync + Send,
) -> Vec<R> {
    assert_eq!(x.len(), y.len(), "two slices of one length");
    let size = size.max(1);
    if x.len() <= size {
        return vec![part(0, x, y)];
    }
    (x.par_chunks_mut(size).zip(y.par_chunks_mut(size)).enumerate())
        .map(|(k, (x, y))| part(k * size, x, y))
        .collect()
}

/// The parts of `x` that begin at `starts` (increasing, the first 0; the last part ends at the
/// end of `x`).
fn split<'a, T>(mut x: &'a mut [T], starts: &[usize]) -> Vec<&'a mut [T]> {
    let mut parts = Vec::with_capacity(starts.len());
    for k in 0..starts.len() {
        let len = starts.get(k + 1).map_or(x.len(), |&next| next - starts[k]);
        let (part, rest) = std::mem::take(&mut x).split_at_mut(len);
        parts.push(part);
        x = rest;
    }
    parts
}

/// `part`(k, part k of x, part k of y) on the parts of two slices that begin at `starts`
/// (increasing, the first 0), in parallel; the results in the parts' order. `y` may be empty:
/// then its parts are.
pub fn map_parts2<T: Send, U: Send, R: Send>(
    x: &mut [T],
    y: &mut [U],
    starts: &[usize],
    part: impl Fn(usize, &mut [T], &mut [U]) -> R + Sync + Send,
) -> Vec<R> {
    let xs = split(x, starts);
    let ys = match y.is_empty() {
        true => (0..starts.len()).map(|_| &mut [][..]).collect(),
        false => split(y, starts),
    };
    if starts.len() == 1 {
        return xs.into_iter().zip(ys).map(|(x, y)| part(0, x, y)).collect();
    }
    (xs.into_par_iter().zip(ys).enumerate())
        .map(|(k, (x, y))| part(k, x, y))
        .collect()
}

/// The entries `value(i)` for i in 0..n, computed in parallel and written in place (no pass
/// that fills the vector first).
pub fn collect<T: Send>(n: usize, value: impl Fn(usize) -> T + Sync + Send) -> Vec<T> {
    (0..n).into_par_iter().with_min_len(PIECE).map(value).collect()
}

/// The entries of 0..n computed by blocks, in parallel and in place: `block(range, values)`
/// pushes the entries of `range` to `values`, `range` one of the blocks `k size..(k + 1) size`
/// (for work that is cheaper over many entries at once, such as quadrature). Each thread keeps
/// its last block, so a block is computed once, or twice where two threads' runs meet in it.
pub fn collect_by_blocks<T: Send + Copy>(
    n: usize,
    size: usize,
    block: impl Fn(Range<usize>, &mut Vec<T>) + Sync + Send,
) -> Vec<T> {
    let size = size.max(1);
    let room = || (usize::MAX, Vec::with_capacity(size));
    (0..n)
        .into_par_iter()
        .with_min_len(size)
        .map_init(room, |(start, values), i| {
            let first = i / size * size;
            if *start != first {
                values.clear();
                block(first..(first + size).min(n), values);
                *start = first;
            }
            values[i - first]
        })
        .collect()
}

/// `a` and `b` side by side when a thread is free (rayon's `join`).
pub fn join<A: Send, B: Send>(a: impl FnOnce() -> A + Send, b: impl FnOnce() -> B + Send) -> (A, B) {
    rayon::join(a, b)
}

/// The most threads a run may ask for: more than any machine's cores, so that a slip of the
/// keyboard (`--threads 100000`) is an error, not thousands of threads that mostly wait.
pub const MAX_THREADS: usize = 1024;

/// Sets the number of threads of the pool, before its first use: `threads` (the `--threads`
/// option), or else rayon's default, `RAYON_NUM_THREADS` or one per core (where it is 0 or
/// empty). `--threads 0`, more than [`MAX_THREADS`] from either, or a `RAYON_NUM_THREADS` that is
/// not a whole number (which rayon ignores), is an error naming where it came from.
pub fn use_threads(threads: Option<usize>) -> Result<(), String> {
    let (threads, from) = match threads {
        Some(0) => return Err("--threads 0: need 1 thread at least".into()),
        Some(t) => (t, format!("--threads {t}")),
        None => match env_threads()? {
            Some(t) => (t, format!("RAYON_NUM_THREADS={t}")),
            None => return Ok(()),
        },
    };
    if threads > MAX_THREADS {
        return Err(format!("{from}: at most {MAX_THREADS} threads"));
    }
    (rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build_global())
    .map_err(|e| format!("{from}: {e}"))
}

/// The threads `RAYON_NUM_THREADS` asks for: `None` where it is unset, empty or 0 (one per core);
/// an error naming it where it is not a whole number (which rayon would ignore).
pub fn env_threads() -> Result<Option<usize>, String> {
    let Some(v) = std::env::var_os("RAYON_NUM_THREADS") else {
        return Ok(None);
    };
    match v.to_string_lossy().trim() {
        "" | "0" => Ok(None),
        t => t.parse::<usize>().map(Some).map_err(|_| {
            format!(
                "RAYON_NUM_THREADS={t}: need a whole number of threads, 1 to {MAX_THREADS} (0: one per core)"
            )
        }),
    }
}

/// The number of threads the pool has.
pub fn threads() -> usize {
    rayon::current_num_threads()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn on_threads<R: Send>(threads: usize, f: impl FnOnce() -> R + Send) -> R {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        pool.install(f)
    }

    #[test]
    fn sums_are_the_same_on_any_number_of_threads() {
        // Terms of many magnitudes, so that another order of addition gives another sum.
        let terms: Vec<f64> = (0..100_003i32)
            .map(|i| ((i * 7919) % 1000) as f64 * 10f64.powi(i % 31 - 15))
            .collect();
        let total = |threads| on_threads(threads, || sum(terms.len(), 1000, |r| terms[r].iter().sum()));
        let one = total(1);
        for threads in [2, 3, 8] {
            assert_eq!(total(threads).to_bits(), one.to_bits());
        }
        // The pieces' partial sums in order, not a sum in one pass.
        let by_pieces: f64 = terms.chunks(1000).map(|c| c.iter().sum::<f64>()).sum();
        assert_eq!(one.to_bits(), by_pieces.to_bits());
    }

    #[test]
    fn pieces_cover_the_items_once_in_order() {
        for n in [0, 1, 999, 1000, 1001, 5432] {
            let parts = map(n, 1000, |r| r);
            let flat: Vec<usize> = parts.into_iter().flatten().collect();
            assert_eq!(flat, (0..n).collect::<Vec<_>>());
        }
        let mut x = vec![0usize; 2500];
        let mut y = vec![0usize; 2500];
        let firsts = map_mut2(&mut x, &mut y, 1000, |base, x, y| {
            for (k, (x, y)) in x.iter_mut().zip(y).enumerate() {
                *x = base + k;
                *y = 2 * (base + k);
            }
            base
        });
        assert_eq!(firsts, [0, 1000, 2000]);
        assert!(x.iter().enumerate().all(|(i, &v)| v == i) && y.iter().enumerate().all(|(i, &v)| v == 2 * i));
        assert_eq!(collect(5000, |i| i * i)[4321], 4321 * 4321);
    }

    #[test]
    fn blocks_give_every_entry_once_on_any_number_of_threads() {
        for threads in [1, 2, 3, 8] {
            for n in [0, 1, 999, 1000, 1001, 54321] {
                let values = on_threads(threads, || {
                    collect_by_blocks(n, 1000, |range, out: &mut Vec<(usize, usize)>| {
                        assert!(range.start.is_multiple_of(1000) && range.end == n.min(range.start + 1000));
                        out.extend(range.map(|i| (i, i * i)));
                    })
                });
                assert!(values.len() == n && values.iter().enumerate().all(|(i, &v)| v == (i, i * i)));
            }
        }
    }
}
