//! The data of problem (1.1) and the discrete problem (3.4) they define on one mesh.
//!
//! (3.4): find (u1h, u2h) in X_h × X_h with u1h = g_h and u2h = 0 on ∂ω and u1h − u2h ≥ 0 at the
//! vertices, minimising Σ_i μ_i/2 ∫|∇u_ih|² − (f_i, u_ih). On T_h it is given by the stiffness
//! matrix K_ab = ∫∇φ_b·∇φ_a, the loads (f_i, φ_a), the masses m_a = ∫φ_a (which pair λ_h with
//! the hat functions, Remark 11) and g_h, the Lagrange interpolant of g on ∂ω.

use crate::assembly::{self, Quadrature, Stiffness};
use crate::expr::Expr;
use crate::mesh::Mesh;
use std::fmt;

/// The data of problem (1.1): tensions, loads and the boundary height of membrane 1.
#[derive(Debug, Clone)]
pub struct Data {
    /// μ1 > 0.
    pub mu1: f64,
    /// μ2 > 0.
    pub mu2: f64,
    /// The load on membrane 1.
    pub f1: Expr,
    /// The load on membrane 2.
    pub f2: Expr,
    /// The height of membrane 1 on ∂ω.
    pub g: Expr,
    /// The rule for the loads (f_i, φ_a).
    pub quadrature: Quadrature,
}

impl Data {
    /// The data, with μ1, μ2 checked to be positive and finite.
    pub fn new(mu: [f64; 2], f1: Expr, f2: Expr, g: Expr, quadrature: Quadrature) -> Result<Self, DataError> {
        for (name, value) in [("mu1", mu[0]), ("mu2", mu[1])] {
            if !(value > 0.0 && value.is_finite()) {
                return Err(DataError::Tension { name, value });
            }
        }
        Ok(Data {
            mu1: mu[0],
            mu2: mu[1],
            f1,
            f2,
            g,
            quadrature,
        })
    }
}

/// Data that do not define a discrete problem on a mesh.
#[derive(Debug, Clone, PartialEq)]
pub enum DataError {
    /// μ1 or μ2 is not a positive number.
    Tension {
        /// "mu1" or "mu2".
        name: &'static str,
        /// Its value.
        value: f64,
    },
    /// A datum is NaN or infinite at a point of ω.
    NotFinite {
        /// The datum's key.
        name: &'static str,
        /// Where.
        point: [f64; 2],
        /// The value there.
        value: f64,
    },
    /// g_h < 0 at a boundary vertex.
    NegativeBoundaryHeight {
        /// The vertex.
        point: [f64; 2],
        /// g there.
        value: f64,
    },
}

impl fmt::Display for DataError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            DataError::Tension { name, value } => {
                write!(f, "key '{name}' = {value}: the tension must be a positive number")
            }
            DataError::NotFinite { name, point, value } => write!(
                f,
                "{name} is {value} at ({}, {}): every datum must be finite in ω",
                point[0], point[1]
            ),
            DataError::NegativeBoundaryHeight { point, value } => write!(
                f,
                "g = {value} < 0 at the boundary vertex ({}, {}): (3.4) takes g_h, the interpolant of g, \
                 which must be ≥ 0 at every boundary vertex of the mesh (g ≥ 0 on ∂ω)",
                point[0], point[1]
            ),
        }
    }
}

impl std::error::Error for DataError {}

/// The discrete problem (3.4) on one mesh.
#[derive(Debug, Clone)]
pub struct DiscreteProblem {
    /// T_h.
    pub mesh: Mesh,
    /// The data it discretises.
    pub data: Data,
    /// K.
    pub stiffness: Stiffness,
    /// m_a = ∫φ_a.
    pub mass: Vec<f64>,
    /// (f1, φ_a) at every vertex.
    pub load1: Vec<f64>,
    /// (f2, φ_a) at every vertex.
    pub load2: Vec<f64>,
    /// g_h: g at the boundary vertices, 0 inside.
    pub g_h: Vec<f64>,
}

impl DiscreteProblem {
    /// Assembles (3.4) on `mesh`; the loads by the data's quadrature rule.
    pub fn new(mesh: Mesh, data: &Data) -> Result<Self, DataError> {
        let g_h = boundary_values(&mesh, data)?;
        let load = |name, f: &Expr| {
            assembly::load(&mesh, f, data.quadrature).map_err(|e| DataError::NotFinite {
                name,
                point: e.point,
                value: e.value,
            })
        };
        let loads = [load("f1", &data.f1)?, load("f2", &data.f2)?];
        Ok(Self::with_loads(mesh, data, g_h, loads))
    }

    /// The problem on `mesh` with its boundary values `g_h` ([`boundary_values`]) and the loads
    /// given. For the coarse levels of nested iteration, the loads restricted from a finer level
    /// by Pᵀ ([`crate::mesh::Prolongation::restrict`]): exactly their own loads (with the finer
    /// mesh's quadrature) when the meshes are nested, and no quadrature to evaluate.
    pub fn with_loads(mesh: Mesh, data: &Data, g_h: Vec<f64>, [load1, load2]: [Vec<f64>; 2]) -> Self {
        let stiffness = Stiffness::assemble(&mesh);
        let mass = assembly::lumped_mass(&mesh);
        DiscreteProblem {
            mesh,
            data: data.clone(),
            stiffness,
            mass,
            load1,
            load2,
            g_h,
        }
    }
}

/// g_h: g at the boundary vertices (finite, ≥ 0), 0 inside. Only the vertex values enter (3.4),
/// so they are what is checked.
pub fn boundary_values(mesh: &Mesh, data: &Data) -> Result<Vec<f64>, DataError> {
    let mut g_h = vec![0.0; mesh.n_vertices()];
    for (a, p) in mesh.points.iter().enumerate() {
        if mesh.on_boundary[a] {
            let value = data.g.eval(p[0], p[1]);
            if !value.is_finite() {
                return Err(DataError::NotFinite {
                    name: "g",
                    point: *p,
                    value,
                });
            }
            if value < 0.0 {
                return Err(DataError::NegativeBoundaryHeight { point: *p, value });
            }
            g_h[a] = value;
        }
    }
    Ok(g_h)
}
