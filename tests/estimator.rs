//! The a posteriori estimator (docs/a-posteriori.md) against what the code does not compute itself:
//! the true energy error from the exact solutions, a linear solution it must reproduce exactly,
//! and the divergence of the equilibrated fluxes against the loads integrated here.

use membrane_contact::assembly::gradients;
use membrane_contact::case::Case;
use membrane_contact::contact::Start;
use membrane_contact::estimator::{equilibration, Estimate};
use membrane_contact::mesh::DualMesh;
use membrane_contact::run::{self, Run};
use std::path::{Path, PathBuf};

fn estimated(case: &Case) -> Run<'_> {
    estimated_with(case, false)
}

/// A run with the estimator and, with `flux`, the fluxes of (4.13).
fn estimated_with(case: &Case, flux: bool) -> Run<'_> {
    let options = run::Options {
        start: Start::Nested,
        hminus1: false,
        flux,
        estimate: true,
        dual: false,
    };
    run::run(case, &options).unwrap()
}

/// The shipped case data/cases/`name`.toml on its built-in mesh with `n` cells per side.
fn shipped(name: &str, n: usize) -> Case {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join(format!("data/cases/{name}.toml"));
    let mut case = Case::read(&path).unwrap();
    case.set_cells(n).unwrap();
    case
}

fn square(body: &str, n: usize, diagonal: &str) -> Case {
    let text = format!("{body}\n[mesh]\nkind = \"rectangle\"\nn = [{n}, {n}]\ndiagonal = \"{diagonal}\"\n");
    Case::parse(&text, "test case", PathBuf::new()).unwrap()
}

/// The bound holds (η ≥ |||u − u_h|||, the error from the exact solution by quadrature) on every
/// shipped case with an exact solution, on the two smallest levels, and is sharp.
#[test]
fn the_bound_holds_on_every_exact_case() {
    let mut checked = 0;
    for entry in std::fs::read_dir(Path::new(env!("CARGO_MANIFEST_DIR")).join("data/cases")).unwrap() {
        let path = entry.unwrap().path();
        if path.extension().is_none_or(|e| e != "toml") {
            continue;
        }
        let case = Case::read(&path).unwrap();
        // Only where the estimator is defined (not with g2).
        if case.exact.is_none() || case.check_options(true).is_err() {
            continue;
        }
        // Above an obstacle η also counts ψ − ψ_h where u_h dips below ψ, which the flux term
        // sees too (docs/a-posteriori.md §14): the bound is looser on coarse meshes. Between two
        // membranes 1.199 at most (lshape_corner at 8²; 1.213 with the corner triangles' lifting
        // bounded by the triangle inequality, 1.311 on lshape_tensions with the radial lifting).
        let loose = if case.data.is_obstacle() { 1.9 } else { 1.2 };
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
                eta <= loose * error,
                "{name}, level {refine}: effectivity {}",
                eta / error
            );
            assert_eq!(r.effectivity(), Some(eta / error), "{name}, level {refine}");
            checked += 1;
        }
    }
    assert!(checked >= 18, "{checked} levels checked");
}

/// u1 = 1 + x + 2y, u2 = 0, no loads: no contact, u_h = u, and the equilibrated flux must be
/// exactly −μ∇u, so that η vanishes to round-off (and so do all its terms). The error is
/// round-off too, and η/error no effectivity (it was printed, 1.2e7 on such a case).
#[test]
fn a_linear_solution_is_reproduced_exactly() {
    for diagonal in ["right", "crossed"] {
        let case = square(
            "mu1 = 2.0\nmu2 = 3.0\nf1 = \"0\"\nf2 = \"0\"\ng = \"1 + x + 2*y\"\n\
             [exact]\nu1 = \"1 + x + 2*y\"\nu2 = \"0\"\nlambda = \"0\"",
            6,
            diagonal,
        );
        let r = estimated(&case);
        let errors = r.errors.as_ref().unwrap();
        assert!(errors.at_round_off(), "{diagonal}: {errors:?}");
        assert_eq!((r.effectivity(), errors.resolved_energy()), (None, None));
        assert!(r
            .summary(false)
            .contains("u_h is the exact solution to round-off"));
        assert!(!r.summary(false).contains("effectivity η/error"));
        // The same plane lifted by 10⁶: the error is the round-off of values of size 10⁶, far
        // above 10⁻¹⁰ |||u_h|||, and still no effectivity.
        let lifted = square(
            "mu1 = 2.0\nmu2 = 3.0\nf1 = \"0\"\nf2 = \"0\"\ng = \"1e6 + x + 2*y\"\n\
             [exact]\nu1 = \"1e6 + x + 2*y\"\nu2 = \"0\"\nlambda = \"0\"",
            6,
            diagonal,
        );
        let errors = estimated(&lifted).errors.unwrap();
        assert!(
            errors.energy.unwrap() > 1e-12 && errors.at_round_off(),
            "{diagonal}: {errors:?}"
        );
        let e = r.estimate.unwrap();
        // Round-off: of the flux terms; of g' along the edges (a difference quotient, ε|g| / step);
        // λ_h ≈ 0 is off the contact set, so η_C = 0.
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
        assert_eq!(e.contact_total, 0.0);
    }
}

/// ∫_κ f_i φ_j on the six cells κ of a triangle, for each membrane i and vertex j.
struct Pairings([[[f64; 3]; 2]; 6]);

impl equilibration::CellPairings for Pairings {
    fn f_phi(&self, c: usize, i: usize) -> [f64; 3] {
        self.0[c][i]
    }
}

/// div τ_i = Π f_i ± λ_h on every cell of S_h, triangle by triangle as the patches hand them over:
/// f1 = x − 10 (Π f1 is f1 at the cell's centroid), f2 = 10, λ_h > 0 somewhere, with the
/// pairings ∫_κ f_i φ_j integrated here (the edge-midpoint rule, exact for the quadratics
/// f_i φ_j).
#[test]
fn the_equilibrated_fluxes_have_the_loads_as_divergence() {
    let case = square(
        "mu1 = 1.0\nmu2 = 2.0\nf1 = \"x - 10\"\nf2 = \"10\"\ng = \"0\"",
        12,
        "right",
    );
    let r = estimated(&case);
    let (mesh, dual) = (&r.problem.mesh, r.dual());
    let lambda = &r.action.lambda;
    assert!(lambda.iter().any(|&l| l > 1.0), "contact");
    let f = [|x: [f64; 2]| x[0] - 10.0, |_: [f64; 2]| 10.0];
    let f_phi = |i: usize, s: usize| -> [f64; 3] {
        let (p, t) = (dual.corners(s), mesh.corners(s / 6));
        let g = gradients(t);
        let phi = |x: [f64; 2], j: usize| {
            f64::from(u8::from(j == 0)) + g[j][0] * (x[0] - t[0][0]) + g[j][1] * (x[1] - t[0][1])
        };
        let area = 0.5 * membrane_contact::mesh::orient(p[0], p[1], p[2]);
        let mids = (0..3).map(|e| [0, 1].map(|k| 0.5 * (p[e][k] + p[(e + 1) % 3][k])));
        std::array::from_fn(|j| mids.clone().map(|m| area / 3.0 * f[i](m) * phi(m, j)).sum())
    };
    let minus: Vec<f64> = lambda.iter().map(|l| -l).collect();
    let membranes = [
        equilibration::Membrane {
            mu: 1.0,
            u: &r.solution.u1,
            on_dual_cell: lambda,
        },
        equilibration::Membrane {
            mu: 2.0,
            u: &r.solution.u2,
            on_dual_cell: &minus,
        },
    ];
    let loads = |triangles: std::ops::Range<usize>, out: &mut Vec<Pairings>| {
        out.extend(triangles.map(|t| Pairings(std::array::from_fn(|c| [0, 1].map(|i| f_phi(i, 6 * t + c))))));
    };
    let patches = equilibration::Patches::new(mesh);
    let worst = equilibration::equilibrate((mesh, &dual, &patches), &membranes, loads, |t, _, tau| {
        let mut worst = 0.0_f64;
        for (c, s) in (6 * t..6 * t + 6).enumerate() {
            let p = dual.corners(s);
            let area = 0.5 * membrane_contact::mesh::orient(p[0], p[1], p[2]);
            let x = p.iter().map(|p| p[0]).sum::<f64>() / 3.0;
            let l = lambda[dual.owner(s)];
            for (i, expected) in [x - 10.0 + l, 10.0 - l].into_iter().enumerate() {
                let div = tau[i][c].iter().sum::<f64>() / area;
                worst = worst.max((div - expected).abs() / (1.0 + expected.abs()));
            }
        }
        worst
    });
    assert_eq!(worst.len(), mesh.n_triangles());
    let worst = worst.into_iter().fold(0.0, f64::max);
    assert!(worst < 1e-9, "div τ off by {worst:e} (relative)");
    let means = &r.estimate.as_ref().unwrap().means;
    assert!(means.iter().all(|&m| m < 1e-12), "{means:?}");
}

/// The ball obstacle (data/cases/ball.toml) from 16² to 128²: the bound holds at every level and
/// tightens, below 1.2 at 128² through ũ = u_h + z (Theorem (O'); through u_h alone, 1.30); the
/// one flux is conserved on the dual cells (Lemma 17 with f).
#[test]
fn above_an_obstacle_the_bound_holds_and_tightens() {
    let mut effectivities = Vec::new();
    for n in [16, 32, 64, 128] {
        let case = shipped("ball", n);
        let r = estimated_with(&case, true);
        let (e, error) = (
            r.estimate.as_ref().unwrap(),
            r.errors.as_ref().unwrap().energy.unwrap(),
        );
        assert!(e.total >= error, "{n}²: η = {:e} < error {error:e}", e.total);
        assert!(
            e.obstacle_total.unwrap() > 0.1 * error,
            "{n}²: u_h = ψ_h dips below ψ"
        );
        let conservation = &r.flux.as_ref().unwrap().conservation;
        assert!(
            conservation.len() == 1 && conservation[0] < 1e-14,
            "{conservation:?}"
        );
        effectivities.push(e.total / error);
        // The summary names the lifting for what it holds, not as boundary data alone.
        let summary = e.summary(None);
        assert!(
            summary.contains(&format!(
                "lifting of g − g_h and ψ − u_h {:.2e} (ψ − u_h alone",
                e.boundary_total
            )) && !summary.contains("boundary data"),
            "{summary}"
        );
        // One membrane: its unknowns are not "per membrane".
        let verbose = r.summary(true);
        assert!(
            verbose.contains(" unknowns; ") && !verbose.contains("per membrane"),
            "{verbose}"
        );
    }
    assert!(effectivities.windows(2).all(|w| w[1] < w[0]), "{effectivities:?}");
    assert!(
        effectivities[2] < 1.25 && effectivities[3] < 1.2,
        "{effectivities:?}"
    );
    // At 128² η is (O')'s, and the summary says so.
    let e = estimated_with(&shipped("ball", 128), false).estimate.unwrap();
    let lifted = e.lifted_membrane.expect("Theorem (O') at 128²");
    assert!(lifted < e.membranes[0] && e.summary(None).contains("Theorem (O')"));
}

/// A membrane pressed onto ψ = sin πx sin πy (f = −1, g = 0): contact everywhere, u = ψ and
/// u_h = ψ_h, so the error is ψ − ψ_h alone; the bound holds and its obstacle term (ψ − u_h on
/// the cells where it is positive) is most of the error. g − ψ = −1.2e-16 on x = 1 is round-off
/// of ψ's size (it was taken for g below ψ on ∂ω, and η for no bound, on the default diagonals).
#[test]
fn in_full_contact_the_obstacle_term_is_the_interpolation_error() {
    let body = "problem = \"obstacle\"\nmu = 1.0\nf = -1\npsi = \"sin(pi*x)*sin(pi*y)\"\ng = 0\n\
                [exact]\nu = \"sin(pi*x)*sin(pi*y)\"\nlambda = \"2*pi^2*sin(pi*x)*sin(pi*y) + 1\"\n\
                grad_u = [\"pi*cos(pi*x)*sin(pi*y)\", \"pi*sin(pi*x)*cos(pi*y)\"]";
    for (n, diagonal) in [(8, "right"), (16, "right"), (32, "right"), (16, "left")] {
        let case = square(body, n, diagonal);
        let r = estimated(&case);
        let e = r.estimate.as_ref().unwrap();
        assert!(
            e.boundary_below.is_none() && e.is_bound(),
            "{n}² {diagonal}: {:?}",
            e.boundary_below
        );
        assert!(r.solution.obstacle.contact.iter().filter(|&&c| c).count() == (n - 1) * (n - 1));
        let (e, error) = (
            r.estimate.as_ref().unwrap(),
            r.errors.as_ref().unwrap().energy.unwrap(),
        );
        // Through u_h alone the interpolation error counts twice (1.42 × the error); through
        // ũ = u_h + z = ψ once (Theorem (O')).
        assert!(
            e.total >= error && e.total <= 1.2 * error,
            "{n}²: η = {:e}, error {error:e}",
            e.total
        );
        let obstacle = e.obstacle_total.unwrap();
        assert!(
            obstacle > 0.85 * error && obstacle < error,
            "{n}²: {obstacle:e} vs {error:e}"
        );
    }
}

/// An affine obstacle ψ = 1 + x + 2y = g pressed on by f = −1: u = ψ, λ = 1 and u_h = u exactly.
/// The obstacle and contact terms vanish to round-off (of the difference quotient of ∇ψ,
/// ε|ψ| / step); what is left is the flux term of the boundary cells, where λ_h = 0 (4.5) but
/// λ = 1: a layer of width h, of order h^{3/2}.
#[test]
fn an_affine_obstacle_in_full_contact_leaves_only_the_boundary_layer() {
    let body = "problem = \"obstacle\"\nmu = 2.0\nf = -1\npsi = \"1 + x + 2*y\"\ng = \"1 + x + 2*y\"";
    let eta = [6, 24].map(|n| {
        let case = square(body, n, "crossed");
        let r = estimated(&case);
        let interior = r.problem.mesh.on_boundary.iter().filter(|&&b| !b).count();
        assert_eq!(
            r.action
                .lambda
                .iter()
                .filter(|&&l| (l - 1.0).abs() < 1e-9)
                .count(),
            interior
        );
        let e = r.estimate.unwrap();
        assert!(
            e.obstacle_total.unwrap() < 1e-10 && e.contact_total.abs() < 1e-15,
            "{n}²: {e:?}"
        );
        e.total
    });
    assert!(eta[0] < 0.02 && eta[1] < eta[0] / 7.0, "η = {eta:?}");
}

/// disk_jump's loads jump across a circle off the grid: the quadrature defect of the loads is
/// lifted (docs/a-posteriori.md §4(c')), so the effectivity does not grow under refinement and
/// stays below 1.15 (bounded by Friedrichs the defect made it 1.19 at 16² and 1.34 at 256²).
#[test]
fn with_a_load_jumping_across_a_curve_the_effectivity_does_not_grow() {
    let mut effectivities = Vec::new();
    for n in [16, 32, 64, 128] {
        let case = shipped("disk_jump", n);
        let r = estimated(&case);
        let (e, error) = (
            r.estimate.as_ref().unwrap(),
            r.errors.as_ref().unwrap().energy.unwrap(),
        );
        assert!(e.means.iter().all(|&m| m < 1e-9 * e.total), "{n}²: {:?}", e.means);
        effectivities.push(e.total / error);
    }
    assert!(
        effectivities.windows(2).all(|w| w[1] <= w[0]),
        "{effectivities:?}"
    );
    assert!(
        effectivities.iter().all(|&x| (1.0..1.15).contains(&x)),
        "{effectivities:?}"
    );
}

/// The setting of the paper's Part 2 experiments (data/cases/part2_disk.toml: a curved domain,
/// μ1 = μ2, loads and λ jumping across the circle r = 1/√2 that no mesh edge follows): with the
/// defect lifted the effectivity falls from 1.16 on the first mesh and stays within [1, 1.2]
/// (bounded by Friedrichs, the defect made it grow on such a disk, 1.31 to 1.77 over four
/// refinements). η bounds the error against ω_h's solution, not the disk's, so 1 is no theorem
/// here; with the new boundary vertices on the circle the two differ by O(h²) on ∂ω_h, and the
/// effectivity stays above 1.04.
#[test]
fn on_the_part_2_disk_the_effectivity_falls_and_stays_within_1_and_1_2() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("data/cases/part2_disk.toml");
    let effectivities: Vec<f64> = (0..4)
        .map(|refine| {
            let mut case = Case::read(&path).unwrap();
            case.refine = refine;
            let r = estimated(&case);
            r.estimate.unwrap().total / r.errors.unwrap().energy.unwrap()
        })
        .collect();
    assert!(
        effectivities.windows(2).all(|w| w[1] <= w[0]),
        "{effectivities:?}"
    );
    assert!(
        effectivities.iter().all(|&x| (1.0..1.2).contains(&x)),
        "{effectivities:?}"
    );
}

/// On a disk the mesh's polygon ω_h is inscribed in the circle: the exact solution takes the
/// boundary data at the boundary vertices but not between them, and the run says so. On
/// part2_disk u2 = (1 − r²)/2 is largest at the midpoint of the longest boundary edge L, where
/// r² = 1 − L²/4: u2 = L²/8 against g2 = 0, relative to the solution's size (the largest of |u1h|
/// and |u2h| at the vertices, and u1 = 0.05 + 0.075 L² + 0.0125 L⁴ there). On the unit square of
/// the default case and of full_contact the exact solution is the data.
#[test]
fn a_curved_domain_s_exact_solution_is_said_to_miss_the_polygon_s_boundary_data() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("data/cases/part2_disk.toml");
    let mut case = Case::read(&path).unwrap();
    case.refine = 0;
    let r = estimated(&case);
    let mesh = &r.problem.mesh;
    let longest = (mesh.triangles())
        .flat_map(|t| [0, 1, 2].map(|j| (t[j], t[(j + 1) % 3])))
        .filter(|&(a, b)| {
            let mid = [0, 1].map(|k| 0.5 * (mesh.points[a][k] + mesh.points[b][k]));
            mesh.on_boundary[a] && mesh.on_boundary[b] && mid[0].hypot(mid[1]) < 1.0 - 1e-9
        })
        .map(|(a, b)| {
            let (p, q) = (mesh.points[a], mesh.points[b]);
            (p[0] - q[0]).hypot(p[1] - q[1])
        })
        .fold(0.0, f64::max);
    let l2 = longest * longest;
    let size = (r.solution.u1.iter().chain(&r.solution.u2))
        .fold(0.05 + 0.075 * l2 + 0.0125 * l2 * l2, |m: f64, u| m.max(u.abs()));
    let expected = (l2 / 8.0) / size;
    let m = r
        .errors
        .as_ref()
        .unwrap()
        .boundary
        .expect("a mismatch on the disk");
    assert!(
        (m.relative - expected).abs() <= 1e-12 * expected,
        "{} against {expected}",
        m.relative
    );
    assert!(
        (m.at[0].hypot(m.at[1]) - (1.0 - l2 / 4.0).sqrt()).abs() < 1e-12,
        "at {:?}",
        m.at
    );
    assert!(!m.at_vertex);
    assert!(r
        .summary(false)
        .contains("the errors above are against the solution on another domain"));
    // An exact solution off g at the vertices of a square is not another domain's: it is not a
    // solution of the case, and the run says so at the vertex.
    let body = "mu1 = 1.0\nmu2 = 1.0\nf1 = -10\nf2 = 0\ng = \"x*y + 0.1\"\n\
                [exact]\nu1 = \"x*y + 0.1 + 0.2*x*(1 - x)\"\nu2 = \"0\"\nlambda = \"0\"";
    let wrong = square(body, 8, "right");
    let r = estimated(&wrong);
    let m = r.errors.as_ref().unwrap().boundary.expect("a mismatch");
    assert!(
        m.at_vertex && m.at[1] * (1.0 - m.at[1]) == 0.0 && (m.at[0] - 0.5).abs() < 0.1,
        "{m:?}"
    );
    assert!(r
        .summary(false)
        .contains("[exact] is not a solution of this case"));
    // With g = g2 = 0 the boundary values are round-off of sin(π) (full_contact): no mismatch.
    for name in ["default", "full_contact"] {
        let square = shipped(name, 8);
        assert!(estimated(&square).errors.unwrap().boundary.is_none(), "{name}");
    }
}

/// The lift of the quadrature defect (§4(c')) by multigrid on the solve's own hierarchy gives the
/// estimate of a direct solve of the same equation: on disk_jump, whose load the rule misses
/// across a circle, every term agrees to 1e-10 of η, and the solve did use multigrid.
#[test]
fn the_lift_by_multigrid_is_the_direct_lift() {
    let case = shipped("disk_jump", 32);
    let mut r = estimated(&case);
    assert!(!r.solution.transfers.is_empty(), "the solve used multigrid");
    let by_multigrid = r.estimate.take().unwrap();
    r.solution.transfers.clear();
    let dual = DualMesh::new(&r.problem.mesh, &r.edges);
    let direct = Estimate::compute(&r.problem, &dual, &r.solution, &r.action);
    let scale = direct.total;
    let pairs = [
        (by_multigrid.total, direct.total),
        (by_multigrid.boundary_total, direct.boundary_total),
        (by_multigrid.contact_total, direct.contact_total),
        (by_multigrid.lambda, direct.lambda),
    ];
    let membranes = by_multigrid.membranes.iter().zip(&direct.membranes);
    for (a, b) in pairs.into_iter().chain(membranes.map(|(a, b)| (*a, *b))) {
        assert!((a - b).abs() <= 1e-10 * scale, "{a} against {b}");
    }
    // What either solve leaves of the defect (ρ, by Friedrichs) is round-off.
    assert!(
        direct.means.iter().all(|&m| m < 1e-6 * scale),
        "{:?}",
        direct.means
    );
}

/// The area and centroid of the part of the triangle `p` with x > x0 (the triangle clipped by
/// the half-plane).
fn right_of(p: [[f64; 2]; 3], x0: f64) -> (f64, [f64; 2]) {
    let mut clipped: Vec<[f64; 2]> = Vec::new();
    for k in 0..3 {
        let (a, b) = (p[k], p[(k + 1) % 3]);
        if a[0] > x0 {
            clipped.push(a);
        }
        if (a[0] > x0) != (b[0] > x0) {
            let s = (x0 - a[0]) / (b[0] - a[0]);
            clipped.push([x0, a[1] + s * (b[1] - a[1])]);
        }
    }
    let (mut area, mut moment) = (0.0, [0.0; 2]);
    for k in 0..clipped.len() {
        let (a, b) = (clipped[k], clipped[(k + 1) % clipped.len()]);
        let cross = a[0] * b[1] - a[1] * b[0];
        area += cross / 2.0;
        moment = [0, 1].map(|i| moment[i] + (a[i] + b[i]) * cross / 6.0);
    }
    match area.abs() > 0.0 {
        true => (area.abs(), moment.map(|m| m / area)),
        false => (0.0, [0.0; 2]),
    }
}

/// η takes the loads' pairings on the cells of S_h by the case's rule as exact. For a load that
/// jumps across the line x = x0, which cuts cells of S_h, what the rule misses is known in closed
/// form (∫ φ_j over the cut cells' parts, |P| φ_j(centroid of P)); lifted as η_data lifts it, it is
/// η_data to 20 % (the finer rule's own error on the cut cells). A load the rule integrates
/// exactly is not checked at all, on a mesh far from the origin too.
#[test]
fn what_the_rule_misses_of_a_jumping_load_is_measured() {
    let x0 = 0.3141;
    let load = format!("if(x > {x0}, -4, 0)");
    let body =
        format!("mu1 = 1.0\nmu2 = 1.0\nf1 = \"{load}\"\nf2 = \"0\"\ng = \"0\"\n[quadrature]\ndegree = 2");
    let case = square(&body, 8, "right");
    let r = estimated(&case);
    let mesh = &r.problem.mesh;
    let dual = DualMesh::new(mesh, &r.edges);
    let rule = membrane_contact::assembly::Quadrature { degree: 2 };
    let f = membrane_contact::expr::Expr::parse(&load).unwrap();
    let mut delta = vec![0.0; mesh.n_vertices()];
    rule.visit(
        |s| dual.corners(s),
        0..dual.n_cells(),
        [&f],
        |s, points, [values]| {
            let (g, tri) = (gradients(mesh.corners(s / 6)), mesh.triangle(s / 6));
            let p0 = mesh.corners(s / 6)[0];
            let phi = |j: usize, x: [f64; 2]| {
                f64::from(u8::from(j == 0)) + g[j][0] * (x[0] - p0[0]) + g[j][1] * (x[1] - p0[1])
            };
            let (area, centroid) = right_of(dual.corners(s), x0);
            for (j, &a) in tri.iter().enumerate() {
                let by_rule: f64 = points
                    .iter()
                    .zip(values)
                    .map(|(q, v)| q.weight * v * phi(j, q.x))
                    .sum();
                if !mesh.on_boundary[a] {
                    delta[a] += -4.0 * area * phi(j, centroid) - by_rule;
                }
            }
        },
    );
    let z = membrane_contact::contact::with_poisson(&r.problem, &[], |solve| solve(&delta, 1e-14)).unwrap();
    let exact = z.iter().zip(&delta).map(|(z, d)| z * d).sum::<f64>().sqrt();
    let e = r.estimate.as_ref().unwrap();
    assert!(exact > 1e-4, "the line cuts cells: {exact}");
    assert!(
        (e.resolution.total / exact - 1.0).abs() < 0.2,
        "η_data {} against {exact}",
        e.resolution.total
    );
    assert!(e.resolution.checked > 0 && e.resolution.checked < mesh.n_triangles());
    let constant = square(
        "mu1 = 1.0\nmu2 = 1.0\nf1 = \"-1\"\nf2 = \"2\"\ng = \"0\"",
        8,
        "right",
    );
    let c = estimated(&constant);
    let c = &c.estimate.as_ref().unwrap();
    assert!(c.resolution.total == 0.0 && c.resolution.checked == 0 && c.loads_resolved());
    // The same on a disk far from the origin, where the cells' corners are rounded by about
    // 1e-10, some 1e-9 of the mesh size: no triangle is taken for a load the rule misses.
    let far = "mu1 = 1.0\nmu2 = 1.0\nf1 = \"-1\"\nf2 = \"2\"\ng = \"0\"\n[mesh]\nkind = \"disk\"\n\
               centre = [1e6, 0.0]\nradius = 1.0\nh = 0.05";
    let far = Case::parse(far, "far", PathBuf::new()).unwrap();
    let r = estimated(&far);
    let e = r.estimate.as_ref().unwrap();
    assert!(
        e.resolution.checked == 0 && e.loads_resolved(),
        "{} checked",
        e.resolution.checked
    );
}

/// A load with a layer far thinner than the mesh (tanh of width 1e-4) is not resolved by the
/// case's rule: the summary says that η is not a guaranteed bound, and where; the default case's
/// loads are resolved.
#[test]
fn a_load_the_rule_does_not_resolve_is_named() {
    let body = "mu1 = 1.0\nmu2 = 1.0\nf1 = \"-10*tanh((x - 0.5123)/1e-4)\"\nf2 = \"0\"\ng = \"0\"\n[quadrature]\ndegree = 2";
    let layer = square(body, 8, "right");
    let r = estimated(&layer);
    let e = r.estimate.as_ref().unwrap();
    assert!(
        !e.loads_resolved(),
        "η_data {} against η {}",
        e.resolution.total,
        e.total
    );
    let summary = e.summary(None);
    assert!(summary.contains("NOT resolved"), "{summary}");
    let [x, _] = e.resolution.worst.unwrap();
    assert!((x - 0.5123).abs() < 0.125, "{summary}");
    let case = shipped("default", 32);
    let default = estimated(&case);
    let d = default.estimate.as_ref().unwrap();
    assert!(d.loads_resolved(), "{}", d.summary(None));
}

/// Boundary values ≥ 0 at the boundary vertices but below 0 between them (so that no u1 ≥ u2
/// takes them: the problem has no solution), or below the obstacle there, are found on the edges
/// and said: η is not a bound. The discrete problem, which takes g_h, solves; g ≥ 0 everywhere
/// (g ≥ ψ) is not flagged.
#[test]
fn boundary_values_below_zero_between_the_vertices_are_named() {
    let body = "mu1 = 1.0\nmu2 = 1.0\nf1 = \"-5\"\nf2 = \"5\"\ng = \"0.01*(1 - 2*sin(16*pi*x)^2)\"";
    let case = square(body, 16, "right");
    let r = estimated(&case);
    let e = r.estimate.as_ref().unwrap();
    let (g, [x, y]) = e
        .boundary_below
        .expect("g = -0.01 at x = 1/32, 3/32, … on y = 0 and 1");
    assert!(g < -0.0099 && (y == 0.0 || y == 1.0), "{g} at ({x}, {y})");
    assert!(((16.0 * x) - (16.0 * x).floor() - 0.5).abs() < 0.1, "{x}");
    assert!(e.summary(None).contains("η is NOT a bound"));
    // Above an obstacle: g = 0 ≥ ψ = −0.001 at the vertices, ψ up to 0.009 between them.
    let obstacle =
        "problem = \"obstacle\"\nmu = 1.0\nf = \"-1\"\ng = 0\npsi = \"0.01*sin(16*pi*x)^2 - 0.001\"";
    let case = square(obstacle, 16, "right");
    let r = estimated(&case);
    let e = r.estimate.as_ref().unwrap();
    let (d, _) = e.boundary_below.expect("g < ψ between the boundary vertices");
    assert!(d < -0.0089, "{d}");
    assert!(e.summary(None).contains("g < ψ on ∂ω"), "{}", e.summary(None));
    let case = shipped("ball", 16);
    let ball = estimated(&case);
    assert_eq!(ball.estimate.as_ref().unwrap().boundary_below, None);
    for body in [
        body.replace("1 - 2*", "1 - "),
        format!("{}\n", shipped_text("default")),
    ] {
        let case = Case::parse(
            &format!("{body}\n[mesh]\nkind = \"rectangle\"\nn = [16, 16]\n"),
            "g",
            PathBuf::new(),
        );
        let r = estimated(case.as_ref().unwrap());
        let e = r.estimate.as_ref().unwrap();
        assert_eq!(e.boundary_below, None, "{}", e.summary(None));
    }
}

/// The text of the shipped case data/cases/`name`.toml without its `[mesh]` table and what follows.
fn shipped_text(name: &str) -> String {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join(format!("data/cases/{name}.toml"));
    let text = std::fs::read_to_string(path).unwrap();
    text[..text.find("[mesh]").unwrap()].to_string()
}

/// An `[exact]` that misses its equation, or whose ∇u is not u's gradient, is named as such (its
/// Laplacian and gradient differentiated from the expression); every shipped exact solution
/// solves its case's equations, the harmonic ones (Δu = 0 from terms that are not) included.
#[test]
fn an_exact_solution_that_misses_its_equation_is_named() {
    use membrane_contact::norms::Missed;
    let body = |f1: &str, dx: &str| {
        format!(
            "mu1 = 2.0\nmu2 = 1.0\nf1 = \"{f1}\"\nf2 = 0\ng = 0\n[exact]\nu1 = \"sin(pi*x)*sin(pi*y)\"\n\
             u2 = \"0\"\nlambda = \"0\"\ngrad_u1 = [\"{dx}\", \"pi*sin(pi*x)*cos(pi*y)\"]"
        )
    };
    let unsolved = |f1: &str, dx: &str| {
        let case = square(&body(f1, dx), 8, "right");
        let r = run::run(&case, &run::Options::default()).unwrap();
        r.errors.unwrap().unsolved.map(|u| u.missed)
    };
    // −μ1Δu1 = 4π² sin πx sin πy: solved; with 1 % more load, or a gradient without its π, not.
    assert_eq!(
        unsolved("4*pi^2*sin(pi*x)*sin(pi*y)", "pi*cos(pi*x)*sin(pi*y)"),
        None
    );
    assert_eq!(
        unsolved("4.04*pi^2*sin(pi*x)*sin(pi*y)", "pi*cos(pi*x)*sin(pi*y)"),
        Some(Missed::Equation(1))
    );
    assert_eq!(
        unsolved("4*pi^2*sin(pi*x)*sin(pi*y)", "cos(pi*x)*sin(pi*y)"),
        Some(Missed::Gradient(1))
    );
    for entry in std::fs::read_dir(Path::new(env!("CARGO_MANIFEST_DIR")).join("data/cases")).unwrap() {
        let path = entry.unwrap().path();
        if path.extension().is_none_or(|e| e != "toml") {
            continue;
        }
        let mut case = Case::read(&path).unwrap();
        if case.set_cells(8).is_err() {
            continue;
        }
        let r = run::run(&case, &run::Options::default()).unwrap();
        if let Some(errors) = r.errors {
            assert!(
                errors.unsolved.is_none(),
                "{}: {:?}",
                path.display(),
                errors.unsolved
            );
        }
    }
}

/// Without `grad_u1` the H¹ errors are those against u1's derivatives: the same, to round-off,
/// as with the gradient written by hand (and above an obstacle, without `grad_u`).
#[test]
fn without_a_gradient_the_h1_errors_differentiate_u() {
    let two = "mu1 = 1.0\nmu2 = 2.0\nf1 = 1\nf2 = 0\ng = 0\n[exact]\n\
               u1 = \"sin(pi*x)*sin(pi*y)*(1 + x)\"\nu2 = \"x*y*(1 - x)*(1 - y)\"\nlambda = \"0\"";
    let by_hand = "\ngrad_u1 = [\"pi*cos(pi*x)*sin(pi*y)*(1 + x) + sin(pi*x)*sin(pi*y)\", \
                   \"pi*sin(pi*x)*cos(pi*y)*(1 + x)\"]\n\
                   grad_u2 = [\"(1 - 2*x)*y*(1 - y)\", \"x*(1 - x)*(1 - 2*y)\"]";
    let obstacle = "problem = \"obstacle\"\nmu = 1.0\nf = -1\npsi = \"0\"\ng = 0\n[exact]\n\
                    u = \"sin(pi*x)*sin(pi*y)*(1 + x)\"\nlambda = \"0\"";
    let by_hand_obstacle = "\ngrad_u = [\"pi*cos(pi*x)*sin(pi*y)*(1 + x) + sin(pi*x)*sin(pi*y)\", \
                            \"pi*sin(pi*x)*cos(pi*y)*(1 + x)\"]";
    let h1 = |body: &str| {
        let case = square(body, 16, "right");
        let e = run::run(&case, &run::Options::default()).unwrap().errors.unwrap();
        [e.h1_u1.unwrap(), e.h1_u2.unwrap_or(0.0)]
    };
    for (derived, given) in [
        (h1(two), h1(&format!("{two}{by_hand}"))),
        (h1(obstacle), h1(&format!("{obstacle}{by_hand_obstacle}"))),
    ] {
        for (d, g) in derived.iter().zip(given) {
            assert!((d - g).abs() <= 1e-12 * g, "{derived:?} against {given:?}");
        }
        assert!(derived[0] > 0.0);
    }
}

/// No contact, u1 = 2 + e^{k(y−1)} sin kx on [0, 1] × [0, 0.7], an error of 1e-10 … 1e-8 against
/// a solution of size 2: λ_h is the solve's round-off, of either sign. Taken into the contact
/// term as it is, its negative part made η_C < 0 and η = 0 < error (k = 80, printed as a
/// guaranteed bound), its positive part η 220 times the error (k = 70).
#[test]
fn round_off_of_lambda_off_the_contact_set_neither_cancels_nor_swamps_eta() {
    for k in [70, 80] {
        let u1 = format!("2 + exp({k}*(y-1))*sin({k}*x)");
        let text = format!(
            "mu1 = 1.0\nmu2 = 3.0\nf1 = \"0\"\nf2 = \"0\"\ng = \"{u1}\"\n\
             [exact]\nu1 = \"{u1}\"\nu2 = \"0\"\nlambda = \"0\"\n\
             [mesh]\nkind = \"polygon\"\nboundary = [[0, 0], [1, 0], [1, 0.7], [0, 0.7]]\nh = 0.1\n"
        );
        let case = Case::parse(&text, "round-off", PathBuf::new()).unwrap();
        let r = estimated(&case);
        let (e, error) = (
            r.estimate.as_ref().unwrap(),
            r.errors.as_ref().unwrap().energy.unwrap(),
        );
        assert!(
            error > 1e-10 && !r.errors.as_ref().unwrap().at_round_off(),
            "k = {k}: {error:e}"
        );
        assert_eq!(e.contact_total, 0.0, "k = {k}");
        // λ_h, all of it off the contact set, enters each η_i by Friedrichs: C_F ‖λ_h‖ / μ_i^½,
        // C_F of the bounding box 1 × 0.7.
        let off: f64 = (r.action.lambda.iter().zip(&r.problem.mass))
            .map(|(l, m)| l * l * m)
            .sum::<f64>()
            .sqrt();
        let c_f = 1.0 / (std::f64::consts::PI * (1.0 + 1.0 / 0.49_f64).sqrt());
        assert!(off > 0.0, "k = {k}");
        for (means, mu) in e.means.iter().zip([1.0_f64, 3.0]) {
            assert!(
                (means - c_f * off / mu.sqrt()).abs() <= 1e-9 * means,
                "k = {k}: {means:e}"
            );
        }
        assert!(
            (1.0..1.5).contains(&(e.total / error)),
            "k = {k}: η = {:e}, error {error:e}",
            e.total
        );
    }
}

/// The estimator's line prints the energy error its effectivity divides by (with μ ≠ 1 the H¹
/// errors beside it are not that error).
#[test]
fn the_estimator_line_prints_the_error_it_divides_by() {
    let case = shipped("default", 16);
    let r = estimated(&case);
    let (eta, error) = (
        r.estimate.as_ref().unwrap().total,
        r.errors.as_ref().unwrap().energy.unwrap(),
    );
    let summary = r.summary(false);
    let expected = format!(
        "effectivity η/error {:.3} (error |||u − u_h||| = {error:.4e})",
        eta / error
    );
    assert!(summary.contains(&expected), "{expected}\n{summary}");
}
