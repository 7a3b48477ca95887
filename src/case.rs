//! Case files (TOML): the data of (1.1), the mesh, the quadrature and the solver settings.
//! The format is documented in `data/cases/README.md`. Every error names the file and the key.

use crate::assembly::Quadrature;
use crate::contact::{LinearSolver, SolverOptions};
use crate::datum::Datum;
use crate::expr::{Expr, ExprError, Names};
use crate::mesh::{self, Curves, Diagonal, Domain, Mesh, MeshError, Point, Postprocess};
use crate::norms::Exact;
use crate::problem::{self, Data, Lower};
use crate::result::{Attr, Attribute, Describe};
use serde::Deserialize;
use std::io::Read;
use std::path::{Path, PathBuf};

/// The built-in default case (`membrane-contact solve` without a case file).
pub const DEFAULT_CASE: &str = include_str!("../data/cases/default.toml");

/// The largest case file read.
const MAX_CASE_BYTES: u64 = 1 << 20;

/// The round-off, relative to the values' size (at least 1), within which an exact solution may
/// miss λ ≥ 0 and u1 ≥ u2.
const EXACT_ROUND_OFF: f64 = 1e-12;

/// The fewest vertices of a generated coarser level of nested iteration.
const COARSEST_VERTICES: usize = 20;

/// Coarsest level of nested iteration on built-in meshes, in cells per side.
pub const COARSEST: usize = 8;

/// A case as written in the file (expressions still as text).
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
struct CaseFile {
    #[serde(default)]
    title: String,
    /// "membranes" (the default) or "obstacle".
    #[serde(default)]
    problem: Option<String>,
    mu1: Option<f64>,
    mu2: Option<f64>,
    f1: Option<Expression>,
    f2: Option<Expression>,
    g: Expression,
    g2: Option<Expression>,
    mu: Option<f64>,
    f: Option<Expression>,
    psi: Option<Expression>,
    /// Named values usable in every expression, in file order (toml's `preserve_order`).
    #[serde(default, rename = "let")]
    names: toml::Table,
    #[serde(default)]
    exact: Option<ExactFile>,
    mesh: MeshTable,
    #[serde(default)]
    quadrature: QuadratureTable,
    #[serde(default)]
    solver: SolverTable,
    #[serde(default)]
    validation: Option<ValidationTable>,
    #[serde(default)]
    adapt: AdaptTable,
}

/// An expression: a string in the case language, or a plain number; for the data that may be
/// given per physical group (f1, f2, f, psi per surface, g, g2 per curve), a table of them keyed
/// by the groups' names.
#[derive(Debug, Clone, Deserialize)]
#[serde(
    untagged,
    expecting = "expected an expression: a string such as \"sin(pi*x)\", a number, or a table of them per physical group"
)]
enum Expression {
    Number(f64),
    Text(String),
    Table(toml::Table),
}

/// The keys whose values may be tables per physical group.
const PER_GROUP: &str = "f1, f2, f and psi (per physical surface), g and g2 (per physical curve)";

#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
struct ExactFile {
    u1: Option<Expression>,
    u2: Option<Expression>,
    u: Option<Expression>,
    lambda: Expression,
    #[serde(default)]
    grad_u1: Option<Vec<Expression>>,
    #[serde(default)]
    grad_u2: Option<Vec<Expression>>,
    #[serde(default)]
    grad_u: Option<Vec<Expression>>,
}

/// The problems a case may state, and the keys of each (beside `g` and the tables).
const PROBLEMS: [(&str, &[&str]); 2] = [
    ("membranes", &["mu1", "mu2", "f1", "f2", "g2"]),
    ("obstacle", &["mu", "f", "psi"]),
];

/// The `[mesh]` table: every key of every kind, so that errors point at the key; which keys a
/// kind takes is checked after.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
struct MeshTable {
    kind: String,
    corners: Option<Vec<Vec<f64>>>,
    n: Option<Cells>,
    diagonal: Option<Diagonal>,
    grading: Option<f64>,
    path: Option<PathBuf>,
    boundary: Option<Vec<Vec<f64>>>,
    holes: Option<Vec<Vec<Vec<f64>>>>,
    centre: Option<Vec<f64>>,
    /// The spelling of Gmsh, VTK and ParaView, accepted for `centre`.
    center: Option<Vec<f64>>,
    radius: Option<f64>,
    inner_radius: Option<f64>,
    h: Option<f64>,
    refine: Option<usize>,
}

/// `n = 8` or `n = [8, 4]`.
#[derive(Debug, Clone, Copy, Deserialize)]
#[serde(
    untagged,
    expecting = "expected the cells per side: a whole number, n = 64, or two, n = [64, 32]"
)]
enum Cells {
    Square(usize),
    Sides([usize; 2]),
}

#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
struct QuadratureTable {
    degree: usize,
}

impl Default for QuadratureTable {
    fn default() -> Self {
        QuadratureTable { degree: 4 }
    }
}

#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
struct SolverTable {
    #[serde(default = "default_max_iterations")]
    max_iterations: usize,
    #[serde(default)]
    linear: Option<String>,
}

fn default_max_iterations() -> usize {
    SolverOptions::default().max_iterations
}

impl Default for SolverTable {
    fn default() -> Self {
        SolverTable {
            max_iterations: default_max_iterations(),
            linear: None,
        }
    }
}

#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
struct ValidationTable {
    sizes: Option<Vec<usize>>,
    refine: Option<Vec<usize>>,
}

/// The mesh of a case.
#[derive(Debug, Clone, PartialEq)]
pub enum MeshSpec {
    /// [x0, x1] × [y0, y1] with nx × ny cells.
    Rectangle {
        /// [[x0, y0], [x1, y1]].
        corners: [[f64; 2]; 2],
        /// [nx, ny].
        n: [usize; 2],
        /// The diagonal of each cell.
        diagonal: Diagonal,
    },
    /// (−1, 1)² \ [0, 1] × [−1, 0] with n × n cells on the square, graded by `grading` ≥ 1.
    Lshape {
        /// Cells per side of the square.
        n: usize,
        /// The diagonal of each cell.
        diagonal: Diagonal,
        /// The grading exponent (Remark 10).
        grading: f64,
    },
    /// A polygon with holes, a disk or an annulus, meshed to the size h.
    Domain {
        /// The domain.
        domain: Domain,
        /// The mesh size: boundary vertices at most h apart, triangles no larger than the
        /// equilateral triangle of side h.
        h: f64,
    },
    /// A triangle mesh file (the path as given, relative to the case file).
    File {
        /// The path.
        path: PathBuf,
    },
    /// A mesh given in memory ([`Case::set_mesh`], the Python package's `mesh=`): solved on as a
    /// file mesh is, in its own vertex numbering.
    Given {
        /// The mesh.
        mesh: std::sync::Arc<Mesh>,
    },
}

/// The levels of a study or a validation: cells per side of a built-in mesh, or numbers of
/// uniform refinements of the case's mesh (any kind).
#[derive(Debug, Clone, PartialEq)]
pub enum Levels {
    /// Cells per side (`--levels`, `[validation] sizes`).
    Cells(Vec<usize>),
    /// Refinements (`--refine`, `[validation] refine`).
    Refine(Vec<usize>),
}

message_error!(
    /// A case error, naming the file and the key.
    CaseError
);

/// The `[adapt]` table: the settings of `membrane-contact adapt`.
#[derive(Debug, Clone, Default, Deserialize)]
#[serde(deny_unknown_fields)]
struct AdaptTable {
    theta: Option<f64>,
    target: Option<f64>,
    max_vertices: Option<usize>,
    steps: Option<usize>,
}

/// The settings of adaptive refinement (solve → estimate → mark → refine → …).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Adaptivity {
    /// Dörfler's bulk parameter θ ∈ (0, 1]: the marked triangles carry at least θ of Σ η_K².
    pub theta: f64,
    /// Stop once η ≤ target.
    pub target: Option<f64>,
    /// Stop before a mesh with more vertices than this.
    pub max_vertices: usize,
    /// Stop after this many refinements.
    pub steps: usize,
}

impl Default for Adaptivity {
    fn default() -> Self {
        Adaptivity {
            theta: 0.7,
            target: None,
            max_vertices: 100_000,
            steps: 40,
        }
    }
}

impl Adaptivity {
    /// Checks the settings; `key` names each as the user gave it (a case key or a CLI option).
    pub fn check(&self, key: impl Fn(&str) -> String) -> Result<(), String> {
        if !(self.theta > 0.0 && self.theta <= 1.0) {
            return Err(format!("{} = {}: θ must lie in (0, 1]", key("theta"), self.theta));
        }
        if let Some(t) = self.target.filter(|t| !(*t > 0.0 && t.is_finite())) {
            return Err(format!(
                "{} = {t}: the target estimate must be a positive number",
                key("target")
            ));
        }
        if self.max_vertices == 0 {
            return Err(format!("{} must be positive", key("max_vertices")));
        }
        if self.steps == 0 {
            return Err(format!("{} must be at least 1", key("steps")));
        }
        Ok(())
    }
}

/// A checked case: parsed expressions and settings.
#[derive(Debug, Clone)]
pub struct Case {
    /// Where it came from (a path, or "built-in default case").
    pub origin: String,
    /// The case text, stored in every result file.
    pub text: String,
    /// The title, free text.
    pub title: String,
    /// The data of (1.1).
    pub data: Data,
    /// The exact solution, when known.
    pub exact: Option<Exact>,
    /// The mesh.
    pub mesh: MeshSpec,
    /// The settings of the active-set method.
    pub solver: SolverOptions,
    /// Uniform refinements of the given mesh (`[mesh] refine`): the mesh solved on is the given
    /// one refined this many times, and the coarser ones are the levels of nested iteration.
    pub refine: usize,
    /// The levels of `make validate` and studies, when the case names them.
    pub validation: Option<Levels>,
    /// The settings of `adapt`.
    pub adapt: Adaptivity,
    /// The case file, when read from one.
    path: Option<PathBuf>,
    base_dir: PathBuf,
}

impl Case {
    /// Reads and checks a case file.
    ///
    /// ```
    /// let case = membrane_contact::case::Case::read(std::path::Path::new("data/cases/disk_jump.toml")).unwrap();
    /// assert!(case.exact.is_some());
    /// ```
    pub fn read(path: &Path) -> Result<Case, CaseError> {
        Case::parse_file(&Case::read_text(path)?, path)
    }

    /// Parses and checks `text`, read from the case file `path` (which names it in errors,
    /// resolves its mesh paths and is an input of its runs).
    pub fn parse_file(text: &str, path: &Path) -> Result<Case, CaseError> {
        let base = path.parent().map(Path::to_path_buf).unwrap_or_default();
        let mut case = Case::parse(text, &path.display().to_string(), base)?;
        case.path = Some(path.to_path_buf());
        Ok(case)
    }

    /// The text of a case file: UTF-8, at most 1 MiB.
    pub fn read_text(path: &Path) -> Result<String, CaseError> {
        let err = |m: String| CaseError(format!("{}: {m}", path.display()));
        let cannot = |e: std::io::Error| err(format!("cannot read the case file: {e}"));
        let file = std::fs::File::open(path).map_err(cannot)?;
        let size = file.metadata().map_err(cannot)?.len();
        if size > MAX_CASE_BYTES {
            return Err(err(format!(
                "the case file has {size} bytes; at most {MAX_CASE_BYTES} are read"
            )));
        }
        // The size of a device or a pipe (/dev/stdin, /dev/zero) says nothing: what arrives counts.
        let mut bytes = Vec::new();
        file.take(MAX_CASE_BYTES + 1)
            .read_to_end(&mut bytes)
            .map_err(cannot)?;
        if bytes.len() as u64 > MAX_CASE_BYTES {
            return Err(err(format!(
                "the case file has more than {MAX_CASE_BYTES} bytes; at most {MAX_CASE_BYTES} are read"
            )));
        }
        String::from_utf8(bytes).map_err(|_| err("cannot read the case file: it is not UTF-8 text".into()))
    }

    /// The built-in default case.
    pub fn default_case() -> Case {
        Case::parse(DEFAULT_CASE, "built-in default case", PathBuf::new()).expect("the default case is valid")
    }

    /// Parses and checks case text; `origin` names it in errors, `base_dir` resolves mesh paths.
    pub fn parse(text: &str, origin: &str, base_dir: PathBuf) -> Result<Case, CaseError> {
        let err = |m: String| CaseError(format!("{origin}: {m}"));
        let file: CaseFile = toml::from_str(text).map_err(|e| err(toml_error(text, &e)))?;
        let names = let_names(&file.names).map_err(err)?;
        let parsed = |key: &str, e: &Expression| parse_expression(key, e, &names);
        let degree = file.quadrature.degree;
        if degree > Quadrature::MAX_DEGREE {
            return Err(err(format!(
                "key 'quadrature.degree' = {degree}: at most {} is available",
                Quadrature::MAX_DEGREE
            )));
        }
        if file.solver.max_iterations == 0 {
            return Err(err("key 'solver.max_iterations' must be at least 1".into()));
        }
        let linear = match file.solver.linear.as_deref() {
            None => LinearSolver::default(),
            Some(name) => LinearSolver::from_name(name).ok_or_else(|| {
                err(format!(
                    "key 'solver.linear' = \"{name}\": expected one of {}",
                    LinearSolver::NAMES.map(|n| format!("\"{n}\"")).join(", ")
                ))
            })?,
        };
        let data = problem_data(&file, &parsed, Quadrature { degree }).map_err(err)?;
        let exact = (file.exact.as_ref())
            .map(|e| exact_solution(e, &data, &parsed))
            .transpose()
            .map_err(err)?;
        let mesh = mesh_spec(&file.mesh).map_err(err)?;
        let validation = (file.validation.as_ref())
            .map(|v| validation_levels(v, &mesh))
            .transpose()
            .map_err(err)?;
        let defaults = Adaptivity::default();
        let adapt = Adaptivity {
            theta: file.adapt.theta.unwrap_or(defaults.theta),
            target: file.adapt.target,
            max_vertices: file.adapt.max_vertices.unwrap_or(defaults.max_vertices),
            steps: file.adapt.steps.unwrap_or(defaults.steps),
        };
        adapt.check(|k| format!("key 'adapt.{k}'")).map_err(err)?;
        Ok(Case {
            origin: origin.to_string(),
            text: text.to_string(),
            title: file.title,
            data,
            exact,
            mesh,
            solver: SolverOptions {
                max_iterations: file.solver.max_iterations,
                linear,
                ..Default::default()
            },
            refine: file.mesh.refine.unwrap_or(0),
            validation,
            adapt,
            path: None,
            base_dir,
        })
    }

    /// Sets the cells per side of a built-in mesh (of a rectangle, along the side with more cells in
    /// the case's n, the other side's in the case's proportion); an error for the other kinds.
    pub fn set_cells(&mut self, cells: usize) -> Result<(), CaseError> {
        match &mut self.mesh {
            _ if cells == 0 => Err(CaseError("the cells per side must be at least 1".into())),
            MeshSpec::Rectangle { n, .. } => {
                // The side with more cells gets `cells`, the other as many as keep the proportion.
                let long = n[0].max(n[1]) as f64;
                *n = n.map(|m| ((m as f64 * cells as f64 / long).round() as usize).max(1));
                Ok(())
            }
            MeshSpec::Lshape { .. } if cells % 2 == 1 => Err(CaseError(format!(
                "{}: {cells} cells per side: {EVEN_LSHAPE}",
                self.origin
            ))),
            MeshSpec::Lshape { n, .. } => {
                *n = cells;
                Ok(())
            }
            _ => Err(CaseError(format!(
                "{}: the cells per side apply to built-in meshes (kind = \"rectangle\" or \"lshape\"), \
                 not to {}: refine it instead (--refine K; in Python refine=K)",
                self.origin,
                self.kind_named()
            ))),
        }
    }

    /// Fails for what a run cannot yet compute on this problem: the estimator with a boundary
    /// value g2 of membrane 2 (its lifting of g2 − g2_h is not in docs/a-posteriori.md).
    pub fn check_options(&self, estimate: bool) -> Result<(), CaseError> {
        match &self.data.lower {
            Lower::Membrane { g2, .. } if estimate && g2.constant() != Some(0.0) => Err(CaseError(format!(
                "{}: the estimator (--estimate, adapt) takes u2 = 0 on ∂ω; with key 'g2' it is not \
                 available yet",
                self.origin
            ))),
            _ => Ok(()),
        }
    }

    /// The problem, as the key `problem` names it.
    pub fn problem_name(&self) -> &'static str {
        if self.data.is_obstacle() {
            "obstacle"
        } else {
            "membranes"
        }
    }

    /// The kind of the case's mesh, as the `[mesh]` table names it.
    pub fn kind(&self) -> &'static str {
        match &self.mesh {
            MeshSpec::Rectangle { .. } => "rectangle",
            MeshSpec::Lshape { .. } => "lshape",
            MeshSpec::Domain {
                domain: Domain::Polygon { .. },
                ..
            } => "polygon",
            MeshSpec::Domain { .. } => "disk",
            MeshSpec::File { .. } => "file",
            MeshSpec::Given { .. } => "given",
        }
    }

    /// The case's mesh as a message names it: `kind = "disk"`, or a mesh given as arrays.
    pub(crate) fn kind_named(&self) -> String {
        match self.mesh {
            MeshSpec::Given { .. } => "a mesh given as arrays".into(),
            _ => format!("kind = \"{}\"", self.kind()),
        }
    }

    /// Replaces the mesh the case's `[mesh]` table names by `mesh`, checked already
    /// ([`Mesh::new`]), as a mesh file of the same triangles would: it keeps its vertex
    /// numbering, the coarser levels of nested iteration are its domain meshed coarser, and the
    /// table's `refine` ([`Case::refine`]) refines it.
    pub fn set_mesh(&mut self, mesh: Mesh) {
        self.mesh = MeshSpec::Given {
            mesh: std::sync::Arc::new(mesh),
        };
    }

    /// Sets the grading exponent of an L-shaped mesh.
    pub fn set_grading(&mut self, g: f64) -> Result<(), CaseError> {
        match &mut self.mesh {
            MeshSpec::Lshape { grading, .. } if g >= 1.0 && g.is_finite() => {
                *grading = g;
                Ok(())
            }
            MeshSpec::Lshape { .. } => Err(CaseError(format!("grading {g}: need a number ≥ 1"))),
            _ => Err(CaseError(format!(
                "{}: grading applies to L-shaped meshes only",
                self.origin
            ))),
        }
    }

    /// Cells per side of a built-in mesh, after refinement.
    pub fn cells(&self) -> Option<usize> {
        match &self.mesh {
            MeshSpec::Rectangle { n, .. } => Some(self.refined_cells(n[0].max(n[1]))),
            MeshSpec::Lshape { n, .. } => Some(self.refined_cells(*n)),
            MeshSpec::Domain { .. } | MeshSpec::File { .. } | MeshSpec::Given { .. } => None,
        }
    }

    /// The cells along the shorter side of a built-in rectangle whose sides have different
    /// numbers of cells (after refinement); none otherwise.
    pub fn cells_across(&self) -> Option<usize> {
        match &self.mesh {
            MeshSpec::Rectangle { n, .. } if n[0] != n[1] => Some(self.refined_cells(n[0].min(n[1]))),
            _ => None,
        }
    }

    /// n cells along a side after the case's refinements (saturating).
    fn refined_cells(&self, n: usize) -> usize {
        n.saturating_mul(2usize.saturating_pow(u32::try_from(self.refine).unwrap_or(u32::MAX)))
    }

    /// The files the case reads: the case file, a mesh file and its heavy data.
    pub fn inputs(&self) -> Vec<PathBuf> {
        let mut files: Vec<PathBuf> = self.path.iter().cloned().collect();
        if let MeshSpec::File { path } = &self.mesh {
            files.extend(mesh::file::inputs(&self.base_dir.join(path)));
        }
        files
    }

    /// The mesh solved on: the given mesh refined `refine` times.
    pub fn mesh(&self) -> Result<Mesh, CaseError> {
        Ok(self.hierarchy(false, Postprocess::default())?.0)
    }

    /// The mesh solved on and, with `coarser`, the meshes of nested iteration below it, finest
    /// first. With `refine` = k ≥ 1 they are the given mesh refined k − 1, …, 0 times: the
    /// coarsest level is the given mesh, new boundary vertices lie on the curves of ∂ω. Otherwise
    /// they are the built-in meshes of ⌈n/2⌉, ⌈n/4⌉, … cells down to [`COARSEST`] below a
    /// built-in mesh of n cells per side. Generated and refined meshes, and built-in meshes with
    /// crossed diagonals (see `geometric`), are renumbered along a Z-order curve; the other
    /// built-in meshes and file meshes keep theirs. Below a disk, polygon or file mesh come, last,
    /// the domain meshed with 2h, 4h, … (not nested).
    /// The memory guard prices the solve and what the run computes `after` it.
    pub fn hierarchy(&self, coarser: bool, after: Postprocess) -> Result<(Mesh, Vec<Mesh>), CaseError> {
        let given = self.given_mesh(after)?;
        let generated = if coarser {
            self.coarser_generated(&given)
        } else {
            Vec::new()
        };
        let mut levels = vec![given];
        let curves = self.curves();
        for k in 1..=self.refine {
            let finer = (levels.last().expect("a level").refined(&curves)).map_err(|e| {
                CaseError(format!(
                    "{}: [mesh] refine = {}: level {k}: {e}",
                    self.origin, self.refine
                ))
            })?;
            levels.push(finer.renumbered());
        }
        let mesh = levels.pop().expect("the finest level");
        levels.reverse();
        let below = match (coarser, self.refine) {
            (false, _) => Vec::new(),
            (true, 0) => self.coarser_builtin()?,
            (true, _) => levels,
        };
        let coarser_meshes: Vec<Mesh> = below.into_iter().chain(generated).collect();
        // Without coarser levels, multigrid asked for is Cholesky: priced as such.
        if coarser && coarser_meshes.is_empty() {
            let price = self.price(LinearSolver::Direct, after);
            mesh::check_memory(mesh.n_vertices(), price).map_err(|e| {
                let why = "(a mesh without coarser levels is solved by Cholesky)";
                CaseError(format!("{}: {e} {why}", self.origin))
            })?;
        }
        Ok((mesh, coarser_meshes))
    }

    /// The curves of ∂ω, on which refinement places new boundary vertices.
    pub fn curves(&self) -> Curves {
        match &self.mesh {
            MeshSpec::Domain { domain, .. } => domain.curves(),
            _ => Curves::default(),
        }
    }

    /// The linear solver of the case's mesh: the one asked for, but Cholesky for a file mesh that
    /// is not refined. Its coarser levels, meshed from its boundary, are not nested in it: they
    /// give nested iteration its guess, but CG's iterations with V-cycles on them grow with
    /// refinement (on a Gmsh square, 17 to 46 from 12k to 400k vertices; 131 on an adapted
    /// L-shape read back), where Cholesky solves such meshes in less time.
    pub fn linear_solver(&self) -> LinearSolver {
        match self.mesh {
            MeshSpec::File { .. } | MeshSpec::Given { .. } if self.refine == 0 => LinearSolver::Direct,
            _ => self.solver.linear,
        }
    }

    /// The memory guard's peak per vertex: the larger of the linear solver's and that of what
    /// the run computes after the solve.
    fn bytes_per_vertex(&self, after: Postprocess) -> f64 {
        self.price(self.linear_solver(), after)
    }

    /// The memory guard's peak per vertex with the linear solver `linear`.
    pub(crate) fn price(&self, linear: LinearSolver, after: Postprocess) -> f64 {
        let solver = match linear {
            LinearSolver::Multigrid => mesh::MULTIGRID_BYTES_PER_VERTEX,
            LinearSolver::Direct => mesh::DIRECT_BYTES_PER_VERTEX,
        };
        solver.max(after.bytes_per_vertex())
    }

    /// Builds or reads the mesh before refinement, after checking that it fits in memory once
    /// refined (built-in meshes and domains before building them, files after reading them).
    fn given_mesh(&self, after: Postprocess) -> Result<Mesh, CaseError> {
        let err = |m: String| CaseError(format!("{}: {m}", self.origin));
        let refine = match self.refine {
            0 => String::new(),
            k => format!(", refine = {k}"),
        };
        let keys = match &self.mesh {
            MeshSpec::Rectangle { corners, n, .. } => {
                format!("[mesh] corners = {corners:?}, n = {n:?}{refine}")
            }
            MeshSpec::Lshape { n, grading, .. } => {
                format!("[mesh] n = {n}, grading = {}{refine}", mesh::Number(*grading))
            }
            MeshSpec::Domain { h, .. } => {
                format!(
                    "[mesh] kind = \"{}\", h = {}{refine}",
                    self.kind(),
                    mesh::Number(*h)
                )
            }
            MeshSpec::File { path } => {
                let mesh = mesh::file::read(&self.base_dir.join(path))
                    .map_err(|e| err(format!("[mesh] path: {e}")))?;
                let refined = mesh.n_vertices().saturating_mul(self.refinement_factor());
                mesh::check_memory(refined, self.bytes_per_vertex(after))
                    .map_err(|e| err(format!("{}{refine}: {e}", path.display())))?;
                return Ok(mesh);
            }
            MeshSpec::Given { mesh } => {
                let refined = mesh.n_vertices().saturating_mul(self.refinement_factor());
                mesh::check_memory(refined, self.bytes_per_vertex(after))
                    .map_err(|e| err(format!("the given mesh{refine}: {e}")))?;
                return Ok(Mesh::clone(mesh));
            }
        };
        if let MeshSpec::Domain { domain, h } = &self.mesh {
            domain.check_size(*h).map_err(|e| err(format!("[mesh] h: {e}")))?;
        }
        mesh::check_memory(self.estimated_vertices(), self.bytes_per_vertex(after))
            .map_err(|e| err(format!("{keys}: {e}")))?;
        // After the memory: 2³² refinements are too many vertices before they are too small.
        if let MeshSpec::Rectangle { corners, n, diagonal } = &self.mesh {
            rectangle_in_range(*corners, *n, *diagonal, self.refine)
                .map_err(|e| err(format!("{keys}: {e}")))?;
        }
        let built = match &self.mesh {
            MeshSpec::Rectangle { corners, n, diagonal } => {
                Mesh::rectangle(corners[0], corners[1], n[0], n[1], *diagonal)
                    .map(|m| geometric(m, *diagonal))
            }
            MeshSpec::Lshape { n, diagonal, grading } => {
                Mesh::l_shape(*n, *diagonal, *grading).map(|m| geometric(m, *diagonal))
            }
            MeshSpec::Domain { domain, h } => domain.mesh(*h).map(|m| m.renumbered()),
            MeshSpec::File { .. } | MeshSpec::Given { .. } => unreachable!("read above"),
        };
        let mesh = built.map_err(|e| match e {
            MeshError::Generation(_) => err(format!("{keys}: {e}")),
            e => err(format!("{keys}: the mesh is not valid: {e}")),
        })?;
        // A polygon's mesh exceeds the estimate where a narrow feature split its edges.
        let refined = mesh.n_vertices().saturating_mul(self.refinement_factor());
        mesh::check_memory(refined, self.bytes_per_vertex(after)).map_err(|e| err(format!("{keys}: {e}")))?;
        Ok(mesh)
    }

    /// Below a disk or polygon meshed with size h, or a file mesh: the domain (a file mesh's,
    /// [`Domain::of_mesh`]) meshed with 2h, 4h, …, coarsened to each size
    /// ([`Domain::coarsened`]), while each level has at most half the vertices of the one above,
    /// at least [`COARSEST_VERTICES`] and boundary data that (3.4) accepts: at most log₂ of
    /// `given`'s vertices levels, whatever the domain. They are not nested in it, which neither a guess nor multigrid needs (transfers
    /// locate each vertex; restricted loads are approximate).
    fn coarser_generated(&self, given: &Mesh) -> Vec<Mesh> {
        let (domain, h) = match &self.mesh {
            MeshSpec::Domain { domain, h } => (domain.clone(), *h),
            MeshSpec::File { .. } | MeshSpec::Given { .. } => match Domain::of_mesh(given) {
                Some(domain) => domain,
                None => return Vec::new(),
            },
            _ => return Vec::new(),
        };
        let mut meshes: Vec<Mesh> = Vec::new();
        let mut size = 2.0 * h;
        loop {
            let above = meshes.last().unwrap_or(given).n_vertices();
            let Ok(mesh) = domain.coarsened(size).mesh(size) else {
                break;
            };
            let n = mesh.n_vertices();
            if n < COARSEST_VERTICES || 2 * n > above || problem::boundary_values(&mesh, &self.data).is_err()
            {
                break;
            }
            meshes.push(mesh.renumbered());
            size *= 2.0;
        }
        meshes
    }

    /// The meshes of nested iteration below a built-in mesh of n cells per side (along its longer
    /// side): ⌈n/2⌉, ⌈n/4⌉, … cells in the same proportion, down to [`COARSEST`] along the longer
    /// side and 2 along the shorter; none for the other kinds.
    fn coarser_builtin(&self) -> Result<Vec<Mesh>, CaseError> {
        let Some(n) = self.cells() else {
            return Ok(Vec::new());
        };
        let mut meshes = Vec::new();
        let mut cells = n.div_ceil(2);
        while cells >= COARSEST {
            let mut coarse = self.clone();
            coarse.set_cells(cells)?;
            if matches!(coarse.mesh, MeshSpec::Rectangle { n, .. } if n[0].min(n[1]) < 2) {
                break;
            }
            meshes.push(coarse.mesh()?);
            cells = cells.div_ceil(2);
        }
        Ok(meshes)
    }

    /// Checks the data on `mesh`: g_h ≥ 0 and finite at its boundary vertices (only they enter
    /// (3.4)), and finite exact u1, u2, λ at every vertex. On a refined mesh the message says so:
    /// a vertex it names may be one the refinement added.
    pub fn check_on(&self, mesh: &Mesh) -> Result<(), CaseError> {
        let refined = match self.refine {
            0 => String::new(),
            1 => " (on the mesh refined once)".into(),
            k => format!(" (on the mesh refined {k} times)"),
        };
        let err = |m: String| CaseError(format!("{}{refined}: {m}", self.origin));
        problem::boundary_values(mesh, &self.data).map_err(|e| err(e.to_string()))?;
        let Some(exact) = &self.exact else {
            return Ok(());
        };
        // Gradients may be singular at a vertex (a re-entrant corner): they are only integrated.
        for (key, e) in [
            ("exact.u1", &exact.u1),
            ("exact.u2", &exact.u2),
            ("exact.lambda", &exact.lambda),
        ] {
            if let Some(p) = first_vertex(mesh, &[e], |v| !v[0].is_finite()).map(|a| mesh.points[a]) {
                return Err(err(format!(
                    "key '{key}' is {} at the vertex {}: an exact solution must be finite",
                    e.eval(p[0], p[1]),
                    Point(p)
                )));
            }
        }
        // The conditions of the problem, to round-off of the values' size: λ ≥ 0, u1 ≥ u2 (u ≥ ψ).
        let below = |a: f64, b: f64| a - b < -EXACT_ROUND_OFF * a.abs().max(b.abs()).max(1.0);
        if let Some(p) = first_vertex(mesh, &[&exact.lambda], |v| below(v[0], 0.0)).map(|a| mesh.points[a]) {
            return Err(err(format!(
                "key 'exact.lambda' is {} at the vertex {}: the contact pressure λ must be ≥ 0",
                exact.lambda.eval(p[0], p[1]),
                Point(p)
            )));
        }
        let pair = [&exact.u1, &exact.u2];
        if let Some(p) = first_vertex(mesh, &pair, |v| below(v[0], v[1])).map(|a| mesh.points[a]) {
            let gap = exact.u1.eval(p[0], p[1]) - exact.u2.eval(p[0], p[1]);
            let (what, must) = match exact.rigid {
                true => ("u − ψ", "u must lie above the obstacle ψ"),
                false => ("u1 − u2", "the membranes must not cross, u1 ≥ u2"),
            };
            return Err(err(format!(
                "the exact {what} is {gap:e} at the vertex {}: {must}",
                Point(p)
            )));
        }
        Ok(())
    }

    /// 4^refine (saturating): refinement multiplies the vertices by less than that.
    fn refinement_factor(&self) -> usize {
        4usize.saturating_pow(u32::try_from(self.refine).unwrap_or(u32::MAX))
    }

    /// The vertices of the mesh solved on (saturating; an estimate from above for disks and
    /// polygons, 0 for files), for the memory guard.
    pub fn estimated_vertices(&self) -> usize {
        let given = match &self.mesh {
            MeshSpec::Rectangle { n, diagonal, .. } => {
                let crossed = usize::from(*diagonal == Diagonal::Crossed);
                (n[0].saturating_add(1))
                    .saturating_mul(n[1].saturating_add(1))
                    .saturating_add(crossed.saturating_mul(n[0].saturating_mul(n[1])))
            }
            MeshSpec::Lshape { n, .. } => n.saturating_add(2).saturating_mul(n.saturating_add(2)),
            MeshSpec::Domain { domain, h } => domain.estimated_vertices(*h),
            MeshSpec::File { .. } => 0,
            MeshSpec::Given { mesh } => mesh.n_vertices(),
        };
        given.saturating_mul(self.refinement_factor())
    }
}

impl Describe for Case {
    fn attributes(&self) -> Vec<Attribute> {
        vec![
            (
                "program",
                Attr::Text(format!("membrane-contact {}", env!("CARGO_PKG_VERSION"))),
            ),
            ("case_origin", Attr::Text(self.origin.clone())),
            ("case_text", Attr::Text(self.text.clone())),
            ("title", Attr::Text(self.title.clone())),
            ("problem", Attr::Text(self.problem_name().into())),
            (
                if self.data.is_obstacle() { "mu" } else { "mu1" },
                self.data.mu1.into(),
            ),
            ("quadrature_degree", self.data.quadrature.degree.into()),
        ]
        .into_iter()
        .chain(self.data.mu2().map(|mu2| ("mu2", mu2.into())))
        .collect()
    }
}

/// A built-in mesh in a numbering whose blocks of rows are regions of ω, as multigrid's block
/// smoother needs (`multigrid::BLOCK_ROWS`): dolfinx's row-by-row numbering is one, but with
/// crossed diagonals it puts the cell midpoints last, and blocks of grid vertices or of midpoints
/// alone (which K couples only to each other) made the smoother a Jacobi iteration: CG's
/// iterations doubled with every refinement from 256² on. Crossed meshes are numbered along a
/// Z-order curve instead.
fn geometric(mesh: Mesh, diagonal: Diagonal) -> Mesh {
    match diagonal {
        Diagonal::Crossed => mesh.renumbered(),
        Diagonal::Right | Diagonal::Left => mesh,
    }
}

/// A TOML error on one line, with the line and column of the key or value it is about (none for
/// the whole file: a top-level key missing).
fn toml_error(text: &str, e: &toml::de::Error) -> String {
    let mut message = e.message().trim_end().replace('\n', " ");
    // serde names Rust's types; a case file has whole numbers and numbers.
    for (rust, toml) in [
        ("expected usize", "expected a whole number ≥ 0"),
        ("expected f64", "expected a number"),
    ] {
        message = message.replace(rust, toml);
    }
    match e.span() {
        Some(span) if span.start == 0 && text[..span.end.min(text.len())].trim_end().contains('\n') => {
            message
        }
        Some(span) => {
            let before = &text[..span.start.min(text.len())];
            let line = before.matches('\n').count() + 1;
            let start = before.rfind('\n').map_or(0, |i| i + 1);
            let column = before.len() - start + 1;
            let source: String = text[start..]
                .lines()
                .next()
                .unwrap_or("")
                .chars()
                .take(60)
                .collect();
            format!("line {line}, column {column} («{}»): {message}", source.trim())
        }
        None => message,
    }
}

/// The data of the case's problem (`problem` = "membranes", the default, or "obstacle"): its keys
/// present, the other problem's keys absent.
fn problem_data(
    file: &CaseFile,
    expr: &dyn Fn(&str, &Expression) -> Result<Expr, String>,
    quadrature: Quadrature,
) -> Result<Data, String> {
    let problem = file.problem.as_deref().unwrap_or("membranes");
    let present: [(&str, bool); 8] = [
        ("mu1", file.mu1.is_some()),
        ("mu2", file.mu2.is_some()),
        ("f1", file.f1.is_some()),
        ("f2", file.f2.is_some()),
        ("g2", file.g2.is_some()),
        ("mu", file.mu.is_some()),
        ("f", file.f.is_some()),
        ("psi", file.psi.is_some()),
    ];
    let Some((_, keys)) = PROBLEMS.iter().find(|(name, _)| *name == problem) else {
        let names = PROBLEMS.map(|(n, _)| format!("\"{n}\"")).join(" or ");
        return Err(format!("key 'problem' = \"{problem}\": expected {names}"));
    };
    if let Some((key, _)) = present.iter().find(|(k, there)| *there && !keys.contains(k)) {
        let owner = PROBLEMS
            .iter()
            .find(|(_, ks)| ks.contains(key))
            .map_or("", |(n, _)| n);
        return Err(format!(
            "key '{key}' belongs to problem = \"{owner}\", not to problem = \"{problem}\""
        ));
    }
    let missing = |key: &str| format!("key '{key}' is missing (problem = \"{problem}\")");
    let need = |key: &str, e: &Option<Expression>| -> Result<Datum, String> {
        let e = e.as_ref().ok_or_else(|| missing(key))?;
        parse_datum(key, e, expr)
    };
    let number = |key: &str, v: Option<f64>| v.ok_or_else(|| missing(key));
    let g = parse_datum("g", &file.g, expr)?;
    let data = match problem {
        "obstacle" => Data::obstacle(
            number("mu", file.mu)?,
            need("f", &file.f)?,
            need("psi", &file.psi)?,
            g,
            quadrature,
        ),
        _ => Data::new(
            [number("mu1", file.mu1)?, number("mu2", file.mu2)?],
            need("f1", &file.f1)?,
            need("f2", &file.f2)?,
            g,
            quadrature,
        ),
    };
    let data = data.map_err(|e| e.to_string())?;
    match &file.g2 {
        Some(g2) => Ok(data.with_g2(parse_datum("g2", g2, expr)?)),
        None => Ok(data),
    }
}

/// The `[exact]` table of the case's problem: u1, u2 (and their gradients) of the membranes, or
/// u (and its gradient) above a rigid obstacle, whose u2 is ψ.
fn exact_solution(
    e: &ExactFile,
    data: &Data,
    expr: &dyn Fn(&str, &Expression) -> Result<Expr, String>,
) -> Result<Exact, String> {
    let one = |key: &str, v: &Option<Expression>| v.as_ref().map(|v| expr(key, v)).transpose();
    // ∇u as given, or u's derivatives where it is not.
    let grad = |key: &str, g: &Option<Vec<Expression>>, u: &Expr| -> Result<[Expr; 2], String> {
        // Named with the entry, ∂/∂x as [0] and ∂/∂y as [1].
        let parse = |k: usize, v| expr(&format!("{key}[{k}]"), v);
        match g.as_deref() {
            None => Ok(u.gradient()),
            Some([gx, gy]) => Ok([parse(0, gx)?, parse(1, gy)?]),
            Some(g) => Err(format!(
                "key '{key}' has {} entries: a gradient has two, [∂/∂x, ∂/∂y]",
                g.len()
            )),
        }
    };
    let (keys, other): (&[&str], &[&str]) = match data.lower {
        Lower::Rigid { .. } => (&["u", "grad_u"], &["u1", "u2", "grad_u1", "grad_u2"]),
        Lower::Membrane { .. } => (&["u1", "u2", "grad_u1", "grad_u2"], &["u", "grad_u"]),
    };
    let present = [
        ("u1", e.u1.is_some()),
        ("u2", e.u2.is_some()),
        ("grad_u1", e.grad_u1.is_some()),
        ("grad_u2", e.grad_u2.is_some()),
        ("u", e.u.is_some()),
        ("grad_u", e.grad_u.is_some()),
    ];
    if let Some((key, _)) = present.iter().find(|(k, there)| *there && other.contains(k)) {
        return Err(format!(
            "key 'exact.{key}' does not belong to this problem: its exact solution has {}",
            keys.iter()
                .map(|k| format!("'exact.{k}'"))
                .collect::<Vec<_>>()
                .join(", ")
        ));
    }
    let missing = |key: &str| format!("key 'exact.{key}' is missing");
    let lambda = expr("exact.lambda", &e.lambda)?;
    Ok(match &data.lower {
        Lower::Rigid { psi } => {
            let u = one("exact.u", &e.u)?.ok_or_else(|| missing("u"))?;
            let psi = (psi.expr().cloned()).ok_or(
                "key 'psi' is a table per physical group: with an [exact] \
                 solution, give ψ as one expression (the errors take it as the obstacle's exact \
                 height)",
            )?;
            Exact {
                grad_u1: grad("exact.grad_u", &e.grad_u, &u)?,
                grad_u2: psi.gradient(),
                gradients_given: [e.grad_u.is_some(), false],
                u1: u,
                u2: psi,
                lambda,
                rigid: true,
            }
        }
        Lower::Membrane { .. } => {
            let u1 = one("exact.u1", &e.u1)?.ok_or_else(|| missing("u1"))?;
            let u2 = one("exact.u2", &e.u2)?.ok_or_else(|| missing("u2"))?;
            Exact {
                grad_u1: grad("exact.grad_u1", &e.grad_u1, &u1)?,
                grad_u2: grad("exact.grad_u2", &e.grad_u2, &u2)?,
                gradients_given: [e.grad_u1.is_some(), e.grad_u2.is_some()],
                u1,
                u2,
                lambda,
                rigid: false,
            }
        }
    })
}

/// An expression of the case language, using the named values `names`.
fn parse_expression(key: &str, e: &Expression, names: &Names) -> Result<Expr, String> {
    let source = match e {
        Expression::Number(v) => number(key, *v)?,
        Expression::Text(s) => s.clone(),
        Expression::Table(_) => {
            return Err(format!(
                "key '{key}' is a table: need an expression (a string or a number); only {PER_GROUP} \
                 may be tables per physical group"
            ))
        }
    };
    Expr::parse_with(&source, names).map_err(|error| quote(key, &source, &error))
}

/// The source of a number given as a TOML float; TOML's nan and inf are refused by name.
fn number(key: &str, v: f64) -> Result<String, String> {
    match v.is_finite() {
        true => Ok(format!("{v:?}")),
        false => Err(format!("key '{key}' = {v}: need a finite number")),
    }
}

/// A datum: an expression, or a table of expressions keyed by the names of physical groups
/// (`{ loaded = "-20", free = 0 }`), in file order.
fn parse_datum(
    key: &str,
    e: &Expression,
    expr: &dyn Fn(&str, &Expression) -> Result<Expr, String>,
) -> Result<Datum, String> {
    let Expression::Table(table) = e else {
        return expr(key, e).map(Datum::Expr);
    };
    if table.is_empty() {
        return Err(format!(
            "key '{key}' is an empty table: give an expression per physical group, e.g. \
             {key} = {{ loaded = \"-20\", free = 0 }}"
        ));
    }
    let entries = table.iter().map(|(group, value)| {
        let path = format!("{key}.{group}");
        let entry = match value {
            toml::Value::String(s) => Expression::Text(s.clone()),
            toml::Value::Float(v) => Expression::Number(*v),
            toml::Value::Integer(v) => Expression::Number(*v as f64),
            other => {
                return Err(format!(
                    "key '{path}' = {other}: need an expression (a string or a number)"
                ))
            }
        };
        Ok((group.clone(), expr(&path, &entry)?))
    });
    entries.collect::<Result<Vec<_>, _>>().map(Datum::Table)
}

/// The `[let]` table: each name may use the names above it (file order), which rules out cycles.
fn let_names(table: &toml::Table) -> Result<Names, String> {
    let keys: Vec<&str> = table.keys().map(String::as_str).collect();
    let mut names = Names::default();
    for (i, (key, value)) in table.iter().enumerate() {
        let key_path = format!("let.{key}");
        let source = match value {
            toml::Value::String(s) => s.clone(),
            toml::Value::Float(v) => number(&key_path, *v)?,
            toml::Value::Integer(v) => v.to_string(),
            other => {
                return Err(format!(
                    "key '{key_path}' = {other}: need an expression (a string or a number)"
                ))
            }
        };
        names
            .define(key, &source, &keys[i + 1..])
            .map_err(|error| quote(&key_path, &source, &error))?;
    }
    Ok(names)
}

/// An expression error naming the key; it quotes at most the first 60 characters, on one line
/// (line breaks and other invisible characters escaped).
fn quote(key: &str, source: &str, error: &ExprError) -> String {
    let visible = |s: &str| -> String { s.chars().map(crate::expr::visible).collect() };
    let shown = match source.char_indices().nth(60) {
        Some((i, _)) => format!(
            "{}… ({} characters)",
            visible(&source[..i]),
            source.chars().count()
        ),
        None => visible(source),
    };
    format!("key '{key}' = \"{shown}\": {error}")
}

/// The typed mesh of a `[mesh]` table: the keys its kind takes, checked (`refine` is taken by
/// every kind).
fn mesh_spec(t: &MeshTable) -> Result<MeshSpec, String> {
    let given = [
        ("corners", t.corners.is_some()),
        ("n", t.n.is_some()),
        ("diagonal", t.diagonal.is_some()),
        ("grading", t.grading.is_some()),
        ("path", t.path.is_some()),
        ("boundary", t.boundary.is_some()),
        ("holes", t.holes.is_some()),
        ("centre", t.centre.is_some()),
        ("center", t.center.is_some()),
        ("radius", t.radius.is_some()),
        ("inner_radius", t.inner_radius.is_some()),
        ("h", t.h.is_some()),
    ];
    let takes: &[&str] = match t.kind.as_str() {
        "rectangle" => &["corners", "n", "diagonal", "refine"],
        "lshape" => &["n", "diagonal", "grading", "refine"],
        "polygon" => &["boundary", "holes", "h", "refine"],
        "disk" => &["centre", "center", "radius", "inner_radius", "h", "refine"],
        "file" => &["path", "refine"],
        other => {
            return Err(format!(
                "key 'mesh.kind' = \"{other}\": the kinds are \"rectangle\", \"lshape\", \"polygon\", \"disk\" and \"file\""
            ))
        }
    };
    if let Some((key, _)) = given.iter().find(|(k, set)| *set && !takes.contains(k)) {
        return Err(format!(
            "key 'mesh.{key}' does not apply to kind = \"{}\" (its keys: {})",
            t.kind,
            takes.join(", ")
        ));
    }
    let need = |key: &str| format!("key 'mesh.{key}' is missing (kind = \"{}\")", t.kind);
    match t.kind.as_str() {
        "rectangle" => rectangle_spec(t, need),
        "lshape" => lshape_spec(t, need),
        "polygon" | "disk" => {
            let domain = match t.kind.as_str() {
                "polygon" => Domain::Polygon {
                    boundary: ring(
                        t.boundary.as_ref().ok_or_else(|| need("boundary"))?,
                        "'mesh.boundary'",
                    )?,
                    holes: (t.holes.iter().flatten().enumerate())
                        .map(|(k, h)| ring(h, &format!("'mesh.holes' (hole {})", k + 1)))
                        .collect::<Result<_, _>>()?,
                },
                _ => Domain::Disk {
                    centre: match (&t.centre, &t.center) {
                        (Some(_), Some(_)) => {
                            return Err("keys 'mesh.centre' and 'mesh.center' are two spellings of \
                                        one key: give one"
                                .into())
                        }
                        (Some(c), None) => point(c, || "key 'mesh.centre'".into())?,
                        (None, Some(c)) => point(c, || "key 'mesh.center'".into())?,
                        (None, None) => [0.0, 0.0],
                    },
                    radius: t.radius.ok_or_else(|| need("radius"))?,
                    inner_radius: t.inner_radius,
                },
            };
            domain.check()?;
            let h = t.h.ok_or_else(|| need("h"))?;
            if !(h > 0.0 && h.is_finite()) {
                return Err(format!("key 'mesh.h' = {h}: need a positive mesh size"));
            }
            Ok(MeshSpec::Domain { domain, h })
        }
        _ => Ok(MeshSpec::File {
            path: t.path.clone().ok_or_else(|| need("path"))?,
        }),
    }
}

/// A point [x, y] of a `[mesh]` key (`what` names it): exactly two numbers. Read as `[f64; 2]`, a
/// longer array would lose the rest silently and a shorter one be refused without saying which.
fn point(v: &[f64], what: impl Fn() -> String) -> Result<[f64; 2], String> {
    match *v {
        [x, y] => Ok([x, y]),
        [_] => Err(format!("{} = {v:?} has 1 number: a point is [x, y]", what())),
        _ => Err(format!(
            "{} = {v:?} has {} numbers: a point is [x, y]",
            what(),
            v.len()
        )),
    }
}

/// The vertices of a polygon's ring (`name`: the key, and the hole), each [x, y]; a last vertex
/// equal to the first (a ring closed as GeoJSON and shapely write it) is left out.
fn ring(vertices: &[Vec<f64>], name: &str) -> Result<Vec<[f64; 2]>, String> {
    let mut ring: Vec<[f64; 2]> = (vertices.iter().enumerate())
        .map(|(i, v)| point(v, || format!("key {name}, vertex {}", i + 1)))
        .collect::<Result<_, _>>()?;
    if ring.len() > 1 && ring.first() == ring.last() {
        ring.pop();
        if ring.len() < 3 {
            return Err(format!(
                "key {name} has {} vertices besides its last, which repeats the first to close it: \
                 a polygon needs at least 3",
                ring.len()
            ));
        }
    }
    Ok(ring)
}

/// `kind = "rectangle"`: n, corners (default the unit square), diagonal.
fn rectangle_spec(t: &MeshTable, need: impl Fn(&str) -> String) -> Result<MeshSpec, String> {
    let n = match t.n.ok_or_else(|| need("n"))? {
        Cells::Square(n) => [n, n],
        Cells::Sides(n) => n,
    };
    if n[0] == 0 || n[1] == 0 {
        return Err(format!("key 'mesh.n' = {n:?}: need at least one cell each way"));
    }
    let corners = match t.corners.as_deref() {
        None => [[0.0, 0.0], [1.0, 1.0]],
        Some([c0, c1]) => [
            point(c0, || "key 'mesh.corners', corner 1".into())?,
            point(c1, || "key 'mesh.corners', corner 2".into())?,
        ],
        Some(c) => {
            return Err(format!(
                "key 'mesh.corners' has {} points: need [[x0, y0], [x1, y1]]",
                c.len()
            ))
        }
    };
    let [c0, c1] = corners;
    let extent = [c1[0] - c0[0], c1[1] - c0[1]];
    if !(extent.iter().all(|e| *e > 0.0 && e.is_finite())) {
        return Err(format!(
            "key 'mesh.corners' = {corners:?}: need [[x0, y0], [x1, y1]] with x0 < x1, y0 < y1 and a finite extent"
        ));
    }
    let diagonal = t.diagonal.unwrap_or(Diagonal::Right);
    Ok(MeshSpec::Rectangle { corners, n, diagonal })
}

/// Whether double precision computes the areas of the triangles of the rectangle `corners` in
/// `n` cells cut along `diagonal`, refined `refine` times, and its diameter squared, which the
/// mesh's checks compare them with ([`mesh::domain::check_area`]); in logarithms, as the products
/// may leave the range.
fn rectangle_in_range(
    [c0, c1]: [[f64; 2]; 2],
    n: [usize; 2],
    diagonal: Diagonal,
    refine: usize,
) -> Result<(), String> {
    let per_cell = match diagonal {
        Diagonal::Crossed => 4.0,
        _ => 2.0,
    };
    let sides = [0, 1].map(|k| (c1[k] - c0[k]) / n[k] as f64);
    let log10 =
        sides.map(f64::log10).iter().sum::<f64>() - f64::log10(per_cell) - refine as f64 * 4f64.log10();
    mesh::domain::check_area(10f64.powf(log10))
        .map_err(|e| format!("the triangles' areas (about 1e{:.0}) lie {e}", log10.floor()))?;
    let diameter = (c1[0] - c0[0]).hypot(c1[1] - c0[1]);
    mesh::domain::check_area(diameter * diameter).map_err(|e| {
        format!(
            "the square of the rectangle's diameter (about 1e{:.0}) lies {e}",
            (2.0 * diameter.log10()).floor()
        )
    })
}

/// Why the L-shape's n must be even.
const EVEN_LSHAPE: &str =
    "the L-shape takes an even number of cells per side (its re-entrant corner is a vertex)";

/// `kind = "lshape"`: n (even, at least 2), diagonal, grading ≥ 1.
fn lshape_spec(t: &MeshTable, need: impl Fn(&str) -> String) -> Result<MeshSpec, String> {
    let n = match t.n.ok_or_else(|| need("n"))? {
        Cells::Square(n) if n >= 2 && n % 2 == 0 => n,
        Cells::Square(n) if n % 2 == 1 => return Err(format!("key 'mesh.n' = {n}: {EVEN_LSHAPE}")),
        Cells::Square(n) => return Err(format!("key 'mesh.n' = {n}: need at least 2")),
        Cells::Sides(n) => return Err(format!("key 'mesh.n' = {n:?}: the L-shape takes one number")),
    };
    let grading = t.grading.unwrap_or(1.0);
    if !(grading >= 1.0 && grading.is_finite()) {
        return Err(format!("key 'mesh.grading' = {grading}: need a number ≥ 1"));
    }
    let diagonal = t.diagonal.unwrap_or(Diagonal::Right);
    Ok(MeshSpec::Lshape { n, diagonal, grading })
}

/// The levels of a `[validation]` table: `sizes` (cells per side, built-in meshes only) or
/// `refine` (refinements, any mesh), increasing.
fn validation_levels(v: &ValidationTable, mesh: &MeshSpec) -> Result<Levels, String> {
    let builtin = matches!(mesh, MeshSpec::Rectangle { .. } | MeshSpec::Lshape { .. });
    let (key, levels) =
        match (&v.sizes, &v.refine) {
            (Some(_), Some(_)) => return Err("[validation] takes 'sizes' or 'refine', not both".into()),
            (None, None) => {
                return Err("[validation] needs 'sizes' (cells per side) or 'refine' (refinements)".into())
            }
            (Some(_), None) if !builtin => return Err(
                "key 'validation.sizes' applies to built-in meshes: use 'validation.refine' (refinements)"
                    .into(),
            ),
            (Some(s), None) => ("validation.sizes", Levels::Cells(s.clone())),
            (None, Some(r)) => ("validation.refine", Levels::Refine(r.clone())),
        };
    let (Levels::Cells(l) | Levels::Refine(l)) = &levels;
    if l.is_empty() || l.windows(2).any(|w| w[1] <= w[0]) {
        return Err(format!("key '{key}' = {l:?}: need increasing levels"));
    }
    if matches!(levels, Levels::Cells(_)) && l[0] == 0 {
        return Err(format!("key '{key}' = {l:?}: need 1 cell per side at least"));
    }
    Ok(levels)
}

/// The first vertex of `mesh` where the values of `exprs` there are `bad`, the vertices evaluated
/// in parallel pieces.
fn first_vertex(mesh: &Mesh, exprs: &[&Expr], bad: impl Fn(&[f64]) -> bool + Sync) -> Option<usize> {
    let pieces = crate::parallel::map(mesh.n_vertices(), crate::parallel::PIECE, |range| {
        let values: Vec<Vec<f64>> = (exprs.iter())
            .map(|e| {
                let mut v = vec![0.0; range.len()];
                e.eval_many(&mesh.points[range.clone()], &mut v);
                v
            })
            .collect();
        (0..range.len())
            .position(|k| bad(&values.iter().map(|v| v[k]).collect::<Vec<f64>>()))
            .map(|k| range.start + k)
    });
    pieces.into_iter().flatten().next()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn default_case_parses() {
        let c = Case::default_case();
        assert!(c.exact.is_some());
        assert!(c.mesh().unwrap().n_vertices() > 100);
    }

    #[test]
    fn points_are_two_numbers() {
        let err = |mesh: &str| {
            let text = format!("mu1 = 1.0\nmu2 = 1.0\nf1 = 0\nf2 = 0\ng = 0\n[mesh]\n{mesh}\n");
            Case::parse(&text, "case.toml", PathBuf::new()).unwrap_err().0
        };
        let polygon = "kind = \"polygon\"\nh = 0.3\nboundary = [[0, 0], [1, 0], [1, 1]]";
        assert_eq!(
            err(&polygon.replace("[1, 0]", "[1, 0, 0]")),
            "case.toml: key 'mesh.boundary', vertex 2 = [1.0, 0.0, 0.0] has 3 numbers: a point is [x, y]"
        );
        assert!(err(&polygon.replace("[1, 1]", "[1]"))
            .contains("'mesh.boundary', vertex 3 = [1.0] has 1 number:"));
        let holes = "holes = [[[0.5, 0.2], [0.6, 0.2], [0.6, 0.3]], [[0.8, 0.5], [0.9, 0.5, 7], [0.9, 0.6]]]";
        assert!(err(&format!("{polygon}\n{holes}"))
            .contains("key 'mesh.holes' (hole 2), vertex 2 = [0.9, 0.5, 7.0] has 3 numbers"));
        let disk = "kind = \"disk\"\nradius = 1\nh = 0.3";
        assert!(
            err(&format!("{disk}\ncentre = [0, 0, 5]")).contains("key 'mesh.centre' = [0.0, 0.0, 5.0] has 3")
        );
        let rectangle = "kind = \"rectangle\"\nn = 4";
        assert!(
            err(&format!("{rectangle}\ncorners = [[0, 0, 0], [1, 1]]")).contains("'mesh.corners', corner 1")
        );
        assert!(err(&format!("{rectangle}\ncorners = [[0, 0], [1, 1], [2, 2]]"))
            .contains("key 'mesh.corners' has 3 points: need [[x0, y0], [x1, y1]]"));
        // Two numbers each: read as given.
        let text = format!("mu1 = 1.0\nmu2 = 1.0\nf1 = 0\nf2 = 0\ng = 0\n[mesh]\n{polygon}\n{holes}\n")
            .replace(", 7]", "]");
        let Ok(Case {
            mesh:
                MeshSpec::Domain {
                    domain: Domain::Polygon { boundary, holes },
                    ..
                },
            ..
        }) = Case::parse(&text, "t", PathBuf::new())
        else {
            panic!("a polygon")
        };
        assert_eq!(boundary, [[0.0, 0.0], [1.0, 0.0], [1.0, 1.0]]);
        assert_eq!(holes[1], [[0.8, 0.5], [0.9, 0.5], [0.9, 0.6]]);
    }

    #[test]
    fn center_is_centre() {
        let disk = |keys: &str| {
            let text = format!(
                "mu1 = 1.0\nmu2 = 1.0\nf1 = 0\nf2 = 0\ng = 0\n[mesh]\nkind = \"disk\"\nradius = 1\nh = 0.3\n{keys}\n"
            );
            Case::parse(&text, "case.toml", PathBuf::new())
        };
        let (centre, center) = (
            disk("centre = [0.5, -1]").unwrap(),
            disk("center = [0.5, -1]").unwrap(),
        );
        assert!(matches!(
            center.mesh,
            MeshSpec::Domain {
                domain: Domain::Disk {
                    centre: [0.5, -1.0],
                    ..
                },
                ..
            }
        ));
        assert_eq!(centre.mesh, center.mesh);
        let (a, b) = (centre.mesh().unwrap(), center.mesh().unwrap());
        assert_eq!(a.points, b.points);
        assert!(a.triangles().eq(b.triangles()));
        assert_eq!(
            disk("centre = [0.5, -1]\ncenter = [0.5, -1]").unwrap_err().0,
            "case.toml: keys 'mesh.centre' and 'mesh.center' are two spellings of one key: give one"
        );
        assert!(disk("center = [0, 0, 1]")
            .unwrap_err()
            .0
            .contains("key 'mesh.center' = [0.0, 0.0, 1.0]"));
    }

    #[test]
    fn errors_name_the_key() {
        let base =
            "mu1 = 1.0\nmu2 = 1.0\nf1 = \"1\"\nf2 = 0\ng = 0\n[mesh]\nkind = \"rectangle\"\nn = [4, 4]\n";
        assert!(Case::parse(base, "t", PathBuf::new()).is_ok());
        let err = |text: &str| Case::parse(text, "case.toml", PathBuf::new()).unwrap_err().0;
        assert!(err(&format!("{base}bogus = 1\n")).contains("unknown field `bogus`"));
        assert!(err(&base.replace("mu1 = 1.0", "mu1 = -1.0")).contains("'mu1'"));
        assert!(err(&base.replace("mu2 = 1.0", "mu2 = \"two\"")).contains("mu2"));
        assert!(err(&base.replace("f1 = \"1\"", "f1 = \"1 +\"")).contains("key 'f1'"));
        assert!(err(&base.replace("g = 0\n", "")).contains("missing field `g`"));
        // A table missing: no line (the error's span is the whole file, not its first line).
        let no_mesh = "mu1 = 1.0\nmu2 = 1.0\nf1 = 1\nf2 = 0\ng = 0\n";
        let missing = Case::parse(no_mesh, "t", PathBuf::new()).unwrap_err().0;
        assert_eq!(missing, "t: missing field `mesh`");
        assert!(err(&base.replace("rectangle", "circle")).contains("circle"));
        // Inside [mesh], errors point at the key's line, and keys of other kinds are refused.
        let typo = err(&format!("{base}gradin = 2\n"));
        assert!(
            typo.contains("line 9, column 1 («gradin = 2»): unknown field `gradin`"),
            "{typo}"
        );
        assert!(err(&format!("{base}grading = 2\n")).contains("'mesh.grading' does not apply"));
        assert!(err(&format!("{base}radius = 2\n")).contains("'mesh.radius' does not apply"));
        let disk = base.replace(
            "kind = \"rectangle\"\nn = [4, 4]",
            "kind = \"disk\"\nradius = 1.0\nh = 0.2",
        );
        assert!(Case::parse(&disk, "t", PathBuf::new()).is_ok());
        assert!(err(&disk.replace("h = 0.2", "h = 0")).contains("key 'mesh.h' = 0"));
        assert!(err(&disk.replace("radius = 1.0", "radius = -1")).contains("key 'mesh.radius' = -1"));
        assert!(err(&format!("{disk}n = 4\n")).contains("'mesh.n' does not apply to kind = \"disk\""));
        assert!(err(&format!("{disk}[validation]\nsizes = [8]\n")).contains("validation.refine"));
        let mut c = Case::parse(&disk, "t", PathBuf::new()).unwrap();
        assert!(c
            .set_cells(8)
            .unwrap_err()
            .0
            .contains("refine it instead (--refine K"));
        // [solver] linear: the two names, anything else named with the key.
        let solver = |v: &str| format!("{base}[solver]\nlinear = {v}\n");
        let mg = Case::parse(&solver("\"multigrid\""), "t", PathBuf::new()).unwrap();
        assert_eq!(mg.solver.linear, LinearSolver::Multigrid);
        assert_eq!(mg.solver.max_iterations, SolverOptions::default().max_iterations);
        let direct = Case::parse(&solver("\"direct\""), "t", PathBuf::new()).unwrap();
        assert_eq!(direct.solver.linear, LinearSolver::Direct);
        assert_eq!(
            Case::parse(base, "t", PathBuf::new()).unwrap().solver.linear,
            LinearSolver::Multigrid
        );
        let bad = err(&solver("\"cholesky\""));
        assert!(
            bad.contains("key 'solver.linear' = \"cholesky\": expected one of \"direct\", \"multigrid\""),
            "{bad}"
        );
        assert!(err(&solver("3")).contains("linear"));
        let long = err(&base.replace("f1 = \"1\"", &format!("f1 = \"{}+\"", "x+".repeat(10_000))));
        assert!(long.len() < 300 && long.contains("20001 characters"), "{long}");
    }

    #[test]
    fn the_memory_guard_prices_the_solver_and_the_postprocessing() {
        let case = |linear: &str, after: Postprocess| {
            let text = format!(
                "mu1 = 1.0\nmu2 = 1.0\nf1 = 0\nf2 = 0\ng = 0\n[mesh]\nkind = \"rectangle\"\n\
                 n = [4, 4]\n[solver]\nlinear = \"{linear}\"\n"
            );
            Case::parse(&text, "t", PathBuf::new())
                .unwrap()
                .bytes_per_vertex(after)
        };
        let none = Postprocess::default();
        assert_eq!(case("multigrid", none), mesh::MULTIGRID_BYTES_PER_VERTEX);
        assert_eq!(case("direct", none), mesh::DIRECT_BYTES_PER_VERTEX);
        // The estimate and the flux after a multigrid solve weigh more than the solve.
        let both = Postprocess {
            flux: true,
            estimate: true,
            hminus1: false,
        };
        assert_eq!(case("multigrid", both), both.bytes_per_vertex());
        assert!(both.bytes_per_vertex() > 2.0 * mesh::MULTIGRID_BYTES_PER_VERTEX);
    }
}
