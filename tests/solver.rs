//! The discrete problem (3.4) and the action (4.5) on cases whose answer is known, against oracles
//! the library does not compute: stiffness matrices and masses assembled densely here from the
//! triangles, solved by faer's dense Cholesky (`Mat::llt`).

use faer::linalg::solvers::Solve;
use faer::{Mat, Side};
use membrane_contact::case::Case;
use membrane_contact::contact::{self, LinearSolver, SolveError, SolverOptions, Start};
use membrane_contact::mesh::Mesh;
use membrane_contact::problem::DiscreteProblem;
use membrane_contact::run::{self, Run};
use std::path::PathBuf;

fn case(body: &str, n: usize) -> Case {
    let text = format!("{body}\n[mesh]\nkind = \"rectangle\"\nn = [{n}, {n}]\ndiagonal = \"crossed\"\n");
    Case::parse(&text, "test case", PathBuf::new()).unwrap()
}

fn max_abs_diff(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| (x - y).abs()).fold(0.0, f64::max)
}

fn solve<'c>(c: &'c Case, start: Start<'c>) -> Run<'c> {
    let options = run::Options {
        start,
        hminus1: false,
        flux: false,
        estimate: false,
        dual: false,
    };
    run::run(c, &options).unwrap()
}

/// K_ab = ∫∇φ_b·∇φ_a (dense) and m_a = ∫φ_a, from the triangles' corners.
fn dense(mesh: &Mesh) -> (Mat<f64>, Vec<f64>) {
    let n = mesh.n_vertices();
    let (mut k, mut m) = (Mat::<f64>::zeros(n, n), vec![0.0; n]);
    for tri in mesh.triangles() {
        let p = tri.map(|v| mesh.points[v]);
        let area =
            0.5 * ((p[1][0] - p[0][0]) * (p[2][1] - p[0][1]) - (p[1][1] - p[0][1]) * (p[2][0] - p[0][0]));
        // ∇φ_i = (rotated opposite edge)/(2|K|).
        let grad = |i: usize| {
            let (q, r) = (p[(i + 1) % 3], p[(i + 2) % 3]);
            [(q[1] - r[1]) / (2.0 * area), (r[0] - q[0]) / (2.0 * area)]
        };
        for i in 0..3 {
            m[tri[i]] += area.abs() / 3.0;
            for j in 0..3 {
                let (gi, gj) = (grad(i), grad(j));
                k[(tri[i], tri[j])] += area.abs() * (gi[0] * gj[0] + gi[1] * gj[1]);
            }
        }
    }
    (k, m)
}

/// μ K u = F at the interior vertices, u = bc on ∂ω, by a dense Cholesky solve.
fn dense_poisson(mesh: &Mesh, k: &Mat<f64>, load: &[f64], mu: f64, bc: &[f64]) -> Vec<f64> {
    dense_dirichlet(k, load, mu, bc, &mesh.on_boundary)
}

/// μ K u = F at the vertices not `fixed`, u = `values` at the fixed ones, by a dense Cholesky solve.
fn dense_dirichlet(k: &Mat<f64>, load: &[f64], mu: f64, values: &[f64], fixed: &[bool]) -> Vec<f64> {
    let n = values.len();
    let inner: Vec<usize> = (0..n).filter(|&a| !fixed[a]).collect();
    let kii = Mat::<f64>::from_fn(inner.len(), inner.len(), |i, j| k[(inner[i], inner[j])]);
    let rhs = Mat::<f64>::from_fn(inner.len(), 1, |i, _| {
        let a = inner[i];
        load[a] / mu
            - (0..n)
                .filter(|&b| fixed[b])
                .map(|b| k[(a, b)] * values[b])
                .sum::<f64>()
    });
    let x = kii.llt(Side::Lower).unwrap().solve(&rhs);
    let mut u = values.to_vec();
    for (i, &a) in inner.iter().enumerate() {
        u[a] = x[(i, 0)];
    }
    u
}

/// (K u)_a with the dense K.
fn apply(k: &Mat<f64>, u: &[f64], a: usize) -> f64 {
    (0..u.len()).map(|b| k[(a, b)] * u[b]).sum()
}

#[test]
fn linear_solution_without_contact_is_reproduced() {
    let c = case("mu1 = 2.0\nmu2 = 0.5\nf1 = 0\nf2 = 0\ng = \"1 + x + 2*y\"", 6);
    let r = solve(&c, Start::Cold);
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
    let r = solve(&c, Start::Cold);
    let p = &r.problem;
    let zero = vec![0.0; p.mesh.n_vertices()];
    let (k, _) = dense(&p.mesh);
    let u1 = dense_poisson(&p.mesh, &k, &p.load1, 1.5, &p.g_h);
    let u2 = dense_poisson(&p.mesh, &k, &p.load2, 3.0, &zero);
    assert!(r.solution.obstacle.contact.iter().all(|&c| !c));
    assert!(max_abs_diff(&u1, &r.solution.u1) < 1e-13);
    assert!(max_abs_diff(&u2, &r.solution.u2) < 1e-13);
    assert!(r.action.lambda.iter().all(|l| l.abs() < 1e-10));
    assert!(r.solution.obstacle.gap.iter().all(|&w| w > 0.0));
}

/// An obstacle far below a membrane that touches nothing: u is the Poisson solution, λ_h = 0, and
/// the checks pass although u_h = ψ_h + w is computed from terms far larger than itself.
#[test]
fn an_obstacle_far_below_is_not_touched() {
    for (f, psi) in [(0.0, -1.0_f64), (1e-3, -1.0), (1.0, -1000.0)] {
        let body = format!("problem = \"obstacle\"\nmu = 2.0\nf = {f:e}\npsi = {psi:e}\ng = 0");
        let c = case(&body, 12);
        let r = solve(&c, Start::Nested);
        let p = &r.problem;
        let (k, _) = dense(&p.mesh);
        let u = dense_poisson(&p.mesh, &k, &p.load1, 2.0, &p.g_h);
        assert!(
            r.solution.obstacle.contact.iter().all(|&c| !c),
            "f = {f}, ψ = {psi}"
        );
        assert!(
            max_abs_diff(&u, &r.solution.u1) <= 1e-14 * psi.abs(),
            "f = {f}, ψ = {psi}"
        );
        assert!(r
            .action
            .lambda
            .iter()
            .all(|l| l.abs() <= 1e-12 * psi.abs() * 144.0));
    }
}

#[test]
fn no_contact_with_g2_equals_two_poisson_solves() {
    // u2 = g2 on ∂ω (here not affine, so that g2_h is what enters).
    let c = case(
        "mu1 = 1.5\nmu2 = 3.0\nf1 = \"1 + x\"\nf2 = \"-2\"\ng = \"0.1 + x*y\"\ng2 = \"-0.3 + 0.2*x*x*y\"",
        12,
    );
    let r = solve(&c, Start::Cold);
    let p = &r.problem;
    let g2: Vec<f64> = (p.mesh.points.iter().enumerate())
        .map(|(a, q)| {
            if p.mesh.on_boundary[a] {
                -0.3 + 0.2 * q[0] * q[0] * q[1]
            } else {
                0.0
            }
        })
        .collect();
    let (k, _) = dense(&p.mesh);
    let u1 = dense_poisson(&p.mesh, &k, &p.load1, 1.5, &p.g_h);
    let u2 = dense_poisson(&p.mesh, &k, &p.load2, 3.0, &g2);
    assert!(r.solution.obstacle.contact.iter().all(|&c| !c));
    assert!(
        max_abs_diff(&u1, &r.solution.u1) < 1e-13,
        "{}",
        max_abs_diff(&u1, &r.solution.u1)
    );
    assert!(
        max_abs_diff(&u2, &r.solution.u2) < 1e-13,
        "{}",
        max_abs_diff(&u2, &r.solution.u2)
    );
}

/// On stretched cells the free boundary moves a few vertices per global step: local corrections
/// go on until a global step repeats a proposal, and carry it across their bands. They stopped at
/// the first step that did not reduce the number of changes (10 × 1000 cells: 69 global steps,
/// now 13), and then at the first that raised it (25 × 250, whose changes go up and down: 31, now
/// 19). The solution is the one Cholesky reaches from no contact.
#[test]
fn stretched_cells_take_few_active_set_steps() {
    // A membrane pressed on the left half; the built-in default case.
    let pressed = "mu1 = 1.0\nmu2 = 2.0\nf1 = \"if(x < 0.5, -20, 0)\"\nf2 = 5\ng = 0.1\n";
    let default = membrane_contact::case::DEFAULT_CASE
        .split("[mesh]")
        .next()
        .unwrap();
    for (data, n, most) in [(pressed, [10, 1000], 20), (default, [25, 250], 25)] {
        let text = format!("{data}\n[mesh]\nkind = \"rectangle\"\nn = {n:?}\n");
        let c = Case::parse(&text, "stretched", PathBuf::new()).unwrap();
        let r = solve(&c, Start::Nested);
        let steps = r.solution.obstacle.stats.iterations;
        assert!(steps <= most, "{n:?}: {steps} active-set steps");
        let mut direct = c.clone();
        direct.solver.linear = LinearSolver::Direct;
        let plain = solve(&direct, Start::Cold);
        assert_eq!(plain.solution.obstacle.contact, r.solution.obstacle.contact);
        assert!(max_abs_diff(&plain.solution.u1, &r.solution.u1) < 1e-12);
    }
}

/// On ∂ω the membranes take their boundary values as given: u1 = g and u2 = 0 to the bit (u2 was
/// v − μ1/(μ1 + μ2) w, 1e-17 there), u2 = g2 to an ulp of g − (g − g2).
#[test]
fn the_membranes_take_their_boundary_values_exactly() {
    for (g2, n) in [("", 12), ("\ng2 = \"-0.3 + 0.2*x*x*y\"", 24), ("obstacle", 12)] {
        let body = match g2 {
            // u1 = ψ_h + w with ψ = 0.3 sin(πx) sin(πy) − 0.1 xy: ψ + (g − ψ) is not g everywhere.
            "obstacle" => "problem = \"obstacle\"\nmu = 1.0\nf = -40\npsi = \"0.3*sin(pi*x)*sin(pi*y) - 0.1*x*y\"\ng = \"0.1 + x*y\"".to_string(),
            _ => format!("mu1 = 1.0\nmu2 = 3.0\nf1 = -40\nf2 = 5\ng = \"0.1 + x*y\"{g2}"),
        };
        let c = case(&body, n);
        let r = solve(&c, Start::Cold);
        let (p, u) = (&r.problem, &r.solution);
        assert!(u.obstacle.contact.iter().any(|&c| c));
        for (a, q) in p
            .mesh
            .points
            .iter()
            .enumerate()
            .filter(|(a, _)| p.mesh.on_boundary[*a])
        {
            assert_eq!(u.u1[a].to_bits(), (0.1 + q[0] * q[1]).to_bits(), "u1 at {q:?}");
            match g2 {
                "" => assert_eq!(u.u2[a].to_bits(), 0f64.to_bits(), "u2 at {q:?}"),
                "obstacle" => {}
                _ => {
                    let g2 = -0.3 + 0.2 * q[0] * q[0] * q[1];
                    assert!(
                        (u.u2[a] - g2).abs() <= f64::EPSILON,
                        "u2 at {q:?}: {} for {g2}",
                        u.u2[a]
                    );
                }
            }
        }
    }
}

#[test]
fn raising_both_boundary_values_by_a_constant_raises_both_membranes() {
    // Constants are harmonic: (g + c, g2 = c) has the solution (u1 + c, u2 + c) and the same λ.
    let body = "mu1 = 1.5\nmu2 = 3.0\nf1 = -10\nf2 = \"5 + x\"\n";
    let low = case(&format!("{body}g = \"0.05 + 0.1*x\""), 24);
    let high = case(&format!("{body}g = \"1.05 + 0.1*x\"\ng2 = 1"), 24);
    let (a, b) = (solve(&low, Start::Nested), solve(&high, Start::Nested));
    let shifted = |u: &[f64]| u.iter().map(|v| v + 1.0).collect::<Vec<_>>();
    assert!(a.solution.obstacle.contact.iter().any(|&c| c));
    assert_eq!(a.solution.obstacle.contact, b.solution.obstacle.contact);
    assert!(max_abs_diff(&shifted(&a.solution.u1), &b.solution.u1) < 1e-11);
    assert!(max_abs_diff(&shifted(&a.solution.u2), &b.solution.u2) < 1e-11);
    let scale = a.action.lambda.iter().fold(0.0_f64, |m, l| m.max(l.abs()));
    assert!(max_abs_diff(&a.action.lambda, &b.action.lambda) < 1e-8 * scale);
}

#[test]
fn the_obstacle_problem_meets_its_conditions_with_a_dense_stiffness() {
    // u_h ≥ ψ_h, the equation μ K u = F off the contact set C (u = ψ_h on C, g_h on ∂ω), and
    // λ_a m_a = μ (K u)_a − F_a ≥ 0 on C: with K assembled here these identify the solution.
    let c = case(
        "problem = \"obstacle\"\nmu = 2.0\nf = \"-8 + 3*x\"\npsi = \"-0.15 - 0.2*(x - 0.5)^2 + 0.1*y\"\ng = \"0.02*x\"",
        24,
    );
    let r = solve(&c, Start::Nested);
    let (p, s) = (&r.problem, &r.solution);
    let mesh = &p.mesh;
    let psi: Vec<f64> = mesh
        .points
        .iter()
        .map(|q| -0.15 - 0.2 * (q[0] - 0.5).powi(2) + 0.1 * q[1])
        .collect();
    let contact = &s.obstacle.contact;
    let fixed: Vec<bool> = (0..mesh.n_vertices())
        .map(|a| mesh.on_boundary[a] || contact[a])
        .collect();
    let values: Vec<f64> = (0..mesh.n_vertices())
        .map(|a| {
            if mesh.on_boundary[a] {
                0.02 * mesh.points[a][0]
            } else {
                psi[a]
            }
        })
        .collect();
    let (k, m) = dense(mesh);
    let u = dense_dirichlet(&k, &p.load1, 2.0, &values, &fixed);
    assert_eq!(s.obstacle.stats.linear, LinearSolver::Multigrid);
    assert!(max_abs_diff(&u, &s.u1) < 1e-12, "{}", max_abs_diff(&u, &s.u1));
    assert!(max_abs_diff(&psi, &s.u2) == 0.0, "u2h is ψ_h");
    let (mut touching, mut free) = (0, 0);
    for a in (0..mesh.n_vertices()).filter(|&a| !mesh.on_boundary[a]) {
        let lambda = (2.0 * apply(&k, &u, a) - p.load1[a]) / m[a];
        assert!((lambda - r.action.lambda[a]).abs() < 1e-9, "λ at {a}");
        match contact[a] {
            true => assert!(lambda >= 0.0, "λ = {lambda} < 0 at {a}"),
            false => assert!(u[a] > psi[a] && lambda.abs() < 1e-9, "at {a}"),
        }
        (touching, free) = (
            touching + usize::from(contact[a]),
            free + usize::from(!contact[a]),
        );
    }
    assert!(touching > 20 && free > 20, "{touching} in contact, {free} free");
}

#[test]
fn full_contact_moves_the_membranes_together() {
    // Pressed together everywhere with g = 0: u1 = u2 = v, (μ1 + μ2) K v = F1 + F2, and
    // λ_a m_a = μ1 (K v)_a − F1_a = (μ2 F1_a − μ1 F2_a)/(μ1 + μ2) · (−1)… > 0.
    let c = case("mu1 = 1.0\nmu2 = 3.0\nf1 = -10\nf2 = \"10 + x\"\ng = 0", 10);
    let r = solve(&c, Start::Cold);
    let p = &r.problem;
    let interior: Vec<usize> = (0..p.mesh.n_vertices())
        .filter(|&a| !p.mesh.on_boundary[a])
        .collect();
    assert!(interior.iter().all(|&a| r.solution.obstacle.contact[a]));
    assert!(max_abs_diff(&r.solution.u1, &r.solution.u2) == 0.0);
    let sum: Vec<f64> = p.load1.iter().zip(&p.load2).map(|(a, b)| a + b).collect();
    let (k, m) = dense(&p.mesh);
    let v = dense_poisson(&p.mesh, &k, &sum, 4.0, &vec![0.0; p.mesh.n_vertices()]);
    assert!(max_abs_diff(&v, &r.solution.u1) < 1e-13);
    for &a in &interior {
        let expected = -(3.0 * p.load1[a] - p.load2[a]) / 4.0 / m[a];
        assert!((r.action.lambda[a] - expected).abs() < 1e-10 * expected.abs().max(1.0));
        assert!(r.action.lambda[a] > 9.0);
    }
}

#[test]
fn membranes_at_rest_do_not_press_on_each_other() {
    // f1 = f2 = 0, g = 0: u1 = u2 = 0, so w = 0 and λ = 0 everywhere. The active set
    // {λ_a − c_a w_a > 0} is empty: the membranes touch but do not press, and the first solve
    // (exactly zero) is confirmed at once.
    let c = case("mu1 = 1.0\nmu2 = 2.0\nf1 = 0\nf2 = 0\ng = 0", 6);
    let r = solve(&c, Start::Cold);
    let o = &r.solution.obstacle;
    assert!(o
        .gap
        .iter()
        .chain(&o.lambda)
        .chain(&r.solution.u1)
        .all(|&x| x == 0.0));
    assert!(o.contact.iter().all(|&c| !c));
    assert_eq!((o.stats.iterations, &o.stats.active_sizes[..]), (1, &[0][..]));
}

#[test]
fn action_satisfies_proposition_12_and_complementarity() {
    // λ from each membrane recomputed here by (4.5), with K and m assembled densely in this test
    // and the loads of the piecewise constant f of the default case integrated exactly… by the
    // library's rule, the one datum taken from it.
    let c = Case::default_case();
    let r = solve(&c, Start::Nested);
    let p = &r.problem;
    let (k, m) = dense(&p.mesh);
    let (u1, u2, gap) = (&r.solution.u1, &r.solution.u2, &r.solution.obstacle.gap);
    let mut lmax = 0.0_f64;
    for a in (0..p.mesh.n_vertices()).filter(|&a| !p.mesh.on_boundary[a]) {
        let l1 = (c.data.mu1 * apply(&k, u1, a) - p.load1[a]) / m[a];
        let l2 = (-c.data.mu2().unwrap() * apply(&k, u2, a) + p.load2[a]) / m[a];
        assert!(
            (l1 - r.action.lambda[a]).abs() < 1e-11,
            "λ1 at {a}: {l1} vs {}",
            r.action.lambda[a]
        );
        assert!(
            (l2 - r.action.lambda2[a]).abs() < 1e-11,
            "λ2 at {a}: {l2} vs {}",
            r.action.lambda2[a]
        );
        assert!((l1 - l2).abs() < 1e-10, "Prop. 12 at {a}: {l1} vs {l2}");
        // The obstacle problem's own λ_a = r_a/m_a (its residual, which warm starts use).
        let lw = r.solution.obstacle.lambda[a];
        assert!((l1 - lw).abs() < 1e-10, "obstacle λ at {a}: {l1} vs {lw}");
        assert!(l1 > -1e-10, "λ ≥ 0 at {a}: {l1}");
        // (4.8): the gap is exactly 0 at contact vertices; elsewhere λ vanishes up to round-off.
        if r.solution.obstacle.contact[a] {
            assert_eq!(gap[a], 0.0);
        } else {
            assert!(
                l1.abs() < 1e-10 && gap[a] > 0.0,
                "at {a}: λ = {l1}, w = {}",
                gap[a]
            );
        }
        lmax = lmax.max(l1);
    }
    for a in (0..p.mesh.n_vertices()).filter(|&a| p.mesh.on_boundary[a]) {
        assert_eq!(r.solution.obstacle.lambda[a], 0.0);
    }
    assert!(lmax > 1.0, "the default case has contact");
    assert!(r.action.checks.verify().is_ok());
}

#[test]
fn exact_solution_errors_on_a_fixed_mesh() {
    // The default case (disk contact, discontinuous f) on 32 × 32 right-diagonal cells.
    let mut c = Case::default_case();
    c.set_cells(32).unwrap();
    let e = solve(&c, Start::Nested).errors.unwrap();
    let (h1_u1, h1_u2) = (e.h1_u1.unwrap(), e.h1_u2.unwrap());
    assert!(h1_u1 < 0.07 && h1_u2 < 0.06, "{e:?}");
    assert!(e.l2_u1 < 8e-4 && e.l2_u2 < 8e-4, "{e:?}");
    assert!(e.l2_lambda < 0.08, "{e:?}");
    // And the H¹ error halves with h (Theorem 9).
    c.set_cells(64).unwrap();
    let fine = solve(&c, Start::Nested).errors.unwrap();
    let rate = (h1_u1 / fine.h1_u1.unwrap()).log2();
    assert!((0.9..1.1).contains(&rate), "H1 rate {rate}");
}

#[test]
fn nested_iteration_and_cold_start_agree() {
    let c = Case::default_case();
    let warm = solve(&c, Start::Nested);
    let cold = solve(&c, Start::Cold);
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
        Start::Cold,
        Vec::new(),
        SolverOptions {
            max_iterations: 2,
            ..Default::default()
        },
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
    c.set_cells(256).unwrap();
    for linear in [LinearSolver::Direct, LinearSolver::Multigrid] {
        c.solver.linear = linear;
        let warm = solve(&c, Start::Nested);
        let s = &warm.solution.obstacle.stats;
        assert_eq!((s.linear, s.iterations), (linear, 2), "{s:?}");
        assert!(s.local_iterations > 0, "{s:?}");
        // The second global factorization reuses the first one's symbolic analysis.
        if linear == LinearSolver::Direct {
            assert_eq!(s.analyses, 1, "{s:?}");
        }
        let cold = solve(&c, Start::Cold);
        assert_eq!(warm.solution.obstacle.contact, cold.solution.obstacle.contact);
        assert!(max_abs_diff(&warm.solution.u2, &cold.solution.u2) < 1e-12);
    }
}

#[test]
fn flux_reconstruction_is_conservative_and_converges() {
    // t_1h (4.13) on S_h: conservative on every D_a (Lemma 17) to round-off, and an O(h)
    // approximation of −μ1 ∇u1 (area-weighted mean deviation at the cell centroids).
    let mut c = Case::default_case();
    let exact = c.exact.clone().unwrap();
    let [gx, gy] = exact.grad_u1;
    let mut deviation = Vec::new();
    for n in [16, 32] {
        c.set_cells(n).unwrap();
        let options = run::Options {
            start: Start::Nested,
            hminus1: false,
            flux: true,
            estimate: false,
            dual: false,
        };
        let r = run::run(&c, &options).unwrap();
        let flux = r.flux.as_ref().unwrap();
        let [d1, d2] = flux.conservation[..] else {
            panic!("two fluxes")
        };
        assert!(d1 < 1e-14 && d2 < 1e-14, "{d1} {d2}");
        let dual = r.dual();
        let mut sum = 0.0;
        for (s, t) in flux.t[0].at_centroids(&dual).into_iter().enumerate() {
            let p = dual.corners(s);
            let x = [0, 1].map(|i| (p[0][i] + p[1][i] + p[2][i]) / 3.0);
            let exact = [gx.eval(x[0], x[1]), gy.eval(x[0], x[1])].map(|g| -c.data.mu1 * g);
            let area =
                0.5 * ((p[1][0] - p[0][0]) * (p[2][1] - p[0][1]) - (p[1][1] - p[0][1]) * (p[2][0] - p[0][0]));
            sum += area * (t[0] - exact[0]).hypot(t[1] - exact[1]);
        }
        deviation.push(sum);
    }
    let rate = (deviation[0] / deviation[1]).log2();
    assert!(rate > 0.9, "deviations {deviation:?}, rate {rate}");
}

#[test]
fn error_norms_have_their_closed_form_values() {
    // With f1 = f2 = 0 and g = 0 the discrete solution and λ_h vanish, so the errors are the norms
    // of the given "exact" functions on the unit square, known in closed form:
    // ‖sin πx sin πy‖_L² = 1/2, |sin πx sin πy|_H¹ = π/√2, ‖x(1−x)y(1−y)‖_L² = 1/30,
    // |x(1−x)y(1−y)|_H¹ = 1/√45, ‖1‖_L² = 1, and ‖1‖²_H⁻¹ = ∫z with −Δz = 1, z = 0 on ∂ω:
    // (64/π⁶) Σ_{m,n odd} 1/(m²n²(m² + n²)).
    let c = case(
        "mu1 = 2.0\nmu2 = 3.0\nf1 = 0\nf2 = 0\ng = 0\n[exact]\nu1 = \"sin(pi*x)*sin(pi*y)\"\n\
         u2 = \"x*(1-x)*y*(1-y)\"\nlambda = 1\n\
         grad_u1 = [\"pi*cos(pi*x)*sin(pi*y)\", \"pi*sin(pi*x)*cos(pi*y)\"]\n\
         grad_u2 = [\"(1-2*x)*y*(1-y)\", \"x*(1-x)*(1-2*y)\"]",
        16,
    );
    let options = run::Options {
        start: Start::Cold,
        hminus1: true,
        flux: false,
        estimate: false,
        dual: false,
    };
    let e = run::run(&c, &options).unwrap().errors.unwrap();
    let pi = std::f64::consts::PI;
    let close = |value: f64, exact: f64, tol: f64| {
        assert!((value - exact).abs() <= tol * exact, "{value} against {exact}");
    };
    // The rules of the error norms integrate these polynomial errors exactly, but for round-off.
    let tol = 1e-12;
    close(e.l2_u1, 0.5, tol);
    close(e.h1_u1.unwrap(), pi / 2f64.sqrt(), tol);
    close(e.l2_u2, 1.0 / 30.0, tol);
    close(e.h1_u2.unwrap(), 45f64.sqrt().recip(), tol);
    close(e.energy.unwrap(), (2.0 * pi * pi / 2.0 + 3.0 / 45.0).sqrt(), tol);
    close(e.l2_lambda, 1.0, tol);
    let odd = (1..400).step_by(2).map(f64::from);
    let series: f64 = odd
        .clone()
        .flat_map(|m| odd.clone().map(move |n| 1.0 / (m * m * n * n * (m * m + n * n))))
        .sum();
    let torsion = (64.0 / pi.powi(6) * series).sqrt();
    // The discrete dual norm (P1 on S_h) is a lower bound converging at O(h²).
    let hminus1 = e.hminus1_lambda.unwrap();
    assert!(
        hminus1 <= torsion && hminus1 > (1.0 - 2e-3) * torsion,
        "{hminus1} against {torsion}"
    );
}

#[test]
fn nested_iteration_on_a_refined_disk() {
    // The exact disk case refined 4 times: nested iteration on the refinement hierarchy (the
    // given spade mesh refined 0…3 times, and below it the disk meshed with 2h) gives the cold
    // start's solution in at most 4 global iterations on every level, and the H¹ error halves
    // with h.
    let mut c = Case::read(std::path::Path::new("data/cases/disk_contact.toml")).unwrap();
    c.refine = 4;
    let warm = solve(&c, Start::Nested);
    let s = &warm.solution.obstacle.stats;
    assert_eq!(s.coarse_iterations.len(), 5, "{s:?}");
    assert!(
        s.coarse_iterations.iter().chain([&s.iterations]).all(|&i| i <= 4),
        "{s:?}"
    );
    let cold = solve(&c, Start::Cold);
    assert_eq!(warm.solution.obstacle.contact, cold.solution.obstacle.contact);
    assert!(max_abs_diff(&warm.solution.u1, &cold.solution.u1) < 1e-12);
    let mut coarser_case = c.clone();
    coarser_case.refine = 3;
    let coarser = solve(&coarser_case, Start::Nested);
    let h1 = |r: &Run| r.errors.as_ref().unwrap().h1_u1.unwrap();
    let ratio = h1(&coarser) / h1(&warm);
    assert!((1.95..2.05).contains(&ratio), "H1 error ratio {ratio}");
}

#[test]
fn annulus_and_polygon_with_hole_solve() {
    // Membrane 1 pressed down onto membrane 2 between two circles, and around a square hole.
    let data = "mu1 = 1.0\nmu2 = 1.0\nf1 = -10\nf2 = 0\ng = 0.05\n";
    for mesh in [
        "[mesh]\nkind = \"disk\"\ncentre = [1.0, 2.0]\nradius = 1.0\ninner_radius = 0.3\nh = 0.1\nrefine = 1\n",
        "[mesh]\nkind = \"polygon\"\nboundary = [[0, 0], [1, 0], [1, 1], [0, 1]]\nholes = [[[0.4, 0.4], [0.6, 0.4], [0.6, 0.6], [0.4, 0.6]]]\nh = 0.1\n",
    ] {
        let c = Case::parse(&format!("{data}{mesh}"), "test case", PathBuf::new()).unwrap();
        let r = solve(&c, Start::Nested);
        let contact = r.solution.obstacle.contact.iter().filter(|&&x| x).count();
        assert!(contact > 10, "{mesh}: contact at {contact} vertices");
        // Both boundaries hold g and 0.
        let m = &r.problem.mesh;
        for a in (0..m.n_vertices()).filter(|&a| m.on_boundary[a]) {
            assert!((r.solution.u1[a] - 0.05).abs() < 1e-15 && r.solution.u2[a].abs() < 1e-15);
        }
    }
}

/// On cells stretched 100:1 multigrid CG does not converge; the run solves again by Cholesky and
/// says so, with the solution an explicit direct solve gives.
#[test]
fn where_multigrid_fails_the_run_solves_by_cholesky() {
    let text = |linear: &str| {
        format!(
            "mu1 = 1.0\nmu2 = 1.0\nf1 = \"-20\"\nf2 = \"5\"\ng = \"0.05\"\n[mesh]\nkind = \"rectangle\"\n\
             n = [10, 1000]\n[solver]\nlinear = \"{linear}\"\n"
        )
    };
    let parse = |t: String| Case::parse(&t, "stretched", PathBuf::new()).unwrap();
    let (asked, direct) = (parse(text("multigrid")), parse(text("direct")));
    let fell_back = solve(&asked, Start::Nested);
    let stats = &fell_back.solution.obstacle.stats;
    let cg = stats
        .multigrid_failed
        .as_ref()
        .expect("multigrid CG fails on these cells");
    assert_eq!((stats.linear, cg.iterations), (LinearSolver::Direct, 200));
    assert!(fell_back
        .summary(false)
        .contains("(Cholesky; multigrid CG did not converge in 200 iterations)"));
    let reference = solve(&direct, Start::Nested);
    assert!(reference.solution.obstacle.stats.multigrid_failed.is_none());
    assert_eq!(
        fell_back.solution.obstacle.contact,
        reference.solution.obstacle.contact
    );
    assert!(max_abs_diff(&fell_back.solution.u1, &reference.solution.u1) < 1e-12);
}

/// On cells stretched 100:1 nested iteration still gives a guess a few steps from the solution:
/// each coarser level settles the free boundary its guess predicts before its step (unsettled, the
/// lag doubled from level to level, and the final mesh took 109 steps).
#[test]
fn nested_iteration_on_stretched_cells_ends_in_a_few_steps() {
    let text = "mu1 = 1.0\nmu2 = 1.0\nf1 = \"-20\"\nf2 = \"5\"\ng = \"0.05\"\n[mesh]\nkind = \"rectangle\"\n\
                n = [30, 3000]\n[solver]\nlinear = \"direct\"\n";
    let c = Case::parse(text, "stretched", PathBuf::new()).unwrap();
    let r = solve(&c, Start::Nested);
    let stats = &r.solution.obstacle.stats;
    assert!(
        stats.coarse_iterations.len() >= 3 && stats.iterations <= 8,
        "{stats:?}"
    );
}

/// Where multigrid was asked for but Cholesky ran (a file mesh without refinement), the short
/// summary says why, not only "(Cholesky)": with tables per group, no coarser level either.
#[test]
fn the_short_summary_says_why_cholesky_ran() {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("data/cases/two_regions.toml");
    let mut case = Case::read(&path).unwrap();
    case.refine = 0;
    let summary = solve(&case, Start::Nested).summary(false);
    assert!(
        summary.contains(
            "(Cholesky; not multigrid, and from a cold start: no coarser mesh of this mesh's boundary"
        ),
        "{summary}"
    );
}
