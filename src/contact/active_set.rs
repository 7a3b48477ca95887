//! The obstacle problem for w on one mesh, μ* K w ≥ f_w, w ≥ 0 with complementarity, by the
//! primal–dual active-set method: A = {a : λ_a − c_a w_a > 0}, w = 0 on A and the equation off
//! A, repeated until A no longer changes.

use super::backend::{self, LinearSolve, Loads, Stop, GUESS_STOP, RESULT_STOP};
use super::nested::Guess;
use super::stats::{SolverStats, Timed};
use super::{Obstacle, SolveError, SolverOptions};
use crate::linear::InteriorSystem;
use crate::multigrid::Hierarchy;
use crate::parallel::{self, PIECE};
use crate::problem::DiscreteProblem;
use std::borrow::Cow;

/// What [`obstacle`] solves for.
#[derive(Clone, Copy, PartialEq)]
pub(super) enum Role {
    /// The solution of the mesh.
    Solution,
    /// A coarser level of nested iteration: from a guess, one global step proposes the next
    /// level's guess, as one Newton step per level of grid sequencing does (no local correction:
    /// the final mesh settles the free boundary); a level without a guess (the coarsest) is solved.
    Proposal,
}

/// The obstacle problem for w on one mesh: μ* K w ≥ f_w, w ≥ 0, complementarity.
pub(super) struct WProblem<'p> {
    pub(super) problem: &'p DiscreteProblem,
    pub(super) mu_star: f64,
    /// Room for the numbering of a local correction's band, one entry per vertex, all
    /// [`crate::linear::Unknown::HELD`] between corrections (so that each costs O(band), not
    /// O(vertices)).
    pub(super) scratch: Vec<crate::linear::Unknown>,
}

/// One primal–dual active-set step: w with w = 0 on the active set and the equation off it, the
/// residual r_a = μ*(K w)_a − (f_w, φ_a) = λ_a m_a and the next active set {r_a − μ* K_aa w_a > 0}.
pub(super) struct Step {
    /// w at every vertex.
    w: Vec<f64>,
    residual: Vec<f64>,
    next: Vec<bool>,
}

impl<'p> WProblem<'p> {
    pub(super) fn new(problem: &'p DiscreteProblem) -> Self {
        let (mu1, mu2) = (problem.data.mu1, problem.data.mu2);
        WProblem {
            problem,
            mu_star: mu1 * mu2 / (mu1 + mu2),
            scratch: Vec::new(),
        }
    }

    /// (f_w, φ_a) = (μ2 (f1, φ_a) − μ1 (f2, φ_a))/(μ1+μ2).
    pub(super) fn load(&self, a: usize) -> f64 {
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
    pub(super) fn rhs(&self, system: &InteriorSystem, bc: &[f64]) -> Vec<f64> {
        system.lifted_rhs(&self.problem.stiffness, |a| self.load(a), self.mu_star, |b| bc[b])
    }

    /// One step: w with `solver` (prepared first for a `new_set`), its residual and the next set.
    fn step(
        &self,
        system: &InteriorSystem,
        solver: &mut dyn LinearSolve,
        [rhs, bc]: [&[f64]; 2],
        new_set: Option<&[bool]>,
    ) -> Result<Step, SolveError> {
        if let Some(active) = new_set {
            solver.analyse(active);
            solver.prepare(active)?;
        }
        let w_int = solver.solve(Cow::Borrowed(rhs))?;
        let w = system.scatter(&w_int, bc);
        let (residual, next) = self.residual_and_next(system, &w_int, |b| w[b]);
        Ok(Step { w, residual, next })
    }

    /// The residual r_a = μ*(K w)_a − (f_w, φ_a) at the unknowns of `system` and the next active
    /// set, for w = w_int there and `w(b)` at every vertex b; in parallel.
    pub(super) fn residual_and_next(
        &self,
        system: &InteriorSystem,
        w_int: &[f64],
        w: impl Fn(usize) -> f64 + Sync,
    ) -> (Vec<f64>, Vec<bool>) {
        let k = &self.problem.stiffness;
        let (mut residual, mut next) = (vec![0.0; system.n()], vec![false; system.n()]);
        parallel::map_mut2(&mut residual, &mut next, PIECE, |base, residual, next| {
            for (i, (r, next)) in (base..).zip(residual.iter_mut().zip(next)) {
                let a = system.vertices[i];
                *r = self.mu_star * k.row(a).map(|(b, v)| v * w(b)).sum::<f64>() - self.load(a);
                *next = self.predicts_contact(a, *r, w_int[i]);
            }
        });
        (residual, next)
    }
}

/// max_a |load(a)|/(scale m_a) over the unknowns of `system`: the density of the loads of
/// scale·K u = load (see [`Stop::Loads`]).
pub(super) fn load_density(
    problem: &DiscreteProblem,
    system: &InteriorSystem,
    load: impl Fn(usize) -> f64,
    scale: f64,
) -> f64 {
    (system.vertices.iter())
        .map(|&a| (load(a) / (scale * problem.mass[a])).abs())
        .fold(0.0, f64::max)
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
        Some(guess) => first_set(&mut w_problem, system, guess, !proposal, &mut stats),
        None => vec![false; system.n()],
    };
    // CG starts from the guess's gap, then from the previous step's w.
    let start = (warm.as_ref()).map(|g| system.vertices.iter().map(|&a| g.gap[a]).collect());
    let loads = Loads {
        density: load_density(problem, system, |a| w_problem.load(a), w_problem.mu_star),
        problem,
        scale: w_problem.mu_star,
    };
    let mut solver = Timed::new(backend::solver(system, multigrid, start, loads));
    if warm.is_some() {
        // The first step from a guess only proposes the next active set: it is solved to the
        // coarser levels' stop, and the set is confirmed by steps to the full one.
        solver.loosen(GUESS_STOP);
    }
    let rhs = w_problem.rhs(system, &problem.g_h);
    let data = [&rhs[..], &problem.g_h[..]];
    let (mut correcting, mut same_set) = (true, false);
    loop {
        if stats.iterations == options.max_iterations {
            return Err(SolveError::IterationCap {
                iterations: stats.iterations,
                changed: stats.changes.last().copied().unwrap_or(0),
            });
        }
        stats.iterations += 1;
        let mut next = w_problem.step(system, &mut solver, data, (!same_set).then_some(&active[..]))?;
        let loose = solver.tighten();
        let changed: Vec<usize> = (0..system.n()).filter(|&i| next.next[i] != active[i]).collect();
        stats.changes.push(changed.len());
        stats.active_sizes.push(next.next.iter().filter(|&&x| x).count());
        same_set = changed.is_empty();
        if same_set && loose {
            // Confirmed to the loose tolerance only: once more to the full one.
            continue;
        }
        if same_set || proposal {
            if !proposal && solver.refines() {
                // The confirmed set's w to the backward error of the checks (not a step).
                solver.loosen(RESULT_STOP);
                next = w_problem.step(system, &mut solver, data, None)?;
                solver.tighten();
            }
            solver.record(&mut stats);
            return Ok(result(problem, system, next, &active, stats));
        }
        // Local corrections only while the number of changes falls, so that they cannot cycle
        // with the global steps; then plain primal–dual active-set steps, which converge on their
        // own when K is an M-matrix (no obtuse angles), and meet the iteration cap otherwise.
        let k = stats.changes.len();
        correcting &= k < 2 || stats.changes[k - 1] < stats.changes[k - 2];
        active = match correcting {
            true => w_problem.local_correction(system, &next.w, &changed, next.next, &mut stats),
            false => next.next,
        };
    }
}

/// The active set the guess predicts; settled locally first (`settle`) with the guess (and g_h
/// on ∂ω) as Dirichlet data, as the guess's free boundary is off by a few mesh sizes.
fn first_set(
    w_problem: &mut WProblem,
    system: &InteriorSystem,
    guess: &Guess,
    settle: bool,
    stats: &mut SolverStats,
) -> Vec<bool> {
    let problem = w_problem.problem;
    let active: Vec<bool> = (system.vertices.iter())
        .map(|&a| w_problem.predicts_contact(a, guess.lambda[a] * problem.mass[a], guess.gap[a]))
        .collect();
    if !settle {
        return active;
    }
    let data: Vec<f64> = (guess.gap.iter().zip(&problem.g_h).enumerate())
        .map(|(a, (&w, &g))| if problem.mesh.on_boundary[a] { g } else { w })
        .collect();
    let seeds = super::local::interface(problem, system, &active);
    w_problem.local_correction(system, &data, &seeds, active, stats)
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
