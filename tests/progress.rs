//! Progress on stderr: the phases of `solve` one line each, in order, when stderr is not a
//! terminal; none with `--quiet`; stdout the summary either way.

use std::process::Command;

fn solve(dir: &std::path::Path, name: &str, quiet: bool) -> (String, String) {
    let mut cmd = Command::new(env!("CARGO_BIN_EXE_membrane-contact"));
    cmd.args(["solve", "--n", "16", "--estimate", "-o"])
        .arg(dir.join(name));
    if quiet {
        cmd.arg("--quiet");
    }
    let out = cmd.output().unwrap();
    let (stdout, stderr) = (
        String::from_utf8_lossy(&out.stdout).to_string(),
        String::from_utf8_lossy(&out.stderr).to_string(),
    );
    assert!(out.status.success(), "{stderr}");
    (stdout, stderr)
}

/// The summary without its timings and memory, which change from run to run.
fn steady(summary: &str, dir: &std::path::Path) -> String {
    let text = summary.replace(&dir.display().to_string(), "DIR");
    let lines = text.lines().filter(|l| !l.starts_with("seconds"));
    lines
        .map(|l| l.replace("/quiet", "/loud"))
        .collect::<Vec<_>>()
        .join("\n")
}

#[test]
fn phases_on_stderr_in_order_and_none_when_quiet() {
    let dir = tempfile::tempdir().unwrap();
    let (stdout, stderr) = solve(dir.path(), "loud", false);
    let lines: Vec<&str> = stderr.lines().collect();
    assert!(
        lines.iter().all(|l| l.starts_with('[') && l.contains(" s] ")),
        "{stderr}"
    );
    let phases = [
        "meshing",
        "assembly: 289 vertices",
        "contact solve",
        "active-set iteration 1: ",
        "postprocess: λ_h and its checks, error norms",
        "estimate",
        "writing ",
    ];
    let mut at = 0;
    for phase in phases {
        let found = lines[at..].iter().position(|l| l.contains(phase));
        at += found.unwrap_or_else(|| panic!("no '{phase}' after line {at}:\n{stderr}")) + 1;
    }
    assert!(
        lines
            .iter()
            .any(|l| l.contains("active-set iteration 2: 0 vertices changed set")),
        "{stderr}"
    );
    assert!(!stdout.contains("] "), "no progress on stdout:\n{stdout}");
    assert!(
        stdout.starts_with("case ") && stdout.contains("\nsolver "),
        "{stdout}"
    );

    let (quiet_stdout, quiet_stderr) = solve(dir.path(), "quiet", true);
    assert_eq!(quiet_stderr, "", "--quiet shows nothing");
    assert_eq!(steady(&quiet_stdout, dir.path()), steady(&stdout, dir.path()));
}

/// A reader that has gone (`… | head -1`: stdout and stderr are pipes whose read ends are
/// closed) does not stop the run, which writes its result and exits 0; a stdout that cannot be
/// written otherwise (a full disk) is one line of error after the result is written, exit 1.
#[test]
fn a_closed_pipe_or_a_full_stdout_does_not_cost_the_result() {
    let dir = tempfile::tempdir().unwrap();
    let mut child = Command::new(env!("CARGO_BIN_EXE_membrane-contact"))
        .args(["solve", "--n", "16", "-o"])
        .arg(dir.path().join("piped"))
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    // Closing the read ends makes every write to them fail with EPIPE.
    drop(child.stdout.take());
    drop(child.stderr.take());
    assert!(child.wait().unwrap().success());
    assert!(dir.path().join("piped/solution.h5").exists());
    let out = Command::new(env!("CARGO_BIN_EXE_membrane-contact"))
        .args(["solve", "--n", "16", "--quiet", "-o"])
        .arg(dir.path().join("full"))
        .stdout(std::fs::File::create("/dev/full").unwrap())
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{stderr}");
    assert!(
        stderr.starts_with("error: cannot write the summary to stdout: ") && stderr.lines().count() == 1,
        "{stderr}"
    );
    assert!(dir.path().join("full/solution.h5").exists());
}

#[test]
fn what_the_problem_cannot_compute_is_refused_before_meshing() {
    // The estimator with g2 ≠ 0 is not available: refused at once, before the mesh is made, so
    // that no phase is shown.
    let dir = tempfile::tempdir().unwrap();
    let case = dir.path().join("g2.toml");
    let text = "mu1 = 1.0\nmu2 = 2.0\nf1 = -5\nf2 = 5\ng = \"0.1*x\"\ng2 = -0.1\n[mesh]\nkind = \"rectangle\"\nn = [6, 6]\n";
    std::fs::write(&case, text).unwrap();
    let out = Command::new(env!("CARGO_BIN_EXE_membrane-contact"))
        .arg("solve")
        .arg(&case)
        .arg("--estimate")
        .arg("-o")
        .arg(dir.path().join("out"))
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        !out.status.success() && stderr.contains("not available yet"),
        "{stderr}"
    );
    assert!(!stderr.contains("meshing"), "{stderr}");
}
