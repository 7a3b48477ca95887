//! How far is u_h from u? A guaranteed bound on the energy error of the discrete solution as
//! computed — reliability constant 1, no unknown constant — derived step by step in
//! docs/a-posteriori.md (Theorem (E)):
//!
//! ```text
//! |||u − u_h|||² = Σ_i μ_i ‖∇(u_i − u_ih)‖² ≤ η² = η_FR² + η_D² + 2 η_C,
//! η_FR² = η_1² + η_2²,   η_i = ( Σ_κ [η_F,κ + η_osc,κ]² )^½ + η_Q,i,                        (7)
//! η_F,κ = μ_i^{-½} ‖μ_i ∇u_ih + τ_i‖_κ,   η_osc,κ = μ_i^{-½} (h_κ/π) ‖f_i − Π f_i‖_κ,
//! η_Q,i = μ_i^{-½} C_F ‖c_i‖,   η_D = μ1^½ ‖∇ψ‖,   η_C = (λ_h, w_h + ψ),
//! ```
//!
//! κ the cells of S_h, τ_i the patch-equilibrated fluxes ([`equilibration`]), c_i the quadrature
//! defect of the loads on the dual cells (§4(c)), C_F the Friedrichs constant of the bounding box,
//! ψ the lifting of g − g_h ([`boundary`]). The action gets the bound of §8 from the same fluxes.
//! Per triangle K the indicator η_K² = Σ_i Σ_{κ⊂K} [η_F,κ + η_osc,κ]² + η_D,K² + 2 η_C,K says
//! where to refine.

pub mod boundary;
pub mod equilibration;

use crate::action::Action;
use crate::assembly::gradients;
use crate::contact::Solution;
use crate::datum::{self, On};
use crate::flux::Flux;
use crate::mesh::{DualMesh, Mesh};
use crate::parallel::{self, PIECE};
use crate::problem::DiscreteProblem;
use crate::result::{Attribute, Describe, Field, Place};
use equilibration::{equilibrate, Membrane, Patches};
use std::f64::consts::PI;

/// The estimator of one discrete solution: per-triangle indicators and totals.
#[derive(Debug, Clone)]
pub struct Estimate {
    /// η_K on each triangle of T_h.
    pub indicator: Vec<f64>,
    /// (Σ_{κ⊂K} η_F,κ²)^½ for membranes 1 and 2.
    pub flux: [Vec<f64>; 2],
    /// (Σ_{κ⊂K} η_osc,κ²)^½ for membranes 1 and 2.
    pub oscillation: [Vec<f64>; 2],
    /// μ1^½ ‖∇ψ‖_K.
    pub boundary: Vec<f64>,
    /// (λ_h, w_h + ψ)_K.
    pub contact: Vec<f64>,
    /// η, the bound of |||u − u_h|||.
    pub total: f64,
    /// η_1, η_2.
    pub membranes: [f64; 2],
    /// η_Q,1, η_Q,2 (included in η_1, η_2).
    pub means: [f64; 2],
    /// η_D.
    pub boundary_total: f64,
    /// η_C.
    pub contact_total: f64,
    /// The bound of ‖λ − λ_h‖_H⁻¹ (§8).
    pub lambda: f64,
    /// τ_1, τ_2.
    pub tau: [Flux; 2],
}

/// What the quadrature of the loads gives on one cell κ of S_h.
#[derive(Debug, Clone, Copy, Default)]
struct CellLoads {
    /// ∫_κ f_i φ_j, j the vertices of the triangle K ⊃ κ in order, for i = 1, 2.
    f_phi: [[f64; 3]; 2],
    /// ‖v − Π v‖²_κ for v = f1, f2 and α f1 − (1 − α) f2 (the residual of the action, §8).
    oscillation: [f64; 3],
}

impl Estimate {
    /// The estimator of `solution` (λ_h = `action`, S_h = `dual`).
    pub fn compute(
        problem: &DiscreteProblem,
        dual: &DualMesh,
        solution: &Solution,
        action: &Action,
    ) -> Estimate {
        let (mesh, data) = (&problem.mesh, &problem.data);
        let mu = [data.mu1, data.mu2().expect("the estimator is of two membranes")];
        let alpha = mu[1] / (mu[0] + mu[1]);
        let patches = Patches::new(mesh);
        let loads = cell_loads(problem, dual, alpha);
        let means = quadrature_defects(problem, &loads);
        let sign = [1.0, -1.0];
        let on_dual_cell: [Vec<f64>; 2] = [0, 1].map(|i| {
            (0..mesh.n_vertices())
                .map(|a| sign[i] * action.lambda[a] - means[i][a])
                .collect()
        });
        let cell_loads = &loads;
        let f_phi = [0, 1].map(|i| move |s: usize| cell_loads[s].f_phi[i]);
        let u = [&solution.u1, &solution.u2];
        let membranes = [0, 1].map(|i| Membrane {
            mu: mu[i],
            u: u[i],
            f_phi: &f_phi[i],
            on_dual_cell: &on_dual_cell[i],
        });
        let tau = equilibrate(mesh, dual, &patches, [&membranes[0], &membranes[1]]);
        let g = (data.g.pieces("g", mesh, On::Curves))
            .expect("the data fit the mesh's groups (checked by DiscreteProblem::new)");
        let psi = boundary::lifting(
            mesh,
            &patches.neighbour,
            &g,
            &action.lambda,
            &solution.obstacle.gap,
        );
        let terms = triangle_terms(problem, dual, solution, action, &tau, &loads);
        let n = mesh.n_triangles();
        let mut e = Estimate {
            indicator: vec![0.0; n],
            flux: [0, 1].map(|i| terms.iter().map(|t| t.flux2[i].sqrt()).collect()),
            oscillation: [0, 1].map(|i| terms.iter().map(|t| t.oscillation2[i].sqrt()).collect()),
            boundary: psi.iter().map(|p| mu[0].sqrt() * p.grad_norm).collect(),
            contact: (psi.iter().zip(&terms))
                .map(|(p, t)| p.with_lambda + t.contact)
                .collect(),
            total: 0.0,
            membranes: [0.0; 2],
            means: [0.0; 2],
            boundary_total: 0.0,
            contact_total: 0.0,
            lambda: 0.0,
            tau,
        };
        let sums = [0, 1].map(|i| terms.iter().map(|t| t.local2[i]).sum::<f64>());
        let lambda_sum: f64 = terms.iter().map(|t| t.lambda2).sum();
        for (t, terms) in terms.iter().enumerate() {
            let local2 = terms.local2[0] + terms.local2[1];
            e.indicator[t] = (local2 + e.boundary[t].powi(2) + 2.0 * e.contact[t])
                .max(0.0)
                .sqrt();
        }
        let friedrichs = friedrichs_constant(mesh);
        let norm = |c: &[f64]| (c.iter().zip(&problem.mass).map(|(c, m)| c * c * m).sum::<f64>()).sqrt();
        e.means = [0, 1].map(|i| friedrichs * norm(&means[i]) / mu[i].sqrt());
        e.membranes = [0, 1].map(|i| sums[i].sqrt() + e.means[i]);
        e.boundary_total = e.boundary.iter().map(|b| b * b).sum::<f64>().sqrt();
        e.contact_total = e.contact.iter().sum();
        let eta_fr2 = e.membranes[0].powi(2) + e.membranes[1].powi(2);
        e.total = (eta_fr2 + e.boundary_total.powi(2) + 2.0 * e.contact_total)
            .max(0.0)
            .sqrt();
        // §8: ‖λ − λ_h‖ ≤ μ̄^½ E_w + η_λ, E_w ≤ (η_λ²/μ̄ + μ̄‖∇ψ‖² + 2η_C)^½.
        let combined: Vec<f64> = (0..mesh.n_vertices())
            .map(|a| alpha * means[0][a] - (1.0 - alpha) * means[1][a])
            .collect();
        let eta_lambda = lambda_sum.sqrt() + friedrichs * norm(&combined);
        let mu_bar = mu[0] * mu[1] / (mu[0] + mu[1]);
        let grad_psi2 = e.boundary_total.powi(2) / mu[0];
        let e_w = (eta_lambda.powi(2) / mu_bar + mu_bar * grad_psi2 + 2.0 * e.contact_total)
            .max(0.0)
            .sqrt();
        e.lambda = mu_bar.sqrt() * e_w + eta_lambda;
        e
    }
}

/// c_{i,a} = [(f_i, φ_a) on the cells of S_h − (f_i, φ_a)_q] / m_a at the interior vertices, 0 at
/// the boundary ones (§4(c)): what the rule of degree q on T_h misses of the load, per dual cell.
fn quadrature_defects(problem: &DiscreteProblem, loads: &[CellLoads]) -> [Vec<f64>; 2] {
    let mesh = &problem.mesh;
    let load = [&problem.load1, &problem.load2];
    [0, 1].map(|i| {
        let mut on_s_h = vec![0.0; mesh.n_vertices()];
        for (s, l) in loads.iter().enumerate() {
            for (a, v) in mesh.triangle(s / 6).into_iter().zip(l.f_phi[i]) {
                on_s_h[a] += v;
            }
        }
        (on_s_h.iter().enumerate())
            .map(|(a, v)| match mesh.on_boundary[a] {
                true => 0.0,
                false => (v - load[i][a]) / problem.mass[a],
            })
            .collect()
    })
}

/// The loads on every cell of S_h by the case's rule (on the cell, not on its triangle), in
/// parallel.
fn cell_loads(problem: &DiscreteProblem, dual: &DualMesh, alpha: f64) -> Vec<CellLoads> {
    let data = &problem.data;
    let corners = |s: usize| dual.corners(s);
    let mesh = &problem.mesh;
    let fit = "the data fit the mesh's groups (checked by DiscreteProblem::new)";
    let f1 = data.f1.pieces("f1", mesh, On::Surfaces).expect(fit);
    let f2 = (data.f2().expect("the estimator is of two membranes"))
        .pieces("f2", mesh, On::Surfaces)
        .expect(fit);
    let mut loads = vec![CellLoads::default(); dual.n_cells()];
    parallel::map_mut(&mut loads, PIECE, |base, out| {
        let range = base..base + out.len();
        // The cell s of S_h lies in the triangle s / 6 of T_h: its loads are that triangle's.
        datum::visit(
            &data.quadrature,
            corners,
            |s| s / 6,
            range,
            [&f1, &f2],
            |s, points, [f1, f2]| {
                let frame = DualMesh::frame(s);
                let mut l = CellLoads::default();
                let f = |k: usize| [f1[k], f2[k], alpha * f1[k] - (1.0 - alpha) * f2[k]];
                let (mut mean, mut area) = ([0.0; 3], 0.0);
                for (k, p) in points.iter().enumerate() {
                    let phi: [f64; 3] =
                        std::array::from_fn(|j| (0..3).map(|v| p.barycentric[v] * frame[v][j]).sum());
                    for (f_phi, f) in l.f_phi.iter_mut().zip(f(k)) {
                        for (v, phi) in f_phi.iter_mut().zip(phi) {
                            *v += p.weight * f * phi;
                        }
                    }
                    for (m, f) in mean.iter_mut().zip(f(k)) {
                        *m += p.weight * f;
                    }
                    area += p.weight;
                }
                // ‖v − Π v‖²_κ in a second pass: ∫v² − (∫v)²/|κ| would cancel to noise where v is
                // nearly constant.
                for (k, p) in points.iter().enumerate() {
                    for ((o, f), m) in l.oscillation.iter_mut().zip(f(k)).zip(mean) {
                        *o += p.weight * (f - m / area).powi(2);
                    }
                }
                out[s - base] = l;
            },
        );
    });
    loads
}

/// The mean over cell s of a P1 field `v` of T_h (its value at the cell's centroid).
fn cell_mean(mesh: &Mesh, s: usize, v: &[f64]) -> f64 {
    let tri = mesh.triangle(s / 6);
    let frame = DualMesh::frame(s);
    (0..3)
        .map(|j| (0..3).map(|c| frame[c][j]).sum::<f64>() / 3.0 * v[tri[j]])
        .sum()
}

/// The terms of one triangle K, summed over its six cells κ of S_h.
#[derive(Debug, Clone, Copy, Default)]
struct TriangleTerms {
    /// Σ_κ η_F,κ² and Σ_κ η_osc,κ² for the two membranes.
    flux2: [f64; 2],
    oscillation2: [f64; 2],
    /// Σ_κ (η_F,κ + η_osc,κ)².
    local2: [f64; 2],
    /// Σ_κ (‖ζ‖_κ + (h_κ/π) ‖ρ − Π ρ‖_κ)² (§8).
    lambda2: f64,
    /// (λ_h, w_h)_K: w_h is affine and λ_h constant on each κ.
    contact: f64,
}

/// The terms of every triangle, in parallel.
fn triangle_terms(
    problem: &DiscreteProblem,
    dual: &DualMesh,
    solution: &Solution,
    action: &Action,
    tau: &[Flux; 2],
    loads: &[CellLoads],
) -> Vec<TriangleTerms> {
    let mesh = &problem.mesh;
    let mu = [
        problem.data.mu1,
        problem.data.mu2().expect("the estimator is of two membranes"),
    ];
    let alpha = mu[1] / (mu[0] + mu[1]);
    let u = [&solution.u1, &solution.u2];
    let part = |triangles: std::ops::Range<usize>| {
        (triangles)
            .map(|t| {
                let g = gradients(mesh.corners(t));
                let tri = mesh.triangle(t);
                let grad = [0, 1]
                    .map(|i| [0, 1].map(|k| mu[i] * (0..3).map(|j| g[j][k] * u[i][tri[j]]).sum::<f64>()));
                let mut terms = TriangleTerms::default();
                for (s, cell_loads) in (6 * t..).zip(&loads[6 * t..6 * t + 6]) {
                    let p = dual.corners(s);
                    let area = 0.5 * crate::mesh::orient(p[0], p[1], p[2]);
                    let diameter = (0..3)
                        .map(|e| crate::mesh::dist(p[e], p[(e + 1) % 3]))
                        .fold(0.0, f64::max);
                    // μ_i ∇u_ih + τ_i at the edge midpoints: ‖·‖²_κ = |κ|/3 Σ_m |·(m)|², exact for
                    // affine fields.
                    let at = |i: usize, m: [f64; 2]| {
                        let f = &tau[i].edge_flux[s];
                        [0, 1].map(|k| {
                            grad[i][k]
                                + (0..3).map(|e| f[e] * (m[k] - p[(e + 2) % 3][k])).sum::<f64>()
                                    / (2.0 * area)
                        })
                    };
                    let mids: [[f64; 2]; 3] =
                        std::array::from_fn(|e| [0, 1].map(|k| 0.5 * (p[e][k] + p[(e + 1) % 3][k])));
                    let norm = |v: &dyn Fn([f64; 2]) -> [f64; 2]| {
                        let squares = mids.iter().map(|&m| v(m)).map(|v| v[0] * v[0] + v[1] * v[1]);
                        (area / 3.0 * squares.sum::<f64>()).sqrt()
                    };
                    for (i, mu_i) in mu.iter().enumerate() {
                        let flux = norm(&|m| at(i, m)) / mu_i.sqrt();
                        let oscillation = diameter / PI * cell_loads.oscillation[i].sqrt() / mu_i.sqrt();
                        terms.flux2[i] += flux * flux;
                        terms.oscillation2[i] += oscillation * oscillation;
                        terms.local2[i] += (flux + oscillation).powi(2);
                    }
                    let zeta = norm(&|m| {
                        let (a, b) = (at(0, m), at(1, m));
                        [0, 1].map(|k| alpha * a[k] - (1.0 - alpha) * b[k])
                    });
                    terms.lambda2 += (zeta + diameter / PI * cell_loads.oscillation[2].sqrt()).powi(2);
                    let lambda_h = action.lambda[dual.owner(s)];
                    terms.contact += lambda_h * area * cell_mean(mesh, s, &solution.obstacle.gap);
                }
                terms
            })
            .collect::<Vec<_>>()
    };
    parallel::map(mesh.n_triangles(), PIECE, part)
        .into_iter()
        .flatten()
        .collect()
}

/// C_F = 1 / (π (L_x⁻² + L_y⁻²)^½), L_x × L_y the bounding box of ω: ‖v‖ ≤ C_F ‖∇v‖ on H¹_0(ω)
/// (the first Dirichlet eigenvalue of the box, and domain monotonicity).
fn friedrichs_constant(mesh: &Mesh) -> f64 {
    let (lo, hi) = (mesh.points.iter()).fold(([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]), |(lo, hi), p| {
        (
            [lo[0].min(p[0]), lo[1].min(p[1])],
            [hi[0].max(p[0]), hi[1].max(p[1])],
        )
    });
    1.0 / (PI * ((hi[0] - lo[0]).powi(-2) + (hi[1] - lo[1]).powi(-2)).sqrt())
}

impl Describe for Estimate {
    fn fields(&self) -> Vec<Field<'_>> {
        vec![
            Field::new("estimator", Place::Cells, &self.indicator),
            Field::new("estimator_flux_1", Place::Cells, &self.flux[0]),
            Field::new("estimator_flux_2", Place::Cells, &self.flux[1]),
            Field::new("estimator_oscillation_1", Place::Cells, &self.oscillation[0]),
            Field::new("estimator_oscillation_2", Place::Cells, &self.oscillation[1]),
            Field::new("estimator_boundary", Place::Cells, &self.boundary),
            Field::new("estimator_contact", Place::Cells, &self.contact),
        ]
    }

    fn attributes(&self) -> Vec<Attribute> {
        vec![
            ("estimator", self.total.into()),
            ("estimator_membrane_1", self.membranes[0].into()),
            ("estimator_membrane_2", self.membranes[1].into()),
            ("estimator_means_1", self.means[0].into()),
            ("estimator_means_2", self.means[1].into()),
            ("estimator_boundary", self.boundary_total.into()),
            ("estimator_contact", self.contact_total.into()),
            ("estimator_hminus1_lambda", self.lambda.into()),
        ]
    }
}
