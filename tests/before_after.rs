//! Results agree with those written before the pipeline was restructured: the files in
//! `tests/data/before-*.h5` were written by the earlier program (`solve CASE --n 16 --hminus1
//! --flux`). Every dataset and every attribute the two share must agree to the bit — or, since K
//! leaves out the couplings that vanish (which changes the order of the Cholesky factorization's
//! sums), to 1e-12 of the dataset's largest magnitude (of the attribute's magnitude) — but for the
//! intended changes: λ_h on the dual cells of boundary vertices is now 0 (the paper's λ_h), not
//! NaN, `error_hm1_lambda` is now spelled `error_hminus1_lambda`, the absolute checks gave way
//! to relative ones (`check_*`), and a zero may change sign (`min` and `max` of case expressions
//! now give −0 and +0 on a tie of ±0, where `f64::min` and `f64::max` left it open). Timings,
//! the relative round-off of the checks (`check_*`, `flux_conservation_*`) and the nonzeros of the Cholesky factor
//! (`factor_nnz`) are not compared.

use membrane_contact::case::Case;
use membrane_contact::contact::{LinearSolver, Start};
use membrane_contact::run;
use std::path::Path;

/// Equal to the bit, or within 1e-12 of `scale`.
fn close(a: f64, b: f64, scale: f64) -> bool {
    a.to_bits() == b.to_bits() || (a - b).abs() <= 1e-12 * scale
}

fn compare(case_file: &str, before: &str) {
    let mut case = Case::read(Path::new(case_file)).unwrap();
    case.set_cells(16).unwrap();
    // The earlier program solved by Cholesky (multigrid agrees to 1e-12: tests/multigrid.rs).
    case.solver.linear = LinearSolver::Direct;
    let dir = tempfile::tempdir().unwrap();
    let target = dir.path().join("after");
    let options = run::Options {
        start: Start::Nested,
        hminus1: true,
        flux: true,
        estimate: false,
        dual: false,
    };
    run::solve(&case, &options, &target).unwrap();
    let old = hdf5::File::open(before).unwrap();
    let new = hdf5::File::open(target.join("solution.h5")).unwrap();
    let mut compared = 0;
    for group in ["mesh", "dual"] {
        let (a, b) = (old.group(group).unwrap(), new.group(group).unwrap());
        let names = a.member_names().unwrap();
        assert_eq!(names, b.member_names().unwrap(), "{group}: the same datasets");
        for name in names {
            let (x, y) = (a.dataset(&name).unwrap(), b.dataset(&name).unwrap());
            let (x, y) = (x.read_raw::<f64>().unwrap(), y.read_raw::<f64>().unwrap());
            assert_eq!(x.len(), y.len(), "{group}/{name}");
            let scale = x.iter().fold(0.0_f64, |m, v| m.max(v.abs()));
            for (i, (p, q)) in x.iter().zip(&y).enumerate() {
                let boundary_lambda = group == "dual" && name == "lambda" && p.is_nan() && *q == 0.0;
                // Only the sign of a zero: min and max of the expressions now settle a tie of ±0.
                let zero_sign = p == q;
                assert!(
                    p.to_bits() == q.to_bits() || boundary_lambda || zero_sign || close(*p, *q, scale),
                    "{case_file}: {group}/{name}[{i}]: {p:e} before, {q:e} after"
                );
            }
            compared += 1;
        }
    }
    let renamed = |n: &str| {
        if n == "error_hm1_lambda" {
            "error_hminus1_lambda".to_string()
        } else {
            n.to_string()
        }
    };
    let after = new.attr_names().unwrap();
    for name in old.attr_names().unwrap() {
        let now = renamed(&name);
        // The absolute checks gave way to the relative check_* attributes.
        let dropped = [
            "max_lambda1_minus_lambda2",
            "max_lambda_times_gap",
            "min_gap",
            "min_lambda",
        ];
        let noise =
            name.starts_with("check_") || name.starts_with("flux_conservation") || name == "factor_nnz";
        if name.starts_with("seconds") || noise || dropped.contains(&name.as_str()) {
            continue;
        }
        assert!(after.contains(&now), "{case_file}: attribute {name} is missing");
        let (x, y) = (old.attr(&name).unwrap(), new.attr(&now).unwrap());
        if x.dtype().unwrap().is::<hdf5::types::VarLenUnicode>() {
            let text =
                |a: hdf5::Attribute| a.read_scalar::<hdf5::types::VarLenUnicode>().unwrap().to_string();
            assert_eq!(text(x), text(y), "{case_file}: attribute {name}");
        } else {
            let (p, q) = (x.read_raw::<f64>().unwrap(), y.read_raw::<f64>().unwrap());
            // The error norms are integrated by a rule per cell now (src/norms/cubature.rs). The
            // fixed degree-10 rule before was off by 1.4e-6 in the default case's |u1 − u1h|_H1
            // (u1 bends on the free boundary) and 1.6e-4 in its ‖λ − λh‖, by 1.2e-5 in the
            // L-shape's |u2 − u2h|_H1 (its corner singularity) and 5.2e-4 in its ‖λ − λh‖.
            let agree = |a: f64, b: f64| match name.starts_with("error_") {
                true => (a - b).abs() <= 1e-3 * a.abs(),
                false => close(a, b, a.abs()),
            };
            assert!(
                p.len() == q.len() && p.iter().zip(&q).all(|(&a, &b)| agree(a, b)),
                "{case_file}: attribute {name}: {p:?} before, {q:?} after"
            );
        }
        compared += 1;
    }
    assert!(compared > 40, "{compared} datasets and attributes compared");
}

#[test]
fn the_default_case_agrees_with_the_earlier_program() {
    compare("data/cases/default.toml", "tests/data/before-default-16.h5");
}

#[test]
fn the_l_shaped_case_agrees_with_the_earlier_program() {
    compare(
        "data/cases/lshape_corner.toml",
        "tests/data/before-lshape_corner-16.h5",
    );
}
