//! Case files (TOML): the data of (1.1), the mesh, the quadrature and the solver settings.
//! The format is documented in `data/cases/README.md`.

use crate::assembly::Quadrature;
use crate::contact::{Data, SolverOptions};
use crate::expr::Expr;
use crate::mesh::{Diagonal, Mesh};
use serde::{Deserialize, Serialize};
use std::fmt;
use std::path::{Path, PathBuf};

/// The built-in default case (`membrane-contact solve` without a case file).
pub const DEFAULT_CASE: &str = include_str!("../data/cases/default.toml");

/// A case as written in the file (expressions still as text).
#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct CaseFile {
    #[serde(default)]
    pub title: String,
    pub mu1: f64,
    pub mu2: f64,
    pub f1: Expression,
    pub f2: Expression,
    pub g: Expression,
    #[serde(default)]
    pub exact: Option<ExactFile>,
    pub mesh: MeshSpec,
    #[serde(default)]
    pub quadrature: QuadratureSpec,
    #[serde(default)]
    pub solver: SolverSpec,
    #[serde(default)]
    pub validation: Option<ValidationSpec>,
}

/// An expression: a string in the case language, or a plain number.
#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(untagged)]
pub enum Expression {
    Number(f64),
    Text(String),
}

impl Expression {
    fn text(&self) -> String {
        match self {
            Expression::Number(v) => format!("{v:?}"),
            Expression::Text(s) => s.clone(),
        }
    }
}

/// Exact solution, for error norms.
#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct ExactFile {
    pub u1: Expression,
    pub u2: Expression,
    pub lambda: Expression,
    /// ∇u1 and ∇u2 as [∂x, ∂y], for the H¹ error.
    #[serde(default)]
    pub grad_u1: Option<[Expression; 2]>,
    #[serde(default)]
    pub grad_u2: Option<[Expression; 2]>,
}

/// The mesh: built in, or read from a file.
#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(tag = "kind", rename_all = "lowercase", deny_unknown_fields)]
pub enum MeshSpec {
    /// [x0, x1] × [y0, y1] with n = [nx, ny] cells.
    Rectangle {
        #[serde(default = "unit_square")]
        corners: [[f64; 2]; 2],
        n: [usize; 2],
        #[serde(default = "right")]
        diagonal: Diagonal,
    },
    /// (−1, 1)² \ [0, 1] × [−1, 0] with n × n cells on the square, graded by `grading` ≥ 1.
    Lshape {
        n: usize,
        #[serde(default = "right")]
        diagonal: Diagonal,
        #[serde(default = "one")]
        grading: f64,
    },
    /// A triangle mesh in XDMF/HDF5 as written by meshio or dolfinx (path relative to the case).
    File { path: PathBuf },
}

fn unit_square() -> [[f64; 2]; 2] {
    [[0.0, 0.0], [1.0, 1.0]]
}
fn right() -> Diagonal {
    Diagonal::Right
}
fn one() -> f64 {
    1.0
}

#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct QuadratureSpec {
    pub degree: usize,
}

impl Default for QuadratureSpec {
    fn default() -> Self {
        QuadratureSpec { degree: 4 }
    }
}

#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct SolverSpec {
    pub max_iterations: usize,
}

impl Default for SolverSpec {
    fn default() -> Self {
        SolverSpec {
            max_iterations: SolverOptions::default().max_iterations,
        }
    }
}

/// Mesh sizes (cells per side) used by `make validate` and convergence studies.
#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct ValidationSpec {
    pub sizes: Vec<usize>,
}

/// A case error, naming the file and the key.
#[derive(Debug, Clone, PartialEq)]
pub struct CaseError(pub String);

impl fmt::Display for CaseError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.0)
    }
}

impl std::error::Error for CaseError {}

/// Exact solution as parsed expressions.
#[derive(Debug, Clone)]
pub struct Exact {
    pub u1: Expr,
    pub u2: Expr,
    pub lambda: Expr,
    pub grad_u1: Option<[Expr; 2]>,
    pub grad_u2: Option<[Expr; 2]>,
}

/// A checked case: parsed expressions and settings.
#[derive(Debug, Clone)]
pub struct Case {
    /// Where it came from (a path, or "built-in default case").
    pub origin: String,
    /// The case text, stored in every result file.
    pub text: String,
    pub file: CaseFile,
    pub data: Data,
    pub exact: Option<Exact>,
    pub options: SolverOptions,
    base_dir: PathBuf,
}

impl Case {
    /// Reads and checks a case file.
    pub fn read(path: &Path) -> Result<Case, CaseError> {
        let text = std::fs::read_to_string(path)
            .map_err(|e| CaseError(format!("{}: cannot read the case file: {e}", path.display())))?;
        let base = path.parent().map(Path::to_path_buf).unwrap_or_default();
        Case::parse(&text, &path.display().to_string(), base)
    }

    /// The built-in default case.
    pub fn default_case() -> Case {
        Case::parse(DEFAULT_CASE, "built-in default case", PathBuf::new()).expect("the default case is valid")
    }

    /// Parses and checks case text; `origin` names it in errors.
    pub fn parse(text: &str, origin: &str, base_dir: PathBuf) -> Result<Case, CaseError> {
        let file: CaseFile =
            toml::from_str(text).map_err(|e| CaseError(format!("{origin}: {}", e.to_string().trim_end())))?;
        let expr = |key: &str, e: &Expression| {
            let source = e.text();
            Expr::parse(&source)
                .map_err(|err| CaseError(format!("{origin}: key '{key}' = \"{source}\": {err}")))
        };
        for (key, value) in [("mu1", file.mu1), ("mu2", file.mu2)] {
            if !(value > 0.0 && value.is_finite()) {
                return Err(CaseError(format!(
                    "{origin}: key '{key}' = {value}: the tension must be a positive number"
                )));
            }
        }
        let degree = file.quadrature.degree;
        if degree > Quadrature::MAX_DEGREE {
            return Err(CaseError(format!(
                "{origin}: key 'quadrature.degree' = {degree}: at most {} is available",
                Quadrature::MAX_DEGREE
            )));
        }
        if file.solver.max_iterations == 0 {
            return Err(CaseError(format!(
                "{origin}: key 'solver.max_iterations' must be at least 1"
            )));
        }
        match &file.mesh {
            MeshSpec::Rectangle { corners, n, .. } => {
                if n[0] == 0 || n[1] == 0 {
                    return Err(CaseError(format!(
                        "{origin}: key 'mesh.n' = {n:?}: need at least one cell each way"
                    )));
                }
                let [c0, c1] = corners;
                if !(c1[0] > c0[0] && c1[1] > c0[1]) || corners.iter().flatten().any(|v| !v.is_finite()) {
                    return Err(CaseError(format!(
                        "{origin}: key 'mesh.corners' = {corners:?}: need [[x0, y0], [x1, y1]] with x0 < x1, y0 < y1"
                    )));
                }
            }
            MeshSpec::Lshape { n, grading, .. } => {
                if *n < 2 {
                    return Err(CaseError(format!(
                        "{origin}: key 'mesh.n' = {n}: need at least 2"
                    )));
                }
                if !(*grading >= 1.0 && grading.is_finite()) {
                    return Err(CaseError(format!(
                        "{origin}: key 'mesh.grading' = {grading}: need a number ≥ 1"
                    )));
                }
            }
            MeshSpec::File { .. } => {}
        }
        let data = Data {
            mu1: file.mu1,
            mu2: file.mu2,
            f1: expr("f1", &file.f1)?,
            f2: expr("f2", &file.f2)?,
            g: expr("g", &file.g)?,
            quadrature: Quadrature { degree },
        };
        let exact = match &file.exact {
            None => None,
            Some(e) => {
                let grad = |key: &str, g: &Option<[Expression; 2]>| -> Result<Option<[Expr; 2]>, CaseError> {
                    g.as_ref()
                        .map(|[gx, gy]| Ok([expr(key, gx)?, expr(key, gy)?]))
                        .transpose()
                };
                Some(Exact {
                    u1: expr("exact.u1", &e.u1)?,
                    u2: expr("exact.u2", &e.u2)?,
                    lambda: expr("exact.lambda", &e.lambda)?,
                    grad_u1: grad("exact.grad_u1", &e.grad_u1)?,
                    grad_u2: grad("exact.grad_u2", &e.grad_u2)?,
                })
            }
        };
        let options = SolverOptions {
            max_iterations: file.solver.max_iterations,
        };
        Ok(Case {
            origin: origin.to_string(),
            text: text.to_string(),
            file,
            data,
            exact,
            options,
            base_dir,
        })
    }

    /// Overrides the number of cells per side of a built-in mesh.
    pub fn set_cells(&mut self, cells: usize) {
        match &mut self.file.mesh {
            MeshSpec::Rectangle { n, .. } => *n = [cells, cells],
            MeshSpec::Lshape { n, .. } => *n = cells,
            MeshSpec::File { .. } => {}
        }
    }

    /// Sets the grading exponent of an L-shaped mesh.
    pub fn set_grading(&mut self, g: f64) -> Result<(), CaseError> {
        match &mut self.file.mesh {
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

    /// Cells per side of a built-in mesh.
    pub fn cells(&self) -> Option<usize> {
        match &self.file.mesh {
            MeshSpec::Rectangle { n, .. } => Some(n[0].max(n[1])),
            MeshSpec::Lshape { n, .. } => Some(*n),
            MeshSpec::File { .. } => None,
        }
    }

    /// Fails early when a built-in mesh would not fit in the available memory.
    pub fn check_memory(&self) -> Result<(), CaseError> {
        let vertices = match &self.file.mesh {
            MeshSpec::Rectangle { n, diagonal, .. } => {
                let crossed = usize::from(*diagonal == Diagonal::Crossed);
                (n[0].saturating_add(1))
                    .saturating_mul(n[1].saturating_add(1))
                    .saturating_add(crossed.saturating_mul(n[0].saturating_mul(n[1])))
            }
            MeshSpec::Lshape { n, .. } => n.saturating_add(2).saturating_mul(n.saturating_add(2)),
            MeshSpec::File { .. } => return Ok(()),
        };
        crate::mesh::check_memory(vertices).map_err(|e| CaseError(format!("{}: mesh: {e}", self.origin)))
    }

    /// Builds or reads the mesh.
    pub fn mesh(&self) -> Result<Mesh, CaseError> {
        let named = |e: crate::mesh::MeshError| CaseError(format!("{}: mesh: {e}", self.origin));
        match &self.file.mesh {
            MeshSpec::Rectangle { corners, n, diagonal } => {
                self.check_memory()?;
                Mesh::rectangle(corners[0], corners[1], n[0], n[1], *diagonal).map_err(named)
            }
            MeshSpec::Lshape { n, diagonal, grading } => {
                self.check_memory()?;
                Mesh::l_shape(*n, *diagonal, *grading).map_err(named)
            }
            MeshSpec::File { path } => {
                let path = self.base_dir.join(path);
                crate::io::read_mesh(&path).map_err(|e| CaseError(e.to_string()))
            }
        }
    }
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
        assert!(err(&base.replace("rectangle", "circle")).contains("circle"));
    }
}
