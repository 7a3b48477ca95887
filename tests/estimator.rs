//! The a posteriori estimator (docs/a-posteriori.md) against what the code does not compute itself:
//! the true energy error from the exact solutions, a linear solution it must reproduce exactly,
//! and the divergence of the equilibrated fluxes against the loads integrated here.

use membrane_contact::case::Case;
use membrane_contact::contact::Start;
use membrane_contact::run::{self, Run};
use std::path::{Path, PathBuf};

fn estimated(case: &Case) -> Run<'_> {
    let options = run::Options {
        start: Start::Nested,
        hminus1: false,
        flux: false,
        estimate: true,
        dual: false,
    };
    run::run(case, &options).unwrap()
}

fn square(body: &str, n: usize, diagonal: &str) -> Case {
    let text = format!("{body}\n[mesh]\nkind = \"rectangle\"\nn = [{n}, {n}]\ndiagonal = \"{diagonal}\"\n");
    Case::parse(&text, "test case", PathBuf::new()).unwrap()
}

/// The bound holds (η ≥ |||u − u_h|||, the error from the exact solution by quadrature) on every
/// shipped case with an exact gradient, on the two smallest levels, and is not loose.
#[test]
fn the_bound_holds_on_every_exact_case() {
    let mut checked = 0;
    for entry in std::fs::read_dir(Path::new(env!("CARGO_MANIFEST_DIR")).join("data/cases")).unwrap() {
        let path = entry.unwrap().path();
        if path.extension().is_none_or(|e| e != "toml") {
            continue;
        }
        let case = Case::read(&path).unwrap();
        // Only where the estimator is defined (two membranes, u2 = 0 on ∂ω), and with ∇u1.
        if case.exact.as_ref().is_none_or(|e| e.grad_u1.is_none()) || case.check_options(false, true).is_err()
        {
            continue;
        }
        for refine in 0..2 {
            let mut c = case.clone();
            match c.cells() {
                Some(_) => c.set_cells(8 << refine).unwrap(),
                None => c.refine = refine,
            }
            let r = estimated(&c);
            let (eta, error) = (
                r.estimate.as_ref().unwrap().total,
                r.errors.as_ref().unwrap().energy.unwrap(),
            );
            let name = path.file_name().unwrap().to_string_lossy();
            assert!(
                eta >= error,
                "{name}, level {refine}: η = {eta:e} < error {error:e}"
            );
            assert!(
                eta <= 1.6 * error,
                "{name}, level {refine}: effectivity {}",
                eta / error
            );
            checked += 1;
        }
    }
    assert!(checked >= 16, "{checked} levels checked");
}

/// u1 = 1 + x + 2y, u2 = 0, no loads: no contact, u_h = u, and the equilibrated flux must be
/// exactly −μ∇u, so that η vanishes to round-off (and so do all its terms).
#[test]
fn a_linear_solution_is_reproduced_exactly() {
    for diagonal in ["right", "crossed"] {
        let case = square(
            "mu1 = 2.0\nmu2 = 3.0\nf1 = \"0\"\nf2 = \"0\"\ng = \"1 + x + 2*y\"",
            6,
            diagonal,
        );
        let r = estimated(&case);
        let e = r.estimate.unwrap();
        // Round-off: of the flux terms; of g' along the edges (a difference quotient, ε|g| / step);
        // of λ_h ≈ 0 in η_C, which enters η² linearly.
        assert!(
            e.membranes.iter().all(|&x| x < 1e-12),
            "{diagonal}: {:?}",
            e.membranes
        );
        assert!(
            e.boundary_total < 1e-11,
            "{diagonal}: η_D = {:e}",
            e.boundary_total
        );
        assert!(e.total.powi(2) < 1e-11, "{diagonal}: η = {:e}", e.total);
        assert!(e.indicator.iter().all(|&x| x * x < 1e-11));
    }
}

/// div τ_i = Π f_i ± λ_h on every cell of S_h: f1 = x − 10 (integrated exactly by the rule, so the
/// quadrature defect c_i vanishes and Π f1 is f1 at the cell's centroid), f2 = 10, and λ_h > 0
/// somewhere.
#[test]
fn the_equilibrated_fluxes_have_the_loads_as_divergence() {
    let case = square(
        "mu1 = 1.0\nmu2 = 2.0\nf1 = \"x - 10\"\nf2 = \"10\"\ng = \"0\"",
        12,
        "right",
    );
    let r = estimated(&case);
    let e = r.estimate.as_ref().unwrap();
    let dual = r.dual();
    let lambda_h = |s: usize| r.action.lambda[dual.owner(s)];
    assert!(r.action.lambda.iter().any(|&l| l > 1.0), "contact");
    for (i, tau) in e.tau.iter().enumerate() {
        for (s, div) in tau.divergence(&dual).into_iter().enumerate() {
            let x = dual.corners(s).iter().map(|p| p[0]).sum::<f64>() / 3.0;
            let expected = if i == 0 {
                x - 10.0 + lambda_h(s)
            } else {
                10.0 - lambda_h(s)
            };
            assert!(
                (div - expected).abs() < 1e-9 * (1.0 + expected.abs()),
                "membrane {}, cell {s}: div τ = {div} ≠ {expected}",
                i + 1
            );
        }
    }
    assert!(e.means.iter().all(|&m| m < 1e-12), "{:?}", e.means);
}
