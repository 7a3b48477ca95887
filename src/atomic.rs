//! Results written whole or not at all.
//!
//! A result is one directory: a solution's HDF5 file and its XDMF sidecars, or a study's tables
//! and plots. It is written into a hidden temporary directory beside its final place and put
//! there by one system call: `renameat2(RENAME_EXCHANGE)` swaps it with an earlier result, a plain
//! `rename` puts it where there was none. Whatever instant the process is killed at, the path
//! shows the complete earlier result or the complete new one, never a mix. SIGINT, SIGTERM and
//! SIGHUP remove the temporaries of the run and the directories it made to hold the result, and it
//! then exits with 128 + the signal's number (130, 143, 129), as a shell reports a process the
//! signal killed; after a SIGKILL, the next run for the same path recognises them by name and
//! removes them once that process has ended (or is ending: a zombie).
//!
//! An existing path is replaced only when it is a result of this program (it holds the marker
//! file [`MARKER`]) and holds none of the run's inputs; anything else is left alone with an error.

use std::ffi::CString;
use std::os::unix::ffi::OsStrExt;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, AtomicI32, Ordering};
use std::sync::{Mutex, MutexGuard, Once};

/// The file that marks a directory as a result of this program.
pub const MARKER: &str = ".membrane-contact";

message_error!(
    /// Why a result could not be put in place, naming the path.
    OutputError
);

/// Temporary directories of this process, each with the directories made to hold its result,
/// removed on SIGINT, SIGTERM or SIGHUP. Held while a result is swapped in, so that a signal waits
/// for the swap to finish.
static PENDING: Mutex<Vec<Pending>> = Mutex::new(Vec::new());
static HANDLER: Once = Once::new();

/// A temporary directory and the directories made to hold its result, innermost first.
type Pending = (PathBuf, Vec<PathBuf>);

fn pending() -> MutexGuard<'static, Vec<Pending>> {
    PENDING.lock().unwrap_or_else(|e| e.into_inner())
}

/// The directories `create_dir_all(parent)` will make, innermost first. Through `..` after one of
/// them the path is followed by its components (a directory made here is no link): `new/../keep`
/// makes `new` alone, whether `keep` exists or not (`keep` was taken for made, and removed if
/// empty, where `new` did not exist).
fn to_be_made(parent: &Path) -> Vec<PathBuf> {
    use std::path::Component;
    let (mut path, mut made) = (PathBuf::new(), Vec::<PathBuf>::new());
    for component in parent.components() {
        match component {
            Component::CurDir => {}
            Component::ParentDir if made.last() == Some(&path) => {
                path.pop();
            }
            other => {
                path.push(other);
                if !matches!(other, Component::ParentDir) && !path.exists() && !made.contains(&path) {
                    made.push(path.clone());
                }
            }
        }
    }
    made.reverse();
    made
}

/// Removes the directories `made` for a result, innermost first, each only while empty: one that
/// something else has written into since stays, with those above it.
fn remove_made(made: &[PathBuf]) {
    for dir in made {
        if std::fs::remove_dir(dir).is_err() {
            break;
        }
    }
}

/// A result directory being written: files go into [`Staging::path`], and [`Staging::commit`]
/// puts the directory in place. Dropped without a commit, it removes what was written.
#[derive(Debug)]
pub struct Staging {
    temporary: PathBuf,
    target: PathBuf,
    committed: bool,
    /// The directories made to hold the result (the parent and those above it that were
    /// missing), removed again if the result is not committed.
    made: Vec<PathBuf>,
}

/// The longest file name, in bytes, of the file systems of Linux.
const NAME_MAX: usize = 255;

/// The extension of `path` where it names a file of a result (.h5, .xdmf, in any case), a name a
/// result directory may not take.
pub fn file_extension(path: &Path) -> Option<String> {
    let extension = path.extension()?.to_string_lossy().to_lowercase();
    matches!(extension.as_str(), "h5" | "xdmf").then_some(extension)
}

impl Staging {
    /// Prepares the result directory `target`, whose `kind` ("solution" or "study") the marker
    /// records. Refuses a `target` that exists and is not a result of this program, that holds
    /// one of `inputs`, or whose parent directory cannot be made (it is made if missing, as
    /// `mkdir -p` would); clears stale temporaries of earlier runs for the same `target`.
    pub fn new(target: &Path, inputs: &[PathBuf], kind: &str) -> Result<Staging, OutputError> {
        let err = |m: String| OutputError(format!("{}: {m}", target.display()));
        // `Path::file_name` reads "r1/." as "r1"; the rename into "r1/." would fail after the run.
        let bytes = target.as_os_str().as_encoded_bytes();
        let trimmed = &bytes[..bytes.iter().rposition(|&b| b != b'/').map_or(0, |i| i + 1)];
        let last = trimmed.rsplit(|&b| b == b'/').next();
        let name = target
            .file_name()
            .filter(|n| !n.is_empty() && !matches!(last, Some(b".") | Some(b"..")))
            .ok_or_else(|| err("not a directory name".into()))?;
        if let Some(ext) = file_extension(target) {
            return Err(err(format!(
                "a result is a directory (of .h5 and .xdmf files), not a .{ext} file: give a \
                 directory name"
            )));
        }
        if name.len() > NAME_MAX {
            return Err(err(format!("a name of {} bytes: at most {NAME_MAX}", name.len())));
        }
        if let (Ok(target), Ok(here)) = (target.canonicalize(), std::env::current_dir()) {
            if here.starts_with(&target) {
                return Err(err(
                    "the current directory is inside it: run from another one".into()
                ));
            }
        }
        let parent = match target.parent() {
            Some(d) if !d.as_os_str().is_empty() => d.to_path_buf(),
            _ => PathBuf::from("."),
        };
        if parent.exists() && !parent.is_dir() {
            return Err(err(format!("{} is not a directory", parent.display())));
        }
        let made = to_be_made(&parent);
        std::fs::create_dir_all(&parent).map_err(|e| {
            err(format!(
                "cannot make the directory {} that should hold the result: {e}",
                parent.display()
            ))
        })?;
        check_replaceable(target, inputs)?;
        let prefix = format!(".{:016x}.", fnv1a(name.as_bytes()));
        clear_stale(&parent, &prefix);
        let temporary = parent.join(format!("{prefix}{}.mc-partial", std::process::id()));
        HANDLER.call_once(install_handler);
        let mut list = pending();
        std::fs::create_dir(&temporary)
            .map_err(|e| err(format!("cannot create a directory beside it: {}", e)))?;
        list.push((temporary.clone(), made.clone()));
        drop(list);
        // From here on the staging exists: dropped on any error, it removes the temporary.
        let staging = Staging {
            temporary,
            target: target.to_path_buf(),
            committed: false,
            made,
        };
        std::fs::write(
            staging.temporary.join(MARKER),
            format!("membrane-contact {kind}\n"),
        )
        .map_err(|e| err(format!("cannot write: {}", e)))?;
        Ok(staging)
    }

    /// The directory to write the result's files into.
    pub fn path(&self) -> &Path {
        &self.temporary
    }

    /// `e` as the user sees it: the files named in the result's place, not the temporary's.
    pub fn named(&self, e: OutputError) -> OutputError {
        let temporary = self.temporary.display().to_string();
        // The target as its components give it: `out/` names its files `out/a`, not `out//a`.
        let target: PathBuf = self.target.components().collect();
        OutputError(e.0.replace(&temporary, &target.display().to_string()))
    }

    /// The final place of the result.
    pub fn target(&self) -> &Path {
        &self.target
    }

    /// Puts the result in place, replacing an earlier one by one atomic exchange.
    pub fn commit(mut self, inputs: &[PathBuf]) -> Result<(), OutputError> {
        let err = |m: String| OutputError(format!("{}: {m}", self.target.display()));
        list_contents(&self.temporary).map_err(|e| err(format!("cannot write: {e}")))?;
        // The target may have changed while the result was computed.
        check_replaceable(&self.target, inputs)?;
        let mut list = pending();
        if self.target.symlink_metadata().is_ok() {
            exchange(&self.temporary, &self.target)
                .map_err(|e| err(format!("cannot replace the earlier result: {}", e)))?;
            // The temporary name now holds the earlier result.
            if let Err(e) = std::fs::remove_dir_all(&self.temporary) {
                list.retain(|(d, _)| *d != self.temporary);
                self.committed = true;
                return Err(err(format!(
                    "the result is in place, but the earlier one, moved to {}, could not be deleted \
                     ({e}): delete it by hand",
                    self.temporary.display()
                )));
            }
        } else {
            std::fs::rename(&self.temporary, &self.target)
                .map_err(|e| err(format!("cannot put the result in place: {}", e)))?;
        }
        list.retain(|(d, _)| *d != self.temporary);
        self.committed = true;
        Ok(())
    }
}

impl Drop for Staging {
    fn drop(&mut self) {
        if !self.committed {
            let mut list = pending();
            let _ = std::fs::remove_dir_all(&self.temporary);
            list.retain(|(d, _)| *d != self.temporary);
            remove_made(&self.made);
        }
    }
}

/// Before the process ends: if a signal came, waits for the thread that handles it to remove the
/// temporaries and exit with 128 + its number, so that a signal received while the run ends
/// (its result already in place) still gives the exit status a shell expects, not success.
pub fn exit_as_signalled() {
    if SIGNALLED.load(Ordering::SeqCst) {
        loop {
            std::thread::park();
        }
    }
}

/// Installs no signal handlers, now or later: for a library inside another program (the Python
/// package, whose interpreter handles Ctrl-C), where SIGINT, SIGTERM and SIGHUP must keep that
/// program's handling. An interrupted run there drops its [`Staging`], which removes what it
/// wrote. Without this call the first [`Staging::new`] installs them.
pub fn leave_signals_alone() {
    HANDLER.call_once(|| {});
}

/// The write end of the pipe on which [`on_signal`] passes the signal's number to the thread that
/// removes the temporaries: a signal handler may do little more than write(2).
static SIGNAL_PIPE: AtomicI32 = AtomicI32::new(-1);

/// Whether a signal has been handled (set before its number is passed on).
static SIGNALLED: AtomicBool = AtomicBool::new(false);

/// The handler of SIGINT, SIGTERM and SIGHUP.
extern "C" fn on_signal(signal: libc::c_int) {
    SIGNALLED.store(true, Ordering::SeqCst);
    let byte = signal as u8;
    // SAFETY: write(2) is async-signal-safe; the pipe stays open for the life of the process.
    unsafe { libc::write(SIGNAL_PIPE.load(Ordering::Relaxed), (&raw const byte).cast(), 1) };
}

/// On SIGINT, SIGTERM or SIGHUP, removes the temporaries of [`PENDING`] and exits with 128 + the
/// signal's number. A signal ignored when the process started (`nohup`) stays ignored; without a
/// pipe, signals keep their default effect. SIGXFSZ is ignored.
/// Writes `text` to stderr, waiting for it at most a fifth of a second: a closed pipe is no
/// panic, and a full one whose reader has stopped does not hold the exit.
fn say_briefly(text: &str) {
    use std::io::Write;
    let (done, wait) = std::sync::mpsc::channel();
    let text = text.to_owned();
    std::thread::spawn(move || {
        let _ = std::io::stderr().write_all(text.as_bytes());
        let _ = done.send(());
    });
    let _ = wait.recv_timeout(std::time::Duration::from_millis(200));
}

fn install_handler() {
    let mut fds = [0; 2];
    // SAFETY: an array of two descriptors to fill.
    if unsafe { libc::pipe2(fds.as_mut_ptr(), libc::O_CLOEXEC) } != 0 {
        return;
    }
    let [read_end, write_end] = fds;
    SIGNAL_PIPE.store(write_end, Ordering::Relaxed);
    std::thread::spawn(move || {
        let mut signal = 0u8;
        loop {
            // SAFETY: reads one byte into `signal`.
            match unsafe { libc::read(read_end, (&raw mut signal).cast(), 1) } {
                1 => break,
                -1 if std::io::Error::last_os_error().kind() == std::io::ErrorKind::Interrupted => {}
                _ => return,
            }
        }
        let pending = pending();
        // The writer goes on while this runs and may add a file after remove_dir_all has listed
        // the directory (its last rmdir then fails): again until it is gone.
        for (dir, made) in pending.iter() {
            for _ in 0..100 {
                if std::fs::remove_dir_all(dir).is_ok() || !dir.exists() {
                    break;
                }
            }
            remove_made(made);
        }
        if !pending.is_empty() {
            // The run's own lines said what was done so far: what became of it is said too.
            say_briefly(&format!(
                "\ninterrupted (signal {signal}): the result being written is discarded, nothing of \
                 it is left (an earlier result in its place is kept)\n"
            ));
        }
        // No exit handlers: another thread may be inside the HDF5 library.
        unsafe { libc::_exit(128 + i32::from(signal)) }
    });
    let handler = on_signal as extern "C" fn(libc::c_int) as libc::sighandler_t;
    for signal in [libc::SIGINT, libc::SIGTERM, libc::SIGHUP] {
        // SAFETY: sigaction structures filled in full; the handler only writes to the pipe.
        unsafe {
            let mut action: libc::sigaction = std::mem::zeroed();
            action.sa_sigaction = handler;
            action.sa_flags = libc::SA_RESTART;
            libc::sigemptyset(&mut action.sa_mask);
            let mut old: libc::sigaction = std::mem::zeroed();
            if libc::sigaction(signal, &action, &mut old) == 0 && old.sa_sigaction == libc::SIG_IGN {
                libc::sigaction(signal, &old, std::ptr::null_mut());
            }
        }
    }
    // Past a file size limit (`ulimit -f`) SIGXFSZ ended the process with the temporary left
    // behind; ignored (as Python ignores it), the write fails with EFBIG and the run says so.
    // SAFETY: sets the disposition of one signal.
    unsafe { libc::signal(libc::SIGXFSZ, libc::SIG_IGN) };
}

/// The directory of the result `target` (itself or one of its steps) whose files this process
/// may not delete, if any: no write and search permission on it, or (sticky, as /tmp is) a file
/// in it that neither it nor the directory belongs to. Replaced, such a result was moved aside
/// and left there.
fn locked_directory(target: &Path) -> Option<PathBuf> {
    use std::os::unix::fs::MetadataExt;
    // SAFETY: geteuid reads the process's user.
    let me = unsafe { libc::geteuid() };
    let steps = std::fs::read_dir(target).into_iter().flatten().flatten();
    let dirs = std::iter::once(target.to_path_buf()).chain(steps.map(|e| e.path()).filter(|p| p.is_dir()));
    dirs.into_iter().find(|dir| {
        use std::os::unix::ffi::OsStrExt;
        let c = std::ffi::CString::new(dir.as_os_str().as_bytes());
        // SAFETY: access(2) reads a NUL-terminated path and changes nothing.
        let writable = c.is_ok_and(|c| unsafe { libc::access(c.as_ptr(), libc::W_OK | libc::X_OK) } == 0);
        let sticky_of_another = dir
            .symlink_metadata()
            .is_ok_and(|m| m.mode() & libc::S_ISVTX != 0 && me != 0 && m.uid() != me);
        let foreign_file = || {
            (std::fs::read_dir(dir).into_iter().flatten().flatten())
                .any(|e| e.metadata().is_ok_and(|m| m.uid() != me))
        };
        !writable || (sticky_of_another && foreign_file())
    })
}

/// `target` may be replaced: absent, or a result directory of this program holding no input,
/// whose files this process may delete.
fn check_replaceable(target: &Path, inputs: &[PathBuf]) -> Result<(), OutputError> {
    let err = |m: String| OutputError(format!("{}: {m}", target.display()));
    let Ok(meta) = target.symlink_metadata() else {
        return Ok(());
    };
    let in_a_result = target.parent().is_some_and(|p| p.join(MARKER).is_file());
    if meta.is_dir() && in_a_result && !target.join(MARKER).is_file() {
        return Err(err(
            "is part of a result of membrane-contact (a step of `adapt`, say), which replacing it \
             would leave inconsistent; it is left alone: choose another name, or replace the whole \
             result"
                .into(),
        ));
    }
    if !meta.is_dir() || !target.join(MARKER).is_file() {
        return Err(err(
            "exists and is not a result of membrane-contact; it is left alone: choose another name".into(),
        ));
    }
    let marker = std::fs::read_to_string(target.join(MARKER)).unwrap_or_default();
    let listed: Vec<&str> = marker.lines().skip(1).collect();
    // A result written before the marker listed its contents is taken as it is.
    if !listed.is_empty() {
        let foreign = foreign_entry(target, "", &listed, listed.contains(&EVERY_DIRECTORY))
            .map_err(|e| err(format!("cannot read: {e}")))?;
        if let Some(name) = foreign {
            return Err(err(format!(
                "holds {name}, which is not part of the result; replacing the result would delete \
                 it: move it away or choose another name"
            )));
        }
    }
    if let Some(dir) = locked_directory(target) {
        return Err(err(format!(
            "the earlier result cannot be replaced: this user may not delete the files of {} \
             (its permissions or owner); it is left alone: choose another name",
            dir.display()
        )));
    }
    let real = target
        .canonicalize()
        .map_err(|e| err(format!("cannot resolve: {e}")))?;
    for input in inputs {
        if input.canonicalize().is_ok_and(|p| p.starts_with(&real)) {
            return Err(err(format!(
                "holds {}, an input of this run; replacing the result would delete it: choose another name",
                input.display()
            )));
        }
    }
    Ok(())
}

/// The line of a marker's list saying that it lists every directory of the result as `name/`
/// (markers before it listed the top level alone, directories as `name`).
const EVERY_DIRECTORY: &str = "./";

/// The first entry below `dir` (its path relative to the result, `prefix` the path of `dir`) that
/// the marker's list `listed` does not hold. A directory is listed as `name/`, and its entries
/// are then checked too; a directory where the list has a file `name` is a user's, put in place
/// of a file of the result, if the list names `every` directory as `name/` (else, an earlier
/// marker's directory, it is taken as it is).
fn foreign_entry(dir: &Path, prefix: &str, listed: &[&str], every: bool) -> std::io::Result<Option<String>> {
    for entry in std::fs::read_dir(dir)? {
        let entry = entry?;
        let path = format!("{prefix}{}", entry.file_name().to_string_lossy());
        if path == MARKER {
            continue;
        }
        let is_dir = entry.file_type()?.is_dir();
        let as_dir = format!("{path}/");
        if is_dir && listed.contains(&as_dir.as_str()) {
            if let Some(inside) = foreign_entry(&entry.path(), &as_dir, listed, every)? {
                return Ok(Some(inside));
            }
        } else if is_dir && (every || !listed.contains(&path.as_str())) {
            return Ok(Some(as_dir));
        } else if !listed.contains(&path.as_str()) {
            return Ok(Some(path));
        }
    }
    Ok(None)
}

/// The entries below `dir`, as paths relative to the result (`prefix` that of `dir`),
/// directories as `name/` followed by their entries.
fn entries(dir: &Path, prefix: &str) -> std::io::Result<Vec<String>> {
    let mut all = Vec::new();
    for entry in std::fs::read_dir(dir)? {
        let entry = entry?;
        let path = format!("{prefix}{}", entry.file_name().to_string_lossy());
        if entry.file_type()?.is_dir() {
            let as_dir = format!("{path}/");
            all.extend(entries(&entry.path(), &as_dir)?);
            all.push(as_dir);
        } else if path != MARKER {
            all.push(path);
        }
    }
    Ok(all)
}

/// Adds the entries of the result directory `dir`, at every depth, to its marker, one a line
/// after the kind: what a later run may replace, and nothing a user put there since.
fn list_contents(dir: &Path) -> std::io::Result<()> {
    let mut names = entries(dir, "")?;
    names.push(EVERY_DIRECTORY.into());
    names.sort();
    let mut marker = std::fs::read_to_string(dir.join(MARKER))?;
    names.iter().for_each(|n| marker += &format!("{n}\n"));
    std::fs::write(dir.join(MARKER), marker)
}

/// Swaps two paths atomically (Linux `renameat2` with `RENAME_EXCHANGE`).
fn exchange(a: &Path, b: &Path) -> std::io::Result<()> {
    let c = |p: &Path| CString::new(p.as_os_str().as_bytes()).map_err(std::io::Error::other);
    let (a, b) = (c(a)?, c(b)?);
    // SAFETY: two valid NUL-terminated paths; the call reads them only.
    let r = unsafe {
        libc::renameat2(
            libc::AT_FDCWD,
            a.as_ptr(),
            libc::AT_FDCWD,
            b.as_ptr(),
            libc::RENAME_EXCHANGE,
        )
    };
    if r == 0 {
        Ok(())
    } else {
        Err(std::io::Error::last_os_error())
    }
}

/// Removes the temporaries `PREFIX<pid>.mc-partial` in `dir` whose process is gone or ending.
fn clear_stale(dir: &Path, prefix: &str) {
    let Ok(entries) = std::fs::read_dir(dir) else {
        return;
    };
    for entry in entries.flatten() {
        let name = entry.file_name();
        let Some(pid) = name
            .to_str()
            .and_then(|n| n.strip_prefix(prefix))
            .and_then(|n| n.strip_suffix(".mc-partial"))
            .and_then(|p| p.parse::<u32>().ok())
        else {
            continue;
        };
        if !alive(pid) {
            let _ = std::fs::remove_dir_all(entry.path());
        }
    }
}

/// Whether process `pid` exists and is not ending: after SIGKILL its entry in /proc stays, in
/// state Z (zombie) or X (dead), until its parent has collected its status.
fn alive(pid: u32) -> bool {
    let Ok(stat) = std::fs::read_to_string(format!("/proc/{pid}/stat")) else {
        return false;
    };
    // "pid (comm) state …": comm may hold spaces and parentheses, so the state follows the last ')'.
    let state = stat
        .rsplit_once(')')
        .and_then(|(_, rest)| rest.trim_start().chars().next());
    !matches!(state, Some('Z' | 'X'))
}

/// The 64-bit FNV-1a hash: a short name for a temporary that is the same in every version.
fn fnv1a(bytes: &[u8]) -> u64 {
    bytes.iter().fold(0xcbf2_9ce4_8422_2325, |h, &b| {
        (h ^ u64::from(b)).wrapping_mul(0x0100_0000_01b3)
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A killed run's temporary is cleared once its process is a zombie (its /proc entry stays
    /// until its parent collects it), not only once the entry is gone.
    #[test]
    fn a_zombie_holds_no_temporary() {
        assert!(alive(std::process::id()));
        let mut child = std::process::Command::new("true").spawn().unwrap();
        let pid = child.id();
        let t = std::time::Instant::now();
        while alive(pid) {
            assert!(t.elapsed().as_secs() < 30, "the child never ended");
            std::thread::sleep(std::time::Duration::from_millis(5));
        }
        // Not yet collected: its entry is there, a zombie.
        assert!(Path::new(&format!("/proc/{pid}")).exists());
        let dir = tempfile::tempdir().unwrap();
        let prefix = ".0123456789abcdef.";
        let stale = dir.path().join(format!("{prefix}{pid}.mc-partial"));
        let running = dir
            .path()
            .join(format!("{prefix}{}.mc-partial", std::process::id()));
        std::fs::create_dir(&stale).unwrap();
        std::fs::create_dir(&running).unwrap();
        clear_stale(dir.path(), prefix);
        assert!(!stale.exists() && running.exists());
        child.wait().unwrap();
        assert!(!alive(pid));
    }

    #[test]
    fn a_result_replaces_only_an_earlier_result() {
        let dir = tempfile::tempdir().unwrap();
        let target = dir.path().join("out");
        let write = |text: &str| {
            let s = Staging::new(&target, &[], "solution").unwrap();
            std::fs::write(s.path().join("data"), text).unwrap();
            s.commit(&[]).unwrap();
        };
        write("first");
        write("second");
        assert_eq!(std::fs::read_to_string(target.join("data")).unwrap(), "second");
        let names: Vec<_> = std::fs::read_dir(dir.path())
            .unwrap()
            .flatten()
            .map(|e| e.file_name())
            .collect();
        assert_eq!(names, ["out"], "no temporary is left");
        // A directory that is not a result, and a result holding an input, are left alone.
        let other = dir.path().join("other");
        std::fs::create_dir(&other).unwrap();
        assert!(Staging::new(&other, &[], "solution")
            .unwrap_err()
            .0
            .contains("not a result"));
        let input = target.join("data");
        assert!(Staging::new(&target, &[input], "solution")
            .unwrap_err()
            .0
            .contains("an input"));
        // Dropped without a commit, the staging leaves nothing.
        drop(Staging::new(&dir.path().join("never"), &[], "solution").unwrap());
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 2);
    }

    /// A file or directory that a user put into a result is not deleted by the next result.
    #[test]
    fn what_a_user_added_to_a_result_is_kept() {
        let dir = tempfile::tempdir().unwrap();
        let target = dir.path().join("out");
        // As `adapt` writes: files at the top and in a directory per step.
        let write = || {
            let s = Staging::new(&target, &[], "solution")?;
            std::fs::write(s.path().join("solution.h5"), "data").unwrap();
            std::fs::create_dir(s.path().join("step-001")).unwrap();
            std::fs::write(s.path().join("step-001/solution.h5"), "data").unwrap();
            s.commit(&[])
        };
        write().unwrap();
        write().unwrap();
        for added in ["notes.txt", "sub", "step-001/notes.txt", "step-001/plots"] {
            let path = target.join(added);
            match added {
                "sub" | "step-001/plots" => std::fs::create_dir(&path).unwrap(),
                _ => std::fs::write(&path, "mine").unwrap(),
            }
            let e = write().unwrap_err();
            let shown = match path.is_dir() {
                true => format!("{added}/"),
                false => added.to_string(),
            };
            assert!(
                e.0.contains(&format!("holds {shown}, which is not part of the result")),
                "{}",
                e.0
            );
            assert!(path.exists());
            std::fs::remove_dir_all(&path)
                .or_else(|_| std::fs::remove_file(&path))
                .unwrap();
        }
        write().unwrap();
        // A directory in place of a file of the result, with what it holds.
        std::fs::remove_file(target.join("solution.h5")).unwrap();
        std::fs::create_dir(target.join("solution.h5")).unwrap();
        std::fs::write(target.join("solution.h5/mine.txt"), "mine").unwrap();
        let e = write().unwrap_err();
        assert!(
            e.0.contains("holds solution.h5/, which is not part of the result"),
            "{}",
            e.0
        );
        assert!(target.join("solution.h5/mine.txt").exists());
        std::fs::remove_dir_all(target.join("solution.h5")).unwrap();
        std::fs::write(target.join("solution.h5"), "data").unwrap();
        write().unwrap();
        // A marker that lists the top level alone (an earlier version's) takes its directories
        // as they are.
        std::fs::write(
            target.join(MARKER),
            "membrane-contact solution\nsolution.h5\nstep-001\n",
        )
        .unwrap();
        std::fs::write(target.join("step-001/older.txt"), "older").unwrap();
        write().unwrap();
    }

    #[test]
    fn missing_parent_directories_are_made_and_unmade_and_a_file_among_them_is_named() {
        let dir = tempfile::tempdir().unwrap();
        let target = dir.path().join("results").join("poly");
        Staging::new(&target, &[], "solution")
            .unwrap()
            .commit(&[])
            .unwrap();
        assert!(target.join(MARKER).exists());
        // A result not committed leaves no directory made for it.
        drop(Staging::new(&dir.path().join("a").join("b").join("out"), &[], "solution").unwrap());
        assert!(!dir.path().join("a").exists());
        // Nor through `..` and `.` (`c` was left behind: `c/..` cannot be removed), and a
        // directory that was there stays (`keep` was taken for made, and removed).
        let odd = dir.path().join("c/../d/./e/out");
        drop(Staging::new(&odd, &[], "solution").unwrap());
        assert!(!dir.path().join("c").exists() && !dir.path().join("d").exists());
        std::fs::create_dir(dir.path().join("keep")).unwrap();
        drop(Staging::new(&dir.path().join("new/../keep/out"), &[], "solution").unwrap());
        assert!(dir.path().join("keep").is_dir() && !dir.path().join("new").exists());
        let file = dir.path().join("afile");
        std::fs::write(&file, "a file").unwrap();
        let e = Staging::new(&file.join("sub").join("out"), &[], "solution").unwrap_err();
        assert!(
            e.0.contains("cannot make the directory") && e.0.contains("afile/sub"),
            "{}",
            e.0
        );
        assert_eq!(std::fs::read_to_string(&file).unwrap(), "a file");
    }

    #[test]
    fn stale_temporaries_of_the_same_target_are_cleared() {
        let dir = tempfile::tempdir().unwrap();
        let target = dir.path().join("out");
        let prefix = format!(".{:016x}.", fnv1a(b"out"));
        // pid 0 is never a user process; another target's temporary stays.
        let stale = dir.path().join(format!("{prefix}0.mc-partial"));
        let foreign = dir.path().join(format!(".{:016x}.0.mc-partial", fnv1a(b"else")));
        std::fs::create_dir(&stale).unwrap();
        std::fs::create_dir(&foreign).unwrap();
        Staging::new(&target, &[], "solution")
            .unwrap()
            .commit(&[])
            .unwrap();
        assert!(!stale.exists() && foreign.exists() && target.join(MARKER).exists());
    }
}
