//! What the solver did: counts and seconds, the seconds measured around the calls of the linear
//! solvers ([`Timed`]), outside the algorithms.

use super::backend::{LinearSolve, Stop, Work};
use super::options::{LinearSolver, SolveError};
use std::borrow::Cow;
use std::time::Instant;

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
    /// the v and w solves; with multigrid, in the coarse operators and the coarsest factorization of each
    /// held set.
    pub numeric_seconds: f64,
    /// Seconds in triangular solves, summed over the v and w solves; with multigrid, in CG.
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
    /// Where multigrid CG failed and the run solved again by Cholesky: how CG failed.
    pub multigrid_failed: Option<crate::cg::NotConverged>,
}

impl SolverStats {
    /// Adds the work of another solve beside this one (the v solve): its factorizations and its
    /// symbolic, numeric and solve seconds.
    pub(super) fn add_work(&mut self, other: &SolverStats) {
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

    /// Counts the `work` of a linear solver.
    pub(super) fn count(&mut self, work: Work) {
        self.factorizations += work.factorizations;
        self.analyses += work.analyses;
        self.cg_iterations.extend(work.cg_iterations);
    }
}

/// A linear solver whose calls are timed: analyses as symbolic, preparations as numeric and
/// solves as solve seconds.
pub(super) struct Timed<'s> {
    solver: Box<dyn LinearSolve + 's>,
    /// Seconds of analyses, preparations and solves.
    pub(super) seconds: [f64; 3],
}

impl<'s> Timed<'s> {
    pub(super) fn new(solver: Box<dyn LinearSolve + 's>) -> Self {
        Timed {
            solver,
            seconds: [0.0; 3],
        }
    }

    /// Adds its seconds and work to `stats`.
    pub(super) fn record(&self, stats: &mut SolverStats) {
        stats.symbolic_seconds += self.seconds[0];
        stats.numeric_seconds += self.seconds[1];
        stats.solve_seconds += self.seconds[2];
        stats.count(self.solver.work());
    }
}

/// `f()`, its seconds added to `seconds`.
fn timed<T>(seconds: &mut f64, f: impl FnOnce() -> T) -> T {
    let t = Instant::now();
    let out = f();
    *seconds += t.elapsed().as_secs_f64();
    out
}

impl LinearSolve for Timed<'_> {
    fn analyse(&mut self, held: &[bool]) {
        let solver = &mut self.solver;
        timed(&mut self.seconds[0], || solver.analyse(held));
    }

    fn prepare(&mut self, held: &[bool]) -> Result<(), SolveError> {
        let solver = &mut self.solver;
        timed(&mut self.seconds[1], || solver.prepare(held))
    }

    fn solve(&mut self, b: Cow<[f64]>) -> Result<Vec<f64>, SolveError> {
        let solver = &mut self.solver;
        timed(&mut self.seconds[2], || solver.solve(b))
    }

    fn loosen(&mut self, stop: Stop) {
        self.solver.loosen(stop);
    }

    fn tighten(&mut self) -> bool {
        self.solver.tighten()
    }

    fn refines(&self) -> bool {
        self.solver.refines()
    }

    fn start_at(&mut self, values: &[(usize, f64)]) {
        self.solver.start_at(values);
    }

    fn work(&self) -> Work {
        self.solver.work()
    }
}
