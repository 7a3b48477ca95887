//! A result is whole or absent: result directories replace earlier ones in one step, any name
//! works, studies check everything before writing, and a run killed at any instant leaves the
//! earlier result or the new one, never a mix.

mod common;
use common::listing;

use std::os::unix::process::CommandExt;
use std::path::Path;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

const BIN: &str = env!("CARGO_BIN_EXE_membrane-contact");

fn solve(out: &Path, n: usize) -> std::process::Output {
    Command::new(BIN)
        .args(["solve", "--n", &n.to_string(), "-o"])
        .arg(out)
        .output()
        .unwrap()
}

/// Reads a result back whole: the XDMF files parse and name datasets of the declared sizes in
/// `solution.h5`, and `dual.xdmf` is there exactly when the group `/dual` is. Returns its vertex
/// count.
fn read_whole(dir: &Path) -> usize {
    let h5 = hdf5::File::open(dir.join("solution.h5")).unwrap();
    let vertices = h5.attr("vertices").unwrap().read_scalar::<i64>().unwrap() as usize;
    let dual = dir.join("dual.xdmf").exists();
    assert_eq!(h5.group("dual").is_ok(), dual, "{}", dir.display());
    for xdmf in ["solution.xdmf", "dual.xdmf"]
        .into_iter()
        .take(1 + usize::from(dual))
    {
        let text = std::fs::read_to_string(dir.join(xdmf)).unwrap();
        let doc = roxmltree::Document::parse(&text).unwrap();
        for item in doc.descendants().filter(|n| n.has_tag_name("DataItem")) {
            let (file, path) = item.text().unwrap().split_once(':').unwrap();
            assert_eq!(file, "solution.h5");
            let rows: usize = item
                .attribute("Dimensions")
                .unwrap()
                .split(' ')
                .next()
                .unwrap()
                .parse()
                .unwrap();
            let data = h5.dataset(path).unwrap();
            assert_eq!(data.shape()[0], rows, "{xdmf}: {path}");
            assert_eq!(data.read_raw::<f64>().unwrap().len(), data.size());
        }
    }
    vertices
}

#[test]
fn the_dual_submesh_is_written_on_request_only() {
    let dir = tempfile::tempdir().unwrap();
    let (plain, dual) = (dir.path().join("plain"), dir.path().join("dual"));
    assert!(solve(&plain, 8).status.success());
    let status = Command::new(BIN)
        .args(["solve", "--n", "8", "--dual", "-o"])
        .arg(&dual)
        .status()
        .unwrap();
    assert!(status.success());
    assert_eq!(read_whole(&plain), 81);
    assert_eq!(read_whole(&dual), 81);
    assert!(!plain.join("dual.xdmf").exists() && dual.join("dual.xdmf").exists());
    let h5 = hdf5::File::open(dual.join("solution.h5")).unwrap();
    // Six cells of S_h per triangle of T_h (128 of them), λ_h and the owner on each.
    for field in ["lambda", "vertex"] {
        assert_eq!(h5.dataset(&format!("dual/{field}")).unwrap().shape(), [6 * 128]);
    }
}

#[test]
fn a_result_replaces_an_earlier_one_whole() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out");
    assert!(solve(&out, 8).status.success());
    assert_eq!(read_whole(&out), 81);
    assert!(solve(&out, 16).status.success());
    assert_eq!(read_whole(&out), 289);
    assert_eq!(listing(dir.path()), ["out"], "no temporary is left");
    // Another result beside it is its own: neither touches the other.
    let dual = dir.path().join("out-dual");
    assert!(solve(&dual, 8).status.success());
    assert_eq!((read_whole(&out), read_whole(&dual)), (289, 81));
}

/// An earlier result whose files this user may not delete (a directory of another owner, or
/// made read-only) is refused and left as it was: it was moved aside into a hidden directory and
/// left there, with success and no word. Run as root, the run is another user's.
#[test]
fn an_earlier_result_this_user_may_not_delete_is_left_alone() {
    use std::fs::Permissions;
    use std::os::unix::fs::PermissionsExt;
    let dir = tempfile::tempdir().unwrap();
    std::fs::set_permissions(dir.path(), Permissions::from_mode(0o777)).unwrap();
    let out = dir.path().join("out");
    assert!(solve(&out, 8).status.success());
    // SAFETY: geteuid reads the process's user.
    let root = unsafe { libc::geteuid() } == 0;
    // Read-only; and (as root, the run another user's) sticky with files of another owner, whose
    // files only their owner may delete, as in /tmp.
    let modes: &[u32] = if root { &[0o555, 0o1777] } else { &[0o555] };
    for &mode in modes {
        std::fs::set_permissions(&out, Permissions::from_mode(mode)).unwrap();
        let mut command = Command::new(BIN);
        command.args(["solve", "--n", "16", "-o"]).arg(&out);
        if root {
            command.uid(65534).gid(65534);
        }
        let run = command.output().unwrap();
        std::fs::set_permissions(&out, Permissions::from_mode(0o755)).unwrap();
        let e = String::from_utf8_lossy(&run.stderr);
        assert!(!run.status.success(), "{mode:o}: {e}");
        assert!(
            e.contains("out: the earlier result cannot be replaced: this user may not delete the files of"),
            "{mode:o}: {e}"
        );
        assert_eq!(listing(dir.path()), ["out"], "{mode:o}: no temporary is left");
        assert_eq!(read_whole(&out), 81);
    }
}

/// A step of an `adapt` result is part of that result: a solve into it is refused as such,
/// and the step is left as it was.
#[test]
fn a_step_of_an_adapt_result_is_not_replaced() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("adapt");
    let adapt = Command::new(BIN)
        .args(["-q", "adapt", "--n", "8", "--steps", "1", "-o"])
        .arg(&out)
        .output()
        .unwrap();
    assert!(adapt.status.success());
    let step = out.join("step-001");
    let before = read_whole(&step);
    let refused = solve(&step, 16);
    let e = String::from_utf8_lossy(&refused.stderr);
    assert!(
        !refused.status.success() && e.contains("is part of a result of membrane-contact"),
        "{e}"
    );
    assert_eq!(read_whole(&step), before);
}

#[test]
fn any_file_name_works() {
    // XML's special characters and a colon never reach the XDMF files, and a name of 250
    // bytes works (its temporary has a short name).
    let dir = tempfile::tempdir().unwrap();
    for name in ["a&b<c\"d:e>f'g".to_string(), "n".repeat(250)] {
        let out = dir.path().join(&name);
        let run = solve(&out, 8);
        assert!(run.status.success(), "{}", String::from_utf8_lossy(&run.stderr));
        assert_eq!(read_whole(&out), 81);
    }
}

/// The file to open is named by its resolved absolute path (it printed "/tmp/x/../x/out//solution.xdmf").
#[test]
fn the_file_to_open_is_named_by_its_resolved_path() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::create_dir(dir.path().join("sub")).unwrap();
    let run = solve(&dir.path().join("sub/../out/"), 8);
    assert!(run.status.success(), "{}", String::from_utf8_lossy(&run.stderr));
    let resolved = std::fs::canonicalize(dir.path())
        .unwrap()
        .join("out/solution.xdmf");
    let stdout = String::from_utf8_lossy(&run.stdout);
    assert!(
        stdout.contains(&format!("open {} in ParaView", resolved.display())),
        "{stdout}"
    );
}

/// The default result directory is named after the case file's stem, "case" where the stem
/// names none ("..toml": it was results/., refused as "not a result"), without an .h5 or .xdmf.
#[test]
fn a_case_file_without_a_stem_names_its_result_case() {
    let dir = tempfile::tempdir().unwrap();
    // Nor is a stem named like a file of a result ("beam.h5", refused as such): it names "beam".
    for (file, result) in [("..toml", "results/case"), ("beam.h5.toml", "results/beam")] {
        std::fs::write(dir.path().join(file), membrane_contact::case::DEFAULT_CASE).unwrap();
        let run = std::process::Command::new(env!("CARGO_BIN_EXE_membrane-contact"))
            .args(["solve", file, "--n", "8", "--quiet"])
            .current_dir(dir.path())
            .output()
            .unwrap();
        assert!(run.status.success(), "{}", String::from_utf8_lossy(&run.stderr));
        assert_eq!(read_whole(&dir.path().join(result)), 81);
    }
}

#[test]
fn a_result_reads_back_as_a_mesh() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("first:result");
    assert!(solve(&out, 8).status.success());
    let case = dir.path().join("case.toml");
    let text = "mu1 = 1.0\nmu2 = 2.0\nf1 = -5\nf2 = 5\ng = \"0.1*x\"\n\
                [mesh]\nkind = \"file\"\npath = \"first:result/solution.xdmf\"\n";
    std::fs::write(&case, text).unwrap();
    let run = Command::new(BIN)
        .arg("solve")
        .arg(&case)
        .arg("-o")
        .arg(dir.path().join("second"))
        .output()
        .unwrap();
    assert!(run.status.success(), "{}", String::from_utf8_lossy(&run.stderr));
    assert_eq!(read_whole(&dir.path().join("second")), 81);
}

#[test]
fn studies_are_whole_or_absent() {
    let dir = tempfile::tempdir().unwrap();
    // One level: a table without EOCs, and every file.
    let one = dir.path().join("one");
    let run = Command::new(BIN)
        .args(["study", "--levels", "8", "-o"])
        .arg(&one)
        .output()
        .unwrap();
    assert!(run.status.success(), "{}", String::from_utf8_lossy(&run.stderr));
    assert!(!String::from_utf8_lossy(&run.stdout).contains("EOC"));
    assert_eq!(
        listing(&one),
        [
            ".membrane-contact",
            "errors.png",
            "iterations.png",
            "study.csv",
            "study.json",
            "study.md"
        ]
    );
    // A level whose boundary data fail: checked before anything is solved or written.
    let case = dir.path().join("case.toml");
    let text =
        "mu1 = 1.0\nmu2 = 2.0\nf1 = -5\nf2 = 5\ng = \"cos(16*pi*x)\"\n[mesh]\nkind = \"rectangle\"\nn = 8\n";
    std::fs::write(&case, text).unwrap();
    let failed = dir.path().join("failed");
    let t = Instant::now();
    let run = Command::new(BIN)
        .args(["study", case.to_str().unwrap(), "--levels", "8,12", "-o"])
        .arg(&failed)
        .output()
        .unwrap();
    assert_eq!(run.status.code(), Some(1));
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert!(stderr.contains("at the boundary vertex"), "{stderr}");
    assert!(t.elapsed() < Duration::from_secs(60));
    assert_eq!(
        listing(dir.path()),
        ["case.toml", "one"],
        "a failed study leaves nothing"
    );
    // Nor does one into the default `study/<case>` (it left an empty `study/`).
    let run = Command::new(BIN)
        .args(["study", "case.toml", "--levels", "8,12"])
        .current_dir(dir.path())
        .output()
        .unwrap();
    assert_eq!(run.status.code(), Some(1));
    assert_eq!(listing(dir.path()), ["case.toml", "one"]);
}

/// The fault test: a run writing a large result is killed at several instants spread over its
/// course (SIGINT, SIGKILL, SIGTERM and SIGHUP in turn). After each, the output is the earlier
/// result or the new one, read back whole; SIGINT, SIGTERM and SIGHUP leave no temporary and exit
/// with 128 + the signal's number, and the next run clears what SIGKILL left.
#[test]
fn killed_runs_leave_the_earlier_result_or_the_new_one() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out");
    assert!(solve(&out, 16).status.success());
    let (old, n) = (read_whole(&out), 256);
    let t = Instant::now();
    assert!(solve(&out, n).status.success());
    let full = t.elapsed();
    let new = read_whole(&out);
    assert_ne!(old, new);
    assert!(solve(&out, 16).status.success());
    // The last of the nine is not SIGKILL, whose temporary only a next run clears.
    let signals = [libc::SIGINT, libc::SIGKILL, libc::SIGTERM, libc::SIGHUP];
    let mut seen = [0, 0];
    for k in 0..9 {
        let mut child = Command::new(BIN)
            .args(["solve", "--flux", "--n", &n.to_string(), "-o"])
            .arg(&out)
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn()
            .unwrap();
        // Instants from a tenth of the run to past its end.
        std::thread::sleep(full.mul_f64(0.1 + 0.125 * k as f64));
        let signal = signals[k % signals.len()];
        unsafe { libc::kill(child.id() as i32, signal) };
        let status = child.wait().unwrap();
        let vertices = read_whole(&out);
        assert!(
            vertices == old || vertices == new,
            "after kill {k}: {vertices} vertices"
        );
        seen[usize::from(vertices == new)] += 1;
        let stray: Vec<String> = listing(dir.path()).into_iter().filter(|f| f != "out").collect();
        if signal != libc::SIGKILL && status.code() != Some(0) {
            assert!(stray.is_empty(), "after signal {signal}: {stray:?}");
            // Before the run installs its handler (at its first temporary), the signal kills it.
            use std::os::unix::process::ExitStatusExt;
            assert!(
                status.code() == Some(128 + signal) || status.signal() == Some(signal),
                "after signal {signal}: {status:?}"
            );
        }
        if vertices == new {
            assert!(solve(&out, 16).status.success());
        }
    }
    assert_eq!(
        listing(dir.path()),
        ["out"],
        "the next runs cleared every temporary"
    );
    assert!(seen[0] > 0, "some kills hit the run before its end: {seen:?}");
}

/// SIGINT, SIGTERM and SIGHUP in the middle of a run: its temporary is removed, and the directories
/// it made to hold the result, it says so, and it exits with 128 + the signal's number (130, 143,
/// 129), as a shell reports a process the signal killed. The
/// signal is sent once the run has made its temporary, which is while it writes (with S_h, to make
/// that take a while); a run that still ends first (the test descheduled on a loaded machine)
/// exits 0 with its result whole, and is tried again, up to 5 times.
#[test]
fn signals_exit_with_128_plus_their_number() {
    for (signal, code) in [(libc::SIGINT, 130), (libc::SIGTERM, 143), (libc::SIGHUP, 129)] {
        let mut codes = Vec::new();
        while codes.len() < 5 && codes.last() != Some(&code) {
            let dir = tempfile::tempdir().unwrap();
            let mut command = Command::new(BIN);
            // A shell without job control starts background jobs with SIGINT ignored, which the
            // program then keeps ignored (as after `nohup`): the run gets the default handling.
            // SAFETY: signal(2) is async-signal-safe, as pre_exec requires.
            unsafe {
                command.pre_exec(|| {
                    for s in [libc::SIGINT, libc::SIGTERM, libc::SIGHUP] {
                        libc::signal(s, libc::SIG_DFL);
                    }
                    Ok(())
                })
            };
            let mut child = command
                .args(["solve", "--n", "256", "--dual", "-o"])
                .arg(dir.path().join("made/deeper/out"))
                .stdout(Stdio::null())
                .stderr(Stdio::piped())
                .spawn()
                .unwrap();
            // The handler is in place once the run has made its temporary.
            let parent = dir.path().join("made/deeper");
            let partial = || parent.exists() && listing(&parent).iter().any(|f| f.ends_with(".mc-partial"));
            let t = Instant::now();
            while !partial() {
                assert!(
                    child.try_wait().unwrap().is_none() && t.elapsed() < Duration::from_secs(60),
                    "the run ended before it was signalled"
                );
                std::thread::sleep(Duration::from_millis(1));
            }
            unsafe { libc::kill(child.id() as i32, signal) };
            let output = child.wait_with_output().unwrap();
            let status = output.status.code();
            // Said, after the lines of what the run had done (it exited without a word).
            let said = format!("interrupted (signal {signal}): the result being written is discarded");
            let stderr = String::from_utf8_lossy(&output.stderr);
            assert!(
                status != Some(code) || stderr.lines().any(|l| l.starts_with(&said)),
                "{stderr}"
            );
            let expected = match status {
                Some(0) => vec!["made".to_string()],
                _ => Vec::new(),
            };
            assert_eq!(listing(dir.path()), expected, "signal {signal}: exit {status:?}");
            codes.push(status.unwrap_or(-1));
        }
        assert!(
            codes.iter().all(|&c| c == 0 || c == code) && codes.last() == Some(&code),
            "signal {signal}: exit codes {codes:?}, expected {code}"
        );
    }
}

/// A study or an adapt run that cannot write its files (past a file size limit, as on a full
/// disk) names them in the result's place, not in its hidden temporary (it said
/// "./.08d9….mc-partial/iterations.png"), and leaves nothing behind.
#[test]
fn write_errors_of_study_and_adapt_name_the_result() {
    let runs: [(&str, &[&str]); 2] = [
        ("study", &["--levels", "8"]),
        ("adapt", &["--n", "8", "--steps", "1"]),
    ];
    for (command, args) in runs {
        let dir = tempfile::tempdir().unwrap();
        let mut cmd = Command::new(BIN);
        cmd.args([command, "--quiet"])
            .args(args)
            .arg("-o")
            .arg(dir.path().join("out/"));
        // SAFETY: setrlimit and signal are async-signal-safe.
        unsafe {
            cmd.pre_exec(|| {
                let limit = libc::rlimit {
                    rlim_cur: 20_000,
                    rlim_max: 20_000,
                };
                libc::signal(libc::SIGXFSZ, libc::SIG_DFL);
                match libc::setrlimit(libc::RLIMIT_FSIZE, &limit) {
                    0 => Ok(()),
                    _ => Err(std::io::Error::last_os_error()),
                }
            });
        }
        let run = cmd.output().unwrap();
        let e = String::from_utf8_lossy(&run.stderr);
        assert_eq!(run.status.code(), Some(1), "{command}: {e}");
        assert!(
            e.contains("/out/") && !e.contains("mc-partial") && !e.contains("//"),
            "{command}: {e}"
        );
        assert!(
            listing(dir.path()).is_empty(),
            "{command}: {:?}",
            listing(dir.path())
        );
    }
}
