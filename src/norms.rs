//! Error norms against an exact solution: ‖u_i − u_ih‖_L², |u_i − u_ih|_H¹ (Theorem 9), the
//! energy norm, ‖λ − λ_h‖_L² with λ_h piecewise constant on the dual cells (Remark 22), and a
//! computable approximation of ‖λ − λ_h‖_H⁻¹ (Theorem 21).

use crate::action::{Action, DualMesh};
use crate::assembly::{gradients, in_two_halves, Quadrature, Stiffness};
use crate::case::Exact;
use crate::contact::{DiscreteProblem, Solution};
use crate::expr::Expr;
use crate::linear::InteriorSystem;
use crate::mesh::Mesh;

/// Degree of the rule used for error integrals (well above the P1 error's).
const ERROR_QUADRATURE: Quadrature = Quadrature { degree: 10 };

/// Errors of one discrete solution.
#[derive(Debug, Clone, Default, serde::Serialize)]
pub struct Errors {
    pub l2_u1: f64,
    pub l2_u2: f64,
    /// |u1 − u1h|_H¹ and |u2 − u2h|_H¹ (NaN without exact gradients).
    pub h1_u1: f64,
    pub h1_u2: f64,
    /// (Σ μ_i |u_i − u_ih|²_H¹)^½.
    pub energy: f64,
    /// max over vertices of |u_i(a) − u_ih(a)|.
    pub max_nodal_u: f64,
    /// ‖λ − λ_h‖_L²(ω), λ_h = Σ_a λ_a χ_{D_a} (zero near ∂ω).
    pub l2_lambda: f64,
    /// ‖λ − λ_h‖_H⁻¹(ω) by [`h_minus_1_lambda`] (NaN unless asked for: it costs a solve on S_h).
    pub h_minus_1_lambda: f64,
}

impl Errors {
    pub fn compute(problem: &DiscreteProblem, solution: &Solution, action: &Action, exact: &Exact) -> Errors {
        let mesh = &problem.mesh;
        let (l2_u1, h1_u1) = p1_errors(mesh, &solution.u1, &exact.u1, exact.grad_u1.as_ref());
        let (l2_u2, h1_u2) = p1_errors(mesh, &solution.u2, &exact.u2, exact.grad_u2.as_ref());
        let max_nodal_u = mesh
            .points
            .iter()
            .enumerate()
            .map(|(a, p)| {
                let e1 = (exact.u1.eval(p[0], p[1]) - solution.u1[a]).abs();
                let e2 = (exact.u2.eval(p[0], p[1]) - solution.u2[a]).abs();
                e1.max(e2)
            })
            .fold(0.0, f64::max);
        let dual = DualMesh::new(mesh);
        let lambda_h = |a: usize| {
            if mesh.on_boundary[a] {
                0.0
            } else {
                action.lambda[a]
            }
        };
        let l2_lambda: f64 = in_two_halves(dual.triangles.len(), |range| {
            let mut sum = 0.0;
            let corners = |t: usize| dual.triangles[t].map(|v| dual.points[v]);
            ERROR_QUADRATURE.visit(corners, range, [&exact.lambda], |t, points, [lambda]| {
                let l = lambda_h(dual.owner[t]);
                sum += points
                    .iter()
                    .zip(lambda)
                    .map(|(p, v)| p.weight * (v - l).powi(2))
                    .sum::<f64>();
            });
            sum
        })
        .iter()
        .sum();
        Errors {
            l2_u1,
            l2_u2,
            h1_u1,
            h1_u2,
            energy: (problem.mu1 * h1_u1 * h1_u1 + problem.mu2 * h1_u2 * h1_u2).sqrt(),
            max_nodal_u,
            l2_lambda: l2_lambda.sqrt(),
            h_minus_1_lambda: f64::NAN,
        }
    }
}

/// (‖u − u_h‖_L², |u − u_h|_H¹) for a P1 field u_h.
fn p1_errors(mesh: &Mesh, uh: &[f64], u: &Expr, grad: Option<&[Expr; 2]>) -> (f64, f64) {
    let [first, second] = in_two_halves(mesh.triangles.len(), |range| {
        p1_error_sums(mesh, uh, u, grad, range)
    });
    let (l2, h1) = (first.0 + second.0, first.1 + second.1);
    (l2.sqrt(), if grad.is_some() { h1.sqrt() } else { f64::NAN })
}

/// ∫ (u − u_h)² and ∫ |∇(u − u_h)|² over the triangles in `range`.
fn p1_error_sums(
    mesh: &Mesh,
    uh: &[f64],
    u: &Expr,
    grad: Option<&[Expr; 2]>,
    range: std::ops::Range<usize>,
) -> (f64, f64) {
    let (mut l2, mut h1) = (0.0, 0.0);
    let corners = |t| mesh.corners(t);
    ERROR_QUADRATURE.visit(corners, range.clone(), [u], |t, points, [u]| {
        let tri = mesh.triangles[t];
        for (p, u) in points.iter().zip(u) {
            let value: f64 = (0..3).map(|k| p.barycentric[k] * uh[tri[k]]).sum();
            l2 += p.weight * (u - value).powi(2);
        }
    });
    if let Some([gx, gy]) = grad {
        ERROR_QUADRATURE.visit(corners, range, [gx, gy], |t, points, [gx, gy]| {
            let tri = mesh.triangles[t];
            let g = gradients(mesh.corners(t));
            let grad_h = [0, 1].map(|k| (0..3).map(|i| g[i][k] * uh[tri[i]]).sum::<f64>());
            for ((p, gx), gy) in points.iter().zip(gx).zip(gy) {
                h1 += p.weight * ((gx - grad_h[0]).powi(2) + (gy - grad_h[1]).powi(2));
            }
        });
    }
    (l2, h1)
}

/// ‖λ − λ_h‖_H⁻¹(ω), approximated by the dual norm over P1 functions on the dual submesh S_h
/// (mesh size about h/2): sup_{v ∈ P1_0(S_h)} (λ − λ_h, v)/|v|_H¹ = |z|_H¹ with z ∈ P1_0(S_h),
/// (∇z, ∇v) = (λ − λ_h, v). A lower bound of the true norm that converges to it; λ_h is constant on
/// each sub-triangle, so the integrals are exact up to the quadrature of λ.
pub fn h_minus_1_lambda(mesh: &Mesh, action: &Action, lambda: &Expr) -> f64 {
    let dual = DualMesh::new(mesh);
    let lambda_h: Vec<f64> = dual
        .owner
        .iter()
        .map(|&a| {
            if mesh.on_boundary[a] {
                0.0
            } else {
                action.lambda[a]
            }
        })
        .collect();
    let sub = Mesh::new(dual.points, dual.triangles).expect("the dual submesh of a valid mesh is valid");
    dual_norm(&sub, lambda, |t| lambda_h[t])
}

/// sup over v ∈ P1_0(mesh) of (r, v)/|v|_H¹ for r = f − c_t on each triangle t.
pub fn dual_norm(mesh: &Mesh, f: &Expr, c: impl Fn(usize) -> f64) -> f64 {
    let k = Stiffness::assemble(mesh);
    let mut b = vec![0.0; mesh.n_vertices()];
    let corners = |t| mesh.corners(t);
    ERROR_QUADRATURE.visit(corners, 0..mesh.triangles.len(), [f], |t, points, [f]| {
        let tri = mesh.triangles[t];
        for (p, f) in points.iter().zip(f) {
            for i in 0..3 {
                b[tri[i]] += p.weight * (f - c(t)) * p.barycentric[i];
            }
        }
    });
    let system = InteriorSystem::new(&k, &mesh.on_boundary);
    let mut factor = system.factorization();
    factor
        .factorize(&vec![false; system.n()])
        .expect("the stiffness matrix of a valid mesh is positive definite");
    let rhs: Vec<f64> = system.vertices.iter().map(|&a| b[a]).collect();
    let mut z = rhs.clone();
    factor.solve(&mut z);
    rhs.iter()
        .zip(&z)
        .map(|(b, z)| b * z)
        .sum::<f64>()
        .max(0.0)
        .sqrt()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::Diagonal;

    #[test]
    fn dual_norm_of_a_sine() {
        // r = sin(πx) sin(πy) on the unit square: −Δz = r gives z = r/(2π²), ‖r‖²_H⁻¹ = ‖r‖²/(2π²).
        let exact = 1.0 / (2.0 * std::f64::consts::SQRT_2 * std::f64::consts::PI);
        let error = |n| {
            let mesh = Mesh::rectangle([0.0, 0.0], [1.0, 1.0], n, n, Diagonal::Right).unwrap();
            let norm = dual_norm(&mesh, &Expr::parse("sin(pi*x)*sin(pi*y)").unwrap(), |_| 0.0);
            assert!(norm <= exact, "the discrete dual norm is a lower bound");
            exact - norm
        };
        let (e32, e64) = (error(32), error(64));
        assert!(e32 < 2e-3 * exact, "{e32}");
        assert!((3.5..4.5).contains(&(e32 / e64)), "O(h²): {e32} / {e64}");
        let mesh = Mesh::rectangle([0.0, 0.0], [1.0, 1.0], 32, 32, Diagonal::Right).unwrap();
        // A field that oscillates at the mesh scale has a much smaller H⁻¹ than L² norm.
        let checker = dual_norm(&mesh, &Expr::parse("0").unwrap(), |t| {
            if t % 2 == 0 {
                1.0
            } else {
                -1.0
            }
        });
        assert!(checker < 0.05, "{checker}");
    }
}
