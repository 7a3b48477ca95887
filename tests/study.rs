//! Convergence studies: the paper's rates on a convex case, the corner singularity and its cure
//! by graded meshes, bounded iterations with nested iteration, and the files the command writes.

use membrane_contact::case::{Case, Levels};
use membrane_contact::study::{self, eoc, Level, StudyOptions};
use std::path::Path;
use std::process::Command;

fn levels(case: &Case, sizes: &[usize], cold: bool) -> Vec<Level> {
    let options = StudyOptions {
        levels: Levels::Cells(sizes.to_vec()),
        cold,
        hminus1_max: 64,
        grading: None,
    };
    let cases: Vec<Case> = (sizes.iter())
        .map(|&n| {
            let mut c = case.clone();
            c.set_cells(n).unwrap();
            c
        })
        .collect();
    study::run_levels(&cases, &options, |_, _| {}).unwrap()
}

fn last_eoc(levels: &[Level], error: impl Fn(&Level) -> f64) -> (f64, f64) {
    let (a, b) = (&levels[levels.len() - 2], &levels[levels.len() - 1]);
    eoc(a, b, error(a), error(b)).unwrap()
}

#[test]
fn convex_case_shows_the_rates_of_theorem_9() {
    let case = Case::read(Path::new("data/cases/disk_jump.toml")).unwrap();
    let l = levels(&case, &[8, 16, 32], true);
    let e = |f: fn(&membrane_contact::norms::Errors) -> f64| move |l: &Level| f(l.errors.as_ref().unwrap());
    for (name, rate, lo, hi) in [
        ("H1 u1", last_eoc(&l, e(|e| e.h1_u1.unwrap())).0, 0.9, 1.1),
        ("H1 u2", last_eoc(&l, e(|e| e.h1_u2.unwrap())).0, 0.9, 1.1),
        ("L2 u1", last_eoc(&l, e(|e| e.l2_u1)).0, 1.8, 2.2),
        ("L2 u2", last_eoc(&l, e(|e| e.l2_u2)).0, 1.8, 2.2),
    ] {
        assert!((lo..hi).contains(&rate), "{name}: EOC {rate}");
    }
    // λ_h → λ in L² (Remark 22) and faster in H⁻¹ (Theorem 21).
    let l2 = last_eoc(&l, e(|e| e.l2_lambda)).0;
    let hm1 = last_eoc(&l, e(|e| e.hminus1_lambda.unwrap())).0;
    assert!(l2 > 0.3 && hm1 > 0.9 && hm1 > l2, "λ: L2 EOC {l2}, H-1 EOC {hm1}");
    // Nested iteration keeps the iterations bounded; a cold start needs more on the finest level.
    assert!(
        l.iter().all(|l| l.iterations <= 4),
        "{:?}",
        l.iter().map(|l| l.iterations).collect::<Vec<_>>()
    );
    assert!(l[2].cold_iterations.unwrap() > l[2].iterations);
}

#[test]
fn graded_meshes_restore_the_rate_at_the_reentrant_corner() {
    let mut case = Case::read(Path::new("data/cases/lshape_corner.toml")).unwrap();
    let sizes = [16, 32, 64];
    let uniform = levels(&case, &sizes, false);
    case.set_grading(2.0).unwrap();
    let graded = levels(&case, &sizes, false);
    let h1_u2 = |l: &Level| l.errors.as_ref().unwrap().h1_u2.unwrap();
    // Against N^(-1/2): the corner singularity r^(2/3) slows the uniform mesh down (towards 2/3),
    // the graded mesh keeps rate 1 (Remark 10).
    let (u, g) = (last_eoc(&uniform, h1_u2).1, last_eoc(&graded, h1_u2).1);
    assert!(u < 0.9, "uniform: {u}");
    assert!((0.95..1.1).contains(&g), "graded: {g}");
}

#[test]
fn study_command_writes_tables_and_plots() {
    let dir = tempfile::tempdir().unwrap();
    let run = Command::new(env!("CARGO_BIN_EXE_membrane-contact"))
        .args([
            "study",
            "data/cases/no_contact.toml",
            "--levels",
            "4,8,16",
            "--cold",
            "-o",
        ])
        .arg(dir.path().join("study"))
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&run.stdout);
    assert!(run.status.success(), "{}", String::from_utf8_lossy(&run.stderr));
    assert!(stdout.contains("| 16² |"), "{stdout}");
    for f in [
        "study.md",
        "study.csv",
        "study.json",
        "errors.png",
        "iterations.png",
    ] {
        let meta = std::fs::metadata(dir.path().join("study").join(f)).unwrap();
        assert!(meta.len() > 100, "{f} is {} bytes", meta.len());
    }
    let csv = std::fs::read_to_string(dir.path().join("study/study.csv")).unwrap();
    assert_eq!(csv.lines().count(), 4);
    assert!(csv.starts_with("cells,h,vertices,h1_u1,eoc_h1_u1"));
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.path().join("study/study.json")).unwrap()).unwrap();
    assert_eq!(json[2]["cells"], 16);
    assert!(json[2]["refine"].is_null());
    assert!(json[2]["errors"]["h1_u1"].as_f64().unwrap() > 0.0);
    // Bad levels are an error, not a panic.
    let bad = Command::new(env!("CARGO_BIN_EXE_membrane-contact"))
        .args(["study", "--levels", "16,8"])
        .output()
        .unwrap();
    assert_eq!(bad.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&bad.stderr).contains("--levels must be increasing"));
}

#[test]
fn disk_study_by_refinement_converges_at_rate_one() {
    // Curved refinement: the polygonal ω_h converges to the disk, so the H¹ errors against the
    // disk's exact solution fall at rate 1 and the L² errors at rate 2.
    let dir = tempfile::tempdir().unwrap();
    let run = Command::new(env!("CARGO_BIN_EXE_membrane-contact"))
        .args([
            "study",
            "data/cases/disk_contact.toml",
            "--refine",
            "0,1,2,3",
            "-o",
        ])
        .arg(dir.path().join("study"))
        .output()
        .unwrap();
    assert!(run.status.success(), "{}", String::from_utf8_lossy(&run.stderr));
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.path().join("study/study.json")).unwrap()).unwrap();
    let level = |i: usize, key: &str| json[i]["errors"][key].as_f64().unwrap();
    let rate = |key: &str| {
        (level(2, key) / level(3, key)).ln()
            / (json[2]["h"].as_f64().unwrap() / json[3]["h"].as_f64().unwrap()).ln()
    };
    let (h1, l2) = (rate("h1_u1"), rate("l2_u2"));
    assert!(
        (0.95..1.05).contains(&h1) && (1.9..2.1).contains(&l2),
        "EOCs {h1}, {l2}"
    );
    assert_eq!(json[3]["refine"], 3);
    assert!(
        (1..4).all(|i| json[i]["iterations"].as_u64().unwrap() <= 4),
        "{json}"
    );
    let csv = std::fs::read_to_string(dir.path().join("study/study.csv")).unwrap();
    assert!(
        csv.starts_with("refine,h,vertices") && csv.contains("\n3,"),
        "{csv}"
    );
    // Cells per side do not apply to a disk.
    let bad = Command::new(env!("CARGO_BIN_EXE_membrane-contact"))
        .args(["study", "data/cases/disk_contact.toml", "--levels", "8,16"])
        .output()
        .unwrap();
    assert_eq!(bad.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&bad.stderr).contains("not of kind = \"disk\": use --refine"));
}
