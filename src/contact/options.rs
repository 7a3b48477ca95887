//! How the contact problem is solved (the linear solver, the iteration cap) and why it can fail.

use crate::multigrid::NotConverged;
use crate::problem::DataError;
use std::fmt;

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
    /// Stopped by [`crate::progress::cancel`] (Ctrl-C in the Python package).
    Cancelled,
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
            SolveError::Cancelled => write!(f, "the solve was interrupted"),
        }
    }
}

impl std::error::Error for SolveError {}

/// Options of the active-set method.
#[derive(Debug, Clone, Copy)]
pub struct SolverOptions {
    /// Active-set iterations before giving up.
    pub max_iterations: usize,
    /// The linear solver of v and of the active-set steps.
    pub linear: LinearSolver,
    /// Told of each active-set iteration on the final mesh as it ends: its number and how many
    /// vertices changed set ([`crate::progress::step`] on the command line). A plain function,
    /// so that the options stay `Copy`.
    pub on_step: Option<fn(usize, usize)>,
}

impl Default for SolverOptions {
    fn default() -> Self {
        SolverOptions {
            max_iterations: 200,
            linear: LinearSolver::Multigrid,
            on_step: None,
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
