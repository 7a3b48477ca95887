//! One run: case → mesh → discrete problem → solution → action → errors → result file.

use crate::action::{Action, DualMesh};
use crate::case::{Case, CaseError};
use crate::contact::{self, DiscreteProblem, Guess, Solution, SolveError};
use crate::flux::Flux;
use crate::io::{self, Attr, Field, Grid, IoError};
use crate::mesh::Prolongation;
use crate::norms::Errors;
use std::fmt;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// Anything that stops a run, with a message naming the cause.
#[derive(Debug)]
pub enum RunError {
    Case(CaseError),
    Solve(SolveError),
    Io(IoError),
}

impl fmt::Display for RunError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            RunError::Case(e) => write!(f, "{e}"),
            RunError::Solve(e) => write!(f, "{e}"),
            RunError::Io(e) => write!(f, "{e}"),
        }
    }
}

impl std::error::Error for RunError {}

impl From<CaseError> for RunError {
    fn from(e: CaseError) -> Self {
        RunError::Case(e)
    }
}
impl From<SolveError> for RunError {
    fn from(e: SolveError) -> Self {
        RunError::Solve(e)
    }
}
impl From<IoError> for RunError {
    fn from(e: IoError) -> Self {
        RunError::Io(e)
    }
}

/// A datum that fails on the mesh (g < 0 on ∂ω, a non-finite load), named with its case.
fn data_error(case: &Case, e: SolveError) -> RunError {
    RunError::Case(CaseError(format!("{}: {e}", case.origin)))
}

/// Wall-clock seconds of each phase.
#[derive(Debug, Clone, Default)]
pub struct Timings {
    pub mesh: f64,
    pub assembly: f64,
    /// The contact solve proper: symbolic analysis, the v solve on one thread, the coarser levels
    /// of nested iteration and the active-set iterations for w on the other.
    pub contact_solve: f64,
    /// The coarser levels of nested iteration (all their phases), part of the contact solve.
    pub coarse: f64,
    /// Symbolic analysis on the final mesh.
    pub symbolic: f64,
    /// Numeric factorizations and triangular solves on the final mesh, summed over the two
    /// threads (v and w).
    pub numeric: f64,
    pub solve: f64,
    pub postprocess: f64,
    pub write: f64,
}

/// The result of one run.
pub struct Run {
    pub problem: DiscreteProblem,
    pub solution: Solution,
    pub action: Action,
    pub errors: Option<Errors>,
    pub timings: Timings,
    /// Active-set iterations on each coarser level of the nested iteration.
    pub coarse_iterations: Vec<usize>,
    /// The flux reconstructions t_1h, t_2h (4.13) with the relative defect of their local
    /// conservation, when asked for ([`Run::compute_flux`]).
    pub flux: Option<[(Flux, f64); 2]>,
}

/// How a run starts its active-set method.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Start {
    /// From no contact.
    Cold,
    /// Nested iteration: solve on built-in meshes with ⌈n/2⌉, ⌈n/4⌉, … cells (down to `COARSEST`)
    /// first, each warm-starting the next (grid sequencing).
    Nested,
}

/// Coarsest level of the nested iteration, in cells per side.
pub const COARSEST: usize = 8;

/// Solves a case.
pub fn solve(
    case: &Case,
    start: Start,
    warm: Option<(&crate::mesh::Mesh, &Solution)>,
) -> Result<Run, RunError> {
    case.check_memory()?;
    let mut timings = Timings::default();
    let t = Instant::now();
    let mesh = case.mesh()?;
    timings.mesh = t.elapsed().as_secs_f64();
    let problem = DiscreteProblem::new(mesh, &case.data).map_err(|e| data_error(case, e))?;
    timings.assembly = problem.setup_seconds;
    let mut coarse_iterations = Vec::new();
    let guess = || -> Result<Option<Guess>, RunError> {
        let t = Instant::now();
        let guess = match (start, case.cells(), warm) {
            (_, _, Some((m, s))) => Some(Guess::interpolate(
                &problem.mesh,
                m,
                &s.obstacle.gap,
                &s.obstacle.multiplier,
            )),
            (Start::Nested, Some(n), None) => nested_guess(case, n, &problem, &mut coarse_iterations)?,
            _ => None,
        };
        timings.coarse = t.elapsed().as_secs_f64();
        Ok(guess)
    };
    let solution = contact::solve(&problem, guess, case.options)?;
    timings.symbolic = solution.obstacle.stats.symbolic_seconds;
    timings.numeric = solution.obstacle.stats.numeric_seconds;
    timings.solve = solution.obstacle.stats.solve_seconds;
    timings.contact_solve = solution.obstacle.stats.wall_seconds;

    let t = Instant::now();
    let action = Action::compute(&problem, &solution);
    let errors = case
        .exact
        .as_ref()
        .map(|e| Errors::compute(&problem, &solution, &action, e));
    timings.postprocess = t.elapsed().as_secs_f64();
    Ok(Run {
        problem,
        solution,
        action,
        errors,
        timings,
        coarse_iterations,
        flux: None,
    })
}

/// Nested iteration: the obstacle problem on built-in meshes with ⌈n/2⌉, ⌈n/4⌉, … cells (down
/// to `COARSEST`), each level warm-started from the one below and its loads restricted from the one
/// above; the last one prolonged onto `fine` is the guess.
fn nested_guess(
    case: &Case,
    n: usize,
    fine: &DiscreteProblem,
    iterations: &mut Vec<usize>,
) -> Result<Option<Guess>, RunError> {
    // levels[k] and the prolongation from it to the next finer level (levels[k-1], or `fine`).
    let mut levels: Vec<(DiscreteProblem, Prolongation)> = Vec::new();
    let mut cells = n.div_ceil(2);
    while cells >= COARSEST {
        let finer = levels.last().map_or(fine, |(p, _)| p);
        let mut coarse_case = case.clone();
        coarse_case.set_cells(cells);
        let mesh = coarse_case.mesh()?;
        let p = Prolongation::new(&finer.mesh, &mesh);
        let problem =
            DiscreteProblem::restricted(mesh, &case.data, finer, &p).map_err(|e| data_error(case, e))?;
        levels.push((problem, p));
        cells = cells.div_ceil(2);
    }
    let mut guess = None;
    for (problem, p) in levels.iter().rev() {
        let o = contact::solve_obstacle(problem, guess.as_ref(), case.options)?;
        iterations.push(o.stats.iterations);
        guess = Some(Guess::prolong(p, &o.gap, &o.multiplier));
    }
    Ok(guess)
}

impl Run {
    /// Adds ‖λ − λ_h‖_H⁻¹ to the errors (a solve on the dual submesh, about 6N unknowns).
    pub fn compute_h_minus_1(&mut self, case: &Case) {
        if let (Some(errors), Some(exact)) = (&mut self.errors, &case.exact) {
            errors.h_minus_1_lambda =
                crate::norms::h_minus_1_lambda(&self.problem.mesh, &self.action, &exact.lambda);
        }
    }

    /// Reconstructs t_1h and t_2h (4.13) on S_h and checks their local conservation at every
    /// interior vertex: ∫_{D_a} div t_1h = (f1, φ_a) + λ_a m_a and ∫_{D_a} div t_2h = (f2, φ_a) −
    /// λ_a m_a (Lemma 17), the defect relative to the largest term summed.
    pub fn compute_flux(&mut self) {
        let p = &self.problem;
        let mesh = &p.mesh;
        let dual = DualMesh::new(mesh);
        let lambda = &self.action.lambda;
        let membranes = [
            (&self.solution.u1, p.mu1, &p.load1, 1.0),
            (&self.solution.u2, p.mu2, &p.load2, -1.0),
        ];
        self.flux = Some(membranes.map(|(u, mu, load, sign)| {
            let flux = Flux::reconstruct(mesh, &dual, u, mu);
            let total = flux.over_dual_cells(mesh, &dual);
            let (mut defect, mut scale) = (0.0_f64, f64::MIN_POSITIVE);
            for a in (0..mesh.n_vertices()).filter(|&a| !mesh.on_boundary[a]) {
                let action = sign * lambda[a] * p.mass[a];
                defect = defect.max((total[a] - load[a] - action).abs());
                // The terms of μ ∫∇u_h·∇φ_a cancel down to O(h²): round-off is relative to them.
                let terms: f64 = p.stiffness.row(a).map(|(b, k)| (mu * k * u[b]).abs()).sum();
                scale = scale.max(load[a].abs()).max(action.abs()).max(terms);
            }
            (flux, defect / scale)
        }));
    }

    /// Writes the result file and its XDMF sidecars; returns the XDMF paths.
    pub fn write(&mut self, case: &Case, h5_path: &Path) -> Result<Vec<PathBuf>, RunError> {
        let t = Instant::now();
        let mesh = &self.problem.mesh;
        let s = &self.solution;
        let contact: Vec<f64> = s
            .obstacle
            .contact
            .iter()
            .map(|&c| f64::from(u8::from(c)))
            .collect();
        let dual = DualMesh::new(mesh);
        let dual_lambda = dual.cell_field(mesh, &self.action.lambda);
        let owner: Vec<f64> = dual.owner.iter().map(|&a| a as f64).collect();
        // With the flux: t_ih at the cell centroids and div t_ih, as cell data of S_h.
        let mut flux_fields: Vec<(&str, Vec<f64>)> = Vec::new();
        for ((flux, _), names) in self
            .flux
            .iter()
            .flatten()
            .zip([["t1_x", "t1_y", "div_t1"], ["t2_x", "t2_y", "div_t2"]])
        {
            let t = flux.at_centroids(&dual);
            flux_fields.push((names[0], t.iter().map(|v| v[0]).collect()));
            flux_fields.push((names[1], t.iter().map(|v| v[1]).collect()));
            flux_fields.push((names[2], flux.divergence(&dual)));
        }
        let mut point_fields = vec![
            Field {
                name: "u1",
                values: &s.u1,
            },
            Field {
                name: "u2",
                values: &s.u2,
            },
            Field {
                name: "gap",
                values: &s.obstacle.gap,
            },
            Field {
                name: "lambda",
                values: &self.action.lambda,
            },
            Field {
                name: "lambda2",
                values: &self.action.lambda2,
            },
            Field {
                name: "contact",
                values: &contact,
            },
        ];
        let exact_fields: Vec<(String, Vec<f64>)> = match &case.exact {
            Some(e) => [
                ("u1_exact", &e.u1),
                ("u2_exact", &e.u2),
                ("lambda_exact", &e.lambda),
            ]
            .iter()
            .map(|(n, ex)| {
                (
                    n.to_string(),
                    mesh.points.iter().map(|p| ex.eval(p[0], p[1])).collect(),
                )
            })
            .collect(),
            None => Vec::new(),
        };
        point_fields.extend(exact_fields.iter().map(|(n, v)| Field { name: n, values: v }));
        let grids = [
            Grid {
                name: "mesh",
                points: &mesh.points,
                triangles: &mesh.triangles,
                point_fields,
                cell_fields: vec![],
            },
            Grid {
                name: "dual",
                points: &dual.points,
                triangles: &dual.triangles,
                point_fields: vec![],
                cell_fields: vec![
                    Field {
                        name: "lambda",
                        values: &dual_lambda,
                    },
                    Field {
                        name: "vertex",
                        values: &owner,
                    },
                ]
                .into_iter()
                .chain(flux_fields.iter().map(|(n, v)| Field { name: n, values: v }))
                .collect(),
            },
        ];
        let st = &s.obstacle.stats;
        let a = &self.action;
        let tm = &self.timings;
        let mut attrs: Vec<(&str, Attr)> = vec![
            (
                "program",
                Attr::Text(format!("membrane-contact {}", env!("CARGO_PKG_VERSION"))),
            ),
            ("case_origin", Attr::Text(case.origin.clone())),
            ("case_text", Attr::Text(case.text.clone())),
            ("title", Attr::Text(case.file.title.clone())),
            ("mu1", Attr::Float(case.data.mu1)),
            ("mu2", Attr::Float(case.data.mu2)),
            ("quadrature_degree", Attr::Int(case.data.quadrature.degree as i64)),
            ("vertices", Attr::Int(mesh.n_vertices() as i64)),
            ("triangles", Attr::Int(mesh.triangles.len() as i64)),
            ("h", Attr::Float(mesh.h())),
            ("iterations", Attr::Int(st.iterations as i64)),
            (
                "coarse_iterations",
                Attr::Floats(self.coarse_iterations.iter().map(|&i| i as f64).collect()),
            ),
            (
                "active_set_sizes",
                Attr::Floats(st.active_sizes.iter().map(|&i| i as f64).collect()),
            ),
            ("factorizations", Attr::Int(st.factorizations as i64)),
            ("local_iterations", Attr::Int(st.local_iterations as i64)),
            ("symbolic_analyses", Attr::Int(st.analyses as i64)),
            ("seconds_local", Attr::Float(st.local_seconds)),
            ("factor_nnz", Attr::Int(st.factor_nnz as i64)),
            ("max_lambda1_minus_lambda2", Attr::Float(a.membrane_difference)),
            ("min_lambda", Attr::Float(a.min_lambda)),
            ("max_lambda_times_gap", Attr::Float(a.complementarity)),
            (
                "min_gap",
                Attr::Float(s.obstacle.gap.iter().copied().fold(f64::INFINITY, f64::min)),
            ),
            ("total_force", Attr::Float(a.total)),
            ("contact_area", Attr::Float(a.contact_area)),
            ("seconds_mesh", Attr::Float(tm.mesh)),
            ("seconds_assembly", Attr::Float(tm.assembly)),
            ("seconds_coarse_levels", Attr::Float(tm.coarse)),
            ("seconds_symbolic", Attr::Float(tm.symbolic)),
            ("seconds_numeric", Attr::Float(tm.numeric)),
            ("seconds_solve", Attr::Float(tm.solve)),
            ("seconds_contact_solve", Attr::Float(tm.contact_solve)),
            ("seconds_postprocess", Attr::Float(tm.postprocess)),
        ];
        if let Some(e) = &self.errors {
            attrs.extend([
                ("error_l2_u1", Attr::Float(e.l2_u1)),
                ("error_l2_u2", Attr::Float(e.l2_u2)),
                ("error_h1_u1", Attr::Float(e.h1_u1)),
                ("error_h1_u2", Attr::Float(e.h1_u2)),
                ("error_energy", Attr::Float(e.energy)),
                ("error_l2_lambda", Attr::Float(e.l2_lambda)),
            ]);
            if e.h_minus_1_lambda.is_finite() {
                attrs.push(("error_hm1_lambda", Attr::Float(e.h_minus_1_lambda)));
            }
        }
        if let Some([(_, d1), (_, d2)]) = &self.flux {
            attrs.extend([
                ("flux_conservation_1", Attr::Float(*d1)),
                ("flux_conservation_2", Attr::Float(*d2)),
            ]);
        }
        let xdmf = io::write_result(h5_path, &grids, &attrs)?;
        self.timings.write = t.elapsed().as_secs_f64();
        Ok(xdmf)
    }

    /// A short human-readable summary.
    pub fn summary(&self) -> String {
        let m = &self.problem.mesh;
        let s = &self.solution.obstacle.stats;
        let a = &self.action;
        let t = &self.timings;
        let lmax = a.lambda.iter().copied().fold(0.0, f64::max);
        let mut out = format!(
            "mesh        {} vertices, {} triangles, h = {:.4e}, {} unknowns per membrane\n\
             solver      {} active-set iterations + {} local ones (coarse levels: {:?}), {} factorizations, contact at {} vertices\n\
             action      ∫λ_h = {:.6e}, contact area = {:.6e}, max λ = {:.6e}\n\
             checks      max|λ1−λ2| = {:.2e} (Prop. 12), min λ = {:.2e}, max|λ·(u1−u2)| = {:.2e} (4.8), min(u1−u2) = {:.2e}\n",
            m.n_vertices(),
            m.triangles.len(),
            m.h(),
            s.unknowns,
            s.iterations,
            s.local_iterations,
            self.coarse_iterations,
            s.factorizations,
            s.active_sizes.last().copied().unwrap_or(0),
            a.total,
            a.contact_area,
            lmax,
            a.membrane_difference,
            a.min_lambda,
            a.complementarity,
            self.solution.obstacle.gap.iter().copied().fold(f64::INFINITY, f64::min),
        );
        if let Some(e) = &self.errors {
            out += &format!(
                "errors      |u1−u1h|_H1 = {:.4e}, |u2−u2h|_H1 = {:.4e}, ‖u1−u1h‖_L2 = {:.4e}, ‖u2−u2h‖_L2 = {:.4e}, ‖λ−λh‖_L2 = {:.4e}\n",
                e.h1_u1, e.h1_u2, e.l2_u1, e.l2_u2, e.l2_lambda
            );
        }
        if let Some([(_, d1), (_, d2)]) = &self.flux {
            out += &format!(
                "flux        t1h, t2h on S_h (4.13); local conservation on the D_a (Lemma 17): relative defect {d1:.2e}, {d2:.2e}\n"
            );
        }
        out += &format!(
            "seconds     mesh {:.3}, assembly {:.3}, contact solve {:.3} (coarse levels {:.3}, symbolic {:.3}, \
             numeric {:.3} + solves {:.3} summed over v and w), postprocess {:.3}, write {:.3}\n",
            t.mesh, t.assembly, t.contact_solve, t.coarse, t.symbolic, t.numeric, t.solve, t.postprocess, t.write
        );
        out
    }
}
