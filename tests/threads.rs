//! The numbers do not depend on the number of threads: a multigrid case large enough that every
//! parallel path works in several pieces (the smoother's blocks, the loops over vertices, rows,
//! triangles and dual cells), solved and postprocessed on 1, 2, 3 and 8 threads, gives the same
//! fields and attributes bit for bit; and the CLI's `--threads` sets the pool.

use membrane_contact::case::Case;
use membrane_contact::contact::{LinearSolver, Start};
use membrane_contact::result::Describe;
use membrane_contact::run;

/// Every field and every attribute but the timings of the default case on 256² cells solved
/// with multigrid, with flux, estimate and ‖λ − λh‖_H⁻¹, on a pool of `threads`, as text that
/// holds each f64 exactly (its shortest round-trip form).
fn everything(threads: usize) -> Vec<String> {
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .unwrap();
    pool.install(|| {
        let mut case = Case::default_case();
        case.set_cells(256).unwrap();
        case.solver.linear = LinearSolver::Multigrid;
        let options = run::Options {
            start: Start::Nested,
            hminus1: true,
            flux: true,
            estimate: true,
            dual: true,
        };
        let dir = tempfile::tempdir().unwrap();
        let r = run::solve(&case, &options, &dir.path().join("out")).unwrap();
        assert!(r.problem.mesh.n_vertices() > 4 * membrane_contact::multigrid::BLOCK_ROWS);
        let mut out: Vec<String> = (r.fields().into_iter())
            .map(|f| format!("{} {:?}", f.name, f.values()))
            .collect();
        out.extend(
            (r.attributes().into_iter())
                .filter(|(name, _)| !name.contains("seconds"))
                .map(|(name, value)| format!("{name} {value:?}")),
        );
        out
    })
}

#[test]
fn fields_are_the_same_bit_for_bit_on_1_2_3_and_8_threads() {
    let one = everything(1);
    assert!(one.len() > 30, "{} fields and attributes", one.len());
    for threads in [2, 3, 8] {
        let other = everything(threads);
        assert_eq!(one.len(), other.len());
        for (a, b) in one.iter().zip(&other) {
            let name = a.split(' ').next().unwrap();
            assert!(a == b, "{name} differs on {threads} threads");
        }
    }
}

#[test]
fn the_threads_option_sets_the_pool() {
    let bin = env!("CARGO_BIN_EXE_membrane-contact");
    let dir = tempfile::tempdir().unwrap();
    let run = |threads: &str| {
        std::process::Command::new(bin)
            .args(["solve", "--n", "32", "--threads", threads, "-o"])
            .arg(dir.path().join(threads))
            .output()
            .unwrap()
    };
    let three = run("3");
    assert!(three.status.success());
    let summary = String::from_utf8_lossy(&three.stdout);
    assert!(summary.contains("on 3 threads"), "{summary}");
    let zero = run("0");
    assert!(!zero.status.success());
    let message = String::from_utf8_lossy(&zero.stderr);
    assert!(message.contains("--threads"), "{message}");
}

/// The peak resident memory of a run of the program, in MB, as its summary says (the process's
/// own: the `ru_maxrss` of a child counts the memory of the parent it was forked from).
fn peak_mb(args: &[&str]) -> u64 {
    let bin = env!("CARGO_BIN_EXE_membrane-contact");
    let out = std::process::Command::new(bin).args(args).output().unwrap();
    assert!(out.status.success());
    let summary = String::from_utf8_lossy(&out.stdout);
    let peak = summary
        .split("peak memory ")
        .nth(1)
        .and_then(|s| s.split(' ').next());
    peak.and_then(|p| p.parse().ok())
        .unwrap_or_else(|| panic!("{summary}"))
}

#[test]
fn memory_does_not_grow_with_the_threads() {
    let dir = tempfile::tempdir().unwrap();
    let peak = |threads: &str| {
        let out = dir.path().join(threads);
        peak_mb(&[
            "solve",
            "--n",
            "512",
            "--threads",
            threads,
            "-o",
            out.to_str().unwrap(),
        ])
    };
    // From two threads on, v's solve and w's steps overlap (on one they run in turn); from two to
    // eight the peak moves by a few per cent (2–4 % here).
    let (two, eight) = (peak("2"), peak("8"));
    assert!(
        eight as f64 <= 1.1 * two as f64,
        "peak {eight} MB on 8 threads, {two} MB on 2"
    );
}
