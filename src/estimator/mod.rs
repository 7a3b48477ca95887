//! How far is u_h from u? A guaranteed bound on the energy error of the discrete solution as
//! computed — reliability constant 1, no unknown constant — derived step by step in
//! docs/a-posteriori.md (Theorem (E)):
//!
//! ```text
//! |||u − u_h|||² = Σ_i μ_i ‖∇(u_i − u_ih)‖² ≤ η² = η_FR² + η_D² + 2 η_C,
//! η_FR² = η_1² + η_2²,   η_i = ( Σ_κ [η_F,κ + η_osc,κ]² )^½ + η_Q,i,                        (7)
//! η_F,κ = μ_i^{-½} ‖μ_i ∇u_ih + τ_i‖_κ,   η_osc,κ = μ_i^{-½} (h_κ/π) ‖f_i − Π f_i‖_κ,
//! η_Q,i = μ_i^{-½} C_F (‖ρ_i‖ + ‖λ_h − λ_h^c‖),   η_D = μ1^½ ‖∇ψ‖,   η_C = (λ_h^c, w_h + ψ),
//! ```
//!
//! κ the cells of S_h, τ_i the patch-equilibrated fluxes ([`equilibration`]) with the quadrature
//! defect c_i of the loads lifted into them ([`means`], §4(c')), ρ_i what the lift's solve leaves
//! (round-off), λ_h^c the part of λ_h on the contact set (off it λ_h is the solve's round-off, §3),
//! C_F the Friedrichs constant of the bounding box, ψ the lifting of g − g_h ([`boundary`]). The
//! action gets the bound of §8 from the same fluxes.
//! Per triangle K the indicator η_K² = Σ_i Σ_{κ⊂K} [η_F,κ + η_osc,κ]² + η_D,K² + 2 η_C,K says
//! where to refine. Above a rigid obstacle (§14, Theorem (O)) the sum is over the one membrane,
//! and the lifting is z = max(ψ, ψ_obstacle − u_h) ([`obstacle`]), which keeps u_h + z above the
//! obstacle itself, not only above ψ_h at the vertices; η is then also the smaller of that and of
//! Theorem (O'), whose flux terms are of u_h + z where the obstacle is above u_h, so that ψ − ψ_h
//! is counted once.

pub mod boundary;
pub mod equilibration;
pub mod means;
pub mod obstacle;
pub mod resolution;

use crate::action::Action;
use crate::assembly::gradients;
use crate::contact::{self, Solution};
use crate::datum::{self, On, Pieces};
use crate::mesh::{DualMesh, Mesh};
use crate::parallel::{self, PIECE};
use crate::problem::{DiscreteProblem, Lower, Membrane, Which};
use crate::result::{Attribute, Describe, Field, Place};
use equilibration::{equilibrate, Patches, TriangleFlux};
use means::Lifted;
use resolution::Resolution;
use std::f64::consts::PI;
use std::ops::Range;

/// The estimator of one discrete solution: per-triangle indicators and totals.
#[derive(Debug, Clone)]
pub struct Estimate {
    /// η_K on each triangle of T_h.
    pub indicator: Vec<f64>,
    /// (Σ_{κ⊂K} η_F,κ²)^½ for each membrane of [`DiscreteProblem::membranes`].
    pub flux: Vec<Vec<f64>>,
    /// (Σ_{κ⊂K} η_osc,κ²)^½ for each membrane.
    pub oscillation: Vec<Vec<f64>>,
    /// μ1^½ ‖∇z‖_K, z the lifting of g − g_h (and above an obstacle of ψ − u_h, §14).
    pub boundary: Vec<f64>,
    /// (λ_h^c, w_h + z)_K (above an obstacle (λ_h^c, u_h + z − ψ)_K), λ_h^c its part on the
    /// contact set.
    pub contact: Vec<f64>,
    /// η, the bound of |||u − u_h|||.
    pub total: f64,
    /// η_i for each membrane.
    pub membranes: Vec<f64>,
    /// η_Q,i for each membrane (included in η_i): what the lifts leave of the quadrature defect and
    /// λ_h off the contact set, by Friedrichs.
    pub means: Vec<f64>,
    /// η_D.
    pub boundary_total: f64,
    /// Above an obstacle, μ^½ ‖∇(ψ − u_h)‖ on the cells where u_h dips below ψ (included in η_D).
    pub obstacle_total: Option<f64>,
    /// η_C.
    pub contact_total: f64,
    /// Above an obstacle, when Theorem (O') gave η: η̃, the membrane's term through u_h + z where
    /// the obstacle is above u_h (in place of η_1 in η).
    pub lifted_membrane: Option<f64>,
    /// The bound of ‖λ − λ_h‖_H⁻¹ (§8).
    pub lambda: f64,
    /// What the case's rule misses of the loads: whether η is a bound for the loads as given.
    pub resolution: Resolution,
    /// g < 0 found on ∂ω between the boundary vertices (above an obstacle g < ψ; the least g (g −
    /// ψ) at the points of the boundary lifting's rule, and where): no u1 ≥ u2 (u ≥ ψ) takes these
    /// boundary values, so the continuous problem has no solution and η bounds nothing. (The
    /// discrete problem takes g_h, ≥ 0 (≥ ψ_h) at the boundary vertices.)
    pub boundary_below: Option<(f64, [f64; 2])>,
    /// Which membrane each of the per-membrane terms is of.
    which: Vec<Which>,
}

/// The loads on the six cells of one triangle K, summed over the cells.
#[derive(Debug, Clone, Copy, Default)]
struct TriangleLoads {
    /// ∫_K f_i φ_j by the case's rule on the cells of K, j the vertices of K in order.
    f_phi: [[f64; 3]; 2],
    /// Σ_κ |∫_κ f_i|: the size two values of ∫_K f_i are compared against.
    size: [f64; 2],
}

/// What the quadrature of the loads gives on one cell κ of S_h.
#[derive(Debug, Clone, Copy, Default)]
struct CellLoads {
    /// ∫_κ f_i φ_j, j the vertices of the triangle K ⊃ κ in order, for each membrane i (with the
    /// lifted defect's ∫_κ c_i φ_j added once the defect is known, §4(c')).
    f_phi: [[f64; 3]; 2],
    /// ‖v − Π v‖²_κ for v = f1, f2 and α f1 − (1 − α) f2 (the residual of the action, §8).
    oscillation: [f64; 3],
}

/// α = μ2/(μ1 + μ2) and μ̄ = μ1μ2/(μ1 + μ2) of §1; above a rigid obstacle (μ2 → ∞) α = 1 and
/// μ̄ = μ, which turns §8 into its single-membrane form (§14).
fn weights(membranes: &[Membrane]) -> (f64, f64) {
    match membranes {
        [m1, m2] => (m2.mu / (m1.mu + m2.mu), m1.mu * m2.mu / (m1.mu + m2.mu)),
        [m] => (1.0, m.mu),
        _ => unreachable!("one or two membranes"),
    }
}

/// η_K of each triangle from its terms (of `m` membranes), its boundary term and its contact term:
/// (Σ_i η_{i,K}² + η_{∂,K}² + 2 η_{C,K})^½.
fn indicators(terms: &[TriangleTerms], boundary: &[f64], contact: &[f64], m: usize) -> Vec<f64> {
    (terms.iter().zip(boundary).zip(contact))
        .map(|((t, b), c)| root(t.local2[..m].iter().sum::<f64>() + b * b + 2.0 * c))
        .collect()
}

/// √x of a sum of squares and cross terms that round-off may take just below 0 (then 0). NaN,
/// what an overflow of the squares leaves, stays NaN, so that the run reports it rather than a
/// bound of 0 (`f64::max` would turn it into 0).
pub(crate) fn root(x: f64) -> f64 {
    if x < 0.0 {
        0.0
    } else {
        x.sqrt()
    }
}

/// ‖c‖ of a field given at the vertices, by the lumped mass (each term (c √m)², of the size of
/// the norm, where c² would overflow).
fn mass_norm(problem: &DiscreteProblem, c: &[f64]) -> f64 {
    // Scaled by the largest term, so that round-off sized values of data of any size neither
    // underflow nor overflow when squared.
    let terms = || c.iter().zip(&problem.mass).map(|(c, m)| c * m.sqrt());
    if terms().any(f64::is_nan) {
        return f64::NAN;
    }
    let largest = terms().fold(0.0_f64, |s, x| s.max(x.abs()));
    if largest == 0.0 || !largest.is_finite() {
        return largest;
    }
    largest * terms().map(|x| (x / largest).powi(2)).sum::<f64>().sqrt()
}

/// What the case's rule of the loads gives and misses: whether it resolves them (§11), and its
/// defect per vertex lifted into the fluxes (§4(c')).
struct LoadData {
    resolution: Resolution,
    defects: Vec<Vec<f64>>,
    lifted: Lifted,
}

impl LoadData {
    /// The loads `f` of `membranes` on the cells of S_h by the case's rule, checked and lifted.
    fn of(
        problem: &DiscreteProblem,
        dual: &DualMesh,
        solution: &Solution,
        membranes: &[Membrane],
        f: [&Pieces; 2],
    ) -> LoadData {
        let (alpha, _) = weights(membranes);
        let sums = triangle_loads(problem, dual, f, alpha);
        let mu: Vec<f64> = membranes.iter().map(|m| m.mu).collect();
        // The check's lifts and the defects' on one analysis of K.
        contact::with_poisson(problem, &solution.transfers, move |solve| {
            let resolution = Resolution::check((problem, dual), f, &mu, &sums, solve);
            let defects = quadrature_defects(problem, membranes, &sums);
            drop(sums);
            let lifted = means::lift(problem, dual, &defects, solve);
            LoadData {
                resolution,
                defects,
                lifted,
            }
        })
    }
}

/// The terms of every triangle: the fluxes equilibrated on the patches for the local problems of
/// u_ih + z_i/μ_i with the loads f_i + c_i (§4(c')), and the terms (7) and (§8) of their cells.
fn local_terms(
    (problem, dual, patches): (&DiscreteProblem, &DualMesh, &Patches),
    (solution, action): (&Solution, &Action),
    membranes: &[Membrane],
    (f, loads): ([&Pieces; 2], &LoadData),
    lifting: &Lifting,
) -> Vec<TriangleTerms> {
    let mesh = &problem.mesh;
    let (alpha, _) = weights(membranes);
    let (defects, lifted) = (&loads.defects, &loads.lifted);
    let on_dual_cell: Vec<Vec<f64>> = (membranes.iter().zip(defects).zip(&lifted.rest))
        .map(|((m, c), rho)| {
            (0..mesh.n_vertices())
                .map(|a| m.sign * action.lambda[a] - c[a] - rho[a])
                .collect()
        })
        .collect();
    let u: Vec<Vec<f64>> = (membranes.iter().zip(&lifted.z))
        .map(|(m, z)| m.u.iter().zip(z).map(|(u, z)| u + z / m.mu).collect())
        .collect();
    let local: Vec<equilibration::Membrane> = (membranes.iter().enumerate())
        .map(|(i, m)| equilibration::Membrane {
            mu: m.mu,
            u: &u[i],
            on_dual_cell: &on_dual_cell[i],
        })
        .collect();
    let cells = |triangles: Range<usize>, out: &mut Vec<[CellLoads; 6]>| {
        let mut cells = [CellLoads::default(); 6];
        let range = 6 * triangles.start..6 * triangles.end;
        visit_cell_loads((problem, dual), f, alpha, range, |s, mut l| {
            let adds = means::on_cells(mesh, dual, [&defects[0], defects.last().expect("one")], s);
            for ((f, add), _) in l.f_phi.iter_mut().zip(adds).zip(defects) {
                *f = std::array::from_fn(|j| f[j] + add[j]);
            }
            cells[s % 6] = l;
            if s % 6 == 5 {
                out.push(cells);
            }
        });
    };
    let psi = match &problem.data.lower {
        Lower::Rigid { psi } => Some(
            (psi.pieces("psi", mesh, datum::On::Surfaces))
                .expect("the data fit the mesh's groups (checked by DiscreteProblem::new)"),
        ),
        Lower::Membrane { .. } => None,
    };
    let psi = psi.as_ref().map(obstacle::WithDerivatives::new);
    let terms = Terms {
        problem,
        dual,
        membranes,
        contact_lambda: &lifting.contact_lambda,
        gap: &solution.obstacle.gap,
        above: (psi.as_ref().zip(lifting.above.as_deref())).map(|(psi, above)| (psi, f[0], above)),
    };
    equilibrate((mesh, dual, patches), &local, cells, |t, loads, tau| {
        terms.of(t, loads, tau)
    })
}

impl Estimate {
    /// The estimator of `solution` (λ_h = `action`, S_h = `dual`): the loads' quadrature checked
    /// and its defect lifted (§4(c'), §11), the fluxes equilibrated on the patches and the local
    /// terms of every triangle (7), the lifting of the boundary data (and of the obstacle), then
    /// the totals and the bound of the action (§8).
    pub fn compute(
        problem: &DiscreteProblem,
        dual: &DualMesh,
        solution: &Solution,
        action: &Action,
    ) -> Estimate {
        let membranes = problem.membranes([&solution.u1, &solution.u2]);
        let pieces = load_pieces(problem, &membranes);
        // Above an obstacle the one load twice, the second unused (α = 1).
        let f = [&pieces[0], pieces.last().expect("one membrane at least")];
        let loads = LoadData::of(problem, dual, solution, &membranes, f);
        let patches = Patches::new(&problem.mesh);
        let lifting = Lifting::compute(problem, dual, solution, action, &patches);
        let setting = (problem, dual, &patches);
        let terms = local_terms(setting, (solution, action), &membranes, (f, &loads), &lifting);
        Estimate::of_terms(problem, &membranes, &terms, &lifting, loads)
    }

    /// The indicators and totals from the terms of each triangle and the lifting.
    fn of_terms(
        problem: &DiscreteProblem,
        membranes: &[Membrane],
        terms: &[TriangleTerms],
        lifting: &Lifting,
        loads: LoadData,
    ) -> Estimate {
        let (m, mu1) = (membranes.len(), membranes[0].mu);
        let friedrichs = friedrichs_constant(&problem.mesh);
        let per = |f: &dyn Fn(&TriangleTerms, usize) -> f64| -> Vec<Vec<f64>> {
            (0..m)
                .map(|i| terms.iter().map(|t| f(t, i).sqrt()).collect())
                .collect()
        };
        let mut e = Estimate {
            indicator: Vec::new(),
            flux: per(&|t, i| t.flux2[i]),
            oscillation: per(&|t, i| t.oscillation2[i]),
            boundary: (lifting.grad2.iter().zip(terms))
                .map(|(g, t)| (mu1 * (g + t.obstacle2)).sqrt())
                .collect(),
            contact: match &lifting.contact {
                Some(c) => c.clone(),
                None => (lifting.with_lambda.iter().zip(terms))
                    .map(|(l, t)| l + t.contact)
                    .collect(),
            },
            total: 0.0,
            membranes: Vec::new(),
            means: Vec::new(),
            boundary_total: 0.0,
            obstacle_total: (lifting.above.is_some())
                .then(|| (mu1 * terms.iter().map(|t| t.obstacle2).sum::<f64>()).sqrt()),
            lifted_membrane: None,
            contact_total: 0.0,
            lambda: 0.0,
            resolution: loads.resolution,
            boundary_below: lifting.below,
            which: membranes.iter().map(|m| m.which).collect(),
        };
        e.indicator = indicators(terms, &e.boundary, &e.contact, m);
        let rest = &loads.lifted.rest;
        e.means = (membranes.iter().zip(rest))
            .map(|(mb, c)| friedrichs * (mass_norm(problem, c) + lifting.off_contact) / mb.mu.sqrt())
            .collect();
        e.membranes = (0..m)
            .map(|i| terms.iter().map(|t| t.local2[i]).sum::<f64>().sqrt() + e.means[i])
            .collect();
        e.boundary_total = e.boundary.iter().map(|b| b * b).sum::<f64>().sqrt();
        e.contact_total = e.contact.iter().sum();
        let eta_fr2: f64 = e.membranes.iter().map(|x| x * x).sum();
        e.total = root(eta_fr2 + e.boundary_total.powi(2) + 2.0 * e.contact_total);
        if lifting.apart {
            let (total, lifted) = e.through_lifted(terms);
            if total < e.total {
                (e.total, e.lifted_membrane) = (total, Some(lifted));
            }
        }
        e.lambda = e.lambda_bound(problem, membranes, terms, (rest, lifting.off_contact), friedrichs);
        e
    }

    /// Theorem (O') of §14, above an obstacle that stays apart from the lifting ℓ of g − g_h:
    /// E ≤ (η̃² + η_D² + 2η_C + 2X)^½, η̃ the membrane's term with the flux terms of ũ = u_h + z on
    /// the cells where the obstacle is above u_h, X = Σ (λ_ψ⁻, ψ − u_h) there. Returns the bound
    /// and η̃.
    fn through_lifted(&self, terms: &[TriangleTerms]) -> (f64, f64) {
        let lifted = terms.iter().map(|t| t.local2_lifted).sum::<f64>().sqrt() + self.means[0];
        let cross: f64 = terms.iter().map(|t| t.cross).sum();
        let total = lifted.powi(2) + self.boundary_total.powi(2) + 2.0 * (self.contact_total + cross);
        (root(total), lifted)
    }

    /// §8: ‖λ − λ_h‖ ≤ μ̄^½ E_w + η_λ, E_w ≤ ((η_λ + C_F‖λ_h − λ_h^c‖)²/μ̄ + μ̄‖∇z‖² + 2η_C)^½
    /// (η_C of λ_h^c, §3), from the totals of the energy bound, the triangles' terms, what the lift
    /// leaves (`rest`), λ_h off the contact set (`off_contact`) and C_F.
    fn lambda_bound(
        &self,
        problem: &DiscreteProblem,
        membranes: &[Membrane],
        terms: &[TriangleTerms],
        (rest, off_contact): (&[Vec<f64>], f64),
        friedrichs: f64,
    ) -> f64 {
        let (alpha, mu_bar) = weights(membranes);
        let combined: Vec<f64> = (0..problem.mesh.n_vertices())
            .map(|a| alpha * rest[0][a] - rest.get(1).map_or(0.0, |c| (1.0 - alpha) * c[a]))
            .collect();
        let lambda_sum: f64 = terms.iter().map(|t| t.lambda2).sum();
        let eta_lambda = lambda_sum.sqrt() + friedrichs * mass_norm(problem, &combined);
        let grad_z2 = self.boundary_total.powi(2) / membranes[0].mu;
        // E_w ≤ E ≤ η as well (E² = (μ1 + μ2)‖∇e_v‖² + E_w²; E_w = E above an obstacle), which
        // is the smaller where (O') of §14 gave η.
        let eta_w = eta_lambda + friedrichs * off_contact;
        let e_w = root(eta_w.powi(2) / mu_bar + mu_bar * grad_z2 + 2.0 * self.contact_total);
        let e_w = if e_w > self.total { self.total } else { e_w };
        mu_bar.sqrt() * e_w + eta_lambda
    }

    /// The summary's line, with the effectivity η/error where the energy `error` is known (and not
    /// round-off).
    pub fn summary(&self, error: Option<f64>) -> String {
        let mut membranes: Vec<String> = self.membranes.iter().map(|x| format!("{x:.3e}")).collect();
        if let Some(lifted) = self.lifted_membrane {
            membranes[0] += &format!(", through u_h + z where ψ is above u_h {lifted:.3e} (Theorem (O'))");
        }
        let label = if self.membranes.len() == 1 {
            "membrane"
        } else {
            "membranes"
        };
        // Above an obstacle one lifting carries g − g_h and ψ − u_h (§14): named as such, with the
        // part ψ − u_h adds.
        let data = match self.obstacle_total {
            None => format!("boundary data {:.2e}", self.boundary_total),
            Some(o) => format!(
                "lifting of g − g_h and ψ − u_h {:.2e} (ψ − u_h alone {o:.2e})",
                self.boundary_total
            ),
        };
        format!(
            "estimator   |||u − u_h||| ≤ η = {:.4e} ({label} {}, {data}, contact {:.2e}){}; \
             ‖λ − λ_h‖_H⁻¹ ≤ {:.4e}\n",
            self.total,
            membranes.join(", "),
            self.contact_total,
            error.map_or(String::new(), |e| format!(
                ", effectivity η/error {:.3} (error |||u − u_h||| = {e:.4e})",
                self.total / e
            )),
            self.lambda
        ) + &self.boundary_summary()
            + &self.loads_summary()
    }

    /// Whether η is a guaranteed bound of the error of this run: the loads resolved by the case's
    /// rule ([`Estimate::loads_resolved`]) and the boundary data such that the problem has a
    /// solution (no [`Estimate::boundary_below`]).
    pub fn is_bound(&self) -> bool {
        self.loads_resolved() && self.boundary_below.is_none()
    }

    /// Whether the loads count as resolved by the case's rule (η_data ≤ [`resolution::RESOLVED`] η),
    /// and η therefore as a bound of the error for the loads as given.
    pub fn loads_resolved(&self) -> bool {
        self.resolution.total <= resolution::RESOLVED * self.total
    }

    /// The summary's line on boundary values below 0 (below ψ) between the boundary vertices, if
    /// any.
    fn boundary_summary(&self) -> String {
        let obstacle = self.membranes.len() == 1;
        let (below, admissible, h) = match obstacle {
            true => ("g < ψ", "u ≥ ψ", "g − ψ"),
            false => ("g < 0", "u1 ≥ u2", "g"),
        };
        self.boundary_below.map_or(String::new(), |(d, at)| {
            format!(
                "boundary    {below} on ∂ω between boundary vertices ({h} = {d:.3e} at {}): no \
                 {admissible} takes these boundary values, so the problem has no solution and η is \
                 NOT a bound; the discrete problem takes their values at the vertices: correct g, or \
                 refine along ∂ω\n",
                crate::mesh::Point(at)
            )
        })
    }

    /// The summary's line on the loads' quadrature.
    fn loads_summary(&self) -> String {
        let r = &self.resolution;
        if r.checked == 0 {
            return "loads       resolved: the case's rule on each triangle and on its six cells of S_h agree\n".into();
        }
        let change = format!(
            "a finer rule on the {} triangles where two rules disagree would change η by about \
             η_data = {:.2e}",
            r.checked, r.total
        );
        let share = r.total / self.total.max(f64::MIN_POSITIVE);
        if self.loads_resolved() {
            return format!("loads       resolved by the case's rule: {change} ({share:.1e} of η)\n");
        }
        let at = (r.worst).map_or(String::new(), |[x, y]| format!(", most near ({x:.4}, {y:.4})"));
        format!(
            "loads       NOT resolved by the case's rule, so η is not a guaranteed bound: {change} \
             ({share:.2e} of η, above the {:e} of η the check allows){at}; refine there (a load that jumps inside a triangle is resolved only by \
             refinement along the jump), or raise [quadrature] degree for a smooth load\n",
            resolution::RESOLVED
        )
    }
}

/// The lifting z of §3 on every triangle: ‖∇z‖²_K and the pieces of (λ_h, ·)_K it adds to the
/// contact term, with λ_h split as that term needs it.
struct Lifting {
    /// λ_h where (5) takes it: on the contact set, where it is positive (and w_h = 0); 0 elsewhere.
    contact_lambda: Vec<f64>,
    /// ‖λ_h − `contact_lambda`‖: off the contact set λ_a is the solve's residual, round-off of
    /// either sign, which (5) cannot take (it needs λ_h ≥ 0, and a negative part of round-off size
    /// made η_C < 0 and η = 0 against an error of 2.6e-10); it enters each η_i by Friedrichs, as ρ_i.
    off_contact: f64,
    /// An upper bound of ‖∇ℓ‖²_K (above an obstacle the sweep adds the part ψ − u_h adds,
    /// [`TriangleTerms::obstacle2`]).
    grad2: Vec<f64>,
    /// ∫_K λ_h ℓ, ℓ the lifting of g − g_h ([`boundary`]); the contact term adds (λ_h, w_h)_K
    /// (λ_h its contact part).
    with_lambda: Vec<f64>,
    /// Above an obstacle, (λ_h, u_h + z − ψ)_K, the whole contact term ([`obstacle`]).
    contact: Option<Vec<f64>>,
    /// Above an obstacle, the cells of each triangle where it is above u_h (bits).
    above: Option<Vec<u8>>,
    /// Whether ℓ vanishes on every triangle where the obstacle is above u_h: the bound through
    /// ũ = u_h + z of §14 (Theorem (O')) holds.
    apart: bool,
    /// The least g − ψ (g between two membranes) found on ∂ω and where, if it is below 0 beyond
    /// round-off (see [`Estimate::boundary_below`]).
    below: Option<(f64, [f64; 2])>,
}

/// The relative round-off (of max |g| at the boundary vertices and |ψ| at every vertex, as the
/// data's check measures it) below which g < 0 (g < ψ) counts as 0.
const G_ROUND_OFF: f64 = 1e-12;

/// The least g − ψ (g between two membranes) the boundary lifting `l` found on ∂ω and where, if
/// it is below 0 beyond round-off.
fn below(problem: &DiscreteProblem, l: &[boundary::OnTriangle]) -> Option<(f64, [f64; 2])> {
    let mesh = &problem.mesh;
    // Of ψ over ω: ψ = sin πx sin πy, 0 on ∂ω with g = 0, is −1.2e-16 at x = 1 (the
    // boundary's own size, 0, took it for g below ψ).
    let size = (0..mesh.n_vertices())
        .filter(|&a| mesh.on_boundary[a])
        .map(|a| problem.g_h[a].abs())
        .chain(problem.psi_h.iter().map(|p| p.abs()))
        .fold(0.0_f64, f64::max);
    boundary::lowest(l).filter(|(d, _)| *d < -G_ROUND_OFF * size)
}

impl Lifting {
    /// z = ℓ between two membranes (§5); z = max(ℓ, ψ − u_h) above a rigid obstacle (§14).
    fn compute(
        problem: &DiscreteProblem,
        dual: &DualMesh,
        solution: &Solution,
        action: &Action,
        patches: &Patches,
    ) -> Lifting {
        let (mesh, data) = (&problem.mesh, &problem.data);
        let g = (data.g.pieces("g", mesh, On::Curves))
            .expect("the data fit the mesh's groups (checked by DiscreteProblem::new)");
        let contact_lambda: Vec<f64> = (action.lambda.iter().zip(&solution.obstacle.contact))
            .map(|(&l, &contact)| if contact && l > 0.0 { l } else { 0.0 })
            .collect();
        let rest: Vec<f64> = (action.lambda.iter().zip(&contact_lambda))
            .map(|(l, c)| l - c)
            .collect();
        let off_contact = mass_norm(problem, &rest);
        let lambda = &contact_lambda[..];
        let Lower::Rigid { psi } = &data.lower else {
            let gap = Some(&solution.obstacle.gap[..]);
            let l = boundary::lifting(mesh, &patches.neighbour, (&g, None), lambda, gap);
            return Lifting {
                grad2: l.iter().map(|l| l.grad_norm.powi(2)).collect(),
                with_lambda: l.iter().map(|l| l.with_lambda).collect(),
                contact_lambda,
                off_contact,
                contact: None,
                above: None,
                apart: false,
                below: below(problem, &l),
            };
        };
        let psi = (psi.pieces("psi", mesh, On::Surfaces))
            .expect("the data fit the mesh's groups (checked by DiscreteProblem::new)");
        let l = boundary::lifting(mesh, &patches.neighbour, (&g, Some(&psi)), lambda, None);
        let o = obstacle::terms(problem, dual, &psi, &solution.u1, lambda, &l);
        let apart =
            (l.iter().zip(&o)).all(|(l, o)| o.above == 0 || (l.grad_norm == 0.0 && l.range == [0.0; 2]));
        Lifting {
            above: Some(o.iter().map(|o| o.above).collect()),
            apart,
            below: below(problem, &l),
            grad2: l.iter().map(|l| l.grad_norm.powi(2)).collect(),
            with_lambda: l.iter().map(|l| l.with_lambda).collect(),
            contact: Some(o.iter().map(|o| o.contact).collect()),
            contact_lambda,
            off_contact,
        }
    }
}

/// c_{i,a} = [(f_i, φ_a) on the cells of S_h − (f_i, φ_a)_q] / m_a at the interior vertices, 0 at
/// the boundary ones (§4(c)): what the rule of degree q on T_h misses of the load, per dual cell.
fn quadrature_defects(
    problem: &DiscreteProblem,
    membranes: &[Membrane],
    sums: &[TriangleLoads],
) -> Vec<Vec<f64>> {
    let mesh = &problem.mesh;
    (membranes.iter().enumerate())
        .map(|(i, m)| {
            let mut on_s_h = vec![0.0; mesh.n_vertices()];
            for (tri, sums) in mesh.triangles().zip(sums) {
                for (a, v) in tri.into_iter().zip(sums.f_phi[i]) {
                    on_s_h[a] += v;
                }
            }
            (on_s_h.iter().enumerate())
                .map(|(a, v)| match mesh.on_boundary[a] {
                    true => 0.0,
                    false => (v - m.load[a]) / problem.mass[a],
                })
                .collect()
        })
        .collect()
}

/// The loads f_i of `membranes` on the triangles of the mesh.
fn load_pieces<'a>(problem: &'a DiscreteProblem, membranes: &[Membrane<'a>]) -> Vec<Pieces<'a>> {
    let fit = "the data fit the mesh's groups (checked by DiscreteProblem::new)";
    (membranes.iter())
        .map(|m| {
            m.f.pieces(m.which.named(["f1", "f2", "f"]), &problem.mesh, On::Surfaces)
                .expect(fit)
        })
        .collect()
}

/// The loads on the cells `cells` of S_h by the case's rule (on the cell, not on its triangle),
/// each handed to `each` with its cell.
fn visit_cell_loads(
    (problem, dual): (&DiscreteProblem, &DualMesh),
    f: [&Pieces; 2],
    alpha: f64,
    cells: Range<usize>,
    mut each: impl FnMut(usize, CellLoads),
) {
    // φ_j, j the vertices of the triangle, at each point of the rule on each of its six cells.
    let phi: Vec<[[f64; 3]; 6]> = (problem.data.quadrature.barycentric())
        .map(|b| {
            DualMesh::FRAMES.map(|frame| std::array::from_fn(|j| (0..3).map(|v| b[v] * frame[v][j]).sum()))
        })
        .collect();
    // The cell s of S_h lies in the triangle s / 6 of T_h: its loads are that triangle's.
    datum::visit(
        &problem.data.quadrature,
        |s| dual.corners(s),
        |s| s / 6,
        cells,
        f,
        |s, points, [f1, f2]| {
            let mut l = CellLoads::default();
            let f = |k: usize| [f1[k], f2[k], alpha * f1[k] - (1.0 - alpha) * f2[k]];
            let (mut mean, mut area) = ([0.0; 3], 0.0);
            for (k, p) in points.iter().enumerate() {
                let phi = phi[k][s % 6];
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
                // (√w (v − Π v))², of the size of the norm, where w (v − Π v)² would overflow.
                let root = p.weight.sqrt();
                for ((o, f), m) in l.oscillation.iter_mut().zip(f(k)).zip(mean) {
                    *o += (root * (f - m / area)).powi(2);
                }
            }
            each(s, l);
        },
    );
}

/// The loads on the six cells of the triangle t, each summed over the cells: ∫_K f_i φ_j by the
/// case's rule on the cells of K, and Σ_κ |∫_κ f_i|, for every triangle, in parallel.
fn triangle_loads(
    problem: &DiscreteProblem,
    dual: &DualMesh,
    f: [&Pieces; 2],
    alpha: f64,
) -> Vec<TriangleLoads> {
    parallel::collect_by_blocks(problem.mesh.n_triangles(), PIECE, |range, out| {
        let mut sum = TriangleLoads::default();
        let cells = 6 * range.start..6 * range.end;
        visit_cell_loads((problem, dual), f, alpha, cells, |s, l| {
            for i in 0..2 {
                sum.f_phi[i] = std::array::from_fn(|j| sum.f_phi[i][j] + l.f_phi[i][j]);
                sum.size[i] += l.f_phi[i].iter().sum::<f64>().abs();
            }
            if s % 6 == 5 {
                out.push(std::mem::take(&mut sum));
            }
        });
    })
}

impl equilibration::CellPairings for [CellLoads; 6] {
    fn f_phi(&self, c: usize, i: usize) -> [f64; 3] {
        self[c].f_phi[i]
    }
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
    /// Σ_κ η_F,κ² and Σ_κ η_osc,κ² for each membrane (one above an obstacle).
    flux2: [f64; 2],
    oscillation2: [f64; 2],
    /// Σ_κ (η_F,κ + η_osc,κ)².
    local2: [f64; 2],
    /// Σ_κ (‖ζ‖_κ + (h_κ/π) ‖ρ − Π ρ‖_κ)² (§8).
    lambda2: f64,
    /// (λ_h^c, w_h)_K: w_h is affine and λ_h^c (λ_h on the contact set) constant on each κ
    /// (between two membranes).
    contact: f64,
    /// Above an obstacle, Σ_κ (η̃_F,κ + η_osc,κ)², η̃_F,κ the flux term of ũ = u_h + z where the
    /// obstacle is above u_h (of u_h elsewhere), and Σ_κ (λ_ψ⁻, ψ − u_h)_κ there (§14).
    local2_lifted: f64,
    cross: f64,
    /// Above an obstacle, Σ_κ ‖∇(ψ − u_h)‖²_κ over the cells where it is above u_h: the part of
    /// ‖∇z‖²_K that ψ − u_h adds ([`obstacle`]).
    obstacle2: f64,
}

/// What the terms of a triangle are computed from, besides its fluxes.
struct Terms<'a> {
    problem: &'a DiscreteProblem,
    dual: &'a DualMesh<'a>,
    membranes: &'a [Membrane<'a>],
    /// λ_h on the contact set ([`Lifting::contact_lambda`]).
    contact_lambda: &'a [f64],
    /// w_h (u1h − u2h), or u_h − ψ_h above an obstacle.
    gap: &'a [f64],
    /// Above an obstacle: ψ with its derivatives, f and the cells of each triangle where ψ is
    /// above u_h (bits).
    above: Option<(&'a obstacle::WithDerivatives<'a>, &'a Pieces<'a>, &'a [u8])>,
}

impl Terms<'_> {
    /// The terms of the triangle t, whose cells carry the loads `loads` and the fluxes `tau`.
    fn of(&self, t: usize, loads: &[CellLoads; 6], tau: &TriangleFlux) -> TriangleTerms {
        let (mesh, dual, membranes) = (&self.problem.mesh, self.dual, self.membranes);
        let (alpha, _) = weights(membranes);
        let g = gradients(mesh.corners(t));
        let tri = mesh.triangle(t);
        let grad: [[f64; 2]; 2] = std::array::from_fn(|i| match membranes.get(i) {
            Some(m) => [0, 1].map(|k| m.mu * (0..3).map(|j| g[j][k] * m.u[tri[j]]).sum::<f64>()),
            None => [0.0; 2],
        });
        let cells = dual.cells_of(t);
        let mut terms = TriangleTerms::default();
        for (c, (s, cell_loads)) in (6 * t..).zip(loads).enumerate() {
            let p = cells[c];
            let area = 0.5 * crate::mesh::orient(p[0], p[1], p[2]);
            let squares: [f64; 3] =
                std::array::from_fn(|e| (0..2).map(|k| (p[(e + 1) % 3][k] - p[e][k]).powi(2)).sum());
            // The longest edge, from the squares (which overflow no sooner than the area).
            let diameter = squares.iter().fold(0.0_f64, |d, &s| d.max(s)).sqrt();
            // μ_i ∇u_ih + τ_i at a point: an RT0 field on κ.
            let at = |i: usize, m: [f64; 2]| {
                let f = &tau[i][c];
                [0, 1].map(|k| {
                    grad[i][k] + (0..3).map(|e| f[e] * (m[k] - p[(e + 2) % 3][k])).sum::<f64>() / (2.0 * area)
                })
            };
            // An RT0 field σ(x) = σ(g) + (div σ / 2)(x − g), g the centroid, has
            // ‖σ‖²_κ = |κ| (|σ(g)|² + (div σ / 2)² r²), r² = Σ_e |e|² / 36 = ∫_κ |x − g|² / |κ|
            // (each factor of the size of σ, so that nothing overflows before ‖σ‖ does).
            let centroid = [0, 1].map(|k| (p[0][k] + p[1][k] + p[2][k]) / 3.0);
            let r = ((squares[0] + squares[1] + squares[2]) / 36.0).sqrt();
            let norm = |(v, outflow): ([f64; 2], f64)| {
                let w = outflow / (2.0 * area) * r;
                (area * (v[0] * v[0] + v[1] * v[1] + w * w)).sqrt()
            };
            let values: [([f64; 2], f64); 2] = std::array::from_fn(|i| match i < membranes.len() {
                true => (at(i, centroid), tau[i][c].iter().sum()),
                false => ([0.0; 2], 0.0),
            });
            for (i, m) in membranes.iter().enumerate() {
                let flux = norm(values[i]) / m.mu.sqrt();
                let oscillation = diameter / PI * cell_loads.oscillation[i].sqrt() / m.mu.sqrt();
                terms.flux2[i] += flux * flux;
                terms.oscillation2[i] += oscillation * oscillation;
                terms.local2[i] += (flux + oscillation).powi(2);
            }
            if self.above.is_some() {
                let mu = membranes[0].mu;
                let cell = self.above_cell((t, c, p), grad[0], |x| at(0, x));
                let lifted = cell.map_or(norm(values[0]).powi(2), |cell| cell.flux2);
                let oscillation = diameter / PI * cell_loads.oscillation[0].sqrt();
                terms.local2_lifted += (lifted.sqrt() + oscillation).powi(2) / mu;
                let cell = cell.unwrap_or_default();
                (terms.cross, terms.obstacle2) = (terms.cross + cell.cross, terms.obstacle2 + cell.grad2);
            }
            // ζ = α(μ1∇u1h + τ1) − (1 − α)(μ2∇u2h + τ2), or μ∇u_h + τ above an obstacle.
            let [(a, div_a), (b, div_b)] = values;
            let zeta = norm((
                [0, 1].map(|k| alpha * a[k] - (1.0 - alpha) * b[k]),
                alpha * div_a - (1.0 - alpha) * div_b,
            ));
            terms.lambda2 += (zeta + diameter / PI * cell_loads.oscillation[2].sqrt()).powi(2);
            let lambda_h = self.contact_lambda[dual.owner(s)];
            terms.contact += lambda_h * area * cell_mean(mesh, s, self.gap);
        }
        terms
    }
}

impl Terms<'_> {
    /// Above an obstacle, on the cell c of the triangle t (corners `p`) if the obstacle is above
    /// u_h there, where μ∇u_h = `grad` and μ∇u_h + τ is `flux` at a point: what the cell
    /// contributes to the lifting and to the bound through ũ = u_h + z (§14).
    fn above_cell(
        &self,
        (t, c, p): (usize, usize, [[f64; 2]; 3]),
        grad: [f64; 2],
        flux: impl Fn([f64; 2]) -> [f64; 2],
    ) -> Option<obstacle::AboveCell> {
        let (mesh, m) = (&self.problem.mesh, &self.membranes[0]);
        let (psi, f, _) = self.above.filter(|(_, _, above)| above[t] & (1 << c) != 0)?;
        // u_h is affine on K: its value at a corner plus its gradient.
        let (tri, corner) = (mesh.triangle(t), mesh.corners(t)[0]);
        let u_at = |x: [f64; 2]| {
            let d = [0, 1].map(|k| grad[k] * (x[k] - corner[k]));
            m.u[tri[0]] + (d[0] + d[1]) / m.mu
        };
        Some(obstacle::AboveCell::compute(
            (psi.on_triangle(t), f.on_triangle(t)),
            p,
            m.mu,
            grad,
            u_at,
            flux,
            obstacle::rule(self.problem),
        ))
    }
}

/// C_F = 1 / (π (L_x⁻² + L_y⁻²)^½), L_x × L_y the bounding box of ω: ‖v‖ ≤ C_F ‖∇v‖ on H¹_0(ω)
/// (the first Dirichlet eigenvalue of the box, and domain monotonicity).
fn friedrichs_constant(mesh: &Mesh) -> f64 {
    let (lo, hi) = mesh.bounding_box();
    1.0 / (PI * ((hi[0] - lo[0]).powi(-2) + (hi[1] - lo[1]).powi(-2)).sqrt())
}

impl Describe for Estimate {
    fn fields(&self) -> Vec<Field<'_>> {
        let mut fields = vec![Field::new("estimator", Place::Cells, &self.indicator)];
        for (i, w) in self.which.iter().enumerate() {
            let flux = w.named(["estimator_flux_1", "estimator_flux_2", "estimator_flux"]);
            let oscillation = w.named([
                "estimator_oscillation_1",
                "estimator_oscillation_2",
                "estimator_oscillation",
            ]);
            fields.push(Field::new(flux, Place::Cells, &self.flux[i]));
            fields.push(Field::new(oscillation, Place::Cells, &self.oscillation[i]));
        }
        fields.push(Field::new("estimator_boundary", Place::Cells, &self.boundary));
        fields.push(Field::new("estimator_contact", Place::Cells, &self.contact));
        fields.push(Field::new(
            "estimator_data",
            Place::Cells,
            &self.resolution.indicator,
        ));
        fields
    }

    fn attributes(&self) -> Vec<Attribute> {
        let mut attrs = vec![("estimator", self.total.into())];
        for (i, w) in self.which.iter().enumerate() {
            let membrane = w.named([
                "estimator_membrane_1",
                "estimator_membrane_2",
                "estimator_membrane",
            ]);
            let means = w.named(["estimator_means_1", "estimator_means_2", "estimator_means"]);
            attrs.push((membrane, self.membranes[i].into()));
            attrs.push((means, self.means[i].into()));
        }
        attrs.push(("estimator_boundary", self.boundary_total.into()));
        if let Some(lifted) = self.lifted_membrane {
            attrs.push(("estimator_membrane_lifted", lifted.into()));
        }
        if let Some(o) = self.obstacle_total {
            attrs.push(("estimator_obstacle", o.into()));
        }
        attrs.push(("estimator_contact", self.contact_total.into()));
        attrs.push(("estimator_hminus1_lambda", self.lambda.into()));
        attrs.push(("estimator_data", self.resolution.total.into()));
        attrs.push(("estimator_data_checked", self.resolution.checked.into()));
        attrs.push((
            "estimator_loads_resolved",
            usize::from(self.loads_resolved()).into(),
        ));
        attrs.push((
            "estimator_boundary_admissible",
            usize::from(self.boundary_below.is_none()).into(),
        ));
        attrs
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::Diagonal;
    use crate::problem::Data;

    /// The lumped-mass norm of values whose squares would underflow or overflow, and a NaN kept
    /// (a fold by `max` had dropped it).
    #[test]
    fn the_mass_norm_neither_underflows_nor_hides_a_nan() {
        let mesh = Mesh::rectangle([0.0, 0.0], [1.0, 1.0], 2, 2, Diagonal::Right).unwrap();
        let zero = || crate::expr::Expr::parse("0").unwrap();
        let quadrature = crate::assembly::Quadrature { degree: 2 };
        let data = Data::new([1.0, 1.0], zero(), zero(), zero(), quadrature).unwrap();
        let problem = DiscreteProblem::new(mesh, &data).unwrap();
        let n = problem.mesh.n_vertices();
        // Σ_a m_a = |ω| = 1.
        for scale in [1e-200, 1.0, 1e200] {
            let norm = mass_norm(&problem, &vec![scale; n]);
            assert!((norm / scale - 1.0).abs() < 1e-14, "{scale:e}: {norm:e}");
        }
        let mut c = vec![1.0; n];
        c[3] = f64::NAN;
        assert!(mass_norm(&problem, &c).is_nan());
    }
}
