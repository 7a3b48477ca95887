//! The linear solvers of the active-set steps behind one trait: a Cholesky factorization of K_FF
//! ([`Cholesky`]), or CG preconditioned by the truncated V-cycle of K_FF ([`MultigridCg`]), and
//! where CG stops ([`Stop`]).

use super::options::SolveError;
use crate::linear::{Factorization, InteriorSystem};
use crate::mesh::Prolongation;
use crate::multigrid::{Hierarchy, Multigrid, Tolerance};
use crate::problem::DiscreteProblem;
use std::borrow::Cow;

/// A solver of K_FF x = b on the unknowns of an [`InteriorSystem`], F the unknowns not held.
pub(super) trait LinearSolve {
    /// Chooses what depends on the held set's pattern only (Cholesky: the symbolic analysis of
    /// K_FF, see [`Factorization::analyse`]).
    fn analyse(&mut self, _held: &[bool]) {}

    /// Factorizes K_FF, or builds the truncated coarse operators, for the held set.
    fn prepare(&mut self, held: &[bool]) -> Result<(), SolveError>;

    /// K_FF x = b, x = 0 on the held unknowns (b owned when the caller has no further use for it,
    /// so that it is not kept beside the solver's vectors).
    fn solve(&mut self, b: Cow<[f64]>) -> Result<Vec<f64>, SolveError>;

    /// Solves to `stop` (when not its own) until [`LinearSolve::tighten`].
    fn loosen(&mut self, _stop: Stop) {}

    /// Back to its own stop; whether the solves stopped elsewhere.
    fn tighten(&mut self) -> bool {
        false
    }

    /// Whether another solve with the same operators refines the last one (CG from its x).
    fn refines(&self) -> bool {
        false
    }

    /// Starts the next solve from `values` at these unknowns (and the last solution elsewhere),
    /// where the solver iterates from a start.
    fn start_at(&mut self, _values: &[(usize, f64)]) {}

    /// Solves the next right-hand side, unrelated to the last, from 0 to `stop`.
    fn restart(&mut self, _stop: Stop) {}

    /// What it did so far.
    fn work(&self) -> Work;
}

/// What a linear solver did.
#[derive(Debug, Clone, Default)]
pub(super) struct Work {
    /// Factorizations (with multigrid: V-cycles made, one per held set).
    pub(super) factorizations: usize,
    /// Symbolic analyses of K_FF patterns (Cholesky).
    pub(super) analyses: usize,
    /// CG iterations of each solve (multigrid).
    pub(super) cg_iterations: Vec<usize>,
}

/// Sparse Cholesky of K_FF, its symbolic analysis kept while the held set moves little.
pub(super) struct Cholesky<'s> {
    factor: Factorization<'s>,
    factorizations: usize,
}

impl<'s> Cholesky<'s> {
    /// The solver of `system` (made with its Cholesky analysis).
    pub(super) fn new(system: &'s InteriorSystem) -> Self {
        Cholesky {
            factor: system.factorization(),
            factorizations: 0,
        }
    }
}

impl LinearSolve for Cholesky<'_> {
    fn analyse(&mut self, held: &[bool]) {
        self.factor.analyse(held);
    }

    fn prepare(&mut self, held: &[bool]) -> Result<(), SolveError> {
        let made = (self.factor.factorize(held)).map_err(|_| SolveError::NotPositiveDefinite)?;
        self.factorizations += usize::from(made);
        Ok(())
    }

    fn solve(&mut self, b: Cow<[f64]>) -> Result<Vec<f64>, SolveError> {
        let mut x = b.into_owned();
        self.factor.solve(&mut x);
        Ok(x)
    }

    fn work(&self) -> Work {
        Work {
            factorizations: self.factorizations,
            analyses: self.factor.analyses,
            cg_iterations: Vec::new(),
        }
    }
}

/// CG preconditioned by the truncated V-cycle of K_FF on a hierarchy, each solve from the last
/// solution. Multigrid works on all vertices of the mesh, the boundary ones skipped: `x` is the
/// last solution there.
pub(super) struct MultigridCg<'s> {
    system: &'s InteriorSystem,
    hierarchy: &'s Hierarchy<'s>,
    cycle: Option<Multigrid<'s>>,
    x: Vec<f64>,
    stop: Stop,
    /// Another stop for the solves until [`LinearSolve::tighten`].
    loose: Option<Stop>,
    loads: Loads<'s>,
    work: Work,
}

impl<'s> MultigridCg<'s> {
    /// CG with V-cycles on `hierarchy` to `stop` (with `loads` those of the system), starting
    /// from `start` (or 0).
    pub(super) fn new(
        system: &'s InteriorSystem,
        hierarchy: &'s Hierarchy<'s>,
        stop: Stop,
        start: Option<Vec<f64>>,
        loads: Loads<'s>,
    ) -> Self {
        MultigridCg {
            system,
            hierarchy,
            cycle: None,
            x: start.map_or_else(|| vec![0.0; system.unknown.len()], |x| system.extended(&x)),
            stop,
            loose: None,
            loads,
            work: Work::default(),
        }
    }
}

impl LinearSolve for MultigridCg<'_> {
    fn prepare(&mut self, held: &[bool]) -> Result<(), SolveError> {
        self.cycle = None;
        let skip = self.system.skipped(held);
        let cycle = (self.hierarchy.preconditioner(skip)).map_err(|_| SolveError::NotPositiveDefinite)?;
        self.cycle = Some(cycle);
        self.work.factorizations += 1;
        Ok(())
    }

    fn solve(&mut self, b: Cow<[f64]>) -> Result<Vec<f64>, SolveError> {
        let cycle = self.cycle.as_mut().expect("prepared before solving");
        let extended = self.system.extended(&b);
        drop(b);
        let loads = self.loads;
        let size = |a: usize| loads.size(a);
        let stop = self.loose.unwrap_or(self.stop);
        let tolerance = stop.tolerance(loads.density, || cycle.density(&extended), &size);
        let iterations = (cycle.solve_to(extended, &mut self.x, tolerance, CG_MAX_ITERATIONS))
            .map_err(SolveError::NotConverged)?;
        self.work.cg_iterations.push(iterations);
        Ok(self.system.gather(&self.x))
    }

    fn loosen(&mut self, stop: Stop) {
        self.loose = (stop != self.stop).then_some(stop);
    }

    fn start_at(&mut self, values: &[(usize, f64)]) {
        for &(i, v) in values {
            self.x[self.system.vertices[i]] = v;
        }
    }

    fn tighten(&mut self) -> bool {
        self.loose.take().is_some()
    }

    fn restart(&mut self, stop: Stop) {
        (self.stop, self.loose) = (stop, None);
        self.x.fill(0.0);
    }

    fn refines(&self) -> bool {
        true
    }

    fn work(&self) -> Work {
        self.work.clone()
    }
}

/// The loads of the system scale·K u = load that a solver solves, as its stops see them.
#[derive(Clone, Copy)]
pub(super) struct Loads<'p> {
    /// Their density (see [`Stop::Loads`]).
    pub(super) density: f64,
    pub(super) problem: &'p DiscreteProblem,
    pub(super) scale: f64,
}

impl Loads<'_> {
    /// (|(f1, φ_a)| + |(f2, φ_a)|)/scale: the sizes of the loads at vertex a that the checks
    /// count (see [`RESULT_BACKWARD`]).
    fn size(&self, a: usize) -> f64 {
        self.problem.load_size(a) / self.scale
    }
}

/// Where multigrid's CG stops: max_a |r_a|/m_a (see [`Tolerance`]) at most a tolerance times a
/// density, and for results also the backward error of the checks.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) enum Stop {
    /// Times max_a |b_a|/m_a, b the right-hand side: a backward error, the scale of the round-off
    /// of K x (like a Cholesky solve's). Next to ∂ω with g ≠ 0, b holds the lift of g, about g/h²:
    /// an error of λ_h growing as h⁻² relative to the loads, but so does its round-off.
    Residual(f64),
    /// As [`Stop::Residual`], and to a componentwise backward error of [`RESULT_BACKWARD`]: the
    /// solves whose result is returned.
    Result(f64),
    /// Times the density of the loads (the right-hand side's when they vanish): the same
    /// accuracy of λ_h relative to the loads on every mesh, which is what the active set a solve
    /// proposes depends on.
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
        let (density, backward) = match self {
            Stop::Loads(tolerance) if loads > 0.0 => (tolerance * loads, None),
            Stop::Loads(tolerance) | Stop::Residual(tolerance) => (tolerance * rhs(), None),
            Stop::Result(tolerance) => (tolerance * rhs(), Some((RESULT_BACKWARD, floor))),
        };
        Tolerance { density, backward }
    }
}

/// The componentwise backward error of the v and w solves whose result is returned. The checks'
/// defects at a vertex are combinations of the two residuals there (Prop. 12's is v's, λ_h ≥ 0's
/// at a free vertex μ1/(μ1+μ2) v's plus w's), each relative to a scale that σ_a bounds from
/// below within a factor 2 (CG's σ_a plus the sizes of the loads, which b may cancel), so an
/// eighth of [`super::CHECK_TOLERANCE`] leaves them at half of it, and round-off the rest.
const RESULT_BACKWARD: f64 = super::CHECK_TOLERANCE / 8.0;

/// The steps that confirm an active set on the final mesh: to the round-off of K x, as the direct
/// solve (how closely the two agree, and why λ_h's agreement widens on fine meshes with g ≠ 0:
/// README).
pub(super) const FINAL_STOP: Stop = Stop::Residual(1e-13);
/// The solves whose result is returned (v's, and w's once its set is confirmed, from the last
/// step's w with the same operators): also to the backward error of the checks.
pub(super) const RESULT_STOP: Stop = Stop::Result(1e-13);
/// The coarser levels of nested iteration and the first step from their guess only propose an
/// active set: λ_h to this part of the loads, far below its discretisation error on those meshes.
pub(super) const GUESS_STOP: Stop = Stop::Loads(1e-4);
/// CG iterations before giving up (a V-cycle preconditioner needs about 10).
const CG_MAX_ITERATIONS: usize = 200;

/// The solver of `system`'s steps: CG with V-cycles on `multigrid` = (hierarchy, stop) from
/// `start`, or else Cholesky.
pub(super) fn solver<'s>(
    system: &'s InteriorSystem,
    multigrid: Option<(&'s Hierarchy<'s>, Stop)>,
    start: Option<Vec<f64>>,
    loads: Loads<'s>,
) -> Box<dyn LinearSolve + 's> {
    match multigrid {
        None => Box::new(Cholesky::new(system)),
        Some((hierarchy, stop)) => Box::new(MultigridCg::new(system, hierarchy, stop, start, loads)),
    }
}

/// The interior unknowns of `problem` with, for the direct solver (no `prolongations`), the
/// Cholesky analysis of K_II, or else its multigrid hierarchy on the `prolongations` below it.
pub(super) fn analysed<'t>(
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
