//! Error norms against an exact solution: ‖u_i − u_ih‖_L², |u_i − u_ih|_H¹ (Theorem 9), the
//! energy norm, ‖λ − λ_h‖_L² with λ_h piecewise constant on the dual cells (Remark 22), and a
//! computable approximation of ‖λ − λ_h‖_H⁻¹ (Theorem 21).

use crate::action::Action;
use crate::assembly::{gradients, Quadrature, Stiffness};
use crate::contact::Solution;
use crate::datum::On;
use crate::expr::{Expr, Program};
use crate::linear::dirichlet_solve;
use crate::mesh::{dist, DualMesh, Mesh};
use crate::parallel::{self, PIECE};
use crate::problem::{DiscreteProblem, Lower};
use crate::result::{Attribute, Describe, Field, Place};
use cubature::{Density, Integral, Rules};

pub(crate) mod cubature;

/// Degree of the rule of the H⁻¹ norm's right-hand side on S_h.
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
    /// ∇u1 as [∂x, ∂y], for the H¹ error: as the case gives it, or u1's derivatives
    /// ([`Expr::gradient`]).
    pub grad_u1: [Expr; 2],
    /// ∇u2 as [∂x, ∂y].
    pub grad_u2: [Expr; 2],
    /// Whether the case gave ∇u1 and ∇u2 (else they are u1's and u2's derivatives).
    pub gradients_given: [bool; 2],
    /// Whether u2 is a rigid obstacle ψ (the classical obstacle problem, whose exact u is u1):
    /// then only u1's errors are reported, as u's.
    pub rigid: bool,
}

impl Exact {
    /// u1, u2 and λ interpolated at the vertices, for comparison in ParaView (u and λ above a
    /// rigid obstacle), evaluated as they are written.
    pub fn fields<'a>(&'a self, mesh: &'a Mesh) -> Vec<Field<'a>> {
        let points = &mesh.points[..];
        let at = |e: &'a Expr| {
            move |rows: std::ops::Range<usize>, out: &mut Vec<f64>| out.extend(e.values_at(&points[rows]))
        };
        if self.rigid {
            return vec![
                Field::computed("u_exact", Place::Vertices, points.len(), at(&self.u1)),
                Field::computed("lambda_exact", Place::Vertices, points.len(), at(&self.lambda)),
            ];
        }
        vec![
            Field::computed("u1_exact", Place::Vertices, points.len(), at(&self.u1)),
            Field::computed("u2_exact", Place::Vertices, points.len(), at(&self.u2)),
            Field::computed("lambda_exact", Place::Vertices, points.len(), at(&self.lambda)),
        ]
    }
}

/// Errors of one discrete solution.
#[derive(Debug, Clone, Default)]
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
    /// The largest estimated relative error of the norms' quadrature (the adaptive rule of
    /// `cubature`; the H⁻¹ norm's fixed rule not included).
    pub quadrature: f64,
    /// Whether u2 is a rigid obstacle ([`Exact::rigid`]): u1's errors are then u's, and u2's
    /// (ψ's interpolation error) are not reported.
    pub rigid: bool,
    /// [`Exact::gradients_given`], to name what a norm that is not finite comes from.
    pub gradients_given: [bool; 2],
    /// Where the exact solution does not take the boundary data on ∂ω_h, the polygon of the mesh
    /// (a curved ω, or a mesh of another domain): the errors are then against the solution of
    /// another problem than the one on ω_h, which the estimator's η bounds the error against.
    pub boundary: Option<Mismatch>,
    /// Where the exact solution does not solve the equations (`unsolved`).
    pub unsolved: Option<Unsolved>,
    /// What the round-off of u_h's and λ_h's values makes of the errors ([`RoundOff`]): an error
    /// below it says nothing of the discretisation.
    pub round_off: RoundOff,
}

/// The norms by name (a study's JSON): u1's and u2's, or above a rigid obstacle u's alone
/// (`l2_u`, `h1_u`, as the study's table names them).
impl serde::Serialize for Errors {
    fn serialize<S: serde::Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        use serde::ser::SerializeMap;
        let membranes = [
            ("l2_u1", Some(self.l2_u1)),
            ("l2_u2", Some(self.l2_u2)),
            ("h1_u1", self.h1_u1),
            ("h1_u2", self.h1_u2),
        ];
        let obstacle = [("l2_u", Some(self.l2_u1)), ("h1_u", self.h1_u1)];
        let u: &[(&str, Option<f64>)] = if self.rigid { &obstacle } else { &membranes };
        let rest = [
            ("energy", self.energy),
            ("l2_lambda", Some(self.l2_lambda)),
            ("hminus1_lambda", self.hminus1_lambda),
            ("quadrature", Some(self.quadrature)),
            // 0 where the exact solution takes the boundary data and solves the equations.
            (
                "exact_boundary_mismatch",
                Some(self.boundary.map_or(0.0, |m| m.relative)),
            ),
            (
                "exact_equation_mismatch",
                Some(self.unsolved.map_or(0.0, |u| u.share)),
            ),
        ];
        let mut map = serializer.serialize_map(Some(u.len() + rest.len()))?;
        for (name, value) in u.iter().chain(&rest) {
            map.serialize_entry(name, value)?;
        }
        map.end()
    }
}

/// The largest difference between the exact solution and the boundary data on ∂ω_h.
#[derive(Debug, Clone, Copy, serde::Serialize)]
pub struct Mismatch {
    /// max |u1 − g|, |u2 − g2| (above a rigid obstacle |u − g|) at the sample points of the
    /// boundary edges, relative to the size of the solution: the largest of these values and of
    /// |u1h|, |u2h| at the vertices.
    pub relative: f64,
    /// The point where it is largest.
    pub at: [f64; 2],
    /// Whether it is a boundary vertex: there ω_h meets ∂ω even on a curved ω, so the exact
    /// solution does not take this case's boundary data.
    pub at_vertex: bool,
}

impl Mismatch {
    /// The note of a table of errors over meshes with these mismatches, if any.
    pub fn note(mismatches: impl Iterator<Item = Mismatch>) -> Option<String> {
        let all: Vec<Mismatch> = mismatches.collect();
        let relative = all.iter().map(|m| m.relative).reduce(f64::max)?;
        Some(match all.iter().find(|m| m.at_vertex) {
            Some(m) => format!(
                "The exact solution does not take the boundary data at the boundary vertex ({:.4}, \
                 {:.4}) (off by {:.1e} of their size): [exact] is not a solution of this case, and \
                 the errors are not its errors.\n\n",
                m.at[0], m.at[1], m.relative
            ),
            None => format!(
                "The exact solution misses the boundary data on ∂ω_h, the meshes' polygons, by up to \
                 {relative:.1e} of their size: the errors are against the solution on another domain \
                 (a curved ω), while η bounds the error against the solution on ω_h, so η/error may \
                 fall below 1 (docs/a-posteriori.md §12).\n\n"
            ),
        })
    }
}

/// A mismatch below this part of the boundary values is round-off.
const MISMATCH: f64 = 1e-9;

/// A mismatch below this many times the two values' changes under a round-off of the coordinates
/// is round-off too: an expression of (x − 10⁵)/10⁻³ loses 8 digits to the coordinates alone.
const NOISE_TIMES: f64 = 8.0;

/// f at `p`, and how much it changes when the coordinates move by a few units of round-off: the
/// lesser change of two opposite moves (round-off changes it either way; a jump of f across ∂ω,
/// which one of them crosses, is not round-off).
fn with_noise(f: impl Fn(f64, f64) -> f64, p: [f64; 2]) -> (f64, f64) {
    let value = f(p[0], p[1]);
    let moved = |s: f64| {
        f(
            p[0] * (1.0 + s * 4.0 * f64::EPSILON),
            p[1] * (1.0 - s * 4.0 * f64::EPSILON),
        )
    };
    let noise = (moved(1.0) - value).abs().min((moved(-1.0) - value).abs());
    (value, noise)
}

/// The relative round-off of u_h's values that [`RoundOff`] allows for: about 450 ε (the
/// solve's own round-off, and the cancellation of u − u_h where both are large).
const VALUE_ROUND_OFF: f64 = 1e-13;

impl Errors {
    /// The energy error |||u − u_h|||, unless it is round-off ([`Errors::at_round_off`]).
    pub fn resolved_energy(&self) -> Option<f64> {
        self.energy.filter(|_| !self.at_round_off())
    }

    /// Whether the energy error is within what the round-off of u_h's values makes of it: u_h is
    /// the exact solution to round-off (a solution exact in P1), and a ratio to the error, as the
    /// effectivity η/error, says nothing.
    pub fn at_round_off(&self) -> bool {
        self.energy.is_some_and(|e| e <= self.round_off.energy)
    }

    /// Whether ‖λ − λ_h‖_L² is within the round-off λ_h can carry (λ = 0 where λ_h is round-off).
    pub fn lambda_at_round_off(&self) -> bool {
        self.l2_lambda <= self.round_off.lambda
    }

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
        let u = p1_errors(mesh, [&solution.u1, &solution.u2], exact);
        let lambda = lambda_error(dual, |s| action.lambda[dual.owner(s)], &exact.lambda);
        let [l2_u1, l2_u2, h1_u1, h1_u2] = u.value.map(f64::sqrt);
        let (h1_u1, h1_u2) = (Some(h1_u1), (!exact.rigid).then_some(h1_u2));
        // The relative error of a norm √S is about half that of S; above a rigid obstacle, u2's
        // (ψ's) norms are not reported.
        let reported = [true, !exact.rigid, true, !exact.rigid, true];
        let value = [&u.value[..], &lambda.value].concat();
        let error = [&u.error[..], &lambda.error].concat();
        let quadrature = (0..5)
            .filter(|&k| reported[k] && value[k] > 0.0)
            .map(|k| 0.5 * error[k] / value[k])
            .fold(0.0, f64::max);
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
            l2_lambda: lambda.value[0].sqrt(),
            hminus1_lambda: hminus1.then(|| hminus1_lambda(dual, &action.lambda, &exact.lambda)),
            quadrature,
            rigid: exact.rigid,
            gradients_given: exact.gradients_given,
            boundary: boundary_mismatch(problem, exact, [&solution.u1, &solution.u2]),
            unsolved: unsolved(problem, exact),
            round_off: RoundOff::of(problem, solution, action),
        }
    }
}

/// What values of u_ih off by 10⁻¹³ of what they are computed from make of the errors' norms:
/// u_ih = v ± w, so of max_b (|u1h| + |u2h| + 2|w_h|)(b) ≥ |v| + |w| (as the action's checks
/// count it: u2h near 0 may be computed from v and w of 10⁶), δ. On a triangle K,
/// Σ_j |∇φ_j| = P_K / (2|K|) (P_K its perimeter). And the round-off λ_h carries.
#[derive(Debug, Clone, Copy, Default)]
pub struct RoundOff {
    /// Of |u_i − u_ih|_H¹: δ (Σ_K P_K² / (4|K|))^½.
    pub h1: f64,
    /// Of ‖u_i − u_ih‖_L²: δ |ω|^½.
    pub l2: f64,
    /// Of the energy error: (Σ_i μ_i)^½ times `h1` (μ1^½ above a rigid obstacle).
    pub energy: f64,
    /// Of ‖λ − λ_h‖_L²: [`crate::action::Checks::noise`] (its largest at a vertex) times |ω|^½.
    pub lambda: f64,
}

impl RoundOff {
    /// The round-off of the errors of `solution` and `action` on `problem`'s mesh.
    pub fn of(problem: &DiscreteProblem, solution: &Solution, action: &Action) -> RoundOff {
        let mesh = &problem.mesh;
        // Σ_K P_K²/(4|K|) and |ω| in one pass.
        let sums = parallel::map(mesh.n_triangles(), PIECE, |triangles| {
            triangles.fold([0.0; 2], |[shape, measure], t| {
                let [p, q, r] = mesh.corners(t);
                let (perimeter, area) = (dist(p, q) + dist(q, r) + dist(r, p), mesh.area(t));
                // P_K/(2|K|) first: P_K² may overflow where the ratio does not.
                [shape + (perimeter / (2.0 * area)).powi(2) * area, measure + area]
            })
        });
        let [shape, measure] = sums.iter().fold([0.0; 2], |a, s| [a[0] + s[0], a[1] + s[1]]);
        let (u1, u2, w) = (&solution.u1, &solution.u2, &solution.obstacle.gap);
        let computed = (0..u1.len()).fold(0.0_f64, |m, b| {
            m.max(u1[b].abs() + u2[b].abs() + 2.0 * w[b].abs())
        });
        let delta = VALUE_ROUND_OFF * computed;
        let mu = problem.data.mu1 + problem.data.mu2().filter(|_| !solution.rigid).unwrap_or(0.0);
        let h1 = delta * shape.sqrt();
        RoundOff {
            h1,
            l2: delta * measure.sqrt(),
            energy: mu.sqrt() * h1,
            lambda: action.checks.noise * measure.sqrt(),
        }
    }
}

/// Where the exact solution differs from the boundary data on ∂ω_h by more than round-off of the
/// solution's size (`uh`'s), at the boundary vertices (where it agrees wherever ω_h is inscribed in
/// ω: a vertex is reported first) and at the quarter points of each boundary edge: u1 against g and
/// u2 against g2, or u against g above a rigid obstacle.
fn boundary_mismatch(problem: &DiscreteProblem, exact: &Exact, uh: [&[f64]; 2]) -> Option<Mismatch> {
    let (mesh, data) = (&problem.mesh, &problem.data);
    let fit = "the data fit the mesh's groups (checked by DiscreteProblem::new)";
    let g = data.g.pieces("g", mesh, On::Curves).expect(fit);
    let g2 = match &data.lower {
        Lower::Membrane { g2, .. } => Some(g2.pieces("g2", mesh, On::Curves).expect(fit)),
        Lower::Rigid { .. } => None,
    };
    let size = uh
        .iter()
        .flat_map(|u| u.iter())
        .fold(0.0_f64, |m, u| m.max(u.abs()));
    let (mut worst, mut scale, mut at) = ([0.0_f64; 2], size, [[0.0; 2]; 2]);
    for (a, b) in mesh.boundary_edges() {
        let (p, q) = (mesh.points[a], mesh.points[b]);
        for t in [0.0, 0.25, 0.5, 0.75] {
            let k = usize::from(t > 0.0);
            let x = [p[0] + t * (q[0] - p[0]), p[1] + t * (q[1] - p[1])];
            let mut pairs = vec![(
                with_noise(|x, y| exact.u1.eval(x, y), x),
                with_noise(|x, y| g.on_edge(a, b).eval(x, y), x),
            )];
            if let Some(g2) = &g2 {
                pairs.push((
                    with_noise(|x, y| exact.u2.eval(x, y), x),
                    with_noise(|x, y| g2.on_edge(a, b).eval(x, y), x),
                ));
            }
            for ((u, u_noise), (given, given_noise)) in pairs {
                scale = scale.max(u.abs()).max(given.abs());
                let off = (u - given).abs();
                if off > worst[k] && off > NOISE_TIMES * (u_noise + given_noise) {
                    (worst[k], at[k]) = (off, x);
                }
            }
        }
    }
    let k = usize::from(worst[0] <= MISMATCH * scale);
    (worst[k] > MISMATCH * scale).then(|| Mismatch {
        relative: worst[k] / scale,
        at: at[k],
        at_vertex: k == 0,
    })
}

/// Where the exact solution misses the equations of (1.1) (above a rigid obstacle −μΔu − λ = f)
/// on a share of sample points too large for a few points near a kink or a jump of the data.
#[derive(Debug, Clone, Copy)]
pub struct Unsolved {
    /// The share of the sample points where a residual exceeds `UNSOLVED` (1e-3) of its terms.
    pub share: f64,
    /// The point of the largest relative residual.
    pub at: [f64; 2],
    /// What is missed there.
    pub missed: Missed,
}

impl Unsolved {
    /// What the exact solution misses, and what that does to the errors, in words (`rigid`: above
    /// a rigid obstacle).
    pub fn describe(&self, rigid: bool) -> String {
        let u = |i: usize| match (rigid, i) {
            (true, _) => "u",
            (false, 1) => "u1",
            _ => "u2",
        };
        let missed = match (self.missed, rigid) {
            (Missed::Equation(_), true) => "does not solve −μΔu − λ = f".to_string(),
            (Missed::Equation(1), false) => "does not solve −μ1Δu1 − λ = f1".to_string(),
            (Missed::Equation(_), false) => "does not solve −μ2Δu2 + λ = f2".to_string(),
            (Missed::Gradient(i), _) => format!("grad_{0} is not the gradient of {0}", u(i)),
            (Missed::Complementarity, true) => "does not satisfy λ ≥ 0, u − ψ ≥ 0, λ (u − ψ) = 0".to_string(),
            (Missed::Complementarity, false) => {
                "does not satisfy λ ≥ 0, u1 − u2 ≥ 0, λ (u1 − u2) = 0".to_string()
            }
        };
        let consequence = match self.missed {
            Missed::Equation(_) | Missed::Complementarity => {
                "[exact] is not a solution of this case, and the errors are not its errors"
            }
            Missed::Gradient(_) => "the H1 errors are against the gradient given, not against ∇u",
        };
        format!(
            "{missed} at {:.0}% of the points sampled (the most at ({:.4}, {:.4})): {consequence}",
            100.0 * self.share,
            self.at[0],
            self.at[1]
        )
    }
}

/// What the exact solution misses at a point.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Missed {
    /// The equation of membrane 1 (or the obstacle problem's), or of membrane 2.
    Equation(usize),
    /// ∇u_i given beside u_i (i = 1, 2) is not its gradient.
    Gradient(usize),
    /// λ ≥ 0, u1 − u2 ≥ 0 (u − ψ ≥ 0) or λ (u1 − u2) = 0.
    Complementarity,
}

/// A residual above this part of the size of its terms misses the equation.
const UNSOLVED: f64 = 1e-3;

/// The exact solution is said not to solve the equations beyond this share of the points.
const UNSOLVED_SHARE: f64 = 0.1;

/// Triangles whose centroids are sampled, at most.
const SAMPLES: usize = 4096;

/// How far λ ≥ 0, u1 − u2 ≥ 0 (u − ψ ≥ 0: `exact.u2` is ψ) and λ (u1 − u2) = 0 are missed at
/// `x`: λ's part relative to |λ| + |f1|, the gap's to |u1| + |u2|, the product's by the smaller of
/// the two (both far from 0).
fn complementarity_miss(exact: &Exact, lambda: f64, f1: f64, x: [f64; 2]) -> f64 {
    let [u1, u2] = [&exact.u1, &exact.u2].map(|u| u.eval(x[0], x[1]));
    let (gap, sizes) = (u1 - u2, (u1.abs() + u2.abs()).max(f64::MIN_POSITIVE));
    let action = (lambda.abs() + f1.abs()).max(f64::MIN_POSITIVE);
    let (l, g) = (lambda / action, gap / sizes);
    (-l).max(-g).max(l.abs().min(g.abs())).max(0.0)
}

/// The residuals of −μ1Δu1 − λ = f1 and −μ2Δu2 + λ = f2 (−μΔu − λ = f above a rigid obstacle) at
/// the centroids of up to [`SAMPLES`] triangles, Δu_i by differentiating u_i's expression
/// ([`Expr::with_derivatives`]), the given ∇u_i against the derivatives of u_i there, and the
/// complementarity of λ and u1 − u2 (u − ψ): [`Unsolved`] when more than [`UNSOLVED_SHARE`] of
/// the points miss one.
fn unsolved(problem: &DiscreteProblem, exact: &Exact) -> Option<Unsolved> {
    let (mesh, data) = (&problem.mesh, &problem.data);
    let fit = "the data fit the mesh's groups (checked by DiscreteProblem::new)";
    let f1 = data.f1.pieces("f1", mesh, On::Surfaces).expect(fit);
    let f2 = match &data.lower {
        Lower::Membrane { f2, .. } => Some(f2.pieces("f2", mesh, On::Surfaces).expect(fit)),
        Lower::Rigid { .. } => None,
    };
    let [u1, u2] = [&exact.u1, &exact.u2].map(|u| u.with_derivatives());
    // −μΔu, the size of its terms μ(|∂xx u| + |∂yy u|) (a harmonic u has Δu = 0 from terms that
    // are not), and their round-off; ∇u, and its round-off.
    let operator = |mu: f64, u: &Program, x: [f64; 2]| {
        let mut at: [[f64; 1]; 5] = [[0.0]; 5];
        let [value, dx, dy, dxx, dyy] = &mut at;
        u.eval_many(&[x], &mut [value, dx, dy, dxx, dyy]);
        let [_, [dx], [dy], [dxx], [dyy]] = at;
        let size = mu * (dxx.abs() + dyy.abs());
        let laplacian = (-mu * (dxx + dyy), size, 16.0 * f64::EPSILON * size);
        let gradient = ([dx, dy], 16.0 * f64::EPSILON * (dx.abs() + dy.abs()));
        (laplacian, gradient)
    };
    // |∇u given − ∇u| relative to their sizes, less the round-off.
    let gradient_miss = |given: &[Expr; 2], (d, noise): ([f64; 2], f64), x: [f64; 2]| {
        let g = given.each_ref().map(|g| g.eval(x[0], x[1]));
        let off = (g[0] - d[0]).abs() + (g[1] - d[1]).abs();
        let size = g[0].abs() + g[1].abs() + d[0].abs() + d[1].abs();
        (off - noise).max(0.0) / size.max(f64::MIN_POSITIVE)
    };
    let stride = (mesh.n_triangles() / SAMPLES).max(1);
    let (mut missed, mut samples, mut worst) = (0, 0, (0.0, [0.0; 2], Missed::Equation(1)));
    for t in (0..mesh.n_triangles()).step_by(stride) {
        let [p, q, r] = mesh.corners(t);
        let x = [0, 1].map(|k| (p[k] + q[k] + r[k]) / 3.0);
        let lambda = exact.lambda.eval(x[0], x[1]);
        let mut equations = vec![(1, data.mu1, &u1, &exact.grad_u1, -lambda, f1.on_triangle(t))];
        if let (Some(mu2), Some(f2)) = (data.mu2(), &f2) {
            equations.push((2, mu2, &u2, &exact.grad_u2, lambda, f2.on_triangle(t)));
        }
        samples += 1;
        let complementarity = complementarity_miss(exact, lambda, f1.on_triangle(t).eval(x[0], x[1]), x);
        let mut miss = complementarity > UNSOLVED;
        if complementarity > worst.0 {
            worst = (complementarity, x, Missed::Complementarity);
        }
        for (i, mu, u, grad, lambda, f) in equations {
            let (((a, size, noise), differences), f) = (operator(mu, u, x), f.eval(x[0], x[1]));
            let terms = (size + lambda.abs() + f.abs()).max(f64::MIN_POSITIVE);
            let relative = ((a + lambda - f).abs() - noise).max(0.0) / terms;
            let gradient = gradient_miss(grad, differences, x);
            for (relative, missed) in [(relative, Missed::Equation(i)), (gradient, Missed::Gradient(i))] {
                miss |= relative > UNSOLVED;
                if relative > worst.0 {
                    worst = (relative, x, missed);
                }
            }
        }
        missed += usize::from(miss);
    }
    let share = missed as f64 / samples.max(1) as f64;
    (share > UNSOLVED_SHARE).then_some(Unsolved {
        share,
        at: worst.1,
        missed: worst.2,
    })
}

impl Errors {
    /// The key of `[exact]` whose error norm is not a finite number, if one is not.
    pub fn not_finite(&self) -> Option<&'static str> {
        let u = if self.rigid { "exact.u" } else { "exact.u1" };
        let grad_u = match (self.rigid, self.gradients_given[0]) {
            (true, true) => "exact.grad_u",
            (true, false) => "the derivatives of exact.u (no grad_u given)",
            (false, true) => "exact.grad_u1",
            (false, false) => "the derivatives of exact.u1 (no grad_u1 given)",
        };
        let grad_u2 = match self.gradients_given[1] {
            true => "exact.grad_u2",
            false => "the derivatives of exact.u2 (no grad_u2 given)",
        };
        [
            (u, Some(self.l2_u1)),
            ("exact.u2", Some(self.l2_u2)),
            (grad_u, self.h1_u1),
            (grad_u2, self.h1_u2),
            ("exact.lambda", Some(self.l2_lambda)),
            ("exact.lambda", self.hminus1_lambda),
        ]
        .into_iter()
        .find(|(_, norm)| norm.is_some_and(|n| !n.is_finite()))
        .map(|(key, _)| key)
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
            ("error_quadrature", "error_quadrature", Some(self.quadrature)),
            (
                "exact_boundary_mismatch",
                "exact_boundary_mismatch",
                Some(self.boundary.map_or(0.0, |m| m.relative)),
            ),
            (
                "exact_equation_mismatch",
                "exact_equation_mismatch",
                Some(self.unsolved.map_or(0.0, |u| u.share)),
            ),
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

/// The rules of the error integrals on T_h: where u is smooth on a triangle, (u − u_h)² is a
/// quartic plus O(h⁵) of its size, which degree 5 integrates to O(h²) of its value and degree 6
/// to O(h³), and |∇(u − u_h)|² a quadratic plus O(h³), to O(h⁴) and O(h⁵).
const ON_TRIANGLES: Rules = Rules {
    lo: Quadrature { degree: 5 },
    hi: Quadrature { degree: 6 },
};

/// The rules on the cells of S_h: where λ is smooth, (λ − λ_a)² is a quadratic plus O(h³) of its
/// size (an exact quartic where λ is quadratic), to O(h³) and O(h⁴) of its value.
const ON_DUAL_CELLS: Rules = Rules {
    lo: Quadrature { degree: 4 },
    hi: Quadrature { degree: 5 },
};

/// (‖u_i − u_ih‖²_L², |u_i − u_ih|²_H¹) of both membranes' P1 fields, the exact fields evaluated
/// together (they share most of their terms).
fn p1_errors<'a>(mesh: &Mesh, uh: [&[f64]; 2], exact: &'a Exact) -> Integral<4> {
    // Above a rigid obstacle u2 = ψ, whose errors are not reported, is left out.
    let exact_u = [Some(&exact.u1), (!exact.rigid).then_some(&exact.u2)];
    let exact_grad = [Some(&exact.grad_u1), (!exact.rigid).then_some(&exact.grad_u2)];
    let mut fields: Vec<&Expr> = Vec::new();
    let mut at = |e: &[&'a Expr]| {
        fields.extend(e);
        fields.len() - e.len()
    };
    let values = exact_u.map(|u| u.map(|u| at(&[u])));
    let grads = exact_grad.map(|g| g.map(|[gx, gy]| at(&[gx, gy])));
    let density = P1Errors {
        mesh,
        uh,
        fields,
        values,
        grads,
    };
    cubature::integrate(mesh.n_triangles(), |t| mesh.corners(t), &density, ON_TRIANGLES)
}

/// The densities (u_i − u_ih)² and |∇u_i − ∇u_ih|² (i = 1, 2) on the triangles of T_h, zero
/// where u_i or ∇u_i is not given; `fields` the u_i given, at `values[i]`, and the components of
/// the ∇u_i given, the first at `grads[i]`.
struct P1Errors<'a> {
    mesh: &'a Mesh,
    uh: [&'a [f64]; 2],
    fields: Vec<&'a Expr>,
    values: [Option<usize>; 2],
    grads: [Option<usize>; 2],
}

impl Density<4> for P1Errors<'_> {
    /// Per membrane, a corner p, u_ih(p) and ∇u_ih on the triangle.
    type Local = [([f64; 2], f64, [f64; 2]); 2];

    fn fields(&self) -> Vec<&Expr> {
        self.fields.clone()
    }

    fn local(&self, t: usize) -> Self::Local {
        let (corners, tri) = (self.mesh.corners(t), self.mesh.triangle(t));
        let g = gradients(corners);
        self.uh.map(|u| {
            let grad = [0, 1].map(|k| (0..3).map(|j| g[j][k] * u[tri[j]]).sum::<f64>());
            (corners[0], u[tri[0]], grad)
        })
    }

    fn at(&self, local: &Self::Local, x: [f64; 2], values: &[Vec<f64>], at: usize) -> [f64; 4] {
        let mut d = [0.0; 4];
        for (i, &(p, value, grad)) in local.iter().enumerate() {
            if let Some(k) = self.values[i] {
                let uh = value + grad[0] * (x[0] - p[0]) + grad[1] * (x[1] - p[1]);
                d[i] = (values[k][at] - uh).powi(2);
            }
            if let Some(k) = self.grads[i] {
                d[2 + i] = (values[k][at] - grad[0]).powi(2) + (values[k + 1][at] - grad[1]).powi(2);
            }
        }
        d
    }
}

/// ∫ (λ − λ_h)² over the cells of S_h, λ_h = `lambda_h` of each cell. Where λ is a constant on a
/// triangle of T_h (away from the contact set, λ = 0), its six cells need no rule.
fn lambda_error(dual: &DualMesh, lambda_h: impl Fn(usize) -> f64 + Sync, lambda: &Expr) -> Integral<1> {
    let mesh = dual.mesh();
    let constant = cubature::constant_on(mesh.n_triangles(), |t| mesh.corners(t), lambda);
    let density = DualError {
        lambda,
        lambda_h,
        constant,
    };
    cubature::integrate(dual.n_cells(), |s| dual.corners(s), &density, ON_DUAL_CELLS)
}

/// The density (λ − λ_h)² on the cells of S_h; `constant` λ's value on each triangle of T_h where
/// it is a constant.
struct DualError<'a, L> {
    lambda: &'a Expr,
    lambda_h: L,
    constant: Vec<Option<f64>>,
}

impl<L: Fn(usize) -> f64 + Sync> Density<1> for DualError<'_, L> {
    /// λ_h on the cell.
    type Local = f64;

    fn fields(&self) -> Vec<&Expr> {
        vec![self.lambda]
    }

    fn local(&self, s: usize) -> f64 {
        (self.lambda_h)(s)
    }

    fn at(&self, lambda_h: &f64, _: [f64; 2], values: &[Vec<f64>], k: usize) -> [f64; 1] {
        [(values[0][k] - lambda_h).powi(2)]
    }

    fn constant(&self, s: usize) -> Option<[f64; 1]> {
        self.constant[s / 6].map(|c| [(c - (self.lambda_h)(s)).powi(2)])
    }
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
    use crate::case::Case;
    use crate::problem::DiscreteProblem;

    /// The shipped exact solutions solve their equations (the ball's is harmonic with f = 0 off
    /// its contact set: Δu = 0 from second derivatives that are not), one written for other loads
    /// does not, and the equation it misses is named.
    #[test]
    fn an_exact_solution_of_other_loads_is_found_out() {
        let unsolved = |case: &Case| {
            let problem = DiscreteProblem::new(case.mesh().unwrap(), &case.data).unwrap();
            super::unsolved(&problem, case.exact.as_ref().unwrap())
        };
        let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("data/cases");
        for name in ["ball", "default", "disk_unloaded", "lshape_corner"] {
            let mut case = Case::read(&dir.join(format!("{name}.toml"))).unwrap();
            let _ = case.set_cells(16);
            assert!(unsolved(&case).is_none(), "{name}");
        }
        let text = |f2: &str, grad_u2: &str| {
            format!(
                "mu1 = 1.0\nmu2 = 2.0\nf1 = -4\nf2 = {f2}\ng = \"x*x + y*y\"\n[exact]\nu1 = \"x*x + y*y\"\n\
                 u2 = \"x*x\"\nlambda = 0\ngrad_u1 = [\"2*x\", \"2*y\"]\ngrad_u2 = {grad_u2}\n\
                 [mesh]\nkind = \"rectangle\"\nn = 8\n"
            )
        };
        let of =
            |f2: &str, grad_u2: &str| unsolved(&Case::parse(&text(f2, grad_u2), "t", ".".into()).unwrap());
        // −Δ(x² + y²) = −4 = f1; −2Δ(x²) = −4 = f2 solves, −2 does not; ∇(x²) = (2x, 0), not (x, 0).
        assert!(of("-4", r#"["2*x", "0"]"#).is_none());
        let u = of("-2", r#"["2*x", "0"]"#).expect("missed");
        assert_eq!((u.share, u.missed), (1.0, Missed::Equation(2)));
        let u = of("-4", r#"["x", "0"]"#).expect("missed");
        assert_eq!((u.share, u.missed), (1.0, Missed::Gradient(2)));
        assert!(u.describe(false).starts_with("grad_u2 is not the gradient of u2"));
        // λ = 3 where u1 > u2 solves both equations (f1 = −7, f2 = −1) but not complementarity
        // (it printed an effectivity of 0.3 without a word); so does u2 above u1 with λ = 0.
        let contact = |lambda: &str, u2: &str, f2: &str| {
            let text = format!(
                "mu1 = 1.0\nmu2 = 1.0\nf1 = \"-4 - ({lambda})\"\nf2 = \"{f2} + ({lambda})\"\ng = \"x*x + y*y\"\n\
                 [exact]\nu1 = \"x*x + y*y\"\nu2 = \"{u2}\"\nlambda = \"{lambda}\"\n[mesh]\nkind = \"rectangle\"\nn = 8\n"
            );
            unsolved(&Case::parse(&text, "t", ".".into()).unwrap())
        };
        let u = contact("3", "x*x - 1", "-2").expect("missed");
        assert_eq!((u.share, u.missed), (1.0, Missed::Complementarity));
        assert!(u
            .describe(false)
            .starts_with("does not satisfy λ ≥ 0, u1 − u2 ≥ 0, λ (u1 − u2) = 0"));
        let u = contact("0", "x*x + y*y + 1", "-4").expect("missed");
        assert_eq!(u.missed, Missed::Complementarity);
        assert!(contact("0", "x*x - 1", "-2").is_none());
    }

    /// An H¹ error that is not finite is named by the key it comes from: a gradient the case
    /// gave, or the derivatives of u where it gave none.
    #[test]
    fn a_norm_that_is_not_finite_names_its_key() {
        let key = |rigid: bool, gradients_given: [bool; 2], h1: [f64; 2]| {
            let e = super::Errors {
                rigid,
                gradients_given,
                h1_u1: Some(h1[0]),
                h1_u2: (!rigid).then_some(h1[1]),
                ..Default::default()
            };
            e.not_finite()
        };
        assert_eq!(key(false, [true; 2], [1.0, 1.0]), None);
        assert_eq!(key(false, [true; 2], [f64::NAN, 1.0]), Some("exact.grad_u1"));
        assert_eq!(
            key(false, [false, true], [f64::NAN, 1.0]),
            Some("the derivatives of exact.u1 (no grad_u1 given)")
        );
        assert_eq!(
            key(false, [true, false], [1.0, f64::INFINITY]),
            Some("the derivatives of exact.u2 (no grad_u2 given)")
        );
        assert_eq!(key(true, [true, false], [f64::NAN, 0.0]), Some("exact.grad_u"));
        assert_eq!(
            key(true, [false; 2], [f64::NAN, 0.0]),
            Some("the derivatives of exact.u (no grad_u given)")
        );
    }

    #[test]
    fn a_study_names_the_norms_of_the_obstacle_problem_as_u() {
        let json = |rigid: bool| {
            let e = super::Errors {
                rigid,
                l2_u1: 0.25,
                h1_u1: Some(0.5),
                ..Default::default()
            };
            serde_json::to_value(&e).unwrap()
        };
        let keys = |rigid: bool| {
            json(rigid)
                .as_object()
                .unwrap()
                .keys()
                .cloned()
                .collect::<Vec<String>>()
        };
        // Above an obstacle u1's values are u's.
        assert_eq!(
            (json(true)["l2_u"].as_f64(), json(true)["h1_u"].as_f64()),
            (Some(0.25), Some(0.5))
        );
        assert_eq!(json(false)["h1_u2"], serde_json::Value::Null);
        let rest = [
            "energy",
            "exact_boundary_mismatch",
            "exact_equation_mismatch",
            "hminus1_lambda",
            "l2_lambda",
            "quadrature",
        ];
        fn sorted(mut v: Vec<&'static str>) -> Vec<&'static str> {
            v.sort_unstable();
            v
        }
        assert_eq!(keys(true), sorted([&["h1_u", "l2_u"][..], &rest].concat()));
        assert_eq!(
            keys(false),
            sorted([&["h1_u1", "h1_u2", "l2_u1", "l2_u2"][..], &rest].concat())
        );
    }

    use super::*;
    use crate::mesh::{Diagonal, Edges};

    /// A layer of width 0.01 across x = 0.4: u = tanh((x − 0.4)/w), |∂x u| = sech²(…)/w.
    const W: f64 = 0.01;
    const LAYER: &str = "tanh((x - 0.4)/0.01)";

    /// ∫ over the unit square of u² and of |∇u|² for the layer, in closed form
    /// (∫ sech⁴ = tanh − tanh³/3).
    fn layer_integrals() -> [f64; 2] {
        let ends = [-0.4 / W, 0.6 / W].map(f64::tanh);
        let [a, b] = ends.map(|t| t - t.powi(3) / 3.0);
        [1.0 - W * (ends[1] - ends[0]), (b - a) / W]
    }

    fn unit_square(n: usize) -> Mesh {
        Mesh::rectangle([0.0, 0.0], [1.0, 1.0], n, n, Diagonal::Right).unwrap()
    }

    /// The errors of u_h = 0 against u (and its gradient) on a 16² mesh: ∫ u² and ∫ |∇u|².
    fn of_zero(u: &str, grad: [&str; 2]) -> Integral<4> {
        let mesh = unit_square(16);
        let zero = vec![0.0; mesh.n_vertices()];
        let exact = Exact {
            u1: Expr::parse(u).unwrap(),
            u2: Expr::parse("0").unwrap(),
            lambda: Expr::parse("0").unwrap(),
            grad_u1: grad.map(|g| Expr::parse(g).unwrap()),
            grad_u2: [(); 2].map(|_| Expr::parse("0").unwrap()),
            gradients_given: [true; 2],
            rigid: false,
        };
        p1_errors(&mesh, [&zero, &zero], &exact)
    }

    /// ∫ (λ − c)² over the cells of S_h of an n² mesh.
    fn dual_of(lambda: &str, c: f64, n: usize) -> Integral<1> {
        let mesh = unit_square(n);
        let edges = Edges::new(&mesh);
        let dual = DualMesh::new(&mesh, &edges);
        lambda_error(&dual, |_| c, &Expr::parse(lambda).unwrap())
    }

    /// Whether `value` is within its estimated error (and a round-off floor) of `exact` and within
    /// the tolerance, and the estimate useful (1e-3).
    fn resolved(value: f64, error: f64, exact: f64) -> bool {
        let off = (value - exact).abs();
        off <= error + 1e-14 * exact && off <= 2.0 * cubature::RTOL * exact && error <= 1e-3 * exact
    }

    #[test]
    fn norms_of_smooth_and_layered_fields() {
        // ∫ (sin πx sin πy)² = 1/4 and ∫ |∇|² = π²/2.
        let sine = of_zero(
            "sin(pi*x)*sin(pi*y)",
            ["pi*cos(pi*x)*sin(pi*y)", "pi*sin(pi*x)*cos(pi*y)"],
        );
        let pi2 = std::f64::consts::PI.powi(2);
        for (k, exact) in [(0, 0.25), (2, pi2 / 2.0)] {
            assert!((sine.value[k] - exact).abs() <= 1e-10 * exact, "{k}: {sine:?}");
        }
        let layer = of_zero(LAYER, ["(1 - tanh((x - 0.4)/0.01)^2)/0.01", "0"]);
        let exact = layer_integrals();
        for (k, exact) in [(0, exact[0]), (2, exact[1])] {
            assert!(
                resolved(layer.value[k], layer.error[k], exact),
                "{k}: {layer:?} against {exact}"
            );
        }
    }

    #[test]
    fn norms_of_a_jump_on_the_dual_cells() {
        // λ = 10 on disk_jump's disk (r² = 0.07), λ_h = 3: ∫ (λ − 3)² = 9 + (100 − 60) 0.07 π; the
        // circle clips corners of some cells that no rule point sees.
        for n in [16, 32] {
            let disk = dual_of("if((x - 0.45)^2 + (y - 0.52)^2 < 0.07, 10, 0)", 3.0, n);
            let exact = 9.0 + 40.0 * 0.07 * std::f64::consts::PI;
            assert!(
                resolved(disk.value[0], disk.error[0], exact),
                "{n}²: {disk:?} against {exact}"
            );
        }
        let layer = dual_of(LAYER, 0.0, 16);
        let exact = layer_integrals()[0];
        assert!(
            resolved(layer.value[0], layer.error[0], exact),
            "{layer:?} against {exact}"
        );
    }

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
