//! The reduced discrete variational inequality (3.4) on K_gh = {v1h − v2h ≥ 0 at the vertices}.
//!
//! For constant μ1, μ2 the discrete energy Σ_i μ_i/2 |∇u_ih|² − (f_i, u_ih) separates exactly in
//!   v = (μ1 u1 + μ2 u2)/(μ1 + μ2)   and   w = u1 − u2:
//!   (μ1+μ2)/2 |∇v|² − (f1 + f2, v)  +  μ*/2 |∇w|² − (f_w, w),
//! with μ* = μ1μ2/(μ1+μ2), f_w = (μ2 f1 − μ1 f2)/(μ1+μ2), v = μ1 g_h/(μ1+μ2) and w = g_h on ∂ω,
//! and the only constraint w(a) ≥ 0 at the interior vertices. So (3.4) is one Poisson solve for v
//! and one scalar obstacle problem for w. Multiplying the two equations of (4.5) by μ2 and μ1 and
//! subtracting shows that the obstacle problem's residual is the action: μ*(K w)_a − (f_w, φ_a)
//! = λ_a m_a, with m_a = ∫φ_a.
//!
//! The obstacle problem is solved by the primal–dual active-set method (a semismooth Newton method
//! for min(w_a, λ_a) = 0): A = {a : λ_a − c_a w_a > 0}, w = 0 on A, the equation off A, repeated
//! until A no longer changes, which is then the exact solution of (3.4) up to round-off.

mod active_set;
mod backend;
mod local;
mod nested;
mod options;
mod stats;
mod w_problem;

pub use active_set::Obstacle;
pub use nested::Start;
pub use options::{LinearSolver, SolveError, SolverOptions};
pub use stats::SolverStats;

use crate::linear::InteriorSystem;
use crate::mesh::{Mesh, Prolongation};
use crate::multigrid::Hierarchy;
use crate::parallel;
use crate::problem::DiscreteProblem;
use crate::result::{Attr, Attribute, Describe, Field, Place};
use active_set::{obstacle, Role};
use backend::{analysed, LinearSolve, Loads, Stop, FINAL_STOP, RESULT_STOP};
use nested::{chain, initial_guess, Started};
use std::borrow::Cow;
use std::time::Instant;

/// Above this many vertices, and with Cholesky on any mesh, w's steps on the final mesh start
/// once v is solved: the CG vectors and coarse operators (or the Cholesky factors) of the two
/// solves are then never in memory at once (measured in docs/performance.md).
pub const SIDE_BY_SIDE_LIMIT: usize = 1 << 22;

/// The largest relative defect of Prop. 12, of λ_a ≥ 0 and of (4.8) a run accepts
/// (`action::Checks`): round-off of the factorizations leaves about 1e-15, and the solves whose
/// result is returned are solved to a backward error below it.
pub const CHECK_TOLERANCE: f64 = 1e-10;

/// The solution (u1h, u2h) of (3.4), with the obstacle problem's w = u1h − u2h, its λ,
/// the contact set and the solver statistics.
#[derive(Debug, Clone)]
pub struct Solution {
    /// u1h at every vertex.
    pub u1: Vec<f64>,
    /// u2h at every vertex.
    pub u2: Vec<f64>,
    /// The obstacle problem's solution w = u1h − u2h, with its λ and contact set.
    pub obstacle: Obstacle,
    /// Whether u2h is a rigid obstacle ψ_h (the classical obstacle problem): its fields are then
    /// written as u = u1h and psi = u2h.
    pub rigid: bool,
    /// The interpolations between the meshes of the solve's multigrid, finest first (none when it
    /// used Cholesky): later Poisson solves on this mesh ([`with_poisson`]) use the same hierarchy.
    pub transfers: Vec<Prolongation>,
}

/// Solves (3.4): the Poisson problem for v beside the obstacle problem for w from the guess of
/// `start` (for [`Start::Nested`], nested iteration on the `coarser` meshes, from fine to coarse),
/// or, with Cholesky and above [`SIDE_BY_SIDE_LIMIT`] vertices, v beside the guess and w's steps
/// after v; u1 = v + μ2/(μ1+μ2) w, u2 = v − μ1/(μ1+μ2) w. A mesh without coarser ones (an adapted
/// mesh, a file mesh not refined) is solved by Cholesky.
///
/// ```
/// use membrane_contact::{case::Case, contact, problem::DiscreteProblem};
/// let case = Case::default_case();
/// let (mesh, coarser) = case.hierarchy(true, Default::default()).unwrap();
/// let problem = DiscreteProblem::new(mesh, &case.data).unwrap();
/// let solution = contact::solve(&problem, contact::Start::Nested, coarser, case.solver).unwrap();
/// // The membranes touch where the gap w = u1h − u2h vanishes, and nowhere cross.
/// assert!(solution.obstacle.contact.iter().any(|&c| c));
/// assert!(solution.obstacle.gap.iter().all(|&w| w >= 0.0));
/// ```
pub fn solve(
    problem: &DiscreteProblem,
    start: Start,
    coarser: Vec<Mesh>,
    options: SolverOptions,
) -> Result<Solution, SolveError> {
    let clock = Instant::now();
    let multigrid = options.linear == LinearSolver::Multigrid && !coarser.is_empty();
    let linear = if multigrid {
        LinearSolver::Multigrid
    } else {
        LinearSolver::Direct
    };
    let options = SolverOptions { linear, ..options };
    let nested = matches!(start, Start::Nested);
    let prolongations = if multigrid || nested {
        chain(&problem.mesh, &coarser)
    } else {
        Vec::new()
    };
    let transfer_seconds = clock.elapsed().as_secs_f64();
    let guess = || initial_guess(problem, start, coarser, &prolongations, options);
    let analyse = || Analysis::new(problem, multigrid.then_some(&prolongations[..]));
    let side_by_side = multigrid && problem.mesh.n_vertices() <= SIDE_BY_SIDE_LIMIT;
    let (analysis, v, obstacle) = if problem.data.is_obstacle() {
        // Below a rigid obstacle there is no v: u1h = ψ_h + w.
        let (analysis, started) = parallel::join(analyse, guess);
        let w = started.and_then(|started| solve_w(problem, &analysis, started, options));
        (analysis, Ok((Vec::new(), SolverStats::default())), w)
    } else if side_by_side {
        let analysis = analyse();
        let (v, w) = parallel::join(
            || solve_v(problem, &analysis),
            || solve_w(problem, &analysis, guess()?, options),
        );
        (analysis, v, w)
    } else {
        let ((analysis, v), started) = parallel::join(
            || {
                let analysis = analyse();
                let v = solve_v(problem, &analysis);
                (analysis, v)
            },
            guess,
        );
        let w = started.and_then(|started| solve_w(problem, &analysis, started, options));
        (analysis, v, w)
    };
    let ((v, mut v_stats), mut obstacle) = (v?, obstacle?);
    // The symbolic analysis (and multigrid's transfers) counts with the v solve.
    v_stats.symbolic_seconds += analysis.seconds + transfer_seconds;
    let stats = &mut obstacle.stats;
    stats.add_work(&v_stats);
    stats.v_cg_iterations = v_stats.cg_iterations.first().copied().unwrap_or(0);
    stats.linear = options.linear;
    stats.multigrid_levels = analysis.hierarchy.as_ref().map_or(0, Hierarchy::levels);
    stats.wall_seconds = clock.elapsed().as_secs_f64();
    drop(analysis);
    let transfers = if multigrid { prolongations } else { Vec::new() };
    Ok(Solution::of(problem, v, obstacle, transfers))
}

/// A solver of Poisson problems handed out by [`with_poisson`]: z for the load b (at every
/// vertex) to a residual (see there).
pub type PoissonSolve<'a> = dyn FnMut(&[f64], f64) -> Result<Vec<f64>, SolveError> + 'a;

/// Hands `work` the solver of the Poisson problems K z = b at the interior vertices, z = 0 on
/// ∂ω: CG with V-cycles on `transfers` (a [`Solution`]'s), each from z = 0 until
/// max_a |r_a|/m_a ≤ `residual` · max_a |b_a|/m_a, or Cholesky without them. One analysis serves
/// every load of `work`, and none is made if it solves none.
pub fn with_poisson<R>(
    problem: &DiscreteProblem,
    transfers: &[Prolongation],
    work: impl FnOnce(&mut PoissonSolve) -> R,
) -> R {
    let analysis = std::cell::OnceCell::new();
    let mut solver: Option<Box<dyn backend::LinearSolve + '_>> = None;
    let zero = vec![0.0; problem.mesh.n_vertices()];
    let mut solve = |load: &[f64], residual: f64| {
        let (system, hierarchy) =
            analysis.get_or_init(|| analysed(problem, (!transfers.is_empty()).then_some(transfers)));
        let solver = match &mut solver {
            Some(solver) => solver,
            None => {
                let sizes = Loads {
                    density: 0.0,
                    problem,
                    scale: 1.0,
                };
                let multigrid = hierarchy.as_ref().map(|h| (h, Stop::Residual(residual)));
                let mut made = backend::solver(system, multigrid, None, sizes);
                made.prepare(&vec![false; system.n()])?;
                solver.insert(made)
            }
        };
        solver.restart(Stop::Residual(residual));
        let rhs = system.lifted_rhs(&problem.stiffness, |a| load[a], 1.0, |_| 0.0);
        Ok(system.scatter(&solver.solve(Cow::Owned(rhs))?, &zero))
    };
    work(&mut solve)
}

/// What the v and w solves on the final mesh share: the unknowns with the Cholesky analysis of
/// K_II or the multigrid hierarchy, whose coarse operators with the boundary alone skipped (v's)
/// are kept (w's steps recompute theirs only near the held set), and the seconds it took.
struct Analysis<'t> {
    system: InteriorSystem,
    hierarchy: Option<Hierarchy<'t>>,
    seconds: f64,
}

impl<'t> Analysis<'t> {
    fn new(problem: &'t DiscreteProblem, prolongations: Option<&'t [Prolongation]>) -> Self {
        let t = Instant::now();
        let (system, hierarchy) = analysed(problem, prolongations);
        let hierarchy = hierarchy.map(|h| h.with_base(problem.mesh.on_boundary.clone()));
        Analysis {
            system,
            hierarchy,
            seconds: t.elapsed().as_secs_f64(),
        }
    }
}

/// v: (μ1+μ2) K v = F1 + F2 inside, v = (μ1 g_h + μ2 g2_h)/(μ1+μ2) = g_h − μ2/(μ1+μ2) w on ∂ω; at
/// every vertex, with the work.
fn solve_v(problem: &DiscreteProblem, analysis: &Analysis) -> Result<(Vec<f64>, SolverStats), SolveError> {
    let (mu1, mu2) = (
        problem.data.mu1,
        problem.data.mu2().expect("v is solved below membrane 2"),
    );
    let system = &analysis.system;
    let bc: Vec<f64> = (problem.g_h.iter().zip(&problem.gap_h))
        .map(|(g, w)| g - mu2 / (mu1 + mu2) * w)
        .collect();
    let load = |a: usize| problem.load1[a] + problem.load2[a];
    let rhs = system.lifted_rhs(&problem.stiffness, load, mu1 + mu2, |a| bc[a]);
    let loads = Loads {
        density: 0.0,
        problem,
        scale: mu1 + mu2,
    };
    let multigrid = analysis.hierarchy.as_ref().map(|h| (h, RESULT_STOP));
    let mut solver = stats::Timed::new(backend::solver(system, multigrid, None, loads));
    solver.prepare(&vec![false; system.n()])?;
    let x = solver.solve(Cow::Owned(rhs))?;
    let mut stats = SolverStats::default();
    solver.record(&mut stats);
    Ok((system.scatter(&x, &bc), stats))
}

/// w: the obstacle problem on the final mesh from the guess `started`, with the coarser levels'
/// counts.
fn solve_w(
    problem: &DiscreteProblem,
    analysis: &Analysis,
    started: Started,
    options: SolverOptions,
) -> Result<Obstacle, SolveError> {
    let multigrid = analysis.hierarchy.as_ref().map(|h| (h, FINAL_STOP));
    let mut w = obstacle(
        problem,
        &analysis.system,
        multigrid,
        started.guess,
        options,
        Role::Solution,
    )?;
    w.stats.coarse_iterations = started.iterations;
    w.stats.coarse_cg_iterations = started.cg_iterations;
    w.stats.coarse_seconds = started.seconds;
    Ok(w)
}

impl Solution {
    /// u1 = v + μ2/(μ1+μ2) w, u2 = v − μ1/(μ1+μ2) w (g_h and g_h − w on ∂ω); below a rigid
    /// obstacle u1 = ψ_h + w (g_h on ∂ω), u2 = ψ_h.
    fn of(problem: &DiscreteProblem, v: Vec<f64>, obstacle: Obstacle, transfers: Vec<Prolongation>) -> Self {
        let w = &obstacle.gap;
        let Some(mu2) = problem.data.mu2() else {
            let psi = &problem.psi_h;
            let on_boundary = &problem.mesh.on_boundary;
            // On ∂ω g as given, not as ψ_h + (g − ψ_h) rounds it.
            let u1 = (psi.iter().zip(w).enumerate())
                .map(|(a, (p, w))| if on_boundary[a] { problem.g_h[a] } else { p + w })
                .collect();
            return Solution {
                u1,
                u2: psi.clone(),
                obstacle,
                rigid: true,
                transfers,
            };
        };
        let mu1 = problem.data.mu1;
        let (c1, c2) = (mu2 / (mu1 + mu2), mu1 / (mu1 + mu2));
        let mut u1: Vec<f64> = v.iter().zip(w).map(|(v, w)| v + c1 * w).collect();
        let mut u2: Vec<f64> = v.iter().zip(w).map(|(v, w)| v - c2 * w).collect();
        // The boundary values as given, not as v and w round them (u2 = g2 = 0 exactly, say).
        for a in (0..u1.len()).filter(|&a| problem.mesh.on_boundary[a]) {
            (u1[a], u2[a]) = (problem.g_h[a], problem.g_h[a] - problem.gap_h[a]);
        }
        Solution {
            u1,
            u2,
            obstacle,
            rigid: false,
            transfers,
        }
    }
}

impl Describe for Solution {
    fn fields(&self) -> Vec<Field<'_>> {
        let contact = &self.obstacle.contact;
        let flags = |rows: std::ops::Range<usize>, out: &mut Vec<f64>| {
            out.extend(contact[rows].iter().map(|&c| f64::from(u8::from(c))));
        };
        let names = if self.rigid { ["u", "psi"] } else { ["u1", "u2"] };
        vec![
            Field::new(names[0], Place::Vertices, &self.u1),
            Field::new(names[1], Place::Vertices, &self.u2),
            Field::new("gap", Place::Vertices, &self.obstacle.gap),
            Field::computed("contact", Place::Vertices, contact.len(), flags),
        ]
    }

    fn attributes(&self) -> Vec<Attribute> {
        let st = &self.obstacle.stats;
        let floats = |v: &[usize]| Attr::Floats(v.iter().map(|&i| i as f64).collect());
        let most = |v: &[Vec<usize>]| {
            Attr::Floats(
                v.iter()
                    .map(|l| l.iter().copied().max().unwrap_or(0) as f64)
                    .collect(),
            )
        };
        let mut attrs = vec![
            ("linear_solver", Attr::Text(st.linear.name().into())),
            ("multigrid_levels", st.multigrid_levels.into()),
            ("cg_iterations", floats(&st.cg_iterations)),
            ("cg_iterations_v", st.v_cg_iterations.into()),
            ("coarse_cg_iterations_max", most(&st.coarse_cg_iterations)),
            ("iterations", st.iterations.into()),
            ("coarse_iterations", floats(&st.coarse_iterations)),
            ("active_set_sizes", floats(&st.active_sizes)),
            ("factorizations", st.factorizations.into()),
            ("local_iterations", st.local_iterations.into()),
            ("symbolic_analyses", st.analyses.into()),
            ("factor_nnz", st.factor_nnz.into()),
            ("seconds_local", st.local_seconds.into()),
            ("seconds_coarse_levels", st.coarse_seconds.into()),
            ("seconds_symbolic", st.symbolic_seconds.into()),
            ("seconds_numeric", st.numeric_seconds.into()),
            ("seconds_solve", st.solve_seconds.into()),
            ("seconds_contact_solve", st.wall_seconds.into()),
        ];
        let failed = st.multigrid_failed.as_ref();
        attrs.extend(failed.map(|cg| {
            (
                "multigrid_failed",
                Attr::Text(SolveError::NotConverged(cg.clone()).to_string()),
            )
        }));
        attrs
    }
}

#[cfg(test)]
mod tests {
    use super::active_set::Guess;
    use super::backend::Stop;
    use super::local::{band, interface, LOCAL_ITERATIONS};
    use super::w_problem::{load_density, WProblem};
    use super::*;
    use crate::assembly::Quadrature;
    use crate::expr::Expr;
    use crate::mesh::Diagonal;
    use crate::problem::Data;

    /// The unit square on n × n right-diagonal cells, μ1 = 1, μ2 = 2, f2 = 0.
    fn problem(n: usize, f1: &str, g: &str) -> DiscreteProblem {
        let e = |s: &str| Expr::parse(s).unwrap();
        let data = Data::new([1.0, 2.0], e(f1), e("0"), e(g), Quadrature { degree: 2 }).unwrap();
        let mesh = Mesh::rectangle([0.0, 0.0], [1.0, 1.0], n, n, Diagonal::Right).unwrap();
        DiscreteProblem::new(mesh, &data).unwrap()
    }

    #[test]
    fn the_summary_says_which_linear_solver_ran() {
        let direct = SolverStats {
            linear: LinearSolver::Direct,
            factorizations: 3,
            ..Default::default()
        };
        assert_eq!(direct.linear_work(), "Cholesky, 3 factorizations");
        let multigrid = SolverStats {
            linear: LinearSolver::Multigrid,
            multigrid_levels: 8,
            v_cg_iterations: 13,
            cg_iterations: vec![10, 6],
            ..Default::default()
        };
        assert_eq!(
            multigrid.linear_work(),
            "multigrid on 8 levels, CG iterations v 13, steps [10, 6]"
        );
    }

    #[test]
    fn adding_the_v_solve_sums_its_work() {
        let mut w = SolverStats {
            symbolic_seconds: 1.0,
            numeric_seconds: 2.0,
            solve_seconds: 3.0,
            factorizations: 4,
            iterations: 5,
            ..Default::default()
        };
        let v = SolverStats {
            symbolic_seconds: 0.5,
            numeric_seconds: 0.25,
            solve_seconds: 0.125,
            factorizations: 1,
            iterations: 7,
            ..Default::default()
        };
        w.add_work(&v);
        let s = (w.symbolic_seconds, w.numeric_seconds, w.solve_seconds);
        assert_eq!(s, (1.5, 2.25, 3.125));
        assert_eq!((w.factorizations, w.iterations), (5, 5));
    }

    #[test]
    fn statistics_count_the_work_of_a_cold_solve() {
        // Membrane 1 pressed onto membrane 2 in the middle: some contact, several iterations.
        let p = problem(24, "-10", "0.05");
        let system = InteriorSystem::new(&p.stiffness, &p.mesh.on_boundary);
        let o = obstacle(&p, &system, None, None, SolverOptions::default(), Role::Solution).unwrap();
        let s = &o.stats;
        let inside = |a: usize| !p.mesh.on_boundary[a];
        let interior = (0..p.mesh.n_vertices()).filter(|&a| inside(a)).count();
        let interior_edges = p
            .mesh
            .edges()
            .iter()
            .filter(|&&(a, b)| inside(a) && inside(b))
            .count();
        assert_eq!(s.unknowns, interior);
        // The factor holds at least the lower triangle of K_II: its diagonal and one entry per
        // interior edge whose vertices K couples.
        let coupled = (p.mesh.edges().iter())
            .filter(|&&(a, b)| inside(a) && inside(b) && p.stiffness.matrix().get(a, b) != 0.0)
            .count();
        assert!(
            coupled <= interior_edges && s.factor_nnz >= interior + coupled,
            "{s:?}"
        );
        let contact = o.contact.iter().filter(|&&c| c).count();
        assert!(contact > 10 && s.iterations > 2, "{s:?}");
        assert_eq!(
            (s.changes.len(), s.active_sizes.len()),
            (s.iterations, s.iterations)
        );
        assert_eq!(
            (s.changes.last(), s.active_sizes.last()),
            (Some(&0), Some(&contact))
        );
        // Each global iteration factorizes for a new held set.
        assert_eq!(s.factorizations, s.iterations);
        assert!((1..=s.iterations).contains(&s.analyses), "{s:?}");
        assert!(s.local_iterations <= LOCAL_ITERATIONS * s.iterations, "{s:?}");
        for (name, t) in [
            ("symbolic", s.symbolic_seconds),
            ("numeric", s.numeric_seconds),
            ("solve", s.solve_seconds),
        ] {
            assert!(t > 0.0 && t < 60.0, "{name} seconds: {t}");
        }
        assert!(s.local_seconds >= 0.0 && s.coarse_seconds == 0.0, "{s:?}");
    }

    #[test]
    fn interface_and_band_follow_the_couplings_of_k() {
        let p = problem(8, "-10", "0.05");
        let system = InteriorSystem::new(&p.stiffness, &p.mesh.on_boundary);
        let n = system.n();
        // The unknowns' neighbours along the edges of the mesh whose vertices K couples (not
        // the diagonals of this right-angled mesh, across which the coupling vanishes).
        let mut neighbours = vec![Vec::new(); n];
        let coupled = |&(a, b): &(usize, usize)| p.stiffness.matrix().get(a, b) != 0.0;
        let edges = p.mesh.edges();
        assert_eq!(edges.iter().filter(|e| coupled(e)).count(), edges.len() - 64);
        for (a, b) in edges.into_iter().filter(coupled) {
            if let (Some(i), Some(j)) = (system.unknown[a].index(), system.unknown[b].index()) {
                neighbours[i].push(j);
                neighbours[j].push(i);
            }
        }
        let x = |i: usize| p.mesh.points[system.vertices[i]];
        let active: Vec<bool> = (0..n).map(|i| x(i)[0] + 0.5 * x(i)[1] < 0.6).collect();
        let expected: Vec<usize> = (0..n)
            .filter(|&i| neighbours[i].iter().any(|&j| active[j] != active[i]))
            .collect();
        assert!(expected.len() > 4 && expected.len() < n / 2);
        assert_eq!(interface(&p, &system, &active), expected);
        // The band of r rings: the unknowns within r edges of a seed, by breadth-first search
        // where active unknowns `held` steps or more from a seed lead no further.
        let seeds = [4 * 9 + 2, 6 * 9 + 6].map(|a| system.unknown[a].index().unwrap());
        let distances = |held: usize| {
            let mut distance = vec![usize::MAX; n];
            let mut queue: std::collections::VecDeque<usize> = seeds.iter().copied().collect();
            seeds.iter().for_each(|&i| distance[i] = 0);
            while let Some(i) = queue.pop_front() {
                if active[i] && distance[i] >= held {
                    continue;
                }
                for &j in &neighbours[i] {
                    if distance[j] == usize::MAX {
                        distance[j] = distance[i] + 1;
                        queue.push_back(j);
                    }
                }
            }
            distance
        };
        let distance = distances(usize::MAX);
        for rings in 0..5 {
            let expected: Vec<usize> = (0..n).filter(|&i| distance[i] <= rings).collect();
            assert_eq!(
                band(&p, &system, &seeds, &active, [rings, rings]),
                expected,
                "{rings} rings"
            );
        }
        let distance = distances(1);
        let expected: Vec<usize> = (0..n).filter(|&i| distance[i] <= 4).collect();
        assert!(expected.len() < band(&p, &system, &seeds, &active, [4, 4]).len());
        assert_eq!(band(&p, &system, &seeds, &active, [4, 1]), expected);
    }

    #[test]
    fn a_start_from_the_solution_is_confirmed_at_once() {
        // With μ1 = 1, μ2 = 2 and f2 = 0, −Δw = f1: w = g − τ for f1 = −1 and g constant, τ the
        // torsion function (max 0.0737), so g = 0.072 gives a small contact set around the centre,
        // whose band of local correction is a small part of the unknowns.
        let p = problem(96, "-1", "0.072");
        let options = SolverOptions::default();
        let cold = solve(&p, Start::Cold, Vec::new(), options).unwrap();
        let start = Start::From {
            mesh: &p.mesh,
            obstacle: &cold.obstacle,
        };
        let warm = solve(&p, start, Vec::new(), options).unwrap();
        let s = &warm.obstacle.stats;
        let contact = warm.obstacle.contact.iter().filter(|&&c| c).count();
        assert!((10..200).contains(&contact), "contact at {contact} vertices");
        assert_eq!(warm.obstacle.contact, cold.obstacle.contact);
        assert_eq!(warm.obstacle.gap, cold.obstacle.gap);
        // The guess's contact set is the solution's: the local correction on the band around its
        // free boundary confirms it in one local iteration, one global solve confirms it again.
        assert_eq!(
            (s.iterations, s.local_iterations, s.factorizations),
            (1, 1, 2),
            "{s:?}"
        );
        assert!(s.local_seconds > 0.0 && s.local_seconds < s.wall_seconds, "{s:?}");
    }

    #[test]
    fn a_proposal_is_solved_relative_to_the_loads_and_a_result_to_the_right_hand_side() {
        // f1 = 1, f2 = 0, μ1 = 1, μ2 = 2: f_w = 2/3 = μ*, so (f_w, φ_a)/(μ* m_a) = 1 exactly;
        // g = 100 puts a lift Σ_b 100 |K_ab|/m_a of up to 2·100·64² next to ∂ω into the
        // right-hand side.
        let p = problem(64, "1", "100");
        let coarser: Vec<Mesh> = [32, 16, 8]
            .map(|n| Mesh::rectangle([0.0, 0.0], [1.0, 1.0], n, n, Diagonal::Right).unwrap())
            .into();
        let prolongations = chain(&p.mesh, &coarser);
        let (system, hierarchy) = analysed(&p, Some(&prolongations));
        let hierarchy = hierarchy.unwrap();
        let w_problem = WProblem::new(&p);
        let rhs = w_problem.rhs(&system, &p.gap_h);
        let loads = load_density(&p, &system, |a| w_problem.load(a), w_problem.mu_star);
        assert!((loads - 1.0).abs() < 1e-12, "{loads}");
        let density = |r: &dyn Fn(usize) -> f64| {
            (system.vertices.iter().enumerate())
                .map(|(i, &a)| (r(i) / p.mass[a]).abs())
                .fold(0.0, f64::max)
        };
        let lifted = density(&|i| rhs[i]);
        assert!(lifted > 8e5, "{lifted}");
        // The true residual density of each solve against its target.
        let mut iterations = Vec::new();
        for (stop, loads) in [
            (Stop::Loads(1e-6), loads),
            (Stop::Result(1e-6), loads),
            (Stop::Loads(1e-6), 0.0),
        ] {
            let loads = Loads {
                density: loads,
                problem: &p,
                scale: w_problem.mu_star,
            };
            let mut solver = backend::solver(&system, Some((&hierarchy, stop)), None, loads);
            solver.prepare(&vec![false; system.n()]).unwrap();
            let x = solver.solve(Cow::Borrowed(&rhs)).unwrap();
            let residual = density(&|i| {
                let a = system.vertices[i];
                let kx: f64 = (p.stiffness.row(a))
                    .filter_map(|(b, v)| system.unknown[b].index().map(|j| v * x[j]))
                    .sum();
                rhs[i] - kx
            });
            let target = match stop {
                Stop::Loads(t) if loads.density > 0.0 => t * loads.density,
                Stop::Residual(t) | Stop::Result(t) | Stop::Loads(t) => t * lifted,
            };
            assert!(residual <= 1.001 * target, "{stop:?}: {residual:e} > {target:e}");
            iterations.push(solver.work().cg_iterations[0]);
        }
        // Against the lift, CG stops about six orders of magnitude earlier; without loads, the
        // loads' stop is the lift's; a result's stop adds the backward error.
        assert!(iterations[0] >= iterations[2] + 3, "{iterations:?}");
        assert!(iterations[1] >= iterations[2], "{iterations:?}");
    }

    #[test]
    fn the_coarser_levels_take_one_step_each_and_the_finest_is_solved() {
        // Nested iteration from the coarsest 8² mesh (solved) through 16² and 32² (one global step
        // each from the guess below) to 64², by both linear solvers: the same solution as from no
        // guess, to round-off.
        let p = problem(64, "-1", "0.072");
        let coarser = || -> Vec<Mesh> {
            [32, 16, 8]
                .map(|n| Mesh::rectangle([0.0, 0.0], [1.0, 1.0], n, n, Diagonal::Right).unwrap())
                .into()
        };
        let cold = solve(&p, Start::Cold, Vec::new(), SolverOptions::default()).unwrap();
        for linear in [LinearSolver::Multigrid, LinearSolver::Direct] {
            let options = SolverOptions {
                linear,
                ..Default::default()
            };
            let nested = solve(&p, Start::Nested, coarser(), options).unwrap();
            let s = &nested.obstacle.stats;
            assert_eq!(s.coarse_iterations.len(), 3, "{linear:?}");
            assert!(s.coarse_iterations[0] > 1, "{:?}", s.coarse_iterations);
            assert_eq!(s.coarse_iterations[1..], [1, 1], "{linear:?}");
            assert_eq!(nested.obstacle.contact, cold.obstacle.contact, "{linear:?}");
            let d = (nested.obstacle.gap.iter().zip(&cold.obstacle.gap))
                .fold(0.0_f64, |m, (a, b)| m.max((a - b).abs()));
            assert!(d < 1e-12, "{linear:?}: {d:e}");
        }
        // A proposal from a guess is one global step after the guess's set is settled locally, as
        // the solution from the same guess starts; the solution goes on to confirm its set.
        let coarse = problem(32, "-1", "0.072");
        let from = solve(&coarse, Start::Cold, Vec::new(), SolverOptions::default()).unwrap();
        let prolongation = Prolongation::new(&p.mesh, &coarse.mesh);
        let system = InteriorSystem::new(&p.stiffness, &p.mesh.on_boundary);
        let options = SolverOptions::default();
        let guess = || Some(Guess::prolong(&prolongation, &from.obstacle));
        let proposal = obstacle(&p, &system, None, guess(), options, Role::Proposal).unwrap();
        let solution = obstacle(&p, &system, None, guess(), options, Role::Solution).unwrap();
        let (s, t) = (&proposal.stats, &solution.stats);
        assert_eq!(s.iterations, 1, "{s:?}");
        assert!(
            s.local_iterations > 0 && s.local_iterations <= t.local_iterations,
            "{s:?}"
        );
        assert_eq!(solution.contact, cold.obstacle.contact);
    }
}
