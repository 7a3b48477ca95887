//! The data of problem (1.1) and the discrete problem (3.4) they define on one mesh.
//!
//! (3.4): find (u1h, u2h) in X_h × X_h with u1h = g_h and u2h = g2_h on ∂ω and u1h − u2h ≥ 0 at
//! the vertices, minimising Σ_i μ_i/2 ∫|∇u_ih|² − (f_i, u_ih). On T_h it is given by the
//! stiffness matrix K_ab = ∫∇φ_b·∇φ_a, the loads (f_i, φ_a), the masses m_a = ∫φ_a (which pair
//! λ_h with the hat functions, Remark 11) and g_h, g2_h, the Lagrange interpolants of g, g2 on ∂ω
//! (the paper's g2 = 0 is the default).
//!
//! The classical obstacle problem is the same inequality with membrane 2 replaced by a rigid body:
//! find u_h in X_h with u_h = g_h on ∂ω and u_h ≥ ψ_h at the vertices, minimising
//! μ/2 ∫|∇u_h|² − (f, u_h), ψ_h the Lagrange interpolant of ψ. It is kept here as u1h = u_h with
//! u2h = ψ_h fixed at every vertex, so that the gap w = u1h − u2h ≥ 0 and the action
//! λ_a m_a = μ(K u1h)_a − (f, φ_a) are those of (3.4) and (4.5).

use crate::assembly::{self, Quadrature, Stiffness};
use crate::datum::{self, Datum, On};
use crate::expr::Expr;
use crate::mesh::{Mesh, Number, Point};
use std::fmt;

/// The data of problem (1.1), or of the obstacle problem: membrane 1's tension, load and boundary
/// height, and what lies below it.
#[derive(Debug, Clone)]
pub struct Data {
    /// μ1 > 0 (the obstacle problem's μ).
    pub mu1: f64,
    /// The load on membrane 1 (the obstacle problem's f), one expression or one per physical
    /// surface.
    pub f1: Datum,
    /// The height of membrane 1 on ∂ω, one expression or one per physical curve.
    pub g: Datum,
    /// Membrane 2 or a rigid obstacle.
    pub lower: Lower,
    /// The rule for the loads (f_i, φ_a).
    pub quadrature: Quadrature,
}

/// What membrane 1 lies on.
#[derive(Debug, Clone)]
pub enum Lower {
    /// Membrane 2 of (1.1).
    Membrane {
        /// μ2 > 0.
        mu2: f64,
        /// Its load (per physical surface, or one expression).
        f2: Datum,
        /// Its height on ∂ω (0 in the paper; per physical curve, or one expression).
        g2: Datum,
    },
    /// A rigid obstacle u1 ≥ ψ: the classical obstacle problem.
    Rigid {
        /// ψ (per physical surface, or one expression).
        psi: Datum,
    },
}

impl Data {
    /// The data of (1.1) with u2 = 0 on ∂ω, with μ1, μ2 checked to be positive and finite.
    pub fn new(
        mu: [f64; 2],
        f1: impl Into<Datum>,
        f2: impl Into<Datum>,
        g: impl Into<Datum>,
        quadrature: Quadrature,
    ) -> Result<Self, DataError> {
        for (name, value) in [("mu1", mu[0]), ("mu2", mu[1])] {
            check_tension(name, value)?;
        }
        let g2 = Expr::parse("0").expect("0 is an expression").into();
        Ok(Data {
            mu1: mu[0],
            f1: f1.into(),
            g: g.into(),
            lower: Lower::Membrane {
                mu2: mu[1],
                f2: f2.into(),
                g2,
            },
            quadrature,
        })
    }

    /// The same data with u2 = `g2` on ∂ω; no change below a rigid obstacle.
    pub fn with_g2(mut self, height: impl Into<Datum>) -> Self {
        if let Lower::Membrane { g2, .. } = &mut self.lower {
            *g2 = height.into();
        }
        self
    }

    /// The data of the obstacle problem: μ (checked), f, the obstacle ψ and g.
    pub fn obstacle(
        mu: f64,
        f: impl Into<Datum>,
        psi: impl Into<Datum>,
        g: impl Into<Datum>,
        quadrature: Quadrature,
    ) -> Result<Self, DataError> {
        check_tension("mu", mu)?;
        Ok(Data {
            mu1: mu,
            f1: f.into(),
            g: g.into(),
            lower: Lower::Rigid { psi: psi.into() },
            quadrature,
        })
    }

    /// Checks every datum given per group against the groups of `mesh`: a mesh with groups, the
    /// table's names among them, an entry for the group of every triangle (boundary edge).
    pub fn check_groups(&self, mesh: &Mesh) -> Result<(), DataError> {
        let (first, second) = match &self.lower {
            Lower::Membrane { f2, g2, .. } => (("f2", f2, On::Surfaces), ("g2", g2, On::Curves)),
            Lower::Rigid { psi } => (("psi", psi, On::Surfaces), ("psi", psi, On::Surfaces)),
        };
        let (f1, g) = match &self.lower {
            Lower::Membrane { .. } => ("f1", "g"),
            Lower::Rigid { .. } => ("f", "g"),
        };
        for (name, datum, on) in [
            (f1, &self.f1, On::Surfaces),
            (g, &self.g, On::Curves),
            first,
            second,
        ] {
            datum.pieces(name, mesh, on)?;
        }
        Ok(())
    }

    /// μ2, when membrane 1 lies on membrane 2.
    pub fn mu2(&self) -> Option<f64> {
        match self.lower {
            Lower::Membrane { mu2, .. } => Some(mu2),
            Lower::Rigid { .. } => None,
        }
    }

    /// f2, when membrane 1 lies on membrane 2.
    pub fn f2(&self) -> Option<&Datum> {
        match &self.lower {
            Lower::Membrane { f2, .. } => Some(f2),
            Lower::Rigid { .. } => None,
        }
    }

    /// Whether membrane 1 lies on a rigid obstacle (the classical obstacle problem).
    pub fn is_obstacle(&self) -> bool {
        matches!(self.lower, Lower::Rigid { .. })
    }
}

/// A tension is a positive, finite, normal number: a subnormal one (below 2.2e-308) has lost
/// significant bits, and the loads divided by it overflow.
fn check_tension(name: &'static str, value: f64) -> Result<(), DataError> {
    match value >= f64::MIN_POSITIVE && value.is_finite() {
        true => Ok(()),
        false => Err(DataError::Tension { name, value }),
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
        /// The physical group whose entry it is, for a datum given per group.
        group: Option<String>,
        /// Where.
        point: [f64; 2],
        /// The value there.
        value: f64,
    },
    /// g_h below the height of what lies below (g2 or ψ) at a boundary vertex.
    BoundaryBelowLower {
        /// "g2" or "psi".
        lower: &'static str,
        /// The vertex.
        point: [f64; 2],
        /// g there.
        g: f64,
        /// g2 or ψ there.
        value: f64,
    },
    /// A datum given per physical group that does not fit the mesh's groups.
    Group {
        /// The datum's key.
        name: &'static str,
        /// What does not fit: a missing or unknown group, a mesh without groups.
        why: String,
    },
    /// A vertex value (g, g2 or ψ) that two groups meeting at a vertex give differently.
    Jump {
        /// The datum's key.
        name: &'static str,
        /// The vertex.
        point: [f64; 2],
        /// The two groups.
        groups: [String; 2],
        /// Their values there.
        values: [f64; 2],
    },
}

impl fmt::Display for DataError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            DataError::Tension { name, value } => {
                if *value > 0.0 && value.is_finite() {
                    write!(
                        f,
                        "key '{name}' = {value:e}: the tension is below double precision's normal \
                         range ({:e}), where it loses significant digits: rescale the data",
                        f64::MIN_POSITIVE
                    )
                } else {
                    write!(f, "key '{name}' = {value}: the tension must be a positive number")
                }
            }
            DataError::NotFinite {
                name,
                group,
                point,
                value,
            } => write!(
                f,
                "{name}{} is {value} at {}: every datum must be finite in ω and on ∂ω",
                group.as_ref().map_or(String::new(), |g| format!(".{g}")),
                Point(*point)
            ),
            DataError::BoundaryBelowLower {
                lower,
                point,
                g,
                value,
            } => write!(
                f,
                "g = {} < {lower} = {} at the boundary vertex {}: (3.4) takes g_h, the \
                 interpolant of g, which must be ≥ {lower} at every boundary vertex of the mesh \
                 ({})",
                Number(*g),
                Number(*value),
                Point(*point),
                match *lower {
                    "psi" => "the membrane may not lie below the obstacle",
                    _ => "membrane 1 may not lie below membrane 2",
                }
            ),
            DataError::Group { name, why } => write!(f, "key '{name}': {why}"),
            DataError::Jump {
                name,
                point,
                groups,
                values,
            } => write!(
                f,
                "key '{name}': the groups '{}' and '{}' meet at the vertex {} with {name} = {} and \
                 {}: a vertex value must agree (to 1e-12 relative) where groups meet",
                groups[0],
                groups[1],
                Point(*point),
                values[0],
                values[1]
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
    /// (f2, φ_a) at every vertex; empty below a rigid obstacle.
    pub load2: Vec<f64>,
    /// g_h: g at the boundary vertices, 0 inside.
    pub g_h: Vec<f64>,
    /// The gap w = u1h − u2h at the boundary vertices (g − g2 or g − ψ), 0 inside.
    pub gap_h: Vec<f64>,
    /// ψ_h at every vertex below a rigid obstacle; empty below a membrane.
    pub psi_h: Vec<f64>,
}

/// What the data fix at the vertices: g_h, the gap on ∂ω and ψ_h ([`DiscreteProblem`]'s fields).
#[derive(Debug, Clone)]
pub struct Heights {
    /// g_h.
    pub g: Vec<f64>,
    /// The gap on ∂ω.
    pub gap: Vec<f64>,
    /// ψ_h, or empty.
    pub psi: Vec<f64>,
}

impl DiscreteProblem {
    /// Assembles (3.4) on `mesh`; the loads by the data's quadrature rule.
    pub fn new(mesh: Mesh, data: &Data) -> Result<Self, DataError> {
        let heights = boundary_values(&mesh, data)?;
        let f1 = if data.is_obstacle() { "f" } else { "f1" };
        let not_finite =
            |(name, datum): (&'static str, &Datum), e: assembly::NotFinite| DataError::NotFinite {
                name,
                group: datum.group_of_triangle(&mesh, e.triangle),
                point: e.point,
                value: e.value,
            };
        let loads = match &data.lower {
            Lower::Membrane { f2, .. } => {
                let both = [
                    &data.f1.pieces(f1, &mesh, On::Surfaces)?,
                    &f2.pieces("f2", &mesh, On::Surfaces)?,
                ];
                assembly::loads(&mesh, both, data.quadrature)
                    .map_err(|(e, bad)| not_finite([(f1, &data.f1), ("f2", f2)][e], bad))?
            }
            Lower::Rigid { .. } => {
                let one = [&data.f1.pieces(f1, &mesh, On::Surfaces)?];
                let [load] = assembly::loads(&mesh, one, data.quadrature)
                    .map_err(|(_, bad)| not_finite((f1, &data.f1), bad))?;
                [load, Vec::new()]
            }
        };
        Ok(Self::with_loads(mesh, data, heights, loads))
    }

    /// The problem on `mesh` with its `heights` ([`boundary_values`]) and the loads given. For
    /// the coarse levels of nested iteration, the loads restricted from a finer level by Pᵀ
    /// ([`crate::mesh::Prolongation::restrict`]): exactly their own loads (with the finer mesh's
    /// quadrature) when the meshes are nested, and no quadrature to evaluate.
    pub fn with_loads(mesh: Mesh, data: &Data, heights: Heights, [load1, load2]: [Vec<f64>; 2]) -> Self {
        let stiffness = Stiffness::assemble(&mesh);
        let mass = assembly::lumped_mass(&mesh);
        DiscreteProblem {
            mesh,
            data: data.clone(),
            stiffness,
            mass,
            load1,
            load2,
            g_h: heights.g,
            gap_h: heights.gap,
            psi_h: heights.psi,
        }
    }

    /// The load (f_w, φ_a) of the obstacle problem for the gap w at vertex a, and its factor μ*
    /// (μ* K w − f_w = λ m): (μ2 (f1, φ_a) − μ1 (f2, φ_a))/(μ1+μ2) with μ* = μ1μ2/(μ1+μ2) on
    /// membrane 2; (f, φ_a) − μ (K ψ_h)_a with μ* = μ on a rigid obstacle.
    pub fn gap_load(&self, a: usize) -> f64 {
        match self.data.lower {
            Lower::Membrane { mu2, .. } => {
                let mu1 = self.data.mu1;
                (mu2 * self.load1[a] - mu1 * self.load2[a]) / (mu1 + mu2)
            }
            Lower::Rigid { .. } => self.load1[a] - self.data.mu1 * self.stiffness.row_dot(a, &self.psi_h),
        }
    }

    /// μ* of [`DiscreteProblem::gap_load`].
    pub fn gap_tension(&self) -> f64 {
        match self.data.lower {
            Lower::Membrane { mu2, .. } => self.data.mu1 * mu2 / (self.data.mu1 + mu2),
            Lower::Rigid { .. } => self.data.mu1,
        }
    }

    /// |(f1, φ_a)| + |(f2, φ_a)|: the size of the loads at a.
    pub fn load_size(&self, a: usize) -> f64 {
        self.load1[a].abs() + self.load2.get(a).map_or(0.0, |l| l.abs())
    }

    /// The membranes that have an equation, with `u` their displacements in order: the two of
    /// (1.1), −μ1Δu1 − λ = f1 and −μ2Δu2 + λ = f2, or the one above a rigid obstacle,
    /// −μΔu − λ = f.
    pub fn membranes<'a>(&'a self, u: [&'a [f64]; 2]) -> Vec<Membrane<'a>> {
        let one = |which: Which, mu, f, load: &'a [f64]| Membrane {
            mu,
            f,
            load,
            u: u[(which == Which::Second) as usize],
            sign: if which == Which::Second { -1.0 } else { 1.0 },
            which,
        };
        match &self.data.lower {
            Lower::Membrane { mu2, f2, .. } => vec![
                one(Which::First, self.data.mu1, &self.data.f1, &self.load1),
                one(Which::Second, *mu2, f2, &self.load2),
            ],
            Lower::Rigid { .. } => vec![one(Which::Alone, self.data.mu1, &self.data.f1, &self.load1)],
        }
    }
}

/// One membrane's equation −μΔu ∓ λ = f, discretised.
#[derive(Debug, Clone, Copy)]
pub struct Membrane<'a> {
    /// μ.
    pub mu: f64,
    /// f.
    pub f: &'a Datum,
    /// (f, φ_a) at every vertex.
    pub load: &'a [f64],
    /// u_h at every vertex.
    pub u: &'a [f64],
    /// The sign of λ in −μΔu = f ± λ: + for membrane 1 (and above an obstacle), − for membrane 2.
    pub sign: f64,
    /// Which: membrane 1, membrane 2, or the one membrane above an obstacle.
    pub which: Which,
}

/// Which membrane a [`Membrane`] is.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Which {
    /// Membrane 1 of (1.1).
    First,
    /// Membrane 2 of (1.1).
    Second,
    /// The membrane above a rigid obstacle.
    Alone,
}

impl Which {
    /// Of three names, the one for this membrane: `names` = [membrane 1's, membrane 2's, the
    /// one above an obstacle's].
    pub fn named(self, names: [&'static str; 3]) -> &'static str {
        names[self as usize]
    }
}

/// The relative round-off below which g < g2 (or g < ψ) at a boundary vertex counts as contact.
const ROUND_OFF: f64 = 1e-12;

/// The heights on `mesh`: g_h and the gap at the boundary vertices (finite, g ≥ g2 or g ≥ ψ), 0
/// inside, and ψ_h (finite) at every vertex below a rigid obstacle. Only the vertex values enter
/// (3.4), so they are what is checked.
pub fn boundary_values(mesh: &Mesh, data: &Data) -> Result<Heights, DataError> {
    data.check_groups(mesh)?;
    let n = mesh.n_vertices();
    let psi: Vec<f64> = match &data.lower {
        Lower::Rigid { psi } => (datum::vertex_values("psi", psi, mesh, On::Surfaces)?.into_iter())
            .map(|v| v.expect("ψ at every vertex"))
            .collect(),
        Lower::Membrane { .. } => Vec::new(),
    };
    let g = datum::vertex_values("g", &data.g, mesh, On::Curves)?;
    let g2 = match &data.lower {
        Lower::Membrane { g2, .. } => Some(datum::vertex_values("g2", g2, mesh, On::Curves)?),
        Lower::Rigid { .. } => None,
    };
    let lower_at = |a: usize| match &g2 {
        Some(g2) => ("g2", g2[a].expect("g2 at every boundary vertex")),
        None => ("psi", psi[a]),
    };
    let boundary = || (0..n).filter(|&a| mesh.on_boundary[a]);
    // g ≥ g2 (ψ) up to round-off of the data's size (of ψ over ω): sin(πx) at x = 1 is 1.2e-16,
    // not 0. Within it the membrane touches: ψ_h := g there, so that w_h = 0 exactly on ∂ω.
    let size = (boundary())
        .map(|a| {
            g[a].expect("g at every boundary vertex")
                .abs()
                .max(lower_at(a).1.abs())
        })
        .chain(psi.iter().map(|p| p.abs()))
        .fold(0.0, f64::max);
    let (mut g_h, mut gap, mut touching) = (vec![0.0; n], vec![0.0; n], Vec::new());
    for a in boundary() {
        let (g, (lower, value)) = (g[a].expect("g at every boundary vertex"), lower_at(a));
        if g < value - ROUND_OFF * size {
            return Err(DataError::BoundaryBelowLower {
                lower,
                point: mesh.points[a],
                g,
                value,
            });
        }
        (g_h[a], gap[a]) = (g, (g - value).max(0.0));
        if g < value {
            touching.push((a, g));
        }
    }
    let mut psi = psi;
    for (a, g) in touching {
        if let Some(psi) = psi.get_mut(a) {
            *psi = g;
        }
    }
    Ok(Heights { g: g_h, gap, psi })
}
