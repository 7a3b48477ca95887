//! One run, told as the paper tells it: case → mesh T_h → discrete problem (3.4) → its solution →
//! the action λ_h (4.5) and its checks → errors against an exact solution → the flux t_ih (4.13)
//! → the a posteriori estimator → a result directory, written whole.

use crate::action::{Action, CheckError};
use crate::atomic::{OutputError, Staging};
use crate::case::{Case, CaseError};
use crate::contact::{self, LinearSolver, Solution, SolveError, SolverOptions, Start};
use crate::estimator::Estimate;
use crate::flux::Fluxes;
use crate::mesh::{self, DualMesh, Edges, Mesh, Postprocess};
use crate::norms::Errors;
use crate::problem::DiscreteProblem;
use crate::progress;
use crate::result::{self, Attr, Attribute, Describe, Field};
use std::fmt;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// What a run computes beyond the solution and the action.
#[derive(Debug, Clone, Copy)]
pub struct Options<'a> {
    /// How the active-set method starts.
    pub start: Start<'a>,
    /// ‖λ − λ_h‖_H⁻¹ for a case with an exact solution (a solve on S_h).
    pub hminus1: bool,
    /// The fluxes t_1h, t_2h (4.13) and their local conservation (Lemma 17).
    pub flux: bool,
    /// The guaranteed error bound and its indicators (docs/a-posteriori.md).
    pub estimate: bool,
    /// Write the dual submesh S_h and its cell fields too (`dual.xdmf`); the fluxes, which live
    /// on S_h only, write it anyway.
    pub dual: bool,
}

/// The command line's `solve` without options: nested iteration, the solution and its checks.
impl Default for Options<'_> {
    fn default() -> Self {
        Options {
            start: Start::Nested,
            hminus1: false,
            flux: false,
            estimate: false,
            dual: false,
        }
    }
}

/// The result of one run.
pub struct Run<'c> {
    /// The case solved.
    pub case: &'c Case,
    /// (3.4) on T_h.
    pub problem: DiscreteProblem,
    /// Its solution.
    pub solution: Solution,
    /// λ_h (4.5) with its checks.
    pub action: Action,
    /// The edge numbering of T_h, which with T_h is S_h ([`Run::dual`]).
    pub edges: Edges,
    /// Errors against the exact solution, when the case has one.
    pub errors: Option<Errors>,
    /// t_1h, t_2h, when asked for.
    pub flux: Option<Fluxes>,
    /// The a posteriori estimator, when asked for.
    pub estimate: Option<Estimate>,
    /// Wall-clock seconds of the phases.
    pub timings: Timings,
    /// Whether the result holds S_h ([`Options::dual`], or the fluxes).
    pub writes_dual: bool,
    /// Whether the solve started by nested iteration ([`Start::Nested`]).
    pub nested: bool,
}

impl Options<'_> {
    /// What is computed after the solve, which the memory guard prices.
    fn postprocess(&self) -> Postprocess {
        Postprocess {
            flux: self.flux,
            estimate: self.estimate,
            hminus1: self.hminus1,
        }
    }
}

/// Solves `case` and writes its result directory `target` whole: an earlier result there is
/// replaced only once this one is complete, and nothing is written when the run fails.
///
/// ```
/// use membrane_contact::{case::Case, contact::Start, run};
/// let case = Case::default_case();
/// let dir = tempfile::tempdir().unwrap();
/// let options = run::Options { start: Start::Nested, hminus1: false, flux: true, estimate: true, dual: false };
/// let r = run::solve(&case, &options, &dir.path().join("default")).unwrap();
/// assert!(r.action.total > 0.0 && dir.path().join("default/solution.xdmf").exists());
/// assert!(r.estimate.unwrap().total >= r.errors.unwrap().energy.unwrap());
/// ```
pub fn solve<'c>(case: &'c Case, options: &Options, target: &Path) -> Result<Run<'c>, RunError> {
    let inputs = case.inputs();
    let staging = Staging::new(target, &inputs, "solution")?;
    let mut run = run(case, options)?;
    run.write(staging, &inputs)?;
    Ok(run)
}

/// Computes a run without writing it.
pub fn run<'c>(case: &'c Case, options: &Options) -> Result<Run<'c>, RunError> {
    if options.hminus1 && case.exact.is_none() {
        return Err(CaseError(format!(
            "{}: --hminus1 is the error ‖λ − λh‖_H⁻¹ against the exact λ, and the case has no [exact] table",
            case.origin
        ))
        .into());
    }
    // Before the mesh is built: what this problem cannot compute fails at once.
    case.check_options(options.estimate)?;
    let clock = Instant::now();
    progress::phase(|| "meshing".into());
    // The coarser meshes serve nested iteration and multigrid.
    let multigrid = case.solver.linear == LinearSolver::Multigrid;
    let after = options.postprocess();
    let (mesh, coarser) = case.hierarchy(multigrid || matches!(options.start, Start::Nested), after)?;
    case.check_on(&mesh)?;
    on_mesh(case, mesh, coarser, options, clock.elapsed().as_secs_f64())
}

/// The run's end when it is asked to stop ([`progress::cancel`]); the phases that loop over
/// blocks stop at their next block and leave values that are not their results.
fn stop_if_cancelled(case: &Case) -> Result<(), RunError> {
    match progress::cancelled() {
        true => Err(RunError::Solve(case.origin.clone(), SolveError::Cancelled)),
        false => Ok(()),
    }
}

/// Computes a run on `mesh` (built in `mesh_seconds`), with the `coarser` meshes of nested
/// iteration.
pub fn on_mesh<'c>(
    case: &'c Case,
    mesh: Mesh,
    coarser: Vec<Mesh>,
    options: &Options,
    mesh_seconds: f64,
) -> Result<Run<'c>, RunError> {
    case.check_options(options.estimate)?;
    let mut clock = Clock(Instant::now());
    progress::phase(|| format!("assembly: {} vertices", mesh.n_vertices()));
    let problem =
        DiscreteProblem::new(mesh, &case.data).map_err(|e| CaseError(format!("{}: {e}", case.origin)))?;
    let assembly = clock.lap();
    let solver = SolverOptions {
        linear: case.linear_solver(),
        on_step: Some(progress::step),
        ..case.solver
    };
    progress::phase(|| "contact solve".into());
    let solution = contact_solve(case, &problem, options, coarser, solver)?;
    clock.lap();
    stop_if_cancelled(case)?;
    progress::phase(|| {
        let errors = if case.exact.is_some() { ", error norms" } else { "" };
        let flux = if options.flux { ", fluxes" } else { "" };
        format!("postprocess: λ_h and its checks{errors}{flux}")
    });
    let action = Action::compute(&problem, &solution);
    (action.checks.verify()).map_err(|e| RunError::Check(case.origin.clone(), e))?;
    let edges = Edges::new(&problem.mesh);
    let dual = DualMesh::new(&problem.mesh, &edges);
    let errors = (case.exact.as_ref())
        .map(|exact| Errors::compute(&problem, &dual, &solution, &action, exact, options.hminus1));
    if let Some(key) = errors.as_ref().and_then(Errors::not_finite) {
        return Err(CaseError(format!(
            "{}: the error norm of {key} is not finite: it, or its difference from the solution, is NaN \
             or infinite at a quadrature point",
            case.origin
        ))
        .into());
    }
    let flux = options
        .flux
        .then(|| Fluxes::reconstruct(&problem, &dual, &solution, &action));
    let postprocess = clock.lap();
    stop_if_cancelled(case)?;
    if options.estimate {
        progress::phase(|| "estimate".into());
    }
    let estimate = (options.estimate).then(|| Estimate::compute(&problem, &dual, &solution, &action));
    // A phase cut short by a cancel leaves values that are not its results.
    stop_if_cancelled(case)?;
    if let Some(e) = estimate
        .as_ref()
        .filter(|e| !(e.total.is_finite() && e.lambda.is_finite()))
    {
        return Err(CaseError(format!(
            "{}: the error estimate is not finite (η = {:.4e}, the bound of ‖λ − λ_h‖ {:.4e}): its \
             squared terms overflow double precision at the size of this case's data; solve without \
             --estimate, or scale the data",
            case.origin, e.total, e.lambda
        ))
        .into());
    }
    let timings = Timings {
        mesh: mesh_seconds,
        assembly,
        postprocess,
        estimate: clock.lap(),
        write: 0.0,
    };
    Ok(Run {
        case,
        problem,
        solution,
        action,
        edges,
        errors,
        flux,
        estimate,
        timings,
        writes_dual: options.dual || options.flux,
        nested: matches!(options.start, Start::Nested),
    })
}

/// The contact solve of `problem`. Where multigrid CG does not converge (on cells stretched
/// about 100:1 its point smoother no longer smooths), the problem is solved again by Cholesky from
/// the same start, if that fits in memory, and the solver's statistics say why.
fn contact_solve(
    case: &Case,
    problem: &DiscreteProblem,
    options: &Options,
    coarser: Vec<Mesh>,
    solver: SolverOptions,
) -> Result<Solution, RunError> {
    let failed = |e| RunError::Solve(case.origin.clone(), e);
    let cg = match contact::solve(problem, options.start, coarser, solver) {
        Err(SolveError::NotConverged(cg)) => cg,
        other => return other.map_err(failed),
    };
    let bytes = case.price(LinearSolver::Direct, options.postprocess());
    if mesh::check_memory(problem.mesh.n_vertices(), bytes).is_err() {
        return Err(failed(SolveError::NotConverged(cg)));
    }
    progress::phase(|| "contact solve again, by Cholesky: multigrid CG did not converge".into());
    let direct = SolverOptions {
        linear: LinearSolver::Direct,
        ..solver
    };
    // The same start: the coarser meshes, consumed by the first solve, made again from the case
    // (none if its mesh is not this one, as after adaptive refinement: a cold start then).
    let coarser = match options.start {
        Start::Nested => (case.hierarchy(true, options.postprocess()).ok())
            .filter(|(fine, _)| fine.n_vertices() == problem.mesh.n_vertices())
            .map_or_else(Vec::new, |(_, coarser)| coarser),
        _ => Vec::new(),
    };
    let mut solution = contact::solve(problem, options.start, coarser, direct).map_err(failed)?;
    solution.obstacle.stats.multigrid_failed = Some(cg);
    Ok(solution)
}

impl Run<'_> {
    /// The fields of the result files, with S_h's if `dual` (already there when the run writes S_h).
    pub fn fields_with_dual(&self, dual: bool) -> Vec<Field<'_>> {
        let mut fields = self.fields();
        if dual && !self.writes_dual {
            fields.extend(self.dual_fields());
        }
        fields
    }

    /// The fields of S_h: λ_h = Σ_a λ_a χ_{D_a} (0 on the cells of boundary vertices), and the a of
    /// each D_a (in [`Describe::fields`] when the result holds S_h).
    pub fn dual_fields(&self) -> Vec<Field<'_>> {
        let vertices = (0..self.problem.mesh.n_vertices())
            .map(|a| a as f64)
            .collect::<Vec<_>>();
        vec![
            Field::on_dual_cells("lambda", &self.action.lambda[..]),
            Field::on_dual_cells("vertex", vertices),
        ]
    }

    /// Writes the result into `staging` and puts it in place.
    pub fn write(&mut self, staging: Staging, inputs: &[PathBuf]) -> Result<(), RunError> {
        let t = Instant::now();
        let dual = self.writes_dual.then(|| self.dual());
        write_staged(
            staging,
            inputs,
            &self.problem.mesh,
            dual.as_ref(),
            &self.fields(),
            &self.attributes(),
        )?;
        self.timings.write = t.elapsed().as_secs_f64();
        Ok(())
    }

    /// The run's result as owned parts, free of the case and of the run: what [`Run::write`]
    /// writes (the same fields and attributes, copied, with the mesh and S_h's edges; S_h also
    /// if `dual`) and the summary, for a caller that keeps the result after the run is gone (the
    /// Python package).
    pub fn parts(&self, verbose: bool, dual: bool) -> Parts {
        Parts {
            fields: (self.fields_with_dual(dual).into_iter())
                .map(Field::into_owned)
                .collect(),
            attributes: self.attributes(),
            summary: self.summary(verbose),
            inputs: self.case.inputs(),
            writes_dual: self.writes_dual || dual,
            mesh: self.problem.mesh.clone(),
            edges: self.edges.clone(),
        }
    }

    /// A short human-readable summary; `verbose` adds the solver's details (coarser levels, local
    /// corrections, CG iterations or factorizations) and why Cholesky ran in place of multigrid.
    pub fn summary(&self, verbose: bool) -> String {
        self.case_line() + &self.figures(verbose) + &self.seconds_line()
    }

    /// The summary's first line: the case, by its origin and title.
    fn case_line(&self) -> String {
        match self.case.title.as_str() {
            "" => format!("case        {}\n", self.case.origin),
            title => format!("case        {} — {title}\n", self.case.origin),
        }
    }

    /// The summary but for its line on the times, which differ from run to run.
    fn figures(&self, verbose: bool) -> String {
        let mut out = self.mesh_line() + &self.solver_line(verbose) + &self.action_lines();
        if let Some(e) = &self.errors {
            let show = |v: Option<f64>| v.map_or("—".into(), |v| format!("{v:.4e}"));
            let norms = if self.solution.rigid {
                format!("|u−uh|_H1 = {}, ‖u−uh‖_L2 = {:.4e}", show(e.h1_u1), e.l2_u1)
            } else {
                format!(
                    "|u1−u1h|_H1 = {}, |u2−u2h|_H1 = {}, ‖u1−u1h‖_L2 = {:.4e}, ‖u2−u2h‖_L2 = {:.4e}",
                    show(e.h1_u1),
                    show(e.h1_u2),
                    e.l2_u1,
                    e.l2_u2
                )
            };
            out += &format!(
                "errors      {norms}, ‖λ−λh‖_L2 = {:.4e}, ‖λ−λh‖_H⁻¹ = {} (quadrature: estimated relative error ≤ {:.0e})\n",
                e.l2_lambda,
                show(e.hminus1_lambda),
                e.quadrature
            );
            if e.at_round_off() {
                out += &format!(
                    "exact       u_h is the exact solution to round-off (|||u − u_h||| = {:.1e}, within the \
                     {:.0e} the round-off of its values makes of it): no effectivity\n",
                    e.energy.unwrap_or(0.0),
                    e.round_off.energy
                );
            }
            if let Some(u) = &e.unsolved {
                out += &format!("exact       {}\n", u.describe(self.solution.rigid));
            }
            if let Some(m) = &e.boundary {
                out += &match m.at_vertex {
                    true => format!(
                        "exact       does not take the boundary data at the boundary vertex ({:.4}, {:.4}) \
                         (off by {:.1e} of their size): [exact] is not a solution of this case, and the \
                         errors above are not its errors\n",
                        m.at[0], m.at[1], m.relative
                    ),
                    false => format!(
                        "exact       misses the boundary data on ∂ω_h, the mesh's polygon, by up to {:.1e} of \
                         their size (at ({:.4}, {:.4})): the errors above are against the solution on \
                         another domain, while η bounds the error against the solution on ω_h\n",
                        m.relative, m.at[0], m.at[1]
                    ),
                };
            }
        }
        if let Some(e) = &self.estimate {
            out += &e.summary(self.errors.as_ref().and_then(|e| e.resolved_energy()));
        }
        if let Some(f) = &self.flux {
            out += &f.summary();
        }
        out
    }

    /// The summary's line on the mesh: its size and the longest edge, beside the case's h.
    fn mesh_line(&self) -> String {
        let m = &self.problem.mesh;
        let refined = match self.case.refine {
            0 => String::new(),
            1 => ", refined once".into(),
            k => format!(", refined {k} times"),
        };
        let given = match &self.case.mesh {
            crate::case::MeshSpec::Domain { h, .. } => {
                format!(" (meshed to h = {}{refined})", crate::mesh::Number(*h))
            }
            _ if !refined.is_empty() => format!(" ({})", &refined[2..]),
            _ => String::new(),
        };
        format!(
            "mesh        {} vertices, {} triangles, longest edge h = {:.3e}{given}\n",
            m.n_vertices(),
            m.n_triangles(),
            m.h(),
        )
    }

    /// The summary's line on the solver: short, or with `verbose` its details.
    fn solver_line(&self, verbose: bool) -> String {
        let s = &self.solution.obstacle.stats;
        let contact = s.active_sizes.last().copied().unwrap_or(0);
        let failed = (s.multigrid_failed.as_ref())
            .map(|cg| format!("multigrid CG did not converge in {} iterations", cg.iterations));
        // Why Cholesky ran where multigrid was asked for.
        let why = match (failed, s.linear, self.case.linear_solver()) {
            (Some(f), ..) => Some(f),
            (None, LinearSolver::Direct, LinearSolver::Multigrid) => {
                Some("not multigrid: this mesh has no coarser levels".into())
            }
            (None, LinearSolver::Direct, _) if self.case.solver.linear == LinearSolver::Multigrid => {
                Some(match (self.nested, s.coarse_iterations.is_empty()) {
                    // Tables per group do not carry over to a mesh of the boundary alone.
                    (true, true) => "not multigrid, and from a cold start: no coarser mesh of this \
                                     mesh's boundary takes these data (tables per group) or is \
                                     small enough to help; with refine = k this mesh is the \
                                     coarser level"
                        .into(),
                    (true, false) => "not multigrid: the coarser levels of a mesh read from a file \
                                      or given, meshed from its boundary, give the guess only"
                        .into(),
                    // From another mesh's solution (adapt's steps) or cold.
                    (false, _) => "not multigrid: a mesh read from a file or given, unrefined, has \
                                   no coarser levels of its own"
                        .into(),
                })
            }
            _ => None,
        };
        if !verbose {
            let solver = match s.linear {
                LinearSolver::Direct => "Cholesky",
                LinearSolver::Multigrid => "multigrid",
            };
            let why = why.map_or(String::new(), |w| format!("; {w}"));
            return format!(
                "solver      {} active-set iterations ({solver}{why}); contact at {contact} vertices\n",
                s.iterations
            );
        }
        let fallback = why.map_or(String::new(), |w| format!(" ({w})"));
        let per = match self.case.data.is_obstacle() {
            true => "",
            false => " per membrane",
        };
        format!(
            "solver      {} unknowns{per}; {} active-set iterations + {} local ones (coarser levels: {:?}); {}{fallback}; contact at {contact} vertices\n",
            s.unknowns,
            s.iterations,
            s.local_iterations,
            s.coarse_iterations,
            s.linear_work(),
        )
    }

    /// The summary's lines on λ_h and the checks of the solution.
    fn action_lines(&self) -> String {
        let (a, c) = (&self.action, &self.action.checks);
        let (same, gap, membranes) = match self.solution.rigid {
            true => (String::new(), "u_h − ψ_h", String::new()),
            false => (
                format!("λ_h the same from either membrane {:.1e}, ", c.prop12),
                "u1h − u2h",
                format!(", of u_ih {:.1e} of their size", c.membrane_resolution()),
            ),
        };
        format!(
            "action      ∫λ_h = {:.6e}, contact area = {:.6e}, max λ = {:.6e}\n\
             checks      passed, each relative to the terms that cancel (tolerance {:.0e}): {same}\
             λ_h ≥ 0 {:.1e}, λ_h ({gap}) = 0 {:.1e}, {gap} ≥ 0 {:.1e}; \
             round-off of λ_h {:.1e} of the loads{membranes} (limit {:.0e})\n",
            a.total,
            a.contact_area,
            a.lambda.iter().copied().fold(0.0, f64::max),
            crate::action::TOLERANCE,
            c.negative_lambda,
            c.complementarity,
            c.negative_gap,
            c.resolution,
            crate::action::RESOLUTION,
        )
    }

    /// The summary's line on the time of each phase, the threads and the peak memory.
    fn seconds_line(&self) -> String {
        let (t, s) = (&self.timings, &self.solution.obstacle.stats);
        let phases = match s.linear {
            LinearSolver::Direct => ["symbolic", "numeric", "solves"],
            LinearSolver::Multigrid => ["interpolations", "coarse operators", "CG"],
        };
        format!(
            "seconds     mesh {:.3}, assembly {:.3}, contact solve {:.3} (coarser levels {:.3}, {} {:.3}, \
             {} {:.3} + {} {:.3} {}), postprocess {:.3}{}, write {:.3}; on {}{}\n",
            t.mesh,
            t.assembly,
            s.wall_seconds,
            s.coarse_seconds,
            phases[0],
            s.symbolic_seconds,
            phases[1],
            s.numeric_seconds,
            phases[2],
            s.solve_seconds,
            if self.solution.rigid {
                "of w"
            } else {
                "summed over v and w"
            },
            t.postprocess,
            (self.estimate.as_ref()).map_or(String::new(), |_| format!(", estimate {:.3}", t.estimate)),
            t.write,
            match crate::parallel::threads() {
                1 => "1 thread".to_string(),
                n => format!("{n} threads"),
            },
            crate::pages::peak_resident_bytes()
                .map_or(String::new(), |b| format!(", peak memory {} MB", b >> 20))
        )
    }
}

impl Run<'_> {
    /// S_h, on which λ_h and t_ih live.
    pub fn dual(&self) -> DualMesh<'_> {
        DualMesh::new(&self.problem.mesh, &self.edges)
    }

    /// Whether u_h is the exact solution to round-off (a solution exact in P1): its energy error,
    /// or without an exact solution η, is within what the round-off of u_h's values makes of it.
    pub fn at_round_off(&self) -> bool {
        match (
            self.errors.as_ref().filter(|e| e.energy.is_some()),
            &self.estimate,
        ) {
            (Some(e), _) => e.at_round_off(),
            (None, Some(e)) => {
                e.total <= crate::norms::RoundOff::of(&self.problem, &self.solution, &self.action).energy
            }
            (None, None) => false,
        }
    }

    /// η / |||u − u_h|||, when both are known and the error is not round-off.
    pub fn effectivity(&self) -> Option<f64> {
        let error = self.errors.as_ref()?.resolved_energy()?;
        Some(self.estimate.as_ref()?.total / error)
    }
}

impl Describe for Run<'_> {
    fn fields(&self) -> Vec<Field<'_>> {
        let mut fields = self.solution.fields();
        fields.extend(result::group_field(&self.problem.mesh));
        fields.extend(self.action.fields());
        if self.writes_dual {
            fields.extend(self.dual_fields());
        }
        if let Some(exact) = &self.case.exact {
            fields.extend(exact.fields(&self.problem.mesh));
        }
        if let Some(flux) = &self.flux {
            fields.extend(flux.fields(&self.dual()));
        }
        fields.extend(self.estimate.iter().flat_map(Describe::fields));
        fields
    }

    fn attributes(&self) -> Vec<Attribute> {
        let mesh = &self.problem.mesh;
        let mut attrs = self.case.attributes();
        attrs.extend([
            ("vertices", mesh.n_vertices().into()),
            ("triangles", mesh.n_triangles().into()),
            ("h", mesh.h().into()),
        ]);
        attrs.extend(result::group_attributes(mesh));
        attrs.extend(self.solution.attributes());
        attrs.extend(self.action.attributes());
        attrs.extend(self.errors.iter().flat_map(Describe::attributes));
        attrs.extend(self.flux.iter().flat_map(Describe::attributes));
        attrs.extend(self.estimate.iter().flat_map(Describe::attributes));
        attrs.extend(self.effectivity().map(|x| ("effectivity", x.into())));
        attrs.extend(self.timings.attributes());
        // The summary as the run printed it, for a reader of the file (the times are above).
        attrs.push(("summary", Attr::Text(self.case_line() + &self.figures(false))));
        attrs
    }
}

/// A finished run's result, owned ([`Run::parts`]).
pub struct Parts {
    /// T_h.
    pub mesh: Mesh,
    /// Its edges, which with T_h are S_h.
    pub edges: Edges,
    /// The fields of the result files ([`Describe::fields`] of the run).
    pub fields: Vec<Field<'static>>,
    /// Their attributes.
    pub attributes: Vec<Attribute>,
    /// The summary ([`Run::summary`]; its write time 0).
    pub summary: String,
    /// The files the case read, which writing must not replace.
    pub inputs: Vec<PathBuf>,
    /// Whether the result holds S_h.
    pub writes_dual: bool,
}

impl Parts {
    /// Writes the result directory `target` whole, as [`solve`] does.
    pub fn write(&self, target: &Path) -> Result<(), RunError> {
        let staging = Staging::new(target, &self.inputs, "solution")?;
        let dual = self.writes_dual.then(|| DualMesh::new(&self.mesh, &self.edges));
        write_staged(
            staging,
            &self.inputs,
            &self.mesh,
            dual.as_ref(),
            &self.fields,
            &self.attributes,
        )
    }
}

/// Writes a result into `staging` and puts it in place.
fn write_staged(
    staging: Staging,
    inputs: &[PathBuf],
    mesh: &Mesh,
    dual: Option<&DualMesh>,
    fields: &[Field],
    attributes: &[Attribute],
) -> Result<(), RunError> {
    progress::phase(|| format!("writing {}", staging.target().display()));
    result::write(staging.path(), mesh, dual, fields, attributes)
        .map_err(|e| OutputError(format!("{}: {e}", staging.target().display())))?;
    staging.commit(inputs)?;
    Ok(())
}

/// Wall-clock seconds of the phases outside the contact solve (whose own are in its statistics).
#[derive(Debug, Clone, Default)]
pub struct Timings {
    /// Building or reading the mesh (and the coarser meshes of nested iteration).
    pub mesh: f64,
    /// Assembling (3.4).
    pub assembly: f64,
    /// The action, its checks, the errors and the flux.
    pub postprocess: f64,
    /// The estimator.
    pub estimate: f64,
    /// Writing the result.
    pub write: f64,
}

impl Describe for Timings {
    fn attributes(&self) -> Vec<Attribute> {
        vec![
            ("seconds_mesh", self.mesh.into()),
            ("seconds_assembly", self.assembly.into()),
            ("seconds_postprocess", self.postprocess.into()),
            ("seconds_estimate", self.estimate.into()),
        ]
    }
}

/// Seconds since the last lap.
struct Clock(Instant);

impl Clock {
    fn lap(&mut self) -> f64 {
        let seconds = self.0.elapsed().as_secs_f64();
        self.0 = Instant::now();
        seconds
    }
}

/// Anything that stops a run, with a message naming the cause. The numerical failures know
/// neither file nor key: they carry the case's origin (its file, or the built-in default case),
/// and their messages start with it, as those of [`CaseError`] do.
#[derive(Debug)]
pub enum RunError {
    /// The case or its data.
    Case(CaseError),
    /// The solver, on the case of the origin given.
    Solve(String, SolveError),
    /// The solution's own checks, on the case of the origin given.
    Check(String, CheckError),
    /// The result directory.
    Output(OutputError),
}

impl RunError {
    /// The error of writing into `staging`, its files named in the result's place.
    pub fn in_target(self, staging: &crate::atomic::Staging) -> Self {
        match self {
            RunError::Output(e) => RunError::Output(staging.named(e)),
            e => e,
        }
    }
}

impl fmt::Display for RunError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            RunError::Case(e) => write!(f, "{e}"),
            RunError::Solve(origin, e) => write!(f, "{origin}: {e}"),
            RunError::Check(origin, e) => write!(f, "{origin}: {e}"),
            RunError::Output(e) => write!(f, "{e}"),
        }
    }
}

impl std::error::Error for RunError {}

impl From<CaseError> for RunError {
    fn from(e: CaseError) -> Self {
        RunError::Case(e)
    }
}
impl From<OutputError> for RunError {
    fn from(e: OutputError) -> Self {
        RunError::Output(e)
    }
}
