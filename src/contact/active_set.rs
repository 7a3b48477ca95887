//! The obstacle problem for w on one mesh, μ* K w ≥ f_w, w ≥ 0 with complementarity, by the
//! primal–dual active-set method: A = {a : λ_a − c_a w_a > 0}, w = 0 on A and the equation off
//! A, repeated until A no longer changes.

use super::backend::{self, LinearSolve, Loads, Stop, GUESS_STOP, RESULT_STOP};
use super::local::interface;
use super::options::{SolveError, SolverOptions};
use super::stats::{SolverStats, Timed};
use super::w_problem::{load_density, Step, WProblem};
use crate::linear::InteriorSystem;
use crate::mesh::Prolongation;
use crate::multigrid::Hierarchy;
use crate::problem::DiscreteProblem;

/// What [`obstacle`] solves for.
#[derive(Clone, Copy, PartialEq)]
pub(super) enum Role {
    /// The solution of the mesh.
    Solution,
    /// A coarser level of nested iteration: from a guess, its active set settled locally, one
    /// global step proposes the next level's guess, as one Newton step per level of grid
    /// sequencing does; a level without a guess (the coarsest) is solved. Unsettled, the guess's
    /// free boundary may lag a vertex per level, and the lag doubles from level to level: on
    /// cells stretched 100:1, 109 steps on the final mesh instead of 5.
    Proposal,
}

/// An initial guess of the gap w and λ at every vertex, e.g. a coarser mesh's solution
/// interpolated here (nested iteration).
pub(super) struct Guess {
    pub(super) gap: Vec<f64>,
    pub(super) lambda: Vec<f64>,
}

impl Guess {
    /// The gap and λ of another mesh's solution, transferred by `p`.
    pub(super) fn prolong(p: &Prolongation, o: &Obstacle) -> Guess {
        Guess {
            gap: p.apply(&o.gap),
            lambda: p.apply(&o.lambda),
        }
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

/// The obstacle problem for w on `problem`'s mesh by primal–dual active sets, its linear solves
/// by Cholesky or, with `multigrid` = (hierarchy, stop), by CG preconditioned by V-cycles; from
/// the guess `warm` when given (dropped once it has given the first active set and CG's start);
/// solved, or one step proposed, as the `role` says.
pub(super) fn obstacle(
    problem: &DiscreteProblem,
    system: &InteriorSystem,
    multigrid: Option<(&Hierarchy, Stop)>,
    warm: Option<Guess>,
    options: SolverOptions,
    role: Role,
) -> Result<Obstacle, SolveError> {
    let proposal = role == Role::Proposal && warm.is_some();
    let mut stats = SolverStats {
        unknowns: system.n(),
        factor_nnz: system.factor_nnz(),
        ..Default::default()
    };
    let mut w_problem = WProblem::new(problem);
    let mut active = match &warm {
        Some(guess) => first_set(&mut w_problem, system, guess, &mut stats),
        None => vec![false; system.n()],
    };
    // CG starts from the guess's gap, then from the previous step's w with the last local
    // correction's solve on its band.
    let start = (warm.as_ref()).map(|g| system.vertices.iter().map(|&a| g.gap[a]).collect());
    let warm = warm.is_some();
    let loads = Loads {
        density: load_density(problem, system, |a| w_problem.load(a), w_problem.mu_star),
        problem,
        scale: w_problem.mu_star,
    };
    let mut solver = Timed::new(backend::solver(system, multigrid, start, loads));
    if warm {
        // The first step from a guess only proposes the next active set: it is solved to the
        // coarser levels' stop, and the set is confirmed by steps to the full one.
        solver.loosen(GUESS_STOP);
    }
    let rhs = w_problem.rhs(system, &problem.gap_h);
    let data = [&rhs[..], &problem.gap_h[..]];
    let (mut correcting, mut same_set) = (true, false);
    let mut proposed = std::collections::HashSet::new();
    loop {
        may_step(&options, &stats)?;
        stats.iterations += 1;
        let mut next = w_problem.step(system, &mut solver, data, (!same_set).then_some(&active[..]))?;
        let loose = solver.tighten();
        let changed: Vec<usize> = (0..system.n()).filter(|&i| next.next[i] != active[i]).collect();
        stats.changes.push(changed.len());
        if let Some(report) = options.on_step.filter(|_| role == Role::Solution) {
            report(stats.iterations, changed.len());
        }
        stats.active_sizes.push(next.next.iter().filter(|&&x| x).count());
        same_set = changed.is_empty();
        if same_set && loose {
            // Confirmed to the loose tolerance only: once more to the full one.
            continue;
        }
        if same_set || proposal {
            if !proposal && solver.refines() {
                // The confirmed set's w to the backward error of the checks (not a step), the
                // step it refines let go first (the two are not held at once).
                drop(next);
                solver.loosen(RESULT_STOP);
                next = w_problem.step(system, &mut solver, data, None)?;
                solver.tighten();
            }
            solver.record(&mut stats);
            return Ok(result(problem, system, next, &active, stats));
        }
        // Local corrections until a global step proposes a set it proposed before (they could
        // then cycle with the global steps); then plain primal–dual active-set steps, which
        // converge on their own when K is an M-matrix (no obtuse angles), and meet the
        // iteration cap otherwise. Where the free boundary moves a few vertices per global step
        // (cells stretched 20:1 and more), the corrections carry it across their bands.
        correcting &= proposed.insert(fingerprint(&next.next));
        active = match correcting {
            true => {
                let corrected = w_problem.local_correction(system, &next.w, &changed, next.next, &mut stats);
                solver.start_at(&corrected.band);
                corrected.active
            }
            false => next.next,
        };
    }
}

/// A fingerprint of an active set (the same on every run of a build, whatever the threads).
fn fingerprint(active: &[bool]) -> u64 {
    use std::hash::{DefaultHasher, Hash, Hasher};
    let mut hasher = DefaultHasher::new();
    active.hash(&mut hasher);
    hasher.finish()
}

/// Whether another active-set step may be taken: not once the run is cancelled, nor beyond
/// `options.max_iterations`.
fn may_step(options: &SolverOptions, stats: &SolverStats) -> Result<(), SolveError> {
    if crate::progress::cancelled() {
        return Err(SolveError::Cancelled);
    }
    if stats.iterations == options.max_iterations {
        return Err(SolveError::IterationCap {
            iterations: stats.iterations,
            changed: stats.changes.last().copied().unwrap_or(0),
        });
    }
    Ok(())
}

/// The active set the guess predicts, settled locally with the guess (and the gap's boundary
/// values on ∂ω) as Dirichlet data, as the guess's free boundary is off by a few mesh sizes.
fn first_set(
    w_problem: &mut WProblem,
    system: &InteriorSystem,
    guess: &Guess,
    stats: &mut SolverStats,
) -> Vec<bool> {
    let problem = w_problem.problem;
    let active: Vec<bool> = (system.vertices.iter())
        .map(|&a| w_problem.predicts_contact(a, guess.lambda[a] * problem.mass[a], guess.gap[a]))
        .collect();
    let data: Vec<f64> = (guess.gap.iter().zip(&problem.gap_h).enumerate())
        .map(|(a, (&w, &g))| if problem.mesh.on_boundary[a] { g } else { w })
        .collect();
    let seeds = interface(problem, system, &active);
    w_problem
        .local_correction(system, &data, &seeds, active, stats)
        .active
}

/// The obstacle solution of the last `step` on the `active` set: w, λ_a = r_a/m_a, the contact set.
fn result(
    problem: &DiscreteProblem,
    system: &InteriorSystem,
    step: Step,
    active: &[bool],
    stats: SolverStats,
) -> Obstacle {
    let nv = problem.mesh.n_vertices();
    let (mut lambda, mut contact) = (vec![0.0; nv], vec![false; nv]);
    for (i, &a) in system.vertices.iter().enumerate() {
        lambda[a] = step.residual[i] / problem.mass[a];
        contact[a] = active[i];
    }
    Obstacle {
        gap: step.w,
        lambda,
        contact,
        stats,
    }
}
