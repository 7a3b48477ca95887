//! Error norms against an exact solution: ‖u_i − u_ih‖_L², |u_i − u_ih|_H¹ (Theorem 9), the
//! energy norm, ‖λ − λ_h‖_L² with λ_h piecewise constant on the dual cells (Remark 22), and a
//! computable approximation of ‖λ − λ_h‖_H⁻¹ (Theorem 21).

use crate::action::Action;
use crate::assembly::{gradients, Quadrature, Stiffness};
use crate::contact::Solution;
use crate::expr::Expr;
use crate::linear::dirichlet_solve;
use crate::mesh::{DualMesh, Mesh};
use crate::parallel::{self, PIECE};
use crate::problem::DiscreteProblem;
use crate::result::{Attribute, Describe, Field, Place};

/// Degree of the rule used for error integrals (well above the P1 error's).
const ERROR_QUADRATURE: Quadrature = Quadrature { degree: 10 };

/// The exact solution of a case, for error norms.
#[derive(Debug, Clone)]
pub struct Exact {
    /// u1.
    pub u1: Expr,
    /// u2.
    pub u2: Expr,
    /// λ.
    pub lambda: Expr,
    /// ∇u1 as [∂x, ∂y], for the H¹ error.
    pub grad_u1: Option<[Expr; 2]>,
    /// ∇u2 as [∂x, ∂y].
    pub grad_u2: Option<[Expr; 2]>,
    /// Whether u2 is a rigid obstacle ψ (the classical obstacle problem, whose exact u is u1):
    /// then only u1's errors are reported, as u's.
    pub rigid: bool,
}

impl Exact {
    /// u1, u2 and λ interpolated at the vertices, for comparison in ParaView (u and λ above a
    /// rigid obstacle).
    pub fn fields(&self, mesh: &Mesh) -> Vec<Field<'static>> {
        let at = |e: &Expr| mesh.points.iter().map(|p| e.eval(p[0], p[1])).collect();
        if self.rigid {
            return vec![
                Field::owned("u_exact", Place::Vertices, at(&self.u1)),
                Field::owned("lambda_exact", Place::Vertices, at(&self.lambda)),
            ];
        }
        vec![
            Field::owned("u1_exact", Place::Vertices, at(&self.u1)),
            Field::owned("u2_exact", Place::Vertices, at(&self.u2)),
            Field::owned("lambda_exact", Place::Vertices, at(&self.lambda)),
        ]
    }
}

/// Errors of one discrete solution.
#[derive(Debug, Clone, Default, serde::Serialize)]
pub struct Errors {
    /// ‖u1 − u1h‖_L².
    pub l2_u1: f64,
    /// ‖u2 − u2h‖_L².
    pub l2_u2: f64,
    /// |u1 − u1h|_H¹ (without exact gradients: none).
    pub h1_u1: Option<f64>,
    /// |u2 − u2h|_H¹.
    pub h1_u2: Option<f64>,
    /// (Σ μ_i |u_i − u_ih|²_H¹)^½.
    pub energy: Option<f64>,
    /// ‖λ − λ_h‖_L²(ω), λ_h = Σ_a λ_a χ_{D_a} (zero near ∂ω).
    pub l2_lambda: f64,
    /// ‖λ − λ_h‖_H⁻¹(ω) by [`hminus1_lambda`], when asked for (it costs a solve on S_h).
    pub hminus1_lambda: Option<f64>,
    /// Whether u2 is a rigid obstacle ([`Exact::rigid`]): u1's errors are then u's, and u2's
    /// (ψ's interpolation error) are not reported.
    #[serde(skip)]
    pub rigid: bool,
}

impl Errors {
    /// The errors of `solution` and `action` against `exact`; with `hminus1`, the H⁻¹ norm too.
    pub fn compute(
        problem: &DiscreteProblem,
        dual: &DualMesh,
        solution: &Solution,
        action: &Action,
        exact: &Exact,
        hminus1: bool,
    ) -> Errors {
        let mesh = &problem.mesh;
        let [(l2_u1, h1_u1), (l2_u2, h1_u2)] = p1_errors(mesh, [&solution.u1, &solution.u2], exact);
        let lambda_h = |s: usize| action.lambda[dual.owner(s)];
        let l2_lambda: f64 = parallel::sum(dual.n_cells(), PIECE, |range| {
            let mut sum = 0.0;
            let corners = |s: usize| dual.corners(s);
            ERROR_QUADRATURE.visit(corners, range, [&exact.lambda], |s, points, [lambda]| {
                let l = lambda_h(s);
                sum += points
                    .iter()
                    .zip(lambda)
                    .map(|(p, v)| p.weight * (v - l).powi(2))
                    .sum::<f64>();
            });
            sum
        });
        let mu1 = problem.data.mu1;
        let energy = match problem.data.mu2() {
            Some(mu2) => h1_u1
                .zip(h1_u2)
                .map(|(e1, e2)| (mu1 * e1 * e1 + mu2 * e2 * e2).sqrt()),
            None => h1_u1.map(|e1| mu1.sqrt() * e1),
        };
        Errors {
            l2_u1,
            l2_u2,
            h1_u1,
            h1_u2,
            energy,
            l2_lambda: l2_lambda.sqrt(),
            hminus1_lambda: hminus1.then(|| hminus1_lambda(dual, &action.lambda, &exact.lambda)),
            rigid: exact.rigid,
        }
    }
}

impl Errors {
    /// Whether every norm computed is a finite number.
    pub fn all_finite(&self) -> bool {
        [self.l2_u1, self.l2_u2, self.l2_lambda]
            .into_iter()
            .chain(
                [self.h1_u1, self.h1_u2, self.energy, self.hminus1_lambda]
                    .into_iter()
                    .flatten(),
            )
            .all(f64::is_finite)
    }
}

impl Describe for Errors {
    fn attributes(&self) -> Vec<Attribute> {
        // The names of membranes 1 and 2, and above a rigid obstacle (u's; ψ's none).
        let named = [
            ("error_l2_u1", "error_l2_u", Some(self.l2_u1)),
            ("error_l2_u2", "", Some(self.l2_u2)),
            ("error_l2_lambda", "error_l2_lambda", Some(self.l2_lambda)),
            ("error_h1_u1", "error_h1_u", self.h1_u1),
            ("error_h1_u2", "", self.h1_u2),
            ("error_energy", "error_energy", self.energy),
            (
                "error_hminus1_lambda",
                "error_hminus1_lambda",
                self.hminus1_lambda,
            ),
        ];
        (named.into_iter())
            .filter_map(|(two, one, value)| {
                let name = if self.rigid { one } else { two };
                value.filter(|_| !name.is_empty()).map(|v| (name, v.into()))
            })
            .collect()
    }
}

/// (‖u_i − u_ih‖_L², |u_i − u_ih|_H¹) of both membranes' P1 fields `uh` (the H¹ error where
/// ∇u_i is given), the exact fields evaluated together (they share most of their terms).
fn p1_errors(mesh: &Mesh, uh: [&[f64]; 2], exact: &Exact) -> [(f64, Option<f64>); 2] {
    let (u, g) = ([&exact.u1, &exact.u2], [&exact.grad_u1, &exact.grad_u2]);
    let parts = parallel::map(mesh.n_triangles(), PIECE, |range| {
        let r = range;
        match g {
            [Some([ax, ay]), Some([bx, by])] => {
                p1_error_sums(mesh, uh, [u[0], u[1], ax, ay, bx, by], [Some(2), Some(4)], r)
            }
            [Some([ax, ay]), None] => p1_error_sums(mesh, uh, [u[0], u[1], ax, ay], [Some(2), None], r),
            [None, Some([bx, by])] => p1_error_sums(mesh, uh, [u[0], u[1], bx, by], [None, Some(2)], r),
            [None, None] => p1_error_sums(mesh, uh, u, [None, None], r),
        }
    });
    let sums = parts
        .iter()
        .fold([0.0; 4], |s, p| std::array::from_fn(|k| s[k] + p[k]));
    [0, 1].map(|i| (sums[i].sqrt(), g[i].as_ref().map(|_| sums[2 + i].sqrt())))
}

/// ∫ (u_i − u_ih)² and ∫ |∇(u_i − u_ih)|² (i = 1, 2) over the triangles in `range`: `fields`
/// u1, u2, then the components of the ∇u_i given, the first at `grads[i]`.
fn p1_error_sums<const E: usize>(
    mesh: &Mesh,
    uh: [&[f64]; 2],
    fields: [&Expr; E],
    grads: [Option<usize>; 2],
    range: std::ops::Range<usize>,
) -> [f64; 4] {
    let mut sums = [0.0; 4];
    let corners = |t| mesh.corners(t);
    ERROR_QUADRATURE.visit(corners, range, fields, |t, points, values| {
        let tri = mesh.triangle(t);
        for i in 0..2 {
            for (p, u) in points.iter().zip(values[i]) {
                let value: f64 = (0..3).map(|k| p.barycentric[k] * uh[i][tri[k]]).sum();
                sums[i] += p.weight * (u - value).powi(2);
            }
            if let Some(at) = grads[i] {
                let g = gradients(mesh.corners(t));
                let grad_h = [0, 1].map(|k| (0..3).map(|j| g[j][k] * uh[i][tri[j]]).sum::<f64>());
                let (gx, gy) = (values[at], values[at + 1]);
                for ((p, gx), gy) in points.iter().zip(gx).zip(gy) {
                    sums[2 + i] += p.weight * ((gx - grad_h[0]).powi(2) + (gy - grad_h[1]).powi(2));
                }
            }
        }
    });
    sums
}

/// ‖λ − λ_h‖_H⁻¹(ω), approximated by the dual norm over P1 functions on the dual submesh S_h
/// (mesh size about h/2): sup_{v ∈ P1_0(S_h)} (λ − λ_h, v)/|v|_H¹ = |z|_H¹ with z ∈ P1_0(S_h),
/// (∇z, ∇v) = (λ − λ_h, v). A lower bound of the true norm that converges to it; λ_h is constant on
/// each sub-triangle (`lambda_h` by vertex: λ_a on D_a), so the integrals are exact up to the
/// quadrature of λ. S_h is built as a mesh here (this norm is optional and costs a solve on it).
pub fn hminus1_lambda(dual: &DualMesh, lambda_h: &[f64], lambda: &Expr) -> f64 {
    let points = (0..dual.n_points()).map(|p| dual.point(p)).collect();
    let cells = (0..dual.n_cells()).map(|s| dual.cell(s)).collect();
    let sub = Mesh::new(points, cells).expect("the dual submesh of a valid mesh is valid");
    dual_norm(&sub, lambda, |s| lambda_h[dual.owner(s)])
}

/// sup over v ∈ P1_0(mesh) of (r, v)/|v|_H¹ for r = f − c_t on each triangle t.
pub(crate) fn dual_norm(mesh: &Mesh, f: &Expr, c: impl Fn(usize) -> f64) -> f64 {
    let k = Stiffness::assemble(mesh);
    let mut b = vec![0.0; mesh.n_vertices()];
    let corners = |t| mesh.corners(t);
    ERROR_QUADRATURE.visit(corners, 0..mesh.n_triangles(), [f], |t, points, [f]| {
        let tri = mesh.triangle(t);
        for (p, f) in points.iter().zip(f) {
            for i in 0..3 {
                b[tri[i]] += p.weight * (f - c(t)) * p.barycentric[i];
            }
        }
    });
    let zero = vec![0.0; mesh.n_vertices()];
    let z = dirichlet_solve(&k, &mesh.on_boundary, &b, 1.0, &zero);
    // |z|²_H¹ = (r, z): z vanishes on ∂ω, where b is not an equation.
    b.iter().zip(&z).map(|(b, z)| b * z).sum::<f64>().max(0.0).sqrt()
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
