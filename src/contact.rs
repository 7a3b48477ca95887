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

use crate::assembly::both;
use crate::linear::{Factorization, InteriorSystem};
use crate::mesh::{Mesh, Prolongation};
use crate::multigrid::{Hierarchy, Multigrid, NotConverged, Tolerance};
use crate::problem::{boundary_values, DataError, DiscreteProblem};
use crate::result::{Attr, Attribute, Describe, Field, Place};
use std::borrow::Cow;
use std::fmt;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Mutex, MutexGuard, OnceLock};
use std::time::Instant;

/// Why the discrete problem could not be solved.
#[derive(Debug, Clone, PartialEq)]
pub enum SolveError {
    /// The active-set method did not converge within the cap.
    IterationCap {
        /// Iterations done.
        iterations: usize,
        /// Vertices that changed in the last one.
        changed: usize,
    },
    /// A factorization failed (cannot happen for a valid mesh; reported, not panicked).
    NotPositiveDefinite,
    /// The data fail on a coarser mesh of nested iteration.
    CoarseData(DataError),
    /// Multigrid-preconditioned CG did not converge (cannot happen for a valid mesh).
    NotConverged(NotConverged),
}

impl fmt::Display for SolveError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            SolveError::IterationCap { iterations, changed } => write!(
                f,
                "the active-set method did not converge in {iterations} iterations \
                 ({changed} vertices changed in the last one); raise solver.max_iterations"
            ),
            SolveError::NotPositiveDefinite => {
                write!(f, "the stiffness matrix is not positive definite")
            }
            SolveError::CoarseData(e) => write!(f, "on a coarser mesh of nested iteration: {e}"),
            SolveError::NotConverged(e) => write!(
                f,
                "conjugate gradients did not converge in {} iterations (residual density {:.1e}, \
                 {:.1e} wanted); try [solver] linear = \"direct\"",
                e.iterations, e.residual, e.target
            ),
        }
    }
}

impl std::error::Error for SolveError {}

/// How the active-set method starts.
#[derive(Debug, Clone, Copy)]
pub enum Start<'a> {
    /// From no contact.
    Cold,
    /// Nested iteration (grid sequencing): the obstacle problem on the coarser meshes passed to
    /// [`solve`] first, each warm-starting the next, the last one prolonged onto this mesh.
    Nested,
    /// From the solution on another mesh of the same domain, interpolated (e.g. the previous
    /// level of a study).
    From {
        /// The other mesh.
        mesh: &'a Mesh,
        /// Its obstacle solution.
        obstacle: &'a Obstacle,
    },
}

/// Options of the active-set method.
#[derive(Debug, Clone, Copy)]
pub struct SolverOptions {
    /// Active-set iterations before giving up.
    pub max_iterations: usize,
    /// The linear solver of v and of the active-set steps.
    pub linear: LinearSolver,
}

impl Default for SolverOptions {
    fn default() -> Self {
        SolverOptions {
            max_iterations: 200,
            linear: LinearSolver::Multigrid,
        }
    }
}

/// The linear solver of the Poisson problem for v and of every active-set step (`[solver] linear`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum LinearSolver {
    /// Sparse Cholesky ([`crate::linear`]).
    Direct,
    /// CG preconditioned by multigrid V-cycles on the hierarchy of meshes, truncated on the held
    /// unknowns ([`crate::multigrid`]): O(n) time and memory, the default.
    #[default]
    Multigrid,
}

impl LinearSolver {
    /// The names of the case file, in order.
    pub const NAMES: [&'static str; 2] = ["direct", "multigrid"];

    /// The name in the case file.
    pub fn name(self) -> &'static str {
        match self {
            LinearSolver::Direct => Self::NAMES[0],
            LinearSolver::Multigrid => Self::NAMES[1],
        }
    }

    /// The solver of a name, `None` for an unknown one.
    pub fn from_name(name: &str) -> Option<Self> {
        [LinearSolver::Direct, LinearSolver::Multigrid]
            .into_iter()
            .find(|s| s.name() == name)
    }
}

/// What the solver did.
#[derive(Debug, Clone, Default)]
pub struct SolverStats {
    /// Active-set iterations (linear solves of the obstacle problem).
    pub iterations: usize,
    /// Size of the active set after each iteration.
    pub active_sizes: Vec<usize>,
    /// Number of vertices entering or leaving the active set in each iteration.
    pub changes: Vec<usize>,
    /// Seconds in the ordering of K_II and the symbolic analyses of the K_FF patterns; with
    /// multigrid, in the interpolations P between the levels.
    pub symbolic_seconds: f64,
    /// Symbolic analyses of K_FF patterns (a pattern serves while the held set moves little).
    pub analyses: usize,
    /// Seconds in numeric factorizations (triangular solves are in `solve_seconds`), summed over
    /// threads; with multigrid, in the coarse operators and the coarsest factorization of each
    /// held set.
    pub numeric_seconds: f64,
    /// Seconds in triangular solves, summed over threads; with multigrid, in CG.
    pub solve_seconds: f64,
    /// Wall-clock seconds of the whole solve (symbolic analysis included).
    pub wall_seconds: f64,
    /// Numeric factorizations (with multigrid: V-cycles made, one per held set and one for v).
    pub factorizations: usize,
    /// Active-set iterations of the local corrections.
    pub local_iterations: usize,
    /// Seconds of the local corrections.
    pub local_seconds: f64,
    /// Interior unknowns of the obstacle problem.
    pub unknowns: usize,
    /// Nonzeros of the Cholesky factor of K_II.
    pub factor_nnz: usize,
    /// Active-set iterations on each coarser level of nested iteration, coarsest first.
    pub coarse_iterations: Vec<usize>,
    /// Wall-clock seconds of the coarser levels (all their phases), part of the solve.
    pub coarse_seconds: f64,
    /// The linear solver used.
    pub linear: LinearSolver,
    /// Levels of the multigrid hierarchy (0 with the direct solver).
    pub multigrid_levels: usize,
    /// CG iterations of each active-set step on this mesh (multigrid only).
    pub cg_iterations: Vec<usize>,
    /// CG iterations of the Poisson solve for v (multigrid only).
    pub v_cg_iterations: usize,
    /// CG iterations of each active-set step on each coarser level of nested iteration,
    /// coarsest first (multigrid only).
    pub coarse_cg_iterations: Vec<Vec<usize>>,
}

impl SolverStats {
    /// Adds the work of another solve beside this one (the v solve): its factorizations and its
    /// symbolic, numeric and solve seconds.
    fn add_work(&mut self, other: &SolverStats) {
        self.symbolic_seconds += other.symbolic_seconds;
        self.numeric_seconds += other.numeric_seconds;
        self.solve_seconds += other.solve_seconds;
        self.factorizations += other.factorizations;
    }

    /// What the linear solver did, for a summary: "Cholesky, 3 factorizations" or "multigrid on 8
    /// levels, CG iterations v 13, steps [10, 6]".
    pub fn linear_work(&self) -> String {
        match self.linear {
            LinearSolver::Direct => format!("Cholesky, {} factorizations", self.factorizations),
            LinearSolver::Multigrid => format!(
                "multigrid on {} levels, CG iterations v {}, steps {:?}",
                self.multigrid_levels, self.v_cg_iterations, self.cg_iterations
            ),
        }
    }

    /// Seconds in numeric factorizations and triangular solves.
    fn factor_and_solve_seconds(&self) -> f64 {
        self.numeric_seconds + self.solve_seconds
    }
}

/// The solution w of the obstacle problem, with its λ and contact set.
#[derive(Debug, Clone)]
pub struct Obstacle {
    /// w = u1h − u2h at every vertex.
    pub gap: Vec<f64>,
    /// λ_a = r_a / m_a at interior vertices (0 on ∂ω).
    pub lambda: Vec<f64>,
    /// Interior vertices where the membranes touch (the final active set).
    pub contact: Vec<bool>,
    /// What the solver did.
    pub stats: SolverStats,
}

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
}

/// An initial guess of the gap w and λ at every vertex, e.g. a coarser mesh's
/// solution interpolated here (nested iteration).
struct Guess {
    gap: Vec<f64>,
    lambda: Vec<f64>,
}

impl Guess {
    /// The gap and λ of another mesh's solution, transferred by `p`.
    fn prolong(p: &Prolongation, o: &Obstacle) -> Guess {
        Guess {
            gap: p.apply(&o.gap),
            lambda: p.apply(&o.lambda),
        }
    }
}

/// Solves (3.4): the Poisson problem for v on one thread while the obstacle problem for w runs on
/// the other (they share the symbolic analysis), then u1 = v + μ2/(μ1+μ2) w, u2 = v − μ1/(μ1+μ2) w.
/// The guess of `start` is computed on the w thread, so that the coarser levels of nested
/// iteration (on `coarser`, from fine to coarse; used by [`Start::Nested`] only) overlap the
/// symbolic analysis and the v solve. With one core v is solved first and w after it; with
/// multigrid on a mesh above 2²² vertices, w's steps on the final mesh wait for v's solve.
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
    let (mu1, mu2) = (problem.data.mu1, problem.data.mu2);
    // A mesh without coarser ones (an adapted mesh, a file mesh not refined) is solved directly:
    // its one-level "multigrid" would be a Cholesky factorization per step without the direct
    // path's reuse of symbolic analyses.
    let multigrid = options.linear == LinearSolver::Multigrid && !coarser.is_empty();
    let options = SolverOptions {
        linear: if multigrid {
            LinearSolver::Multigrid
        } else {
            LinearSolver::Direct
        },
        ..options
    };
    // Multigrid needs the interpolations on both threads from the start; the direct path builds
    // them for nested iteration on the w thread, beside the symbolic analysis.
    let prolongations = multigrid.then(|| chain(&problem.mesh, &coarser));
    let transfer_seconds = clock.elapsed().as_secs_f64();
    let shared = OnceLock::new();
    // Two cores: v beside w (w's V-cycles take both once v is done) or, above OVERLAP_LIMIT,
    // beside the coarser levels and the final mesh's set-up only (then v takes both, and w's
    // steps wait for its solve). One core: one after the other (time-sliced, they share its
    // cache: 7.3–8.7 s against 6.2 s).
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
    let large = multigrid && problem.mesh.n_vertices() > OVERLAP_LIMIT;
    // Whether the second core is free for the V-cycles of v and of w (see multigrid::BLOCK_ROWS).
    let (v_free, w_free) = (AtomicBool::new(false), AtomicBool::new(false));
    // The two solves on the final mesh take turns (see take_turn): with Cholesky, and with
    // multigrid above OVERLAP_LIMIT (w's steps there start once v is solved).
    let turn = &Mutex::new(());
    let turn = (!multigrid || large).then_some(turn);
    let analyse = || {
        let t = Instant::now();
        let (system, hierarchy) = analysed(problem, prolongations.as_deref());
        // v's coarse operators are kept: w's steps recompute theirs only near the held set.
        let hierarchy = hierarchy.map(|h| h.with_base(problem.mesh.on_boundary.clone()));
        (system, hierarchy, t.elapsed().as_secs_f64())
    };
    let v_job = || {
        let (system, hierarchy, _) = shared.get_or_init(analyse);
        // v: (μ1+μ2) K v = F1 + F2 inside, v = μ1 g_h/(μ1+μ2) on ∂ω.
        let bc = |a: usize| mu1 * problem.g_h[a] / (mu1 + mu2);
        let load = |a: usize| problem.load1[a] + problem.load2[a];
        let rhs = system.lifted_rhs(&problem.stiffness, load, mu1 + mu2, bc);
        let mut stats = SolverStats::default();
        let multigrid = hierarchy.as_ref().map(|h| (h, RESULT_STOP, Some(&v_free)));
        let loads = Loads {
            density: 0.0,
            problem,
            scale: mu1 + mu2,
        };
        let mut solver = Inner::new(system, multigrid, None, loads);
        let x = {
            let _turn = turn.map(take_turn);
            solver.prepare(&vec![false; system.n()], &mut stats)?;
            solver.solve(Cow::Owned(rhs), &mut stats)?
        };
        w_free.store(cores > 1, Ordering::Relaxed);
        let bc: Vec<f64> = (0..problem.g_h.len()).map(bc).collect();
        Ok::<_, SolveError>((system.scatter(&x, &bc), stats))
    };
    let guess_job = || {
        initial_guess(
            problem,
            start,
            coarser,
            prolongations.as_deref(),
            options,
            &w_free,
        )
    };
    let w_job = |nested: Result<_, SolveError>| {
        let ((guess, coarse_iterations, coarse_cg), coarse_seconds) = nested?;
        let (system, hierarchy, _) = shared.get_or_init(analyse);
        let multigrid = hierarchy.as_ref().map(|h| (h, FINAL_STOP, Some(&w_free)));
        let mut w = obstacle(problem, system, multigrid, guess, options, Role::Solution(turn))?;
        w.stats.coarse_iterations = coarse_iterations;
        w.stats.coarse_cg_iterations = coarse_cg;
        w.stats.coarse_seconds = coarse_seconds;
        Ok::<_, SolveError>(w)
    };
    let (v, obstacle) = match (cores > 1, large) {
        (false, _) => (v_job(), w_job(guess_job())),
        (true, false) => std::thread::scope(|scope| {
            let v = scope.spawn(v_job);
            let w = w_job(guess_job());
            (v.join().expect("the v thread does not panic"), w)
        }),
        (true, true) => std::thread::scope(|scope| {
            let v = scope.spawn(v_job);
            let guess = guess_job();
            v_free.store(true, Ordering::Relaxed);
            let w = w_job(guess);
            (v.join().expect("the v thread does not panic"), w)
        }),
    };
    let (analysis_seconds, levels) = shared
        .get()
        .map_or((0.0, 1), |s| (s.2, s.1.as_ref().map_or(1, Hierarchy::levels)));
    let mut obstacle = obstacle?;
    let (v, mut v_stats) = v?;
    // The shared symbolic analysis (and multigrid's transfers) counts with the v solve (which did
    // it or waited for it).
    v_stats.symbolic_seconds = analysis_seconds + transfer_seconds;
    let stats = &mut obstacle.stats;
    stats.add_work(&v_stats);
    stats.v_cg_iterations = v_stats.cg_iterations.first().copied().unwrap_or(0);
    stats.linear = options.linear;
    stats.multigrid_levels = if multigrid { levels } else { 0 };
    stats.wall_seconds = clock.elapsed().as_secs_f64();
    let (c1, c2) = (mu2 / (mu1 + mu2), mu1 / (mu1 + mu2));
    let w = &obstacle.gap;
    let u1 = v.iter().zip(w).map(|(v, w)| v + c1 * w).collect();
    let u2 = v.iter().zip(w).map(|(v, w)| v - c2 * w).collect();
    Ok(Solution { u1, u2, obstacle })
}

/// The guess of `start` on `problem`'s mesh (for [`Start::Nested`], by nested iteration on the
/// `coarser` meshes, with their interpolations when multigrid made them already), with the
/// coarser levels' active-set and CG iterations and the seconds it took.
fn initial_guess(
    problem: &DiscreteProblem,
    start: Start,
    coarser: Vec<Mesh>,
    prolongations: Option<&[Prolongation]>,
    options: SolverOptions,
    second_core: &AtomicBool,
) -> Result<(NestedGuess, f64), SolveError> {
    let t = Instant::now();
    let (guess, iterations, cg) = match start {
        Start::Cold => (None, Vec::new(), Vec::new()),
        Start::Nested => {
            let built;
            let prolongations = match prolongations {
                Some(p) => p,
                None => {
                    built = chain(&problem.mesh, &coarser);
                    &built
                }
            };
            nested_guess(problem, coarser, prolongations, options, second_core)?
        }
        Start::From { mesh, obstacle } => {
            let p = Prolongation::new(&problem.mesh, mesh);
            (Some(Guess::prolong(&p, obstacle)), Vec::new(), Vec::new())
        }
    };
    Ok(((guess, iterations, cg), t.elapsed().as_secs_f64()))
}

/// The interior unknowns of `problem` with, for the direct solver (no `prolongations`), the
/// Cholesky analysis of K_II, or else its multigrid hierarchy on the `prolongations` below it.
fn analysed<'t>(
    problem: &'t DiscreteProblem,
    prolongations: Option<&'t [Prolongation]>,
) -> (InteriorSystem, Option<Hierarchy<'t>>) {
    let (k, on_boundary) = (&problem.stiffness, &problem.mesh.on_boundary);
    match prolongations {
        None => (InteriorSystem::new(k, on_boundary), None),
        Some(p) => (
            InteriorSystem::numbering(on_boundary),
            Some(Hierarchy::new(k, &problem.mass, p)),
        ),
    }
}

/// The interpolations between consecutive meshes of `fine` and the `coarser` ones (fine to
/// coarse): element l interpolates from level l + 1 onto level l.
fn chain(fine: &Mesh, coarser: &[Mesh]) -> Vec<Prolongation> {
    let mut finer = fine;
    (coarser.iter())
        .map(|mesh| {
            let p = Prolongation::new(finer, mesh);
            finer = mesh;
            p
        })
        .collect()
}

/// The initial guess of nested iteration, with the active-set iterations of each coarser level
/// and the CG iterations of each of their steps, coarsest first.
type NestedGuess = (Option<Guess>, Vec<usize>, Vec<Vec<usize>>);

/// Nested iteration: the obstacle problem on the `coarser` meshes (from fine to coarse, with the
/// `prolongations` between them), each level's loads restricted from the one above, from the
/// coarsest up: the coarsest solved, each finer one by one global step from the guess of the one
/// below ([`Role::Proposal`]); the last one prolonged onto `problem`'s mesh is the guess. With
/// multigrid, each level's steps are solved by multigrid on the levels below it.
fn nested_guess(
    problem: &DiscreteProblem,
    coarser: Vec<Mesh>,
    prolongations: &[Prolongation],
    options: SolverOptions,
    second_core: &AtomicBool,
) -> Result<NestedGuess, SolveError> {
    let multigrid = options.linear == LinearSolver::Multigrid;
    // The boundary values of each level (checked here, finest first) and its loads restricted
    // from the one above; each level's problem is assembled when it is solved and dropped once
    // solved.
    let mut levels: Vec<(Mesh, Vec<f64>, [Vec<f64>; 2])> = Vec::new();
    for (mesh, p) in coarser.into_iter().zip(prolongations) {
        let g_h = boundary_values(&mesh, &problem.data).map_err(SolveError::CoarseData)?;
        let [f1, f2] = levels
            .last()
            .map_or([&problem.load1, &problem.load2], |(_, _, [f1, f2])| [f1, f2]);
        let loads = [p.restrict(f1), p.restrict(f2)];
        levels.push((mesh, g_h, loads));
    }
    let (mut guess, mut iterations, mut cg) = (None, Vec::new(), Vec::new());
    while let Some((mesh, g_h, loads)) = levels.pop() {
        let k = levels.len();
        let level = DiscreteProblem::with_loads(mesh, &problem.data, g_h, loads);
        // The coarsest level has no levels below: Cholesky.
        let below = (multigrid && k + 1 < prolongations.len()).then(|| &prolongations[k + 1..]);
        let (system, hierarchy) = analysed(&level, below);
        let multigrid = hierarchy.as_ref().map(|h| (h, GUESS_STOP, Some(second_core)));
        let o = obstacle(&level, &system, multigrid, guess.take(), options, Role::Proposal)?;
        iterations.push(o.stats.iterations);
        cg.push(o.stats.cg_iterations.clone());
        guess = Some(Guess::prolong(&prolongations[k], &o));
    }
    Ok((guess, iterations, cg))
}

/// What [`obstacle`] solves for.
#[derive(Clone, Copy)]
enum Role<'t> {
    /// The solution of the mesh; the steps take turns with v's solve on `turn` when given.
    Solution(Option<&'t Mutex<()>>),
    /// A coarser level of nested iteration: from a guess, one global step proposes the next
    /// level's guess, as one Newton step per level of grid sequencing does (no local correction:
    /// the final mesh settles the free boundary); a level without a guess (the coarsest) is solved.
    Proposal,
}

/// The obstacle problem for w on `problem`'s mesh by primal–dual active sets, its linear solves
/// by Cholesky or, with `multigrid` = (hierarchy, stop, second core), by CG preconditioned by
/// V-cycles; from the guess `warm` when given (dropped once it has given the first active set and
/// CG's start); solved, or one step proposed, as the `role` says.
fn obstacle(
    problem: &DiscreteProblem,
    system: &InteriorSystem,
    multigrid: Option<Multilevel>,
    warm: Option<Guess>,
    options: SolverOptions,
    role: Role,
) -> Result<Obstacle, SolveError> {
    let (turn, proposal) = match role {
        Role::Solution(turn) => (turn, false),
        Role::Proposal => (None, warm.is_some()),
    };
    let n = system.n();
    let mut stats = SolverStats {
        unknowns: n,
        factor_nnz: system.factor_nnz(),
        ..Default::default()
    };
    let mut w_problem = WProblem::new(problem, multigrid.and_then(|m| m.2));
    let rhs = w_problem.rhs(system, &problem.g_h);
    let mut active: Vec<bool> = match &warm {
        Some(guess) => (system.vertices.iter())
            .map(|&a| w_problem.predicts_contact(a, guess.lambda[a] * problem.mass[a], guess.gap[a]))
            .collect(),
        None => vec![false; n],
    };
    if let (Some(guess), false) = (&warm, proposal) {
        // The guess's free boundary is off by a few mesh sizes: settle it locally first, with the
        // guess (and g_h on ∂ω) as Dirichlet data.
        let data: Vec<f64> = (guess.gap.iter().zip(&problem.g_h).enumerate())
            .map(|(a, (&w, &g))| if problem.mesh.on_boundary[a] { g } else { w })
            .collect();
        let seeds = interface(problem, system, &active);
        active = w_problem.local_correction(system, &data, &seeds, active, &mut stats);
    }
    // CG starts from the guess's gap, then from the previous step's w.
    let warm_start = warm.is_some();
    let start = warm.map(|g| system.vertices.iter().map(|&a| g.gap[a]).collect());
    let loads = Loads {
        density: load_density(problem, system, |a| w_problem.load(a), w_problem.mu_star),
        problem,
        scale: w_problem.mu_star,
    };
    let mut solver = Inner::new(system, multigrid, start, loads);
    if warm_start {
        // The first step from a guess only proposes the next active set: it is solved to the
        // coarser levels' stop, and the set is confirmed by steps to the full one.
        solver.loosen(GUESS_STOP);
    }
    let (mut correcting, mut same_set) = (true, false);
    loop {
        if stats.iterations == options.max_iterations {
            return Err(SolveError::IterationCap {
                iterations: stats.iterations,
                changed: stats.changes.last().copied().unwrap_or(0),
            });
        }
        stats.iterations += 1;
        if !same_set {
            solver.analyse(&active, &mut stats);
        }
        // Multigrid's first operators are made before the turn, beside v's solve (which the
        // steps wait for on the largest meshes); Cholesky factorizes in turn (two factors at once
        // would double the memory).
        let early = stats.iterations == 1 && multigrid.is_some();
        if !same_set && early {
            solver.prepare(&active, &mut stats)?;
        }
        let step = {
            let _turn = turn.map(take_turn);
            if !same_set && !early {
                solver.prepare(&active, &mut stats)?;
            }
            w_problem.step(system, &mut solver, &rhs, &problem.g_h, &mut stats)?
        };
        let loose = solver.tighten();
        let changed: Vec<usize> = (0..n).filter(|&i| step.next[i] != active[i]).collect();
        stats.changes.push(changed.len());
        stats.active_sizes.push(step.next.iter().filter(|&&x| x).count());
        same_set = changed.is_empty();
        if same_set && loose {
            // Confirmed to the loose tolerance only: once more to the full one.
            continue;
        }
        if same_set || proposal {
            // The confirmed set's w to the backward error of the checks (not counted as a step).
            let step = if proposal || !solver.refines() {
                step
            } else {
                solver.loosen(RESULT_STOP);
                let _turn = turn.map(take_turn);
                let result = w_problem.step(system, &mut solver, &rhs, &problem.g_h, &mut stats)?;
                solver.tighten();
                result
            };
            stats.analyses = solver.analyses();
            let nv = problem.mesh.n_vertices();
            let (mut lambda, mut contact) = (vec![0.0; nv], vec![false; nv]);
            for (i, &a) in system.vertices.iter().enumerate() {
                lambda[a] = step.residual[i] / problem.mass[a];
                contact[a] = active[i];
            }
            return Ok(Obstacle {
                gap: step.w,
                lambda,
                contact,
                stats,
            });
        }
        // Local corrections only while the number of changes falls, so that they cannot cycle
        // with the global steps; then plain primal–dual active-set steps, which converge on their
        // own when K is an M-matrix (no obtuse angles), and meet the iteration cap otherwise.
        let k = stats.changes.len();
        correcting &= k < 2 || stats.changes[k - 1] < stats.changes[k - 2];
        active = if correcting {
            w_problem.local_correction(system, &step.w, &changed, step.next, &mut stats)
        } else {
            step.next
        };
    }
}

/// Rings of vertices around the changed ones on which a local correction solves: steps along
/// K's couplings (on right-angled meshes not across the diagonals, so that 24 of them reach about
/// as far as 16 mesh edges; with 16, one more global step at 1024² cells).
const BAND_RINGS: usize = 24;
/// The rings of the band inside the proposed contact set: w = 0 there whatever the data outside
/// the band, so the band needs only room for the free boundary to move in (measured in the
/// README).
const HELD_RINGS: usize = 4;
/// Active-set iterations of one local correction.
const LOCAL_ITERATIONS: usize = 20;
/// A local correction is skipped when its band would hold more than this share of the unknowns
/// (at 256² cells the band of the first step holds a third of them).
const BAND_SHARE: f64 = 0.5;

/// max_a |load(a)|/(scale m_a) over the unknowns of `system`: the density of the loads of
/// scale·K u = load (see [`Stop::Loads`]).
fn load_density(
    problem: &DiscreteProblem,
    system: &InteriorSystem,
    load: impl Fn(usize) -> f64,
    scale: f64,
) -> f64 {
    (system.vertices.iter())
        .map(|&a| (load(a) / (scale * problem.mass[a])).abs())
        .fold(0.0, f64::max)
}

/// The obstacle problem for w on one mesh: μ* K w ≥ f_w, w ≥ 0, complementarity.
struct WProblem<'p> {
    problem: &'p DiscreteProblem,
    mu_star: f64,
    /// Whether the second core is free for the residuals (see [`Multigrid::second_core`]).
    second_core: Option<&'p AtomicBool>,
    /// Room for the numbering of a local correction's band, one entry per vertex, all
    /// `usize::MAX` between corrections (so that each costs O(band), not O(vertices)).
    scratch: Vec<usize>,
}

/// One primal–dual active-set step: w with w = 0 on the active set and the equation off it, the
/// residual r_a = μ*(K w)_a − (f_w, φ_a) = λ_a m_a and the next active set {r_a − μ* K_aa w_a > 0}.
struct Step {
    /// w at every vertex.
    w: Vec<f64>,
    residual: Vec<f64>,
    next: Vec<bool>,
}

impl<'p> WProblem<'p> {
    fn new(problem: &'p DiscreteProblem, second_core: Option<&'p AtomicBool>) -> Self {
        WProblem {
            problem,
            second_core,
            mu_star: problem.data.mu1 * problem.data.mu2 / (problem.data.mu1 + problem.data.mu2),
            scratch: Vec::new(),
        }
    }

    /// (f_w, φ_a) = (μ2 (f1, φ_a) − μ1 (f2, φ_a))/(μ1+μ2).
    fn load(&self, a: usize) -> f64 {
        let p = self.problem;
        let (mu1, mu2) = (p.data.mu1, p.data.mu2);
        (mu2 * p.load1[a] - mu1 * p.load2[a]) / (mu1 + mu2)
    }

    /// The active-set rule at vertex a: λ_a m_a − μ* K_aa w_a > 0 (i.e. λ_a > c_a w_a with
    /// c_a = μ* K_aa / m_a).
    fn predicts_contact(&self, a: usize, residual: f64, w: f64) -> bool {
        residual - self.mu_star * self.problem.stiffness.diagonal(a) * w > 0.0
    }

    /// The right-hand side of `system` with the values `bc` off its unknowns.
    fn rhs(&self, system: &InteriorSystem, bc: &[f64]) -> Vec<f64> {
        system.lifted_rhs(&self.problem.stiffness, |a| self.load(a), self.mu_star, |b| bc[b])
    }

    fn step(
        &self,
        system: &InteriorSystem,
        solver: &mut Inner,
        rhs: &[f64],
        bc: &[f64],
        stats: &mut SolverStats,
    ) -> Result<Step, SolveError> {
        let w_int = solver.solve(Cow::Borrowed(rhs), stats)?;
        let w = system.scatter(&w_int, bc);
        let (residual, next) = self.residual_and_next(system, &w_int, |b| w[b]);
        Ok(Step { w, residual, next })
    }

    /// The residual r_a = μ*(K w)_a − (f_w, φ_a) at the unknowns of `system` and the next active
    /// set, for w = w_int there and `w(b)` at every vertex b.
    fn residual_and_next(
        &self,
        system: &InteriorSystem,
        w_int: &[f64],
        w: impl Fn(usize) -> f64 + Sync,
    ) -> (Vec<f64>, Vec<bool>) {
        let k = &self.problem.stiffness;
        // The two halves of the unknowns, on two threads when the second core is free.
        let part = |unknowns: std::ops::Range<usize>| {
            let residual: Vec<f64> = (system.vertices[unknowns.clone()].iter())
                .map(|&a| self.mu_star * k.row(a).map(|(b, v)| v * w(b)).sum::<f64>() - self.load(a))
                .collect();
            let next: Vec<bool> = (unknowns.zip(&residual))
                .map(|(i, &r)| self.predicts_contact(system.vertices[i], r, w_int[i]))
                .collect();
            (residual, next)
        };
        let (n, parallel) = (
            system.n(),
            self.second_core.is_some_and(|f| f.load(Ordering::Relaxed)),
        );
        let ((mut residual, mut next), (residual1, next1)) =
            both(parallel, || part(0..n / 2), || part(n / 2..n));
        residual.extend(residual1);
        next.extend(next1);
        (residual, next)
    }

    /// A local correction of the proposed active set `next` (a Schwarz-type predictor): the
    /// obstacle problem on the band of [`BAND_RINGS`] rings of vertices around `seeds`, with the
    /// current iterate `w` as Dirichlet data outside the band, solved by primal–dual active sets;
    /// its active set replaces `next` on the band. The set changes only near the free boundary,
    /// where this settles it at the cost of small factorizations. The global iteration still stops
    /// only when a global solve reproduces its active set, so this changes the cost, not the result.
    fn local_correction(
        &mut self,
        system: &InteriorSystem,
        w: &[f64],
        seeds: &[usize],
        mut next: Vec<bool>,
        stats: &mut SolverStats,
    ) -> Vec<bool> {
        let p = self.problem;
        let band = band(p, system, seeds, &next, [BAND_RINGS, HELD_RINGS]);
        if band.is_empty() || band.len() as f64 > BAND_SHARE * system.n() as f64 {
            return next;
        }
        // The band's numbering in the scratch room of one entry per vertex: O(band) work.
        let mut scratch = std::mem::take(&mut self.scratch);
        scratch.resize(p.mesh.n_vertices(), usize::MAX);
        let vertices = band.iter().map(|&i| system.vertices[i]).collect();
        let local = InteriorSystem::on_vertices(&p.stiffness, vertices, scratch);
        let rhs = self.rhs(&local, w);
        // Both vertex lists are increasing, so the local unknown j is the unknown band[j].
        let global_index = |j: usize| band[j];
        let mut active: Vec<bool> = (0..local.n()).map(|j| next[global_index(j)]).collect();
        let mut solver = Inner::Direct(local.factorization());
        let mut local_stats = SolverStats::default();
        let mut settled = true;
        for _ in 0..LOCAL_ITERATIONS {
            stats.local_iterations += 1;
            let solved = (solver.prepare(&active, &mut local_stats))
                .and_then(|()| solver.solve(Cow::Borrowed(&rhs), &mut local_stats));
            let Ok(w_int) = solved else {
                settled = false;
                break;
            };
            // w is w_int on the band and the current iterate elsewhere.
            let value = |b: usize| match local.unknown[b] {
                usize::MAX => w[b],
                j => w_int[j],
            };
            let (_, step) = self.residual_and_next(&local, &w_int, value);
            let done = step == active;
            active = step;
            if done {
                break;
            }
        }
        if settled {
            for (j, &a) in active.iter().enumerate() {
                next[global_index(j)] = a;
            }
        }
        drop(solver);
        self.scratch = local.into_scratch();
        stats.local_seconds += local_stats.factor_and_solve_seconds();
        next
    }
}

/// The unknowns of `system` within `rings[0]` graph steps of `seeds`, sorted, where the steps
/// from an `active` unknown go on only while fewer than `rings[1]`.
fn band(
    problem: &DiscreteProblem,
    system: &InteriorSystem,
    seeds: &[usize],
    active: &[bool],
    [rings, held_rings]: [usize; 2],
) -> Vec<usize> {
    let index = &system.unknown;
    let mut in_band = vec![false; system.n()];
    let mut front: Vec<usize> = seeds.to_vec();
    for &i in &front {
        in_band[i] = true;
    }
    for ring in 0..rings {
        let mut next = Vec::new();
        for &i in &front {
            if active[i] && ring >= held_rings {
                continue;
            }
            for (b, _) in problem.stiffness.row(system.vertices[i]) {
                let j = index[b];
                if j != usize::MAX && !in_band[j] {
                    in_band[j] = true;
                    next.push(j);
                }
            }
        }
        front = next;
    }
    (0..system.n()).filter(|&i| in_band[i]).collect()
}

/// Unknowns on the free boundary of `active`: those with a neighbour on the other side.
fn interface(problem: &DiscreteProblem, system: &InteriorSystem, active: &[bool]) -> Vec<usize> {
    let index = &system.unknown;
    (0..system.n())
        .filter(|&i| {
            problem
                .stiffness
                .row(system.vertices[i])
                .any(|(b, _)| index[b] != usize::MAX && active[index[b]] != active[i])
        })
        .collect()
}

/// The linear solver of one mesh's steps: a Cholesky factorization of K_FF, or CG preconditioned by
/// the truncated V-cycle of K_FF with the last solution as the next start.
enum Inner<'s> {
    Direct(Factorization<'s>),
    /// Multigrid works on all vertices of the mesh, the boundary ones skipped: `x` is the last
    /// solution there.
    Multigrid {
        system: &'s InteriorSystem,
        hierarchy: &'s Hierarchy<'s>,
        cycle: Option<Multigrid<'s>>,
        x: Vec<f64>,
        stop: Stop,
        /// Another stop for the solves until [`Inner::tighten`].
        loose: Option<Stop>,
        loads: Loads<'s>,
        second_core: Option<&'s AtomicBool>,
    },
}

/// The loads of the system scale·K u = load that an [`Inner`] solves, as its stops see them.
#[derive(Clone, Copy)]
struct Loads<'p> {
    /// Their density (see [`Stop::Loads`]).
    density: f64,
    problem: &'p DiscreteProblem,
    scale: f64,
}

impl Loads<'_> {
    /// (|(f1, φ_a)| + |(f2, φ_a)|)/scale: the sizes of the loads at vertex a that the checks
    /// count (see [`RESULT_BACKWARD`]).
    fn size(&self, a: usize) -> f64 {
        (self.problem.load1[a].abs() + self.problem.load2[a].abs()) / self.scale
    }
}

/// Multigrid's hierarchy, where CG stops, and whether the second core is free (see
/// [`Multigrid::second_core`]).
type Multilevel<'s> = (&'s Hierarchy<'s>, Stop, Option<&'s AtomicBool>);

impl<'s> Inner<'s> {
    /// Cholesky on `system`, or CG with V-cycles on the hierarchy of `multigrid` to its stop
    /// (with `loads` those of the system), starting from `start` (or 0).
    fn new(
        system: &'s InteriorSystem,
        multigrid: Option<Multilevel<'s>>,
        start: Option<Vec<f64>>,
        loads: Loads<'s>,
    ) -> Self {
        match multigrid {
            None => Inner::Direct(system.factorization()),
            Some((hierarchy, stop, second_core)) => Inner::Multigrid {
                system,
                hierarchy,
                cycle: None,
                x: start.map_or_else(|| vec![0.0; system.unknown.len()], |x| system.extended(&x)),
                stop,
                loose: None,
                loads,
                second_core,
            },
        }
    }

    /// Multigrid: solves to `stop` (when not its own) until [`Inner::tighten`].
    fn loosen(&mut self, stop: Stop) {
        if let Inner::Multigrid { stop: own, loose, .. } = self {
            *loose = (stop != *own).then_some(stop);
        }
    }

    /// Whether another solve with the same operators can refine the last one (CG from its x).
    fn refines(&self) -> bool {
        matches!(self, Inner::Multigrid { .. })
    }

    /// Back to its own stop; whether the solves stopped elsewhere.
    fn tighten(&mut self) -> bool {
        match self {
            Inner::Multigrid { loose, .. } => loose.take().is_some(),
            Inner::Direct(_) => false,
        }
    }

    /// Cholesky: chooses the pattern of K_FF for the held set (see [`Factorization::analyse`]).
    fn analyse(&mut self, held: &[bool], stats: &mut SolverStats) {
        if let Inner::Direct(factor) = self {
            let t = Instant::now();
            factor.analyse(held);
            stats.symbolic_seconds += t.elapsed().as_secs_f64();
        }
    }

    /// Factorizes K_FF, or builds the truncated coarse operators, for the held set.
    fn prepare(&mut self, held: &[bool], stats: &mut SolverStats) -> Result<(), SolveError> {
        match self {
            Inner::Direct(factor) => factorize(factor, held, stats),
            Inner::Multigrid {
                system,
                hierarchy,
                cycle,
                second_core,
                ..
            } => {
                let t = Instant::now();
                *cycle = None;
                let skip = system.skipped(held);
                let mut mg = (hierarchy.preconditioner(skip)).map_err(|_| SolveError::NotPositiveDefinite)?;
                mg.second_core = *second_core;
                *cycle = Some(mg);
                stats.factorizations += 1;
                stats.numeric_seconds += t.elapsed().as_secs_f64();
                Ok(())
            }
        }
    }

    /// K_FF x = b, x = 0 on the held unknowns (b owned when the caller has no further use for it,
    /// so that it is not kept beside CG's vectors; borrowed, it is not copied for CG).
    fn solve(&mut self, b: Cow<[f64]>, stats: &mut SolverStats) -> Result<Vec<f64>, SolveError> {
        match self {
            Inner::Direct(factor) => Ok(solve_with(factor, b.into_owned(), stats)),
            Inner::Multigrid {
                system,
                cycle,
                x,
                stop,
                loose,
                loads,
                ..
            } => {
                let t = Instant::now();
                let cycle = cycle.as_mut().expect("prepared before solving");
                let extended = system.extended(&b);
                drop(b);
                let size = |a: usize| loads.size(a);
                let stop = loose.unwrap_or(*stop);
                let tolerance = stop.tolerance(loads.density, || cycle.density(&extended), &size);
                let iterations = (cycle.solve_to(extended, x, tolerance, CG_MAX_ITERATIONS))
                    .map_err(SolveError::NotConverged)?;
                stats.cg_iterations.push(iterations);
                stats.solve_seconds += t.elapsed().as_secs_f64();
                Ok(system.gather(x))
            }
        }
    }

    /// Symbolic analyses of K_FF patterns (Cholesky).
    fn analyses(&self) -> usize {
        match self {
            Inner::Direct(factor) => factor.analyses,
            Inner::Multigrid { .. } => 0,
        }
    }
}

/// Where multigrid's CG stops: max_a |r_a|/m_a (see [`Tolerance`]) at most a tolerance times a
/// density, and for results also the backward error of the checks.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Stop {
    /// Times max_a |b_a|/m_a, b the right-hand side: a backward error, the scale of the round-off
    /// of K x (like a Cholesky solve's). Next to ∂ω with g ≠ 0, b holds the lift of g, about g/h²:
    /// an error of λ_h growing as h⁻² relative to the loads, but so does its round-off.
    Residual(f64),
    /// As [`Stop::Residual`], and to a componentwise backward error of [`RESULT_BACKWARD`]: the
    /// solves whose result is returned.
    Result(f64),
    /// Times the density of the loads ([`load_density`]; the right-hand side's when they vanish):
    /// the same accuracy of λ_h relative to the loads on every mesh, which is what the active
    /// set a solve proposes depends on.
    Loads(f64),
}

impl Stop {
    /// CG's tolerance for loads of density `loads` and a right-hand side of density `rhs()`, with
    /// the sizes of the loads at each vertex `floor` for a result's backward error.
    fn tolerance<'f>(
        self,
        loads: f64,
        rhs: impl FnOnce() -> f64,
        floor: &'f (dyn Fn(usize) -> f64 + Sync),
    ) -> Tolerance<'f> {
        match self {
            Stop::Loads(tolerance) if loads > 0.0 => Tolerance {
                density: tolerance * loads,
                backward: None,
            },
            Stop::Loads(tolerance) => Tolerance {
                density: tolerance * rhs(),
                backward: None,
            },
            Stop::Residual(tolerance) => Tolerance {
                density: tolerance * rhs(),
                backward: None,
            },
            Stop::Result(tolerance) => Tolerance {
                density: tolerance * rhs(),
                backward: Some((RESULT_BACKWARD, floor)),
            },
        }
    }
}

/// The componentwise backward error of the v and w solves whose result is returned. The checks'
/// defects at a vertex are combinations of the two residuals there (Prop. 12's is v's, λ_h ≥ 0's
/// at a free vertex μ1/(μ1+μ2) v's plus w's), each relative to a scale that σ_a bounds from
/// below within a factor 2 (`Multigrid`'s σ_a plus the sizes of the loads, which b may cancel),
/// so an eighth of [`crate::action::TOLERANCE`] leaves them at half of it, and round-off the
/// rest.
const RESULT_BACKWARD: f64 = crate::action::TOLERANCE / 8.0;

/// The steps that confirm an active set on the final mesh: to the round-off of K x, as the direct
/// solve (how closely the two agree, and why λ_h's agreement widens on fine meshes with g ≠ 0:
/// README).
const FINAL_STOP: Stop = Stop::Residual(1e-13);
/// The solves whose result is returned (v's, and w's once its set is confirmed, from the last
/// step's w with the same operators): also to the backward error of the checks.
const RESULT_STOP: Stop = Stop::Result(1e-13);
/// The coarser levels of nested iteration and the first step from their guess only propose an
/// active set: λ_h to this part of the loads, far below its discretisation error on those meshes.
const GUESS_STOP: Stop = Stop::Loads(1e-4);
/// Above this many vertices the multigrid v solve runs beside the coarser levels of nested
/// iteration and the final mesh's set-up only, and w's steps there after it: the CG vectors and
/// coarse operators of the two solves on the final mesh are then never in memory at once
/// (measured in the README).
const OVERLAP_LIMIT: usize = 1 << 22;
/// CG iterations before giving up (a V-cycle preconditioner needs about 10).
const CG_MAX_ITERATIONS: usize = 200;

/// The v and w factorizations on the final mesh take turns: two large sparse factorizations at
/// once contend for memory bandwidth and were measured slower together than one after the other
/// (at 1024² cells 3.3 s and 2.7 s side by side, 1.5 s and 1.2 s in turn). The coarse levels of
/// nested iteration run beside the v factorization.
fn take_turn(turn: &Mutex<()>) -> MutexGuard<'_, ()> {
    turn.lock().unwrap_or_else(|e| e.into_inner())
}

fn factorize(factor: &mut Factorization, held: &[bool], stats: &mut SolverStats) -> Result<(), SolveError> {
    let t = Instant::now();
    if factor
        .factorize(held)
        .map_err(|_| SolveError::NotPositiveDefinite)?
    {
        stats.factorizations += 1;
    }
    stats.numeric_seconds += t.elapsed().as_secs_f64();
    Ok(())
}

/// Solves with the factorization's held unknowns fixed at 0.
fn solve_with(factor: &mut Factorization, b: Vec<f64>, stats: &mut SolverStats) -> Vec<f64> {
    let t = Instant::now();
    let mut x = b;
    factor.solve(&mut x);
    stats.solve_seconds += t.elapsed().as_secs_f64();
    x
}

impl Describe for Solution {
    fn fields(&self) -> Vec<Field<'_>> {
        let contact = self
            .obstacle
            .contact
            .iter()
            .map(|&c| f64::from(u8::from(c)))
            .collect();
        vec![
            Field::new("u1", Place::Vertices, &self.u1),
            Field::new("u2", Place::Vertices, &self.u2),
            Field::new("gap", Place::Vertices, &self.obstacle.gap),
            Field::owned("contact", Place::Vertices, contact),
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
        vec![
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
        ]
    }
}

#[cfg(test)]
mod tests {
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
        assert_eq!(v.factor_and_solve_seconds(), 0.375);
    }

    #[test]
    fn statistics_count_the_work_of_a_cold_solve() {
        // Membrane 1 pressed onto membrane 2 in the middle: some contact, several iterations.
        let p = problem(24, "-10", "0.05");
        let system = InteriorSystem::new(&p.stiffness, &p.mesh.on_boundary);
        let o = obstacle(
            &p,
            &system,
            None,
            None,
            SolverOptions::default(),
            Role::Solution(None),
        )
        .unwrap();
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
            let (i, j) = (system.unknown[a], system.unknown[b]);
            if i != usize::MAX && j != usize::MAX {
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
        let seeds = [system.unknown[4 * 9 + 2], system.unknown[6 * 9 + 6]];
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
        let w_problem = WProblem::new(&p, None);
        let rhs = w_problem.rhs(&system, &p.g_h);
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
            let mut solver = Inner::new(&system, Some((&hierarchy, stop, None)), None, loads);
            let mut stats = SolverStats::default();
            solver.prepare(&vec![false; system.n()], &mut stats).unwrap();
            let x = solver.solve(Cow::Borrowed(&rhs), &mut stats).unwrap();
            let residual = density(&|i| {
                let a = system.vertices[i];
                let kx: f64 = (p.stiffness.row(a))
                    .filter(|&(b, _)| system.unknown[b] != usize::MAX)
                    .map(|(b, v)| v * x[system.unknown[b]])
                    .sum();
                rhs[i] - kx
            });
            let target = match stop {
                Stop::Loads(t) if loads.density > 0.0 => t * loads.density,
                Stop::Residual(t) | Stop::Result(t) | Stop::Loads(t) => t * lifted,
            };
            assert!(residual <= 1.001 * target, "{stop:?}: {residual:e} > {target:e}");
            iterations.push(stats.cg_iterations[0]);
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
        // A proposal from a guess is one global step, without local correction; the solution
        // from the same guess corrects it locally first.
        let coarse = problem(32, "-1", "0.072");
        let from = solve(&coarse, Start::Cold, Vec::new(), SolverOptions::default()).unwrap();
        let prolongation = Prolongation::new(&p.mesh, &coarse.mesh);
        let system = InteriorSystem::new(&p.stiffness, &p.mesh.on_boundary);
        let options = SolverOptions::default();
        let guess = || Some(Guess::prolong(&prolongation, &from.obstacle));
        let proposal = obstacle(&p, &system, None, guess(), options, Role::Proposal).unwrap();
        let solution = obstacle(&p, &system, None, guess(), options, Role::Solution(None)).unwrap();
        let (s, t) = (&proposal.stats, &solution.stats);
        assert_eq!((s.iterations, s.local_iterations), (1, 0), "{s:?}");
        assert!(t.local_iterations > 0, "{t:?}");
        assert_eq!(solution.contact, cold.obstacle.contact);
    }
}
