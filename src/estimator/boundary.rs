//! The lifting ψ of the boundary mismatch g − g_h (docs/a-posteriori.md §5): on a triangle K with
//! a boundary edge e = [p, q] and third vertex c, with s = λ_p + λ_q = 1 − λ_c and τ = λ_q / s,
//!
//! ```text
//! ψ_e = s^k δ(τ),   δ(τ) = g(p + τ(q − p)) − [(1 − τ) g(p) + τ g(q)],   k ≥ 1,
//! ```
//!
//! zero on the two other edges, so ψ = Σ_e ψ_e ∈ H¹(ω) with ψ = g − g_h on ∂ω, and w_h + ψ ≥ 0
//! (w_h + ψ_e ≥ min(w_h, (1 − s) w_h(c) + s g) ≥ 0 on K, as s^k δ ≥ min(0, s δ)). In the coordinates
//! (s, τ) ∈ [0, 1]², dx = 2|K| s ds dτ and ∇ψ_e = s^{k−1} [k δ(τ) ∇s + δ'(τ) v], v = ∇λ_q − τ∇s,
//! so ‖∇ψ_e‖²_K = (|K|/k) ∫_0^1 |k δ∇s + δ'v|² dτ = |K| (k A + 2C + B/k) with A = ∫ δ²|∇s|²,
//! B = ∫ δ'²|v|², C = ∫ δδ' ∇s·v: least at k = (B/A)^½ (≥ 1 except on triangles very flat towards
//! e, as ∫δ'² ≥ π² ∫δ²; k = 1 there), where it is
//! 2|K| ((AB)^½ + C). k = 1 is the radial extension of docs/a-posteriori.md §5; the least k takes
//! a quarter off ‖∇ψ_e‖ for a parabola on a right triangle. ∫_K λ_h ψ_e = λ_c 2|K| ∫_0^1 δ
//! s*^{k+2}/(k+2) dτ with s* = 1 / (1 + max(τ, 1 − τ)) bounding D_c ∩ K (λ_h = 0 on the cells of
//! p and q). The integrals in τ: Gauss–Legendre on [0, ½] and [½, 1] (s* has a kink at ½). On a
//! corner triangle (two boundary edges) the two liftings' cross term (∇ψ_e1, ∇ψ_e2)_K is added by
//! a two-dimensional rule (`cross_term`).

use super::equilibration::ON_BOUNDARY;
use crate::assembly::gradients;
use crate::datum::Pieces;
use crate::expr::Program;
use crate::mesh::Mesh;

/// Gauss–Legendre points per half of [0, 1].
const POINTS: usize = 12;
/// Gauss–Legendre points per direction of the collapsed rules of [`cross_term`].
const CROSS_POINTS: usize = 16;

/// The lifting's contribution on one triangle.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct OnTriangle {
    /// ‖∇ψ‖_K.
    pub grad_norm: f64,
    /// ∫_K λ_h ψ.
    pub with_lambda: f64,
    /// Bounds of ψ on K: min(0, min δ) and max(0, max δ), summed over K's boundary edges.
    pub range: [f64; 2],
    /// The least g − ψ (g between two membranes) at the rule's points on K's boundary edges, and
    /// where.
    pub lowest: Option<(f64, [f64; 2])>,
}

/// The lower of two least values (a NaN one loses).
fn lower(a: Option<(f64, [f64; 2])>, b: Option<(f64, [f64; 2])>) -> Option<(f64, [f64; 2])> {
    match (a, b) {
        (Some(x), Some(y)) => Some(if y.0 < x.0 { y } else { x }),
        (x, None) | (None, x) => x,
    }
}

/// The least g − ψ (g) over the boundary edges of every triangle of `on`, and where.
pub fn lowest(on: &[OnTriangle]) -> Option<(f64, [f64; 2])> {
    on.iter().fold(None, |m, t| lower(m, t.lowest))
}

/// ψ on every triangle of `mesh` (zero on those without a boundary edge). `neighbour[t][j]` is
/// [`ON_BOUNDARY`] when the edge `(t[j], t[j + 1])` lies on ∂ω; `lambda` is λ_a; `gap` is w_h when
/// ψ is to keep w_h + ψ ≥ 0 at the corners of ω (between two membranes; `None` above an
/// obstacle, whose lifting takes care of the constraint itself, §14); `obstacle` is the obstacle
/// (whose value g must not fall below on ∂ω; 0 between two membranes).
pub fn lifting(
    mesh: &Mesh,
    neighbour: &[[u32; 3]],
    (g, obstacle): (&Pieces, Option<&Pieces>),
    lambda: &[f64],
    gap: Option<&[f64]>,
) -> Vec<OnTriangle> {
    let rule = gauss_legendre_halves();
    let with_derivatives: Vec<Program> = g.exprs().iter().map(|g| g.with_derivatives()).collect();
    (0..mesh.n_triangles())
        .map(|t| {
            let on_boundary: Vec<usize> = (0..3).filter(|&j| neighbour[t][j] == ON_BOUNDARY).collect();
            let tri = mesh.triangle(t);
            // g of the edge's physical curve (one expression without groups).
            let g = |j: usize| &with_derivatives[g.edge_entry(tri[j], tri[(j + 1) % 3])];
            let below = obstacle.map(|o| o.on_triangle(t));
            let edge = |j: usize| on_edge(mesh, (t, j), (g(j), below), lambda, &rule);
            match on_boundary[..] {
                [] => OnTriangle::default(),
                [j] => edge(j).0,
                [i, j] => corner(mesh, t, [edge(i), edge(j)], gap),
                _ => unreachable!("a mesh with an interior vertex has no triangle bounded by ∂ω alone"),
            }
        })
        .collect()
}

/// ψ_e = s^k δ(τ) on K for one boundary edge e = [p, q] of K (third vertex c): what its norms and
/// its gradient at any point of K need.
struct EdgeLifting<'a> {
    /// The position j of p in K (q at j + 1, c at j + 2).
    j: usize,
    p: [f64; 2],
    q: [f64; 2],
    /// g with its derivatives ([`crate::expr::Expr::with_derivatives`]).
    g: &'a Program,
    /// g(p), g(q).
    ends: [f64; 2],
    /// ∇λ_q and ∇s = −∇λ_c.
    grad_q: [f64; 2],
    grad_s: [f64; 2],
    /// The exponent k.
    k: f64,
}

impl EdgeLifting<'_> {
    /// δ(τ) and δ'(τ), g(p + τ(q − p))' = ∇g · (q − p).
    fn delta(&self, tau: f64) -> (f64, f64) {
        let (p, q, [gp, gq]) = (self.p, self.q, self.ends);
        let (g, grad) = value_and_gradient(self.g, [0, 1].map(|k| p[k] + tau * (q[k] - p[k])));
        let derivative = grad[0] * (q[0] - p[0]) + grad[1] * (q[1] - p[1]);
        (g - ((1.0 - tau) * gp + tau * gq), derivative - (gq - gp))
    }

    /// v = ∇λ_q − τ∇s.
    fn v(&self, tau: f64) -> [f64; 2] {
        [0, 1].map(|k| self.grad_q[k] - tau * self.grad_s[k])
    }

    /// ∇ψ_e = s^{k−1} [k δ(τ) ∇s + δ'(τ) v] at the point of barycentric coordinates `l` (s > 0).
    fn gradient(&self, l: [f64; 3]) -> [f64; 2] {
        let s = 1.0 - l[(self.j + 2) % 3];
        let tau = l[(self.j + 1) % 3] / s;
        let (delta, d1) = self.delta(tau);
        let v = self.v(tau);
        [0, 1].map(|i| s.powf(self.k - 1.0) * (self.k * delta * self.grad_s[i] + d1 * v[i]))
    }
}

/// g and ∇g at x, g with its derivatives.
fn value_and_gradient(g: &Program, x: [f64; 2]) -> (f64, [f64; 2]) {
    let mut at = [[0.0]; 5];
    let [value, dx, dy, dxx, dyy] = &mut at;
    g.eval_many(&[x], &mut [value, dx, dy, dxx, dyy]);
    (at[0][0], [at[1][0], at[2][0]])
}

/// ψ_e on K for the boundary edge j of triangle t, g on it and the obstacle below it, if any.
fn on_edge<'a>(
    mesh: &Mesh,
    (t, j): (usize, usize),
    (g, obstacle): (&'a Program, Option<&crate::expr::Expr>),
    lambda: &[f64],
    rule: &[(f64, f64)],
) -> (OnTriangle, EdgeLifting<'a>) {
    let tri = mesh.triangle(t);
    let corners = mesh.corners(t);
    let (p, q, c) = (corners[j], corners[(j + 1) % 3], corners[(j + 2) % 3]);
    let grads = gradients(corners);
    let area = 0.5 * crate::mesh::orient(p, q, c);
    let mut edge = EdgeLifting {
        j,
        p,
        q,
        g,
        ends: [p, q].map(|x| value_and_gradient(g, x).0),
        grad_q: grads[(j + 1) % 3],
        grad_s: grads[(j + 2) % 3].map(|x| -x),
        k: 1.0,
    };
    let lambda_c = lambda[tri[(j + 2) % 3]];
    let dot = |a: [f64; 2], b: [f64; 2]| a[0] * b[0] + a[1] * b[1];
    let grad_s = edge.grad_s;
    let (mut a, mut b, mut c, mut range) = (0.0, 0.0, 0.0, [0.0_f64; 2]);
    let mut lowest = None;
    let deltas: Vec<f64> = (rule.iter())
        .map(|&(tau, w)| {
            let (delta, d1) = edge.delta(tau);
            let v = edge.v(tau);
            let x = [0, 1].map(|k| p[k] + tau * (q[k] - p[k]));
            let above = obstacle.map_or(0.0, |o| o.eval(x[0], x[1]));
            let g = delta + (1.0 - tau) * edge.ends[0] + tau * edge.ends[1];
            lowest = lower(lowest, Some((g - above, x)));
            a += w * delta * delta * dot(grad_s, grad_s);
            b += w * d1 * d1 * dot(v, v);
            c += w * delta * d1 * dot(grad_s, v);
            range = [range[0].min(delta), range[1].max(delta)];
            delta
        })
        .collect();
    let k = if a > 0.0 { (b / a).sqrt().max(1.0) } else { 1.0 };
    edge.k = k;
    let with_lambda: f64 = (rule.iter().zip(&deltas))
        .map(|(&(tau, w), delta)| {
            let s_star = 1.0 / (1.0 + tau.max(1.0 - tau));
            w * delta * s_star.powf(k + 2.0) / (k + 2.0)
        })
        .sum();
    let on = OnTriangle {
        grad_norm: super::root(area * (k * a + 2.0 * c + b / k)),
        with_lambda: lambda_c * 2.0 * area * with_lambda,
        range,
        lowest,
    };
    (on, edge)
}

/// A triangle with two boundary edges (all its vertices on ∂ω, so λ_h = 0 on it): ψ_0 = ψ_e1 +
/// ψ_e2, ‖∇ψ_0‖²_K = ‖∇ψ_e1‖² + ‖∇ψ_e2‖² + 2 (∇ψ_e1, ∇ψ_e2)_K ([`cross_term`]; at most the
/// triangle inequality's (‖∇ψ_e1‖ + ‖∇ψ_e2‖)²); where ψ_0 might dip below −w_h (g small at the
/// vertices, δ negative), ψ = max(ψ_0, −w_h) instead, with |∇ψ|² ≤ |∇ψ_0|² + |∇w_h|².
fn corner(mesh: &Mesh, t: usize, edges: [(OnTriangle, EdgeLifting); 2], gap: Option<&[f64]>) -> OnTriangle {
    let [(e1, l1), (e2, l2)] = &edges;
    let (n1, n2) = (e1.grad_norm, e2.grad_norm);
    let cross = cross_term(mesh.corners(t), l1, l2);
    let norm0 = super::root(n1 * n1 + n2 * n2 + 2.0 * cross).min(n1 + n2);
    let range = [0, 1].map(|k| e1.range[k] + e2.range[k]);
    let tri = mesh.triangle(t);
    let grad_norm = match gap {
        Some(gap) if tri.iter().map(|&a| gap[a]).fold(f64::INFINITY, f64::min) < -range[0] => {
            let g = gradients(mesh.corners(t));
            let gw = [0, 1].map(|k| (0..3).map(|i| g[i][k] * gap[tri[i]]).sum::<f64>());
            (norm0 * norm0 + mesh.area(t) * (gw[0] * gw[0] + gw[1] * gw[1])).sqrt()
        }
        _ => norm0,
    };
    OnTriangle {
        grad_norm,
        with_lambda: 0.0,
        range,
        lowest: lower(e1.lowest, e2.lowest),
    }
}

/// (∇ψ_e1, ∇ψ_e2)_K for the two boundary edges of a corner triangle K. ∇ψ_e is smooth on K but at
/// the vertex opposite e, where it depends on the direction (τ is constant on the rays from it).
/// K is cut by the segment from the two edges' common vertex to the midpoint m of the other two
/// vertices, and each half integrated by a Gauss rule collapsed at the one such vertex it holds
/// (x = v + r((1 − θ) a + θ b − v), dx = 2|T| r dr dθ): smooth in (r, θ).
fn cross_term(corners: [[f64; 2]; 3], e1: &EdgeLifting, e2: &EdgeLifting) -> f64 {
    // c1 = the vertex opposite e1 (on e2), c2 = the one opposite e2 (on e1), q their common one.
    let (c1, c2) = ((e1.j + 2) % 3, (e2.j + 2) % 3);
    let q = 3 - c1 - c2;
    let unit = |i: usize| std::array::from_fn::<f64, 3, _>(|k| f64::from(u8::from(k == i)));
    let m: [f64; 3] = std::array::from_fn(|k| 0.5 * (unit(c1)[k] + unit(c2)[k]));
    let rule: Vec<(f64, f64)> = (gauss_legendre(CROSS_POINTS).into_iter())
        .map(|(x, w)| (0.5 * (x + 1.0), 0.5 * w))
        .collect();
    let mut sum = 0.0;
    for (v, a, b) in [(unit(c1), unit(q), m), (unit(c2), m, unit(q))] {
        let at =
            |l: [f64; 3]| std::array::from_fn::<f64, 2, _>(|d| (0..3).map(|i| l[i] * corners[i][d]).sum());
        let area = 0.5 * crate::mesh::orient(at(v), at(a), at(b)).abs();
        for &(r, wr) in &rule {
            for &(theta, wt) in &rule {
                let l: [f64; 3] =
                    std::array::from_fn(|i| v[i] + r * ((1.0 - theta) * a[i] + theta * b[i] - v[i]));
                let (g1, g2) = (e1.gradient(l), e2.gradient(l));
                sum += 2.0 * area * r * wr * wt * (g1[0] * g2[0] + g1[1] * g2[1]);
            }
        }
    }
    sum
}

/// Gauss–Legendre points and weights on [0, ½] and on [½, 1].
fn gauss_legendre_halves() -> Vec<(f64, f64)> {
    let unit = gauss_legendre(POINTS);
    [0.0, 0.5]
        .iter()
        .flat_map(|&left| {
            unit.iter()
                .map(move |&(x, w)| (left + 0.25 * (x + 1.0), 0.25 * w))
        })
        .collect()
}

/// The n-point Gauss–Legendre rule on [−1, 1]: the roots of P_n by Newton's method from
/// Chebyshev guesses, weights 2 / ((1 − x²) P_n'(x)²).
fn gauss_legendre(n: usize) -> Vec<(f64, f64)> {
    (0..n)
        .map(|i| {
            let mut x = (std::f64::consts::PI * (i as f64 + 0.75) / (n as f64 + 0.5)).cos();
            let mut derivative = 0.0;
            for _ in 0..100 {
                let (mut p0, mut p1) = (1.0, x);
                for k in 2..=n {
                    (p0, p1) = (p1, ((2 * k - 1) as f64 * x * p1 - (k - 1) as f64 * p0) / k as f64);
                }
                derivative = n as f64 * (x * p1 - p0) / (x * x - 1.0);
                let dx = p1 / derivative;
                x -= dx;
                if dx.abs() < 1e-16 {
                    break;
                }
            }
            (x, 2.0 / ((1.0 - x * x) * derivative * derivative))
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::expr::Expr;

    /// The mesh of the one triangle (0,0), (1,0), (0,1).
    fn reference_triangle() -> Mesh {
        Mesh::from_parts(
            vec![[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]],
            vec![[0, 1, 2]],
            vec![true; 3],
        )
    }

    #[test]
    fn gauss_legendre_integrates_degree_2n_minus_1() {
        let rule = gauss_legendre_halves();
        assert_eq!(rule.len(), 2 * POINTS);
        for k in 0..2 * POINTS {
            let integral: f64 = rule.iter().map(|&(x, w)| w * x.powi(k as i32)).sum();
            assert!((integral - 1.0 / (k as f64 + 1.0)).abs() < 1e-14, "x^{k}");
        }
    }

    /// A corner triangle K = (0,0), (1,0), (0,1) with both legs on ∂ω and g = x² + y²: on each leg
    /// δ = τ² − τ and k = √14, ψ_0 = s1^k δ(τ1) + s2^k δ(τ2) with s1 = 1 − y, τ1 = x/(1 − y),
    /// s2 = 1 − x, τ2 = (1 − x − y)/(1 − x). ‖∇ψ_0‖_K against the gradient of its P1 interpolant
    /// on a fine grid of K (from ψ_0's values alone), well below the triangle inequality's bound.
    #[test]
    fn a_corner_triangle_gets_the_norm_of_the_sum() {
        let mesh = reference_triangle();
        let neighbour = [[ON_BOUNDARY, 0, ON_BOUNDARY]];
        let datum = crate::datum::Datum::from(Expr::parse("x^2 + y^2").unwrap());
        let pieces = datum.pieces("g", &mesh, crate::datum::On::Curves).unwrap();
        let on = lifting(&mesh, &neighbour, (&pieces, None), &[0.0; 3], None);
        let k = 14f64.sqrt();
        let leg = |s: f64, tau: f64| {
            if s > 0.0 {
                s.powf(k) * (tau * tau - tau)
            } else {
                0.0
            }
        };
        let psi = |x: f64, y: f64| leg(1.0 - y, x / (1.0 - y)) + leg(1.0 - x, (1.0 - x - y) / (1.0 - x));
        let n = 1000;
        let h = 1.0 / n as f64;
        let (mut brute, value) = (0.0, |i: usize, j: usize| psi(i as f64 * h, j as f64 * h));
        for i in 0..n {
            for j in 0..n - i {
                // The lower grid triangle (i, j), (i + 1, j), (i, j + 1), and the upper one beside it.
                let (a, b, c) = (value(i, j), value(i + 1, j), value(i, j + 1));
                brute += ((b - a).powi(2) + (c - a).powi(2)) * 0.5;
                if i + j + 1 < n {
                    let d = value(i + 1, j + 1);
                    brute += ((d - c).powi(2) + (d - b).powi(2)) * 0.5;
                }
            }
        }
        let single = (2.0 * 14f64.sqrt() + 1.0) / 60.0;
        let computed = on[0].grad_norm.powi(2);
        assert!((computed - brute).abs() < 1e-4 * brute, "{computed} vs {brute}");
        assert!(
            computed < 0.8 * 4.0 * single,
            "{computed} against (2 ‖∇ψ_e‖)² = {}",
            4.0 * single
        );
    }

    /// K = (0,0), (1,0), (0,1), the edge y = 0 on ∂ω, g = x²: s = 1 − y, τ = x/(1 − y),
    /// δ = τ² − τ, ∇s = (0, −1), v = (1, τ), so A = ∫ δ² = 1/30, B = ∫ (2τ − 1)²(1 + τ²) = 7/15,
    /// C = −∫ (τ² − τ)(2τ − 1)τ = 1/60: k = √14 and ‖∇ψ‖²_K = (AB)^½ + C = (2√14 + 1)/60, against
    /// 4/15 for the radial extension ψ = s δ (k = 1).
    #[test]
    fn the_lifting_of_a_parabola_has_its_closed_form_norm() {
        let mesh = reference_triangle();
        let neighbour = [[ON_BOUNDARY, 0, 0]];
        let g = Expr::parse("x^2").unwrap();
        let datum = crate::datum::Datum::from(g.clone());
        let pieces = datum.pieces("g", &mesh, crate::datum::On::Curves).unwrap();
        let on = lifting(
            &mesh,
            &neighbour,
            (&pieces, None),
            &[0.0, 0.0, 2.0],
            Some(&[0.0; 3]),
        );
        assert!(
            (on[0].grad_norm.powi(2) - (2.0 * 14f64.sqrt() + 1.0) / 60.0).abs() < 1e-12,
            "{}",
            on[0].grad_norm
        );
        // ∫_K λ_h ψ with λ_h = 2 on D_c ∩ K = {y ≥ x, y ≥ 1 − x − y}: by the (s, τ) formula,
        // 2 · 2|K| ∫ (τ² − τ) s*^{k+2}/(k + 2) dτ; against a brute-force sum over a fine grid of K.
        let k = 14f64.sqrt();
        let (mut brute, n) = (0.0, 2000);
        let cell = 1.0 / n as f64;
        // The grid's lower and upper triangles inside K, by their centroids.
        for i in 0..n {
            for j in 0..n - i {
                for (shift, inside) in [(1.0 / 3.0, true), (2.0 / 3.0, i + j + 2 <= n)] {
                    let (x, y) = ((i as f64 + shift) * cell, (j as f64 + shift) * cell);
                    if inside && y >= x && y >= 1.0 - x - y {
                        let (s, tau) = (1.0 - y, x / (1.0 - y));
                        brute += 2.0 * s.powf(k) * (tau * tau - tau) * 0.5 * cell * cell;
                    }
                }
            }
        }
        assert!(
            (on[0].with_lambda - brute).abs() < 2e-3 * brute.abs(),
            "{} vs {brute}",
            on[0].with_lambda
        );
    }
}
