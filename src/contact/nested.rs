//! The guess the active-set iteration starts from: nested iteration (grid sequencing) on coarser
//! meshes, or another mesh's solution interpolated.

use super::active_set::Obstacle;
use super::active_set::{obstacle, Guess, Role};
use super::backend::{analysed, GUESS_STOP};
use super::options::{LinearSolver, SolveError, SolverOptions};
use crate::mesh::{Mesh, Prolongation};
use crate::problem::{boundary_values, DiscreteProblem, Heights};
use std::time::Instant;

/// How the active-set method starts.
#[derive(Debug, Clone, Copy)]
pub enum Start<'a> {
    /// From no contact.
    Cold,
    /// Nested iteration (grid sequencing): the obstacle problem on the coarser meshes passed to
    /// [`super::solve`] first, each warm-starting the next, the last one prolonged onto this mesh.
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

/// The guess of a start, with the coarser levels' active-set iterations and the CG iterations of
/// each of their steps (coarsest first), and the seconds it took.
pub(super) struct Started {
    pub(super) guess: Option<Guess>,
    pub(super) iterations: Vec<usize>,
    pub(super) cg_iterations: Vec<Vec<usize>>,
    pub(super) seconds: f64,
}

/// The guess of `start` on `problem`'s mesh (for [`Start::Nested`], by nested iteration on the
/// `coarser` meshes with the `prolongations` between them).
pub(super) fn initial_guess(
    problem: &DiscreteProblem,
    start: Start,
    coarser: Vec<Mesh>,
    prolongations: &[Prolongation],
    options: SolverOptions,
) -> Result<Started, SolveError> {
    let t = Instant::now();
    let mut started = match start {
        Start::Cold => Started::from(None),
        Start::Nested => nested_guess(problem, coarser, prolongations, options)?,
        Start::From { mesh, obstacle } => {
            let p = Prolongation::new(&problem.mesh, mesh);
            Started::from(Some(Guess::prolong(&p, obstacle)))
        }
    };
    started.seconds = t.elapsed().as_secs_f64();
    Ok(started)
}

impl From<Option<Guess>> for Started {
    fn from(guess: Option<Guess>) -> Self {
        Started {
            guess,
            iterations: Vec::new(),
            cg_iterations: Vec::new(),
            seconds: 0.0,
        }
    }
}

/// The interpolations between consecutive meshes of `fine` and the `coarser` ones (fine to
/// coarse): element l interpolates from level l + 1 onto level l.
pub(super) fn chain(fine: &Mesh, coarser: &[Mesh]) -> Vec<Prolongation> {
    let mut finer = fine;
    (coarser.iter())
        .map(|mesh| {
            let p = Prolongation::new(finer, mesh);
            finer = mesh;
            p
        })
        .collect()
}

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
) -> Result<Started, SolveError> {
    let multigrid = options.linear == LinearSolver::Multigrid;
    // The boundary values of each level (checked here, finest first) and its loads restricted
    // from the one above; each level's problem is assembled when it is solved and dropped once
    // solved.
    let mut levels: Vec<(Mesh, Heights, [Vec<f64>; 2])> = Vec::new();
    for (mesh, p) in coarser.into_iter().zip(prolongations) {
        let heights = boundary_values(&mesh, &problem.data).map_err(SolveError::CoarseData)?;
        let above = levels
            .last()
            .map_or([&problem.load1, &problem.load2], |(_, _, loads)| {
                [&loads[0], &loads[1]]
            });
        // Below a rigid obstacle there is no load on membrane 2 to restrict.
        let loads = above.map(|f| if f.is_empty() { Vec::new() } else { p.restrict(f) });
        levels.push((mesh, heights, loads));
    }
    let mut started = Started::from(None);
    while let Some((mesh, heights, loads)) = levels.pop() {
        let k = levels.len();
        let level = DiscreteProblem::with_loads(mesh, &problem.data, heights, loads);
        // The coarsest level has no levels below: Cholesky.
        let below = (multigrid && k + 1 < prolongations.len()).then(|| &prolongations[k + 1..]);
        let (system, hierarchy) = analysed(&level, below);
        let multigrid = hierarchy.as_ref().map(|h| (h, GUESS_STOP));
        let guess = started.guess.take();
        let o = obstacle(&level, &system, multigrid, guess, options, Role::Proposal)?;
        started.iterations.push(o.stats.iterations);
        started.cg_iterations.push(o.stats.cg_iterations.clone());
        started.guess = Some(Guess::prolong(&prolongations[k], &o));
    }
    Ok(started)
}
