//! The discrete problem (3.4) and the action (4.5) on cases whose answer is known.

use membrane_contact::action::DualMesh;
use membrane_contact::assembly::Stiffness;
use membrane_contact::case::Case;
use membrane_contact::contact::{self, DiscreteProblem, SolveError, SolverOptions};
use membrane_contact::linear::InteriorSystem;
use membrane_contact::mesh::orient;
use membrane_contact::run::{self, Start};
use std::path::PathBuf;

fn case(body: &str, n: usize) -> Case {
    let text = format!("{body}\n[mesh]\nkind = \"rectangle\"\nn = [{n}, {n}]\ndiagonal = \"crossed\"\n");
    Case::parse(&text, "test case", PathBuf::new()).unwrap()
}

fn max_abs_diff(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| (x - y).abs()).fold(0.0, f64::max)
}

/// u with K u = F/μ in the interior and u = bc on ∂ω, by a plain Poisson solve.
fn poisson(problem: &DiscreteProblem, load: &[f64], mu: f64, bc: &[f64]) -> Vec<f64> {
    let k: &Stiffness = &problem.stiffness;
    let sys = InteriorSystem::new(k, &problem.mesh.on_boundary);
    let mut factor = sys.factorization();
    factor.factorize(&vec![false; sys.n()]).unwrap();
    let mut x: Vec<f64> = sys
        .vertices
        .iter()
        .map(|&a| {
            load[a] / mu
                - k.row(a)
                    .filter(|(b, _)| problem.mesh.on_boundary[*b])
                    .map(|(b, v)| v * bc[b])
                    .sum::<f64>()
        })
        .collect();
    factor.solve(&mut x);
    let mut u = bc.to_vec();
    for (i, &a) in sys.vertices.iter().enumerate() {
        u[a] = x[i];
    }
    u
}

#[test]
fn linear_solution_without_contact_is_reproduced() {
    let c = case("mu1 = 2.0\nmu2 = 0.5\nf1 = 0\nf2 = 0\ng = \"1 + x + 2*y\"", 6);
    let r = run::solve(&c, Start::Cold, None).unwrap();
    for (a, p) in r.problem.mesh.points.iter().enumerate() {
        assert!((r.solution.u1[a] - (1.0 + p[0] + 2.0 * p[1])).abs() < 1e-13);
        assert!(r.solution.u2[a].abs() < 1e-13);
    }
    assert!(r.solution.obstacle.contact.iter().all(|&c| !c));
    assert!(r.action.lambda.iter().all(|l| l.abs() < 1e-11));
}

#[test]
fn no_contact_equals_two_poisson_solves() {
    let c = case(
        "mu1 = 1.5\nmu2 = 3.0\nf1 = \"1 + x\"\nf2 = \"-2\"\ng = \"0.1 + x*y\"",
        12,
    );
    let r = run::solve(&c, Start::Cold, None).unwrap();
    let p = &r.problem;
    let zero = vec![0.0; p.mesh.n_vertices()];
    let u1 = poisson(p, &p.load1, 1.5, &p.g_h);
    let u2 = poisson(p, &p.load2, 3.0, &zero);
    assert!(r.solution.obstacle.contact.iter().all(|&c| !c));
    assert!(max_abs_diff(&u1, &r.solution.u1) < 1e-13);
    assert!(max_abs_diff(&u2, &r.solution.u2) < 1e-13);
    assert!(r.action.lambda.iter().all(|l| l.abs() < 1e-10));
    assert!(r.solution.obstacle.gap.iter().all(|&w| w > 0.0));
}

#[test]
fn full_contact_moves_the_membranes_together() {
    // Pressed together everywhere with g = 0: u1 = u2 = v, (μ1 + μ2) K v = F1 + F2, and
    // λ_a m_a = μ1 (K v)_a − F1_a = (μ2 F1_a − μ1 F2_a)/(μ1 + μ2) · (−1)… > 0.
    let c = case("mu1 = 1.0\nmu2 = 3.0\nf1 = -10\nf2 = \"10 + x\"\ng = 0", 10);
    let r = run::solve(&c, Start::Cold, None).unwrap();
    let p = &r.problem;
    let interior = p.mesh.interior();
    assert!(interior.iter().all(|&a| r.solution.obstacle.contact[a]));
    assert!(max_abs_diff(&r.solution.u1, &r.solution.u2) == 0.0);
    let sum: Vec<f64> = p.load1.iter().zip(&p.load2).map(|(a, b)| a + b).collect();
    let v = poisson(p, &sum, 4.0, &vec![0.0; p.mesh.n_vertices()]);
    assert!(max_abs_diff(&v, &r.solution.u1) < 1e-13);
    for &a in &interior {
        let expected = -(3.0 * p.load1[a] - p.load2[a]) / 4.0 / p.mass[a];
        assert!((r.action.lambda[a] - expected).abs() < 1e-10 * expected.abs().max(1.0));
        assert!(r.action.lambda[a] > 9.0);
    }
}

#[test]
fn action_satisfies_proposition_12_and_complementarity() {
    let c = Case::default_case();
    let r = run::solve(&c, Start::Nested, None).unwrap();
    let a = &r.action;
    let lmax = a.lambda.iter().copied().fold(0.0, f64::max);
    let wmax = r.solution.obstacle.gap.iter().copied().fold(0.0, f64::max);
    assert!(lmax > 1.0, "the default case has contact");
    assert!(
        a.membrane_difference / lmax < 1e-10,
        "Prop. 12: {}",
        a.membrane_difference
    );
    assert!(
        a.complementarity / (lmax * wmax) < 1e-12,
        "(4.8): {}",
        a.complementarity
    );
    assert!(a.min_lambda > -1e-10 * lmax);
    assert!(r.solution.obstacle.gap.iter().all(|&w| w >= 0.0));
    // At contact vertices the gap is exactly 0; elsewhere λ vanishes up to round-off.
    for (v, &touch) in r.solution.obstacle.contact.iter().enumerate() {
        if touch {
            assert_eq!(r.solution.obstacle.gap[v], 0.0);
        } else {
            assert!(a.lambda[v].abs() < 1e-10 * lmax);
        }
    }
}

#[test]
fn exact_solution_errors_on_a_fixed_mesh() {
    // The default case (disk contact, discontinuous f) on 32 × 32 right-diagonal cells.
    let mut c = Case::default_case();
    c.set_cells(32);
    let r = run::solve(&c, Start::Nested, None).unwrap();
    let e = r.errors.unwrap();
    assert!(e.h1_u1 < 0.07 && e.h1_u2 < 0.06, "{e:?}");
    assert!(e.l2_u1 < 8e-4 && e.l2_u2 < 8e-4, "{e:?}");
    assert!(e.l2_lambda < 0.08, "{e:?}");
    // And the H¹ error halves with h (Theorem 9).
    c.set_cells(64);
    let fine = run::solve(&c, Start::Nested, None).unwrap().errors.unwrap();
    let rate = (e.h1_u1 / fine.h1_u1).log2();
    assert!((0.9..1.1).contains(&rate), "H1 rate {rate}");
}

#[test]
fn nested_iteration_and_cold_start_agree() {
    let c = Case::default_case();
    let warm = run::solve(&c, Start::Nested, None).unwrap();
    let cold = run::solve(&c, Start::Cold, None).unwrap();
    assert_eq!(warm.solution.obstacle.contact, cold.solution.obstacle.contact);
    assert!(max_abs_diff(&warm.solution.u1, &cold.solution.u1) < 1e-13);
    assert!(max_abs_diff(&warm.action.lambda, &cold.action.lambda) < 1e-9);
    assert!(
        warm.solution.obstacle.stats.iterations <= 4,
        "{:?}",
        warm.solution.obstacle.stats
    );
    assert!(cold.solution.obstacle.stats.iterations > warm.solution.obstacle.stats.iterations);
}

#[test]
fn iteration_cap_is_an_error() {
    let c = Case::default_case();
    let p = DiscreteProblem::new(c.mesh().unwrap(), &c.data).unwrap();
    let err = contact::solve(
        &p,
        || Ok::<_, SolveError>(None),
        SolverOptions { max_iterations: 2 },
    )
    .unwrap_err();
    assert!(
        matches!(err, SolveError::IterationCap { iterations: 2, .. }),
        "{err}"
    );
    assert!(err.to_string().contains("did not converge in 2 iterations"));
}

#[test]
fn local_corrections_leave_two_global_iterations() {
    // On 256² cells the free boundary of the 128² guess is off by a few vertices. The local
    // corrections settle it, so one global solve finds the contact set and a second confirms it
    // (three without them). The result is that of a cold start.
    let mut c = Case::default_case();
    c.set_cells(256);
    let warm = run::solve(&c, Start::Nested, None).unwrap();
    let s = &warm.solution.obstacle.stats;
    assert_eq!(s.iterations, 2, "{s:?}");
    assert!(s.local_iterations > 0, "{s:?}");
    // The second global factorization reuses the first one's symbolic analysis.
    assert_eq!(s.analyses, 1, "{s:?}");
    let cold = run::solve(&c, Start::Cold, None).unwrap();
    assert_eq!(warm.solution.obstacle.contact, cold.solution.obstacle.contact);
    assert!(max_abs_diff(&warm.solution.u2, &cold.solution.u2) < 1e-13);
}

#[test]
fn flux_reconstruction_is_conservative_and_converges() {
    // t_1h (4.13) on S_h: conservative on every D_a (Lemma 17) to round-off, and an O(h)
    // approximation of −μ1 ∇u1 (area-weighted mean deviation at the cell centroids).
    let mut c = Case::default_case();
    let exact = c.exact.clone().unwrap();
    let [gx, gy] = exact.grad_u1.unwrap();
    let mut deviation = Vec::new();
    for n in [16, 32] {
        c.set_cells(n);
        let mut r = run::solve(&c, Start::Nested, None).unwrap();
        r.compute_flux();
        let [(t1, d1), (_, d2)] = r.flux.as_ref().unwrap();
        assert!(*d1 < 1e-14 && *d2 < 1e-14, "{d1} {d2}");
        let dual = DualMesh::new(&r.problem.mesh);
        let mut sum = 0.0;
        for (cell, t) in dual.triangles.iter().zip(t1.at_centroids(&dual)) {
            let p = cell.map(|v| dual.points[v]);
            let x = [0, 1].map(|i| (p[0][i] + p[1][i] + p[2][i]) / 3.0);
            let exact = [gx.eval(x[0], x[1]), gy.eval(x[0], x[1])].map(|g| -c.data.mu1 * g);
            sum += 0.5 * orient(p[0], p[1], p[2]) * (t[0] - exact[0]).hypot(t[1] - exact[1]);
        }
        deviation.push(sum);
    }
    let rate = (deviation[0] / deviation[1]).log2();
    assert!(rate > 0.9, "deviations {deviation:?}, rate {rate}");
}
