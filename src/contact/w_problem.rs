//! The obstacle problem for w on one mesh (the reduced problem (3.4) after the v/w split): its
//! loads, its right-hand side, one active-set step and the rule of the next active set.

use super::backend::LinearSolve;
use super::options::SolveError;
use crate::linear::InteriorSystem;
use crate::parallel::{self, PIECE};
use crate::problem::DiscreteProblem;
use std::borrow::Cow;

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
    pub(super) w: Vec<f64>,
    pub(super) residual: Vec<f64>,
    pub(super) next: Vec<bool>,
}

impl<'p> WProblem<'p> {
    pub(super) fn new(problem: &'p DiscreteProblem) -> Self {
        WProblem {
            problem,
            mu_star: problem.gap_tension(),
            scratch: Vec::new(),
        }
    }

    /// (f_w, φ_a) ([`DiscreteProblem::gap_load`]).
    pub(super) fn load(&self, a: usize) -> f64 {
        self.problem.gap_load(a)
    }

    /// The active-set rule at vertex a: λ_a m_a − μ* K_aa w_a > 0 (i.e. λ_a > c_a w_a with
    /// c_a = μ* K_aa / m_a).
    pub(super) fn predicts_contact(&self, a: usize, residual: f64, w: f64) -> bool {
        residual - self.mu_star * self.problem.stiffness.diagonal(a) * w > 0.0
    }

    /// The right-hand side of `system` with the values `bc` off its unknowns.
    pub(super) fn rhs(&self, system: &InteriorSystem, bc: &[f64]) -> Vec<f64> {
        system.lifted_rhs(&self.problem.stiffness, |a| self.load(a), self.mu_star, |b| bc[b])
    }

    /// One step: w with `solver` (prepared first for a `new_set`), its residual and the next set.
    pub(super) fn step(
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
/// scale·K u = load (see [`super::backend::Stop::Loads`]).
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
