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
    let rule = Quadrature {
        degree: problem.data.quadrature.degree.max(4),
    };
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
    let corners = mesh.corners(t);
    let g = gradients(corners);
    let grad_u = [0, 1].map(|k| (0..3).map(|j| g[j][k] * u[tri[j]]).sum::<f64>());
    let diameter = (0..3)
        .map(|e| crate::mesh::dist(corners[e], corners[(e + 1) % 3]))
        .fold(0.0, f64::max);
    let h = STEP * diameter;
    let psi = psi.on_triangle(t);
    let derivative = |x: [f64; 2], k: usize| {
        let at = |d: f64| {
            let mut y = x;
            y[k] += d;
            psi.eval(y[0], y[1])
        };
        (8.0 * (at(h) - at(-h)) - at(2.0 * h) + at(-2.0 * h)) / (12.0 * h)
    };
    (points.iter())
        .map(|p| {
            let d = [0, 1].map(|k| derivative(p.x, k) - grad_u[k]);
            p.weight * (d[0] * d[0] + d[1] * d[1])
        })
        .sum()
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
}
