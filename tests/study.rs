//! Convergence studies: the paper's rates on every pair of levels after the first two, on convex
//! and non-convex domains, the corner singularity and its cure by graded meshes, bounded iterations with nested iteration, and the files the command writes.

use membrane_contact::case::{Case, Levels};
use membrane_contact::norms::Errors;
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
    study::run_levels(&cases, &options, |_, _, _| {}).unwrap()
}

/// The EOCs (against h, and against N^(−1/2)) of `error` between every pair of successive levels
/// after the first two.
fn eocs(levels: &[Level], error: impl Fn(&Level) -> f64) -> Vec<(f64, f64)> {
    (levels.windows(2).skip(1))
        .map(|w| eoc(&w[0], &w[1], error(&w[0]), error(&w[1])).unwrap())
        .collect()
}

type Norm = fn(&Errors) -> f64;

/// Asserts the EOC against h of each norm within its bounds on every pair after the first two.
fn rates(case_file: &str, bounds: &[(&str, Norm, f64, f64)]) -> Vec<Level> {
    let case = Case::read(Path::new(case_file)).unwrap();
    let l = levels(&case, &[8, 16, 32, 64], false);
    for &(name, norm, lo, hi) in bounds {
        for (k, (rate, _)) in eocs(&l, |l| norm(l.errors.as_ref().unwrap()))
            .into_iter()
            .enumerate()
        {
            assert!(
                (lo..hi).contains(&rate),
                "{case_file}: {name}, EOC {rate} at pair {}",
                k + 2
            );
        }
    }
    l
}

/// Theorem 9 (H¹: 1), the L² rate 2 on convex domains, Theorem 21 (H⁻¹ of λ: at least 1).
const CONVEX: [(&str, Norm, f64, f64); 5] = [
    ("H1 u1", |e| e.h1_u1.unwrap(), 0.95, 1.1),
    ("H1 u2", |e| e.h1_u2.unwrap(), 0.95, 1.1),
    ("L2 u1", |e| e.l2_u1, 1.85, 2.15),
    ("L2 u2", |e| e.l2_u2, 1.85, 2.15),
    ("H-1 lambda", |e| e.hminus1_lambda.unwrap(), 0.9, 2.5),
];

#[test]
fn convex_cases_show_the_rates_of_theorems_9_and_21() {
    for case in ["data/cases/disk_jump.toml", "data/cases/default.toml"] {
        let l = rates(case, &CONVEX);
        // Nested iteration keeps the iterations bounded.
        assert!(
            l.iter().all(|l| l.iterations <= 4),
            "{case}: {:?}",
            l.iter().map(|l| l.iterations).collect::<Vec<_>>()
        );
    }
}

#[test]
fn the_ball_obstacle_converges_at_the_rates_of_p1_in_few_iterations() {
    // The field's benchmark (data/cases/ball.toml): u ∈ H^{2-ε}, so |u − u_h|_H¹ at rate 1 and
    // ‖u − u_h‖_L² at about 2 (the measured values, not only the rates, against the closed form),
    // and at most 4 active-set iterations per level after the first with nested iteration.
    let case = Case::read(Path::new("data/cases/ball.toml")).unwrap();
    let l = levels(&case, &[16, 32, 64, 128], false);
    let h1 = |l: &Level| l.errors.as_ref().unwrap().h1_u1.unwrap();
    for (rate, _) in eocs(&l, h1) {
        assert!((0.95..1.1).contains(&rate), "H1 u, EOC {rate}");
    }
    for (rate, _) in eocs(&l, |l| l.errors.as_ref().unwrap().l2_u1) {
        assert!((1.8..2.5).contains(&rate), "L2 u, EOC {rate}");
    }
    // |u − u_h|_H¹ ≈ 4.4e-3 · (1/h) with h = 4/n: 3.43e-2 at 128².
    assert!((3.3e-2..3.6e-2).contains(&h1(&l[3])), "{}", h1(&l[3]));
    assert!(
        l.iter().skip(1).all(|l| l.iterations <= 4),
        "{:?}",
        l.iter().map(|l| l.iterations).collect::<Vec<_>>()
    );
    // The study estimates above an obstacle too (docs/a-posteriori.md §14): η bounds the error.
    for l in &l {
        let errors = l.errors.as_ref().unwrap();
        assert!(errors.rigid && l.estimator.unwrap() >= errors.energy.unwrap());
    }
    // … and its table shows η beside the error, as between two membranes.
    let table = study::markdown_table("ball", &l);
    assert!(table.contains("η (bound of energy)"), "{table}");
    // Every row has as many cells as the header: the bars of |u−uh|_H1 are escaped.
    let cells = |row: &str| row.replace("\\|", "").matches('|').count();
    let rows: Vec<&str> = table.lines().filter(|r| r.starts_with('|')).collect();
    assert!(
        rows.len() == 6 && rows.iter().all(|r| cells(r) == cells(rows[0])),
        "{table}"
    );
}

#[test]
fn a_smooth_solution_on_a_non_convex_domain_keeps_rate_one() {
    // The L-shape with μ1 ≠ μ2 and g ≠ 0: H¹ at rate 1 (Theorem 9 needs no convexity for a smooth
    // solution); L² at least 4/3, the duality argument's rate on this corner.
    let mut bounds = CONVEX;
    bounds[2].2 = 1.3;
    bounds[3].2 = 1.3;
    rates("data/cases/lshape_tensions.toml", &bounds);
}

#[test]
fn nested_iteration_beats_a_cold_start() {
    let case = Case::read(Path::new("data/cases/disk_jump.toml")).unwrap();
    let l = levels(&case, &[8, 16, 32], true);
    assert!(l.iter().all(|l| l.iterations <= 4));
    assert!(l[2].cold_iterations.unwrap() > l[2].iterations);
}

#[test]
fn graded_meshes_restore_the_rate_at_the_reentrant_corner() {
    let mut case = Case::read(Path::new("data/cases/lshape_corner.toml")).unwrap();
    let sizes = [8, 16, 32, 64];
    let uniform = levels(&case, &sizes, false);
    case.set_grading(2.0).unwrap();
    let graded = levels(&case, &sizes, false);
    let h1_u2 = |l: &Level| l.errors.as_ref().unwrap().h1_u2.unwrap();
    // Against N^(-1/2): the corner singularity r^(2/3) slows the uniform mesh down (towards 2/3),
    // the graded mesh keeps rate 1 (Remark 10), on every pair after the first two.
    let (u, g) = (eocs(&uniform, h1_u2), eocs(&graded, h1_u2));
    for ((_, u), (_, g)) in u.iter().zip(&g) {
        assert!(*u < 0.95 && (0.95..1.1).contains(g), "uniform {u}, graded {g}");
    }
    assert!(u[u.len() - 1].1 < 0.9, "uniform, last pair: {:?}", u.last());
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
    // On a polygon that is ω itself, no note that the exact solution misses the boundary data.
    assert!(!stdout.contains("misses the boundary data"), "{stdout}");
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
    assert!(csv.starts_with("cells,cells_across,h,vertices,h1_u1,eoc_h1_u1,eoc_n_h1_u1,"));
    // The EOC against N^(−1/2) from the CSV's own N and errors (it had only the EOC against h).
    let rows: Vec<Vec<f64>> = (csv.lines().skip(1))
        .map(|r| {
            r.split(',')
                .take(7)
                .map(|x| x.parse().unwrap_or(f64::NAN))
                .collect()
        })
        .collect();
    let expected = 2.0 * (rows[1][4] / rows[2][4]).ln() / (rows[2][3] / rows[1][3]).ln();
    assert!(
        (rows[2][6] - expected).abs() < 1e-12,
        "{} against {expected}",
        rows[2][6]
    );
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
    // The exact solution is the disk's: the table says that its errors are not of ω_h's problem.
    let md = std::fs::read_to_string(dir.path().join("study/study.md")).unwrap();
    assert!(
        md.contains("The exact solution misses the boundary data on ∂ω_h"),
        "{md}"
    );
    assert!(
        (1..4).all(|i| json[i]["iterations"].as_u64().unwrap() <= 4),
        "{json}"
    );
    let csv = std::fs::read_to_string(dir.path().join("study/study.csv")).unwrap();
    assert!(
        csv.starts_with("refine,cells_across,h,vertices") && csv.contains("\n3,"),
        "{csv}"
    );
    // Cells per side do not apply to a disk.
    let bad = Command::new(env!("CARGO_BIN_EXE_membrane-contact"))
        .args(["study", "data/cases/disk_contact.toml", "--levels", "8,16"])
        .output()
        .unwrap();
    assert_eq!(bad.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&bad.stderr)
        .contains("not to kind = \"disk\": give refinements instead (--refine"));
}

#[test]
fn a_rectangle_with_unequal_sides_is_labelled_by_both() {
    // 2.5 × 2 with 40 × 32 cells: at 10 cells along the longer side, 8 along the shorter.
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("rect.toml");
    let text = "mu1 = 1.0\nmu2 = 2.0\nf1 = -5\nf2 = 5\ng = 0\n[mesh]\nkind = \"rectangle\"\n\
                corners = [[-1.0, -1.0], [1.5, 1.0]]\nn = [40, 32]\n";
    std::fs::write(&path, text).unwrap();
    let case = Case::read(&path).unwrap();
    let l = levels(&case, &[10, 20], false);
    assert_eq!(l[0].vertices, 11 * 9);
    let table = study::markdown_table("rect", &l);
    assert!(
        table.contains("| 10 × 8 |") && table.contains("| 20 × 16 |"),
        "{table}"
    );
}

/// An `[exact]` that misses its equation is flagged per level in the CSV and JSON, and the note
/// names the levels (it said "On a level", and the CSV's effectivities carried no mark).
#[test]
fn a_wrong_exact_solution_is_flagged_on_each_level() {
    let dir = tempfile::tempdir().unwrap();
    let text = std::fs::read_to_string("data/cases/default.toml").unwrap();
    let wrong = text.replacen("f2 = \"2*pi^2*", "f2 = \"3*pi^2*", 1);
    assert_ne!(wrong, text);
    std::fs::write(dir.path().join("wrong.toml"), wrong).unwrap();
    study_command(&dir.path().join("wrong.toml"), "8,16", &dir.path().join("study"));
    let md = std::fs::read_to_string(dir.path().join("study/study.md")).unwrap();
    assert!(
        md.contains("On every level, [exact] does not solve −μ2Δu2 + λ = f2"),
        "{md}"
    );
    let csv = std::fs::read_to_string(dir.path().join("study/study.csv")).unwrap();
    let header: Vec<&str> = csv.lines().next().unwrap().split(',').collect();
    let column = header
        .iter()
        .position(|c| *c == "exact_equation_mismatch")
        .unwrap();
    for row in csv.lines().skip(1) {
        let share: f64 = row.split(',').nth(column).unwrap().parse().unwrap();
        assert!(share > 0.5, "{row}");
    }
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.path().join("study/study.json")).unwrap()).unwrap();
    assert!(json[1]["errors"]["exact_equation_mismatch"].as_f64().unwrap() > 0.5);
}

/// A load the case's rule does not resolve (a layer of width 3e-3 on 8² and 16² meshes): η is
/// not a guaranteed bound there, and the study says so per level in its table, CSV and JSON
/// (it headed the column "η (bound of energy)" on every level without a word).
#[test]
fn a_study_says_on_which_levels_eta_is_not_a_bound() {
    let dir = tempfile::tempdir().unwrap();
    let text = "mu1 = 1.0\nmu2 = 1.0\nf1 = \"-1 - 50*exp(-(x - 0.3)^2/1e-5)\"\nf2 = \"0\"\ng = \"0\"\n\
                [mesh]\nkind = \"rectangle\"\nn = 8\n";
    std::fs::write(dir.path().join("layer.toml"), text).unwrap();
    study_command(&dir.path().join("layer.toml"), "8,16", &dir.path().join("study"));
    let read = |name: &str| std::fs::read_to_string(dir.path().join("study").join(name)).unwrap();
    let md = read("study.md");
    assert!(
        md.contains("**only on the levels with \"yes\" under \"bound\"**"),
        "{md}"
    );
    assert_eq!(md.matches("| NO |").count(), 2, "{md}");
    let csv = read("study.csv");
    let header: Vec<&str> = csv.lines().next().unwrap().split(',').collect();
    let column = header.iter().position(|c| *c == "bound").unwrap();
    assert!(
        csv.lines()
            .skip(1)
            .all(|row| row.split(',').nth(column) == Some("0")),
        "{csv}"
    );
    let json: serde_json::Value = serde_json::from_str(&read("study.json")).unwrap();
    assert_eq!(json[0]["bound"], serde_json::Value::Bool(false));
}

/// `membrane-contact study CASE --levels LEVELS -o OUT`, which must succeed.
fn study_command(case: &Path, levels: &str, out: &Path) {
    let run = Command::new(env!("CARGO_BIN_EXE_membrane-contact"))
        .args(["-q", "study", "--levels", levels, "-o"])
        .arg(out)
        .arg(case)
        .output()
        .unwrap();
    assert!(run.status.success(), "{}", String::from_utf8_lossy(&run.stderr));
}

/// The study's CSV as (header, rows).
fn csv_of(dir: &Path) -> (Vec<String>, Vec<Vec<String>>) {
    let text = std::fs::read_to_string(dir.join("study.csv")).unwrap();
    let mut lines = text
        .lines()
        .map(|l| l.split(',').map(str::to_string).collect::<Vec<_>>());
    (lines.next().unwrap(), lines.collect())
}

/// Round-off has no EOC and no curve: on a solution exact in P1 no column gets one (η and
/// ‖λ − λ_h‖ had EOCs of −1 … −2 from their round-off, the errors none), and no plot is drawn; where
/// λ = 0 and λ_h is round-off (no_contact), ‖λ − λ_h‖_L² gets none while the errors of u keep theirs.
#[test]
fn round_off_gets_no_eoc_and_no_curve() {
    let dir = tempfile::tempdir().unwrap();
    let linear = "mu1 = 1.0\nmu2 = 2.0\nf1 = 0\nf2 = 0\ng = \"1 + x + y\"\n\
                  [exact]\nu1 = \"1 + x + y\"\nu2 = \"0\"\nlambda = \"0\"\n\
                  [mesh]\nkind = \"rectangle\"\nn = 8\n";
    std::fs::write(dir.path().join("linear.toml"), linear).unwrap();
    let study = |case: &Path, out: &str| {
        study_command(case, "8,16,32", &dir.path().join(out));
        csv_of(&dir.path().join(out))
    };
    let (header, rows) = study(&dir.path().join("linear.toml"), "linear");
    for (k, name) in header.iter().enumerate().filter(|(_, n)| n.starts_with("eoc_")) {
        assert!(rows.iter().all(|r| r[k].is_empty()), "{name}: {rows:?}");
    }
    assert!(!dir.path().join("linear/errors.png").exists());
    let md = std::fs::read_to_string(dir.path().join("linear/study.md")).unwrap();
    assert!(md.contains("No plot: no error or η above round-off"), "{md}");
    // Without [exact], η alone: its round-off gets no EOC either (it got −2.0 and −5.5).
    let plane = linear.split("[exact]").next().unwrap().to_string() + "[mesh]\nkind = \"rectangle\"\nn = 8\n";
    std::fs::write(dir.path().join("plane.toml"), plane).unwrap();
    let (header, rows) = study(&dir.path().join("plane.toml"), "plane");
    let eta = header.iter().position(|c| c == "eoc_estimator").unwrap();
    assert!(rows.iter().all(|r| r[eta].is_empty()), "{rows:?}");
    assert!(!dir.path().join("plane/errors.png").exists());
    // u1 = 10⁶ + sin πx sin πy and u2 = 0, computed from v and w of 10⁶: u2's errors are the
    // round-off of those (about 10⁻⁷), without EOCs, while u1's keep theirs (they had −1.1 … 0.3).
    let lifted = "mu1 = 1.0\nmu2 = 1.0\nf1 = \"2*pi^2*sin(pi*x)*sin(pi*y)\"\nf2 = 0\ng = \"1e6\"\n\
                  [exact]\nu1 = \"1e6 + sin(pi*x)*sin(pi*y)\"\nu2 = 0\nlambda = 0\n\
                  [mesh]\nkind = \"rectangle\"\nn = 8\n";
    std::fs::write(dir.path().join("lifted.toml"), lifted).unwrap();
    let (header, rows) = study(&dir.path().join("lifted.toml"), "lifted");
    let column = |name: &str| header.iter().position(|c| c == name).unwrap();
    assert!(rows
        .iter()
        .all(|r| r[column("eoc_h1_u2")].is_empty() && r[column("eoc_l2_u2")].is_empty()));
    assert!(
        rows[1..].iter().all(|r| !r[column("eoc_h1_u1")].is_empty()),
        "{rows:?}"
    );
    let (header, rows) = study(Path::new("data/cases/no_contact.toml"), "no_contact");
    let column = |name: &str| header.iter().position(|c| c == name).unwrap();
    assert!(
        rows.iter().all(|r| r[column("eoc_l2_lambda")].is_empty()),
        "{rows:?}"
    );
    assert!(
        rows[1..].iter().all(|r| !r[column("eoc_energy")].is_empty()),
        "{rows:?}"
    );
}
