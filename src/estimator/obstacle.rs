//! The lifting above a rigid obstacle (docs/a-posteriori.md §14). The bound of §3 needs
//! u_h + z ≥ ψ for the obstacle ψ itself, not only ψ_h at the vertices: on the contact set
//! u_h = ψ_h dips below a concave ψ inside every triangle. With ℓ the lifting of g − g_h (§5),
//!
//! ```text
//! z = max(ℓ, ψ − u_h)
//! ```
//!
//! has the trace g − g_h (g ≥ ψ on ∂ω) and u_h + z = max(u_h + ℓ, ψ) ≥ ψ. On a cell κ of S_h where
//! ψ − u_h exceeds min ℓ at a point of the rule ("the obstacle is above u_h on κ"),
//!
//! ```text
//! ‖∇z‖²_κ ≤ ‖∇ℓ‖²_κ + ‖∇(ψ − u_h)‖²_κ,     (λ_h, u_h + z − ψ)_κ ≤ (λ_h, max ℓ⁺)_κ + (λ_h, (u_h − ψ)⁺)_κ,
//! ```
//!
//! and on every other cell z = ℓ: (λ_h, u_h + z − ψ)_κ = (λ_h, ℓ)_κ + (λ_h, u_h − ψ)_κ. ∇ψ is
//! a difference quotient of the case's expression; the rule has degree max(q, 4) on each κ.

use super::boundary;
use crate::assembly::{gradients, Quadrature};
use crate::datum::{self, Pieces};
use crate::mesh::DualMesh;
use crate::parallel::{self, PIECE};
use crate::problem::DiscreteProblem;

/// The step of the difference quotient for ∇ψ, relative to the diameter of the triangle (fourth
/// order: error O(step⁴ ψ⁽⁵⁾)).
const STEP: f64 = 1e-3;

/// The obstacle's part of the lifting on one triangle K.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct OnTriangle {
    /// Σ ‖∇(ψ − u_h)‖²_κ over the cells κ ⊂ K where the obstacle is above u_h.
    pub grad2: f64,
    /// The bound of (λ_h, u_h + z − ψ)_K: the whole contact term of K.
    pub contact: f64,
    /// Bit c set where the obstacle is above u_h on the cell c of K.
    pub above: u8,
}

/// The obstacle's part of z on every triangle: ψ given by `psi`, u_h = `u`, λ_a = `lambda`, ℓ as
/// [`boundary::lifting`] computed it.
pub fn terms(
    problem: &DiscreteProblem,
    dual: &DualMesh,
    psi: &Pieces,
    u: &[f64],
    lambda: &[f64],
    lifting: &[boundary::OnTriangle],
) -> Vec<OnTriangle> {
    let mesh = &problem.mesh;
    let rule = rule(problem);
    let mut out = vec![OnTriangle::default(); mesh.n_triangles()];
    parallel::map_mut(&mut out, PIECE, |base, out| {
        let cells = 6 * base..6 * (base + out.len());
        // Per cell: whether the obstacle is above u_h, ‖∇(ψ − u_h)‖² there, and λ_h's pairings.
        let mut cell = |s: usize, points: &[crate::assembly::QuadraturePoint], [psi_at]: [&[f64]; 1]| {
            let t = s / 6;
            let tri = mesh.triangle(t);
            let frame = DualMesh::frame(s);
            let u_at = |b: [f64; 3]| -> f64 {
                (0..3)
                    .map(|j| (0..3).map(|v| b[v] * frame[v][j]).sum::<f64>() * u[tri[j]])
                    .sum()
            };
            let l = &lifting[t];
            // ψ − u_h at the rule's points, with their weights.
            let dip = || (points.iter().zip(psi_at)).map(|(p, psi)| (p.weight, psi - u_at(p.barycentric)));
            let above = dip().any(|(_, d)| d > l.range[0]);
            let lambda_h = lambda[dual.owner(s)];
            let o = &mut out[t - base];
            if above {
                o.above |= 1 << (s % 6);
                o.grad2 += grad2(mesh, t, psi, u, points);
                o.contact += lambda_h * dip().map(|(w, d)| w * (-d).max(0.0)).sum::<f64>();
            } else {
                o.contact -= lambda_h * dip().map(|(w, d)| w * d).sum::<f64>();
            }
            above
        };
        let mut above = vec![false; cells.len()];
        let first = cells.start;
        datum::visit(
            &rule,
            |s| dual.corners(s),
            |s| s / 6,
            cells,
            [psi],
            |s, points, values| {
                above[s - first] = cell(s, points, values);
            },
        );
        for (k, o) in out.iter_mut().enumerate() {
            let (t, l) = (base + k, &lifting[base + k]);
            o.contact += match above[6 * k..6 * k + 6].iter().any(|&a| a) {
                // (λ_h, ℓ)_K ≤ Σ_κ λ_h|κ| |κ| max ℓ⁺ where the obstacle is above u_h on some κ.
                true => (6 * t..6 * t + 6)
                    .map(|s| lambda[dual.owner(s)] * mesh.area(t) / 6.0 * l.range[1])
                    .sum(),
                false => l.with_lambda,
            };
        }
    });
    out
}

/// The rule on the cells of S_h: the case's, of degree 4 at least.
pub(super) fn rule(problem: &DiscreteProblem) -> Quadrature {
    Quadrature {
        degree: problem.data.quadrature.degree.max(4),
    }
}

/// ‖∇(ψ − u_h)‖²_κ by the rule's `points` on κ ⊂ K = triangle t, ∇ψ by a fourth-order central
/// difference.
fn grad2(
    mesh: &crate::mesh::Mesh,
    t: usize,
    psi: &Pieces,
    u: &[f64],
    points: &[crate::assembly::QuadraturePoint],
) -> f64 {
    let tri = mesh.triangle(t);
    let g = gradients(mesh.corners(t));
    let grad_u = [0, 1].map(|k| (0..3).map(|j| g[j][k] * u[tri[j]]).sum::<f64>());
    let psi = Differences::new(psi.on_triangle(t), mesh.diameter(t));
    let x: Vec<[f64; 2]> = points.iter().map(|p| p.x).collect();
    (points.iter().zip(psi.at(&x)))
        .map(|(p, psi)| {
            let d = [0, 1].map(|k| psi.gradient[k] - grad_u[k]);
            p.weight * (d[0] * d[0] + d[1] * d[1])
        })
        .sum()
}

/// Derivatives of ψ on one triangle by fourth-order central differences of step [`STEP`] × its
/// diameter.
struct Differences<'e> {
    psi: &'e crate::expr::Expr,
    h: f64,
}

/// ψ, ∇ψ and Δψ at a point.
struct Stencil {
    value: f64,
    gradient: [f64; 2],
    laplacian: f64,
}

/// The offsets of the stencil from its centre, in steps h: the centre, then ±1 and ±2 along x
/// and along y.
const OFFSETS: [[f64; 2]; 9] = [
    [0.0, 0.0],
    [1.0, 0.0],
    [-1.0, 0.0],
    [2.0, 0.0],
    [-2.0, 0.0],
    [0.0, 1.0],
    [0.0, -1.0],
    [0.0, 2.0],
    [0.0, -2.0],
];

impl<'e> Differences<'e> {
    fn new(psi: &'e crate::expr::Expr, diameter: f64) -> Self {
        Differences {
            psi,
            h: STEP * diameter,
        }
    }

    /// ψ, ∇ψ and Δψ at each of `points`, ψ evaluated at all their stencils together.
    fn at(&self, points: &[[f64; 2]]) -> Vec<Stencil> {
        let h = self.h;
        let stencils: Vec<[f64; 2]> = (points.iter())
            .flat_map(|x| OFFSETS.map(|o| [x[0] + o[0] * h, x[1] + o[1] * h]))
            .collect();
        let mut values = vec![0.0; stencils.len()];
        self.psi.eval_many(&stencils, &mut values);
        (values.chunks_exact(OFFSETS.len()))
            .map(|v| {
                // Along axis k: ψ(x ± h e_k) = v[1 + 4k], v[2 + 4k]; ψ(x ± 2h e_k) = v[3 + 4k], v[4 + 4k].
                let along = |k: usize| [v[1 + 4 * k], v[2 + 4 * k], v[3 + 4 * k], v[4 + 4 * k]];
                let gradient = [0, 1].map(|k| {
                    let [p1, m1, p2, m2] = along(k);
                    (8.0 * (p1 - m1) - p2 + m2) / (12.0 * h)
                });
                let laplacian = (0..2)
                    .map(|k| {
                        let [p1, m1, p2, m2] = along(k);
                        (16.0 * (p1 + m1) - p2 - m2 - 30.0 * v[0]) / (12.0 * h * h)
                    })
                    .sum();
                Stencil {
                    value: v[0],
                    gradient,
                    laplacian,
                }
            })
            .collect()
    }
}

/// What the bound through ũ = u_h + z (§14, Theorem (O')) needs of one cell κ where the obstacle
/// is above u_h: an upper bound of ‖μ∇ũ + τ‖²_κ (∇ũ = ∇ψ where ψ > u_h, ∇u_h elsewhere: at a
/// cell where the rule's points disagree, the sum of the two squares), and (λ_ψ⁻, ψ − u_h)_κ with
/// λ_ψ = −μΔψ − f, the action the obstacle would exert where it held the membrane.
pub struct AboveCell {
    /// The bound of ‖μ∇ũ + τ‖²_κ.
    pub flux2: f64,
    /// (λ_ψ⁻, ψ − u_h)_κ where ψ > u_h.
    pub cross: f64,
}

impl AboveCell {
    /// On the cell with corners `p` (in its triangle t of the obstacle's `psi`, diameter of t
    /// `diameter`), for the tension `mu`, the load `f`, μ∇u_h = `grad_u`, u_h at a point `u_at`
    /// and μ∇u_h + τ at a point `flux`, by the rule `rule`.
    pub fn compute(
        (psi, f): (&crate::expr::Expr, &crate::expr::Expr),
        (p, diameter): ([[f64; 2]; 3], f64),
        mu: f64,
        grad_u: [f64; 2],
        u_at: impl Fn([f64; 2]) -> f64,
        flux: impl Fn([f64; 2]) -> [f64; 2],
        rule: Quadrature,
    ) -> AboveCell {
        let area = 0.5 * crate::mesh::orient(p[0], p[1], p[2]);
        let points: Vec<[f64; 2]> = (rule.barycentric())
            .map(|b| [0, 1].map(|k| b[0] * p[0][k] + b[1] * p[1][k] + b[2] * p[2][k]))
            .collect();
        let (psi_at, f_at) = (Differences::new(psi, diameter).at(&points), f.values_at(&points));
        let (mut on_u, mut on_psi, mut cross, mut everywhere) = (0.0, 0.0, 0.0, true);
        for (((&[_, _, w], &x), psi), f) in rule.rule().iter().zip(&points).zip(&psi_at).zip(f_at) {
            let w = 2.0 * area * w;
            let v = flux(x);
            let v_psi = [0, 1].map(|k| v[k] - grad_u[k] + mu * psi.gradient[k]);
            on_u += w * (v[0] * v[0] + v[1] * v[1]);
            on_psi += w * (v_psi[0] * v_psi[0] + v_psi[1] * v_psi[1]);
            let dip = psi.value - u_at(x);
            everywhere &= dip > 0.0;
            if dip > 0.0 {
                let lambda_psi = -mu * psi.laplacian - f;
                cross += w * (-lambda_psi).max(0.0) * dip;
            }
        }
        AboveCell {
            flux2: if everywhere { on_psi } else { on_u + on_psi },
            cross,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::assembly::Quadrature;
    use crate::datum::{Datum, On};
    use crate::expr::Expr;
    use crate::mesh::{Edges, Mesh};
    use crate::problem::Data;

    /// K = (0,0), (1,0), (0,1) and ψ = −x² − y², whose interpolant is −x − y: ψ − ψ_h = x + y − x²
    /// − y² ≥ 0 on K, and by hand ‖∇(ψ − ψ_h)‖²_K = ∫_K (1 − 2x)² + (1 − 2y)² = 1/3; with u_h one
    /// above ψ_h the obstacle is nowhere above it and (λ_h, u_h − ψ)_K = 1/2 − 1/3 + 1/6 = 1/3 for
    /// λ_h = 1.
    #[test]
    fn on_one_triangle_the_terms_have_their_closed_forms() {
        let mesh = Mesh::from_parts(
            vec![[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]],
            vec![[0, 1, 2]],
            vec![true; 3],
        );
        let edges = Edges::new(&mesh);
        let dual = DualMesh::new(&mesh, &edges);
        let psi = Datum::from(Expr::parse("-x^2 - y^2").unwrap());
        let zero = || Datum::from(Expr::parse("0").unwrap());
        let data = Data::obstacle(1.0, zero(), psi.clone(), zero(), Quadrature { degree: 4 }).unwrap();
        let problem = DiscreteProblem::new(mesh.clone(), &data).unwrap();
        let pieces = psi.pieces("psi", &mesh, On::Surfaces).unwrap();
        let none = [boundary::OnTriangle::default()];
        let on_psi_h = terms(&problem, &dual, &pieces, &[0.0, -1.0, -1.0], &[1.0; 3], &none);
        assert!((on_psi_h[0].grad2 - 1.0 / 3.0).abs() < 1e-9, "{:?}", on_psi_h[0]);
        assert!(on_psi_h[0].contact.abs() < 1e-15, "{:?}", on_psi_h[0]);
        let above = terms(&problem, &dual, &pieces, &[1.0, 0.0, 0.0], &[1.0; 3], &none);
        assert_eq!(above[0].grad2, 0.0);
        assert!((above[0].contact - 1.0 / 3.0).abs() < 1e-14, "{:?}", above[0]);
    }

    /// The same K and ψ with u_h = ψ_h = −x − y, μ = 1, f = 5 and τ = −μ∇u_h: λ_ψ = −Δψ − f = −1,
    /// so Σ_κ (λ_ψ⁻, ψ − u_h)_κ = ∫_K x + y − x² − y² = 1/6, and ψ is above u_h inside K, so the
    /// flux term of ũ = ψ is Σ_κ ‖μ∇ψ + τ‖²_κ = ∫_K |∇ψ − ∇ψ_h|² = 1/3.
    #[test]
    fn above_the_obstacle_the_terms_through_the_lifted_solution_have_their_closed_forms() {
        let corners = [[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]];
        let mesh = Mesh::from_parts(corners.to_vec(), vec![[0, 1, 2]], vec![true; 3]);
        let edges = Edges::new(&mesh);
        let dual = DualMesh::new(&mesh, &edges);
        let (psi, f) = (Expr::parse("-x^2 - y^2").unwrap(), Expr::parse("5").unwrap());
        let grad_u = [-1.0, -1.0];
        let (mut flux2, mut cross) = (0.0, 0.0);
        for s in 0..6 {
            let cell = AboveCell::compute(
                (&psi, &f),
                (dual.corners(s), mesh.diameter(0)),
                1.0,
                grad_u,
                |x| -x[0] - x[1],
                |_| [0.0; 2],
                Quadrature { degree: 4 },
            );
            (flux2, cross) = (flux2 + cell.flux2, cross + cell.cross);
        }
        assert!((cross - 1.0 / 6.0).abs() < 1e-9, "{cross}");
        assert!((flux2 - 1.0 / 3.0).abs() < 1e-9, "{flux2}");
    }
}
