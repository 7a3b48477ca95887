//! The progress of a run on stderr, as it happens: the phase (meshing, assembly, each active-set
//! iteration, estimate, writing, a study's levels, adapt's steps). The run driver (`run`, `study`,
//! `adapt`) reports its phases here and the active-set method reports its iterations through
//! [`crate::contact::SolverOptions::on_step`]; nothing is shown until [`show`] is called (the
//! command line calls it unless `--quiet`), so the library stays silent, and stdout is never
//! written.

use indicatif::{ProgressBar, ProgressStyle};
use std::io::{IsTerminal, Write};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::OnceLock;
use std::time::{Duration, Instant};

/// How the phases are shown.
enum Display {
    /// A live line on a terminal: the current phase and the time since the start.
    Live(ProgressBar),
    /// One line per phase, with the seconds since the start (stderr is a file or a pipe).
    Lines(Instant),
}

static DISPLAY: OnceLock<Display> = OnceLock::new();

/// Shows the phases on stderr from now on: a live display when stderr is a terminal, one line per
/// phase otherwise.
pub fn show() {
    let display = if std::io::stderr().is_terminal() {
        let bar = ProgressBar::new_spinner();
        bar.set_style(ProgressStyle::with_template("{spinner} [{elapsed}] {msg}").expect("a valid template"));
        bar.enable_steady_tick(Duration::from_millis(120));
        Display::Live(bar)
    } else {
        Display::Lines(Instant::now())
    };
    let _ = DISPLAY.set(display);
}

/// Reports that the phase `what` begins (its text is made only when it is shown). A stderr that
/// cannot be written (a closed pipe) does not stop the run.
pub fn phase(what: impl FnOnce() -> String) {
    match DISPLAY.get() {
        Some(Display::Live(bar)) => bar.set_message(what()),
        Some(Display::Lines(start)) => {
            let line = format!("[{:8.2} s] {}\n", start.elapsed().as_secs_f64(), what());
            let _ = std::io::stderr().write_all(line.as_bytes());
        }
        None => {}
    }
}

/// The first failure to write to stdout other than a closed pipe.
static STDOUT_ERROR: OnceLock<String> = OnceLock::new();

/// Writes `text` to stdout (the command line's summary and tables). A reader that has gone (a
/// closed pipe: `| head -1`) does not stop the run, nor does another failure (a full disk), which
/// [`stdout_error`] then gives.
pub fn print(text: &str) {
    let mut out = std::io::stdout().lock();
    if let Err(e) = out.write_all(text.as_bytes()).and_then(|()| out.flush()) {
        if e.kind() != std::io::ErrorKind::BrokenPipe {
            let _ = STDOUT_ERROR.set(e.to_string());
        }
    }
}

/// Why stdout could not be written, if it could not (not for a closed pipe).
pub fn stdout_error() -> Option<&'static str> {
    STDOUT_ERROR.get().map(String::as_str)
}

/// Reports an active-set iteration on the final mesh as it ends: its number and how many
/// vertices changed set (the form of [`crate::contact::SolverOptions::on_step`]).
pub fn step(iteration: usize, changed: usize) {
    phase(|| format!("active-set iteration {iteration}: {changed} vertices changed set"));
}

/// Runs `f` (which writes to stdout) with the live display cleared, so that the two do not mix.
pub fn suspend<R>(f: impl FnOnce() -> R) -> R {
    match DISPLAY.get() {
        Some(Display::Live(bar)) => bar.suspend(f),
        _ => f(),
    }
}

/// Clears the live display for good (before the summary).
pub fn finish() {
    if let Some(Display::Live(bar)) = DISPLAY.get() {
        bar.finish_and_clear();
    }
}

/// Whether the runs of this process are asked to stop ([`cancel`]).
static CANCELLED: AtomicBool = AtomicBool::new(false);

/// Asks the runs of this process to stop: the active-set method checks before each iteration and
/// fails with [`crate::contact::SolveError::Cancelled`], and so does a run between its phases; the
/// estimator's patches stop at their next block and the error norms' cutting at its next round.
/// The command line never calls it (its signals end the process, [`crate::atomic`]); the Python
/// package does on Ctrl-C. Process-wide: every run under way stops, until [`resume`].
pub fn cancel() {
    CANCELLED.store(true, Ordering::SeqCst);
}

/// Lets runs go on again after [`cancel`] (before a new one starts).
pub fn resume() {
    CANCELLED.store(false, Ordering::SeqCst);
}

/// Whether [`cancel`] was called since the last [`resume`].
pub fn cancelled() -> bool {
    CANCELLED.load(Ordering::Relaxed)
}
