//! Local corrections of a proposed active set (a Schwarz-type predictor): the obstacle problem
//! on a band of vertices around the free boundary, the current iterate as Dirichlet data outside
//! it, solved by primal–dual active sets with small Cholesky factorizations.

use super::backend::{Cholesky, LinearSolve};
use super::stats::{SolverStats, Timed};
use super::w_problem::WProblem;
use crate::linear::{InteriorSystem, Unknown};
use crate::problem::DiscreteProblem;
use std::borrow::Cow;

/// A local correction's active set of all unknowns, and w on its band as (unknown, value): the
/// band's last local solve, from which the next global solve starts.
pub(super) struct Corrected {
    pub(super) active: Vec<bool>,
    pub(super) band: Vec<(usize, f64)>,
}

/// Rings of vertices around the changed ones on which a local correction solves: steps along
/// K's couplings (on right-angled meshes not across the diagonals, so that 24 of them reach about
/// as far as 16 mesh edges; with 16, one more global step at 1024² cells).
const BAND_RINGS: usize = 24;
/// The rings of the band inside the proposed contact set: w = 0 there whatever the data outside
/// the band, so the band needs only room for the free boundary to move in.
const HELD_RINGS: usize = 4;
/// Active-set iterations of one local correction.
pub(super) const LOCAL_ITERATIONS: usize = 20;
/// A local correction is skipped when its band would hold more than this share of the unknowns
/// (at 256² cells the band of the first step holds a third of them).
const BAND_SHARE: f64 = 0.5;

impl WProblem<'_> {
    /// A local correction of the proposed active set `next`: the obstacle problem on the band of
    /// [`BAND_RINGS`] rings of vertices around `seeds`, with the current iterate `w` as Dirichlet
    /// data outside the band, solved by primal–dual active sets; its active set replaces `next`
    /// on the band. The set changes only near the free boundary, where this settles it at the
    /// cost of small factorizations. The global iteration still stops only when a global solve
    /// reproduces its active set, so this changes the cost, not the result.
    pub(super) fn local_correction(
        &mut self,
        system: &InteriorSystem,
        w: &[f64],
        seeds: &[usize],
        mut next: Vec<bool>,
        stats: &mut SolverStats,
    ) -> Corrected {
        let p = self.problem;
        let band = band(p, system, seeds, &next, [BAND_RINGS, HELD_RINGS]);
        if band.is_empty() || band.len() as f64 > BAND_SHARE * system.n() as f64 {
            return Corrected {
                active: next,
                band: Vec::new(),
            };
        }
        // The band's numbering in the scratch room of one entry per vertex: O(band) work.
        let mut scratch = std::mem::take(&mut self.scratch);
        scratch.resize(p.mesh.n_vertices(), Unknown::HELD);
        let vertices = band.iter().map(|&i| system.vertices[i]).collect();
        let local = InteriorSystem::on_vertices(&p.stiffness, vertices, scratch);
        // Both vertex lists are increasing, so the local unknown j is the unknown band[j].
        let active: Vec<bool> = band.iter().map(|&i| next[i]).collect();
        let mut solver = Timed::new(Box::new(Cholesky::new(&local)));
        let mut values = Vec::new();
        if let Some((active, w_band)) = self.settle(&local, w, active, &mut solver, stats) {
            for (j, a) in active.into_iter().enumerate() {
                next[band[j]] = a;
            }
            values = band.iter().copied().zip(w_band).collect();
        }
        stats.local_seconds += solver.seconds[1] + solver.seconds[2];
        drop(solver);
        self.scratch = local.into_scratch();
        Corrected {
            active: next,
            band: values,
        }
    }

    /// The active set on the band `local` by at most [`LOCAL_ITERATIONS`] active-set steps from
    /// `active`, w outside the band, with the last step's w on the band; `None` when a
    /// factorization fails.
    fn settle(
        &self,
        local: &InteriorSystem,
        w: &[f64],
        mut active: Vec<bool>,
        solver: &mut dyn LinearSolve,
        stats: &mut SolverStats,
    ) -> Option<(Vec<bool>, Vec<f64>)> {
        let rhs = self.rhs(local, w);
        let mut w_band = Vec::new();
        for _ in 0..LOCAL_ITERATIONS {
            stats.local_iterations += 1;
            solver.prepare(&active).ok()?;
            let w_int = solver.solve(Cow::Borrowed(&rhs)).ok()?;
            // w is w_int on the band and the current iterate elsewhere.
            let value = |b: usize| local.unknown[b].index().map_or(w[b], |j| w_int[j]);
            let (_, step) = self.residual_and_next(local, &w_int, value);
            w_band = w_int;
            if step == active {
                break;
            }
            active = step;
        }
        Some((active, w_band))
    }
}

/// The unknowns of `system` within `rings[0]` graph steps of `seeds`, sorted, where the steps
/// from an `active` unknown go on only while fewer than `rings[1]`.
pub(super) fn band(
    problem: &DiscreteProblem,
    system: &InteriorSystem,
    seeds: &[usize],
    active: &[bool],
    [rings, held_rings]: [usize; 2],
) -> Vec<usize> {
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
                if let Some(j) = system.unknown[b].index().filter(|&j| !in_band[j]) {
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
pub(super) fn interface(problem: &DiscreteProblem, system: &InteriorSystem, active: &[bool]) -> Vec<usize> {
    (0..system.n())
        .filter(|&i| {
            (problem.stiffness.row(system.vertices[i]))
                .any(|(b, _)| system.unknown[b].index().is_some_and(|j| active[j] != active[i]))
        })
        .collect()
}
