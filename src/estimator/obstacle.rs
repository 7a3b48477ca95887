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
//! and on every other cell z = ℓ: (λ_h, u_h + z − ψ)_κ = (λ_h, ℓ)_κ + (λ_h, u_h − ψ)_κ. ∇ψ and
//! Δψ are the derivatives of the case's expression ([`crate::expr::Expr::with_derivatives`]);
//! the rule has degree max(q, 4) on each κ. [`terms`] finds the cells where the obstacle is above
//! u_h and the contact term; [`AboveCell`] the rest of what such a cell contributes, in the sweep
//! over the patches.

use super::boundary;
use crate::assembly::Quadrature;
use crate::datum::{self, Pieces};
use crate::expr::{Expr, Program};
use crate::mesh::DualMesh;
use crate::parallel::{self, PIECE};
use crate::problem::DiscreteProblem;

/// The obstacle's part of the lifting on one triangle K.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct OnTriangle {
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
        // Per cell: whether the obstacle is above u_h, and λ_h's pairings.
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

/// ψ with its first and second derivatives, compiled per expression of the datum.
pub struct WithDerivatives<'a> {
    psi: &'a Pieces<'a>,
    programs: Vec<Program>,
}

impl<'a> WithDerivatives<'a> {
    /// Each expression of `psi` compiled with its derivatives.
    pub fn new(psi: &'a Pieces<'a>) -> Self {
        let programs = psi.exprs().iter().map(|e| e.with_derivatives()).collect();
        WithDerivatives { psi, programs }
    }

    /// The program on triangle t.
    pub fn on_triangle(&self, t: usize) -> &Program {
        &self.programs[self.psi.entry(t)]
    }
}

/// What a cell κ where the obstacle is above u_h contributes: to the lifting's ‖∇z‖²,
/// ‖∇(ψ − u_h)‖²_κ; to the bound through ũ = u_h + z (§14, Theorem (O')), an upper bound of
/// ‖μ∇ũ + τ‖²_κ (∇ũ = ∇ψ where ψ > u_h, ∇u_h elsewhere: at a cell where the rule's points
/// disagree, the sum of the two squares), and (λ_ψ⁻, ψ − u_h)_κ with λ_ψ = −μΔψ − f, the action
/// the obstacle would exert where it held the membrane.
#[derive(Debug, Clone, Copy, Default)]
pub struct AboveCell {
    /// ‖∇(ψ − u_h)‖²_κ.
    pub grad2: f64,
    /// The bound of ‖μ∇ũ + τ‖²_κ.
    pub flux2: f64,
    /// (λ_ψ⁻, ψ − u_h)_κ where ψ > u_h.
    pub cross: f64,
}

impl AboveCell {
    /// On the cell with corners `p`, for ψ with its derivatives `psi`
    /// ([`Expr::with_derivatives`]), the load `f`, the tension `mu`, μ∇u_h = `grad_u`, u_h at a
    /// point `u_at` and μ∇u_h + τ at a point `flux`, by the rule `rule`.
    pub fn compute(
        (psi, f): (&Program, &Expr),
        p: [[f64; 2]; 3],
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
        // ψ, ∂ψ/∂x, ∂ψ/∂y, ∂²ψ/∂x², ∂²ψ/∂y² and f at the points.
        let mut values = vec![0.0; 6 * points.len()];
        let mut at: Vec<&mut [f64]> = values.chunks_exact_mut(points.len()).collect();
        let (psi_at, f_at) = at.split_at_mut(5);
        psi.eval_many(&points, psi_at);
        f.eval_many(&points, f_at[0]);
        let at: Vec<&[f64]> = values.chunks_exact(points.len()).collect();
        let (mut cell, mut on_u, mut on_psi, mut everywhere) = (AboveCell::default(), 0.0, 0.0, true);
        for (k, (&[_, _, w], &x)) in rule.rule().iter().zip(&points).enumerate() {
            let w = 2.0 * area * w;
            let (v, grad_psi) = (flux(x), [at[1][k], at[2][k]]);
            let v_psi = [0, 1].map(|i| v[i] - grad_u[i] + mu * grad_psi[i]);
            let d = [0, 1].map(|i| grad_psi[i] - grad_u[i] / mu);
            cell.grad2 += w * (d[0] * d[0] + d[1] * d[1]);
            on_u += w * (v[0] * v[0] + v[1] * v[1]);
            on_psi += w * (v_psi[0] * v_psi[0] + v_psi[1] * v_psi[1]);
            let dip = at[0][k] - u_at(x);
            everywhere &= dip > 0.0;
            if dip > 0.0 {
                let lambda_psi = -mu * (at[3][k] + at[4][k]) - at[5][k];
                cell.cross += w * (-lambda_psi).max(0.0) * dip;
            }
        }
        cell.flux2 = if everywhere { on_psi } else { on_u + on_psi };
        cell
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::assembly::Quadrature;
    use crate::datum::{Datum, On};
    use crate::mesh::{Edges, Mesh};
    use crate::problem::Data;

    /// K = (0,0), (1,0), (0,1) and ψ = −x² − y², whose interpolant is −x − y: ψ − ψ_h = x + y − x²
    /// − y² ≥ 0 on K, so with u_h = ψ_h the obstacle is above u_h on every cell and
    /// (λ_h, (u_h − ψ)⁺)_K = 0; with u_h one above ψ_h it is nowhere above it and (λ_h, u_h − ψ)_K
    /// = 1/2 − 1/3 + 1/6 = 1/3 for λ_h = 1.
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
        assert_eq!(on_psi_h[0].above, 0b111111);
        assert!(on_psi_h[0].contact.abs() < 1e-15, "{:?}", on_psi_h[0]);
        let above = terms(&problem, &dual, &pieces, &[1.0, 0.0, 0.0], &[1.0; 3], &none);
        assert_eq!(above[0].above, 0);
        assert!((above[0].contact - 1.0 / 3.0).abs() < 1e-14, "{:?}", above[0]);
    }

    /// The same K and ψ with u_h = ψ_h = −x − y, μ = 1, f = 5 and τ = −μ∇u_h: λ_ψ = −Δψ − f = −1,
    /// so Σ_κ (λ_ψ⁻, ψ − u_h)_κ = ∫_K x + y − x² − y² = 1/6; by hand ‖∇(ψ − u_h)‖²_K = ∫_K (1 −
    /// 2x)² + (1 − 2y)² = 1/3, and ψ is above u_h inside K, so the flux term of ũ = ψ is Σ_κ
    /// ‖μ∇ψ + τ‖²_κ = ∫_K |∇ψ − ∇ψ_h|² = 1/3 too.
    #[test]
    fn above_the_obstacle_the_terms_through_the_lifted_solution_have_their_closed_forms() {
        let corners = [[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]];
        let mesh = Mesh::from_parts(corners.to_vec(), vec![[0, 1, 2]], vec![true; 3]);
        let edges = Edges::new(&mesh);
        let dual = DualMesh::new(&mesh, &edges);
        let (psi, f) = (Expr::parse("-x^2 - y^2").unwrap(), Expr::parse("5").unwrap());
        let psi = psi.with_derivatives();
        let grad_u = [-1.0, -1.0];
        let (mut grad2, mut flux2, mut cross) = (0.0, 0.0, 0.0);
        for s in 0..6 {
            let cell = AboveCell::compute(
                (&psi, &f),
                dual.corners(s),
                1.0,
                grad_u,
                |x| -x[0] - x[1],
                |_| [0.0; 2],
                Quadrature { degree: 4 },
            );
            (grad2, flux2, cross) = (grad2 + cell.grad2, flux2 + cell.flux2, cross + cell.cross);
        }
        assert!((grad2 - 1.0 / 3.0).abs() < 1e-14, "{grad2}");
        assert!((cross - 1.0 / 6.0).abs() < 1e-14, "{cross}");
        assert!((flux2 - 1.0 / 3.0).abs() < 1e-14, "{flux2}");
    }
}
