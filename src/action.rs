//! The discrete action λ_h by local postprocessing (4.5), and the checks the paper proves of it.
//!
//! At each interior vertex a, with m_a = ∫φ_a = meas(D_a) (Remark 11, Section 4.2):
//!   λ1_a m_a =  μ1 ∫∇u1h·∇φ_a − ∫f1 φ_a,
//!   λ2_a m_a = −μ2 ∫∇u2h·∇φ_a + ∫f2 φ_a,
//! which coincide (Proposition 12); λ_a ≥ 0 and λ_a (u1h − u2h)(a) = 0 (4.8). λ_h = Σ_a λ_a χ_{D_a}
//! over the interior vertices is piecewise constant on the barycentric dual cells D_a, and 0 on
//! the cells of the boundary vertices.
//!
//! The right-hand sides of (4.5) are differences of terms that cancel down to O(h²), so the
//! checks are measured relative to the size of those terms at each vertex, and a solution that
//! misses them by more than [`TOLERANCE`] is not a solution of (3.4): the run fails.

use crate::contact::Solution;
use crate::problem::DiscreteProblem;
use crate::result::{Attribute, Describe, Field, Place};
use std::fmt;

pub use crate::contact::CHECK_TOLERANCE as TOLERANCE;

/// A dual cell below this part of the largest is a feature of the domain far smaller than the
/// mesh size (1000 times narrower), where the round-off of λ_h is named as such.
const SMALL_CELL: f64 = 1e-6;

/// The largest round-off of λ_h a run accepts, relative to the size of the loads.
pub const RESOLUTION: f64 = 1e-3;

/// Round-off of a sum of the terms of (4.5), relative to the sum of their sizes: a few units of
/// f64's precision for the rows of K, and as much again for the Cholesky solve behind u_ih.
const ROUNDOFF: f64 = 8.0 * f64::EPSILON;

/// λ_h from each membrane, the total force, the contact area and the checks.
#[derive(Debug, Clone)]
pub struct Action {
    /// λ_a from membrane 1 at each vertex (0 on ∂ω): λ_h of (4.5).
    pub lambda: Vec<f64>,
    /// λ_a from membrane 2 (empty below a rigid obstacle).
    pub lambda2: Vec<f64>,
    /// ∫_ω λ_h = Σ_a λ_a meas(D_a): the total contact force.
    pub total: f64,
    /// Σ_{a in contact} meas(D_a): the measure of the contact region on the dual mesh.
    pub contact_area: f64,
    /// Prop. 12, λ ≥ 0, (4.8) and w ≥ 0, relative to the terms that cancel.
    pub checks: Checks,
}

/// The checks of a discrete solution, each relative to the size of the terms that cancel.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Checks {
    /// Prop. 12: max_a |λ1_a − λ2_a| m_a / s_a, with s_a = Σ_b |μ1 K_ab| c_b + |(f1, φ_a)| +
    /// Σ_b |μ2 K_ab| c_b + |(f2, φ_a)| the size of the terms of (4.5) at a, c_b = max(|u1_b|,
    /// |u2_b|) + 2 |w_b| the size of the terms u_ib is computed from.
    pub prop12: f64,
    /// max_a max(0, −λ_a m_a) / s_a: how negative λ_h is.
    pub negative_lambda: f64,
    /// (4.8): max_a |λ_a m_a| |w_a| / (s_a max_b |w_b|).
    pub complementarity: f64,
    /// max(0, −min_a w_a) / max_b |w_b|: how far u1h − u2h ≥ 0 is missed.
    pub negative_gap: f64,
    /// The round-off λ_h can carry, max_a ε s_a / m_a, relative to the size of the loads
    /// max_a (|(f1, φ_a)| + |(f2, φ_a)|)/m_a (0 without loads, where λ = 0): large when the data
    /// span too many orders of magnitude for double precision.
    pub resolution: f64,
    /// max_a ε s_a / m_a.
    pub noise: f64,
    /// The vertex where `noise` is reached, and its m_a relative to the largest m_b.
    pub noisiest: ([f64; 2], f64),
    /// max_a (|(f1, φ_a)| + |(f2, φ_a)|)/m_a.
    pub loads: f64,
    /// The size of the smaller membrane, min_i max_b |u_ib| (above an obstacle max_b |u_b|), and
    /// the largest size c_b of the terms the u_ib are computed from: far apart when the other
    /// membrane or the obstacle is far from it.
    pub values: [f64; 2],
    /// The round-off λ_h would carry if each u_ib were exact to its own size: `noise` with s_a
    /// made of the |μ_i K_ab u_ib|.
    pub own_noise: f64,
    /// The size of each membrane, max(the displacement its own data give, max_b |u_ib|)
    /// (`own_size`), against which the round-off of its values is measured; 0 where its data are
    /// all 0 (it moves only where it touches the other) and above a rigid obstacle (not checked).
    pub sizes: [f64; 2],
    /// The round-off of each membrane's values, computed as u1 = v + μ2/(μ1+μ2) w and
    /// u2 = v − μ1/(μ1+μ2) w: 8ε max_b (|v_b| + μ_j/(μ1+μ2) |w_b|), j the other membrane.
    pub noises: [f64; 2],
}

/// A discrete solution that fails its own checks.
#[derive(Debug, Clone, PartialEq)]
pub enum CheckError {
    /// A value overflowed or is NaN.
    NotFinite,
    /// A membrane is below the round-off of what its values are computed from.
    MembraneUnresolved {
        /// 1 or 2.
        which: usize,
        /// The round-off of its values.
        noise: f64,
        /// Its size (`own_size`).
        size: f64,
    },
    /// λ_h is below the round-off of (4.5).
    Unresolved {
        /// The round-off λ_h can carry.
        noise: f64,
        /// The size of the loads.
        loads: f64,
        /// [`Checks::values`], where the round-off comes from computing the u_ib from larger terms
        /// (the values exact to their own size would resolve λ_h).
        cancelled: Option<[f64; 2]>,
        /// [`Checks::noisiest`], where that dual cell is below 10⁻⁶ of the largest: a
        /// feature of the domain far smaller than the mesh size, whose cells' tiny m_a divide the
        /// round-off of (4.5).
        small_cell: Option<([f64; 2], f64)>,
    },
    /// A check exceeds [`TOLERANCE`].
    Failed {
        /// What is checked.
        what: &'static str,
        /// Its relative defect.
        value: f64,
    },
}

impl fmt::Display for CheckError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            CheckError::NotFinite => write!(
                f,
                "the discrete solution has non-finite values (overflow): the data are too large for \
                 double precision; nothing is written"
            ),
            CheckError::MembraneUnresolved { which, noise, size } => write!(
                f,
                "u{which}h is not resolved in double precision: it is computed (from v and w) with \
                 a round-off of {noise:.1e}, {:.1e} of the displacement of size {size:.1e} that its \
                 own data give (limit {RESOLUTION:.0e}): the two membranes' data are too many orders \
                 of magnitude apart; nothing is written",
                noise / size
            ),
            CheckError::Unresolved {
                noise,
                loads,
                cancelled,
                small_cell,
            } => {
                write!(
                    f,
                    "λ_h is not resolved in double precision: the round-off of (4.5) reaches {noise:.1e}, \
                     against loads of size {loads:.1e} "
                )?;
                if let Some(([x, y], share)) = small_cell {
                    write!(
                        f,
                        "at the vertex ({x}, {y}), whose dual cell is {share:.0e} of the largest (a \
                         feature of the domain there is far smaller than the mesh: widen or remove it)"
                    )?;
                } else if let Some(values) = cancelled {
                    write!(
                        f,
                        "(u_h, at most {:.1e}, is computed from terms up to {:.1e}, its gap to the \
                         other membrane or the obstacle: bring g2 or ψ closer)",
                        values[0], values[1]
                    )?;
                } else {
                    write!(f, "(the data span too many orders of magnitude: rescale them)")?;
                }
                write!(f, "; nothing is written")
            }
            CheckError::Failed { what, value } => write!(
                f,
                "the discrete solution fails {what}: relative defect {value:.2e} > {TOLERANCE:.0e} \
                 (relative to the terms of (4.5) that cancel); nothing is written"
            ),
        }
    }
}

impl std::error::Error for CheckError {}

impl Checks {
    /// The largest round-off of a membrane's values relative to its size ([`Checks::sizes`]).
    pub fn membrane_resolution(&self) -> f64 {
        (self.sizes.iter().zip(self.noises))
            .filter(|&(&s, _)| s > 0.0)
            .fold(0.0, |m, (s, noise)| m.max(noise / s))
    }

    /// Fails when a check exceeds [`TOLERANCE`] or is not a number.
    pub fn verify(&self) -> Result<(), CheckError> {
        let all = [
            ("Proposition 12 (λ1 = λ2)", self.prop12),
            ("λ_h ≥ 0", self.negative_lambda),
            ("the complementarity (4.8)", self.complementarity),
            ("u1h − u2h ≥ 0", self.negative_gap),
        ];
        if all.iter().any(|(_, v)| !v.is_finite())
            || !self.resolution.is_finite()
            || self.noises.iter().any(|n| !n.is_finite())
        {
            return Err(CheckError::NotFinite);
        }
        for (i, (&size, noise)) in self.sizes.iter().zip(self.noises).enumerate() {
            if size > 0.0 && noise > RESOLUTION * size {
                return Err(CheckError::MembraneUnresolved {
                    which: i + 1,
                    noise,
                    size,
                });
            }
        }
        if self.resolution > RESOLUTION {
            return Err(CheckError::Unresolved {
                noise: self.noise,
                loads: self.loads,
                cancelled: (self.own_noise <= RESOLUTION * self.loads).then_some(self.values),
                small_cell: Some(self.noisiest).filter(|n| n.1 < SMALL_CELL),
            });
        }
        match all.iter().find(|(_, v)| *v > TOLERANCE) {
            Some(&(what, value)) => Err(CheckError::Failed { what, value }),
            None => Ok(()),
        }
    }
}

impl Action {
    /// Computes (4.5) from both membranes, with the checks.
    ///
    /// ```
    /// use membrane_contact::{action::Action, case::Case, contact, problem::DiscreteProblem};
    /// let case = Case::default_case();
    /// let problem = DiscreteProblem::new(case.mesh().unwrap(), &case.data).unwrap();
    /// let solution = contact::solve(&problem, contact::Start::Cold, Vec::new(), case.solver).unwrap();
    /// let action = Action::compute(&problem, &solution);
    /// assert!(action.checks.verify().is_ok() && action.total > 0.0);
    /// ```
    pub fn compute(problem: &DiscreteProblem, solution: &Solution) -> Action {
        let (mesh, k) = (&problem.mesh, &problem.stiffness);
        let (mu1, mu2) = (problem.data.mu1, problem.data.mu2());
        let (u1, u2, gap) = (&solution.u1, &solution.u2, &solution.obstacle.gap);
        let n = mesh.n_vertices();
        // Below a rigid obstacle only membrane 1 has an equation: no λ2, no Prop. 12.
        let (mut lambda, mut lambda2) = (vec![0.0; n], vec![0.0; if mu2.is_some() { n } else { 0 }]);
        let gap_scale = gap.iter().fold(f64::MIN_POSITIVE, |m, w| m.max(w.abs()));
        let mut checks = Checks {
            prop12: 0.0,
            negative_lambda: 0.0,
            complementarity: 0.0,
            negative_gap: gap.iter().fold(0.0_f64, |m, &w| m.max(-w)) / gap_scale,
            resolution: 0.0,
            noise: 0.0,
            noisiest: ([0.0; 2], 1.0),
            loads: 0.0,
            values: [0.0; 2],
            own_noise: 0.0,
            sizes: [0.0; 2],
            noises: [0.0; 2],
        };
        // The size of u_ib as computed, v + μ2/(μ1+μ2) w and v − μ1/(μ1+μ2) w (ψ_h + w above a rigid
        // obstacle), which bounds its round-off: |v| + |w| ≤ |u_ib| + 2|w| for both. It is not |u_ib|,
        // which cancellation makes small where u_ih is far above the other (ψ = −1 below u = 0).
        let computed = |b: usize| u1[b].abs().max(u2[b].abs()) + 2.0 * gap[b].abs();
        let (mut total, mut contact_area) = (0.0, 0.0);
        // The smaller membrane's size (above an obstacle, u's) against what it is computed from.
        let largest = |u: &[f64]| u.iter().fold(0.0_f64, |m, x| m.max(x.abs()));
        let smaller = if solution.rigid {
            largest(u1)
        } else {
            largest(u1).min(largest(u2))
        };
        checks.values = [smaller, (0..n).map(computed).fold(0.0, f64::max)];
        if !solution.rigid {
            checks.sizes = [own_size(problem, 0, u1), own_size(problem, 1, u2)];
            checks.noises = membrane_noises(problem, u1, u2, gap);
        }
        let largest_cell = problem.mass.iter().fold(f64::MIN_POSITIVE, |m, &x| m.max(x));
        for a in (0..n).filter(|&a| !mesh.on_boundary[a]) {
            let m = problem.mass[a];
            let l1 = (mu1 * k.row_dot(a, u1) - problem.load1[a]) / m;
            let terms =
                |mu: f64, c: &dyn Fn(usize) -> f64| k.row(a).map(|(b, v)| (mu * v).abs() * c(b)).sum::<f64>();
            let mut size = terms(mu1, &computed) + problem.load_size(a);
            let mut own = terms(mu1, &|b| u1[b].abs()) + problem.load_size(a);
            lambda[a] = l1;
            let mut l2 = l1;
            if let Some(mu2) = mu2 {
                l2 = (-mu2 * k.row_dot(a, u2) + problem.load2[a]) / m;
                size += terms(mu2, &computed);
                own += terms(mu2, &|b| u2[b].abs());
                lambda2[a] = l2;
            }
            let s = size.max(f64::MIN_POSITIVE);
            if ROUNDOFF * size / m > checks.noise {
                (checks.noise, checks.noisiest) = (ROUNDOFF * size / m, (mesh.points[a], m / largest_cell));
            }
            checks.own_noise = checks.own_noise.max(ROUNDOFF * own / m);
            checks.loads = checks.loads.max(problem.load_size(a) / m);
            checks.prop12 = checks.prop12.max((l1 - l2).abs() * m / s);
            checks.negative_lambda = checks.negative_lambda.max(-l1 * m / s);
            checks.complementarity = checks
                .complementarity
                .max((l1 * m / s).abs() * gap[a].abs() / gap_scale);
            total += l1 * m;
            if solution.obstacle.contact[a] {
                contact_area += m;
            }
        }
        if checks.loads > 0.0 {
            checks.resolution = checks.noise / checks.loads;
        }
        Action {
            lambda,
            lambda2,
            total,
            contact_area,
            checks,
        }
    }
}

/// [`Checks::noises`] of the displacements `u1`, `u2` with the gap `w` (two membranes).
fn membrane_noises(problem: &DiscreteProblem, u1: &[f64], u2: &[f64], w: &[f64]) -> [f64; 2] {
    let (mu1, mu2) = (problem.data.mu1, problem.data.mu2().expect("two membranes"));
    let v = |b: usize| (mu1 * u1[b] + mu2 * u2[b]) / (mu1 + mu2);
    [mu2, mu1].map(|mu_j| {
        let largest = (0..w.len()).map(|b| v(b).abs() + mu_j / (mu1 + mu2) * w[b].abs());
        ROUNDOFF * largest.fold(0.0, f64::max)
    })
}

/// The size of membrane i (0 or 1, of displacement `u`) for the round-off of its values: the
/// displacement its own data give, max |g_ih| on ∂ω + max_a |(f_i, φ_a)|/m_a · d²/(8μ_i) (d the
/// diameter of the mesh: the Poisson problem's bound on a disk of diameter d), or max_b |u_ib| if
/// larger; 0 when its data are all 0 (it moves only where it touches the other membrane).
fn own_size(problem: &DiscreteProblem, i: usize, u: &[f64]) -> f64 {
    let mesh = &problem.mesh;
    let (lo, hi) = mesh.bounding_box();
    let d2 = (hi[0] - lo[0]).powi(2) + (hi[1] - lo[1]).powi(2);
    let (load, mu) = match i {
        0 => (&problem.load1, problem.data.mu1),
        _ => (&problem.load2, problem.data.mu2().expect("two membranes")),
    };
    let height = |a: usize| match i {
        0 => problem.g_h[a],
        _ => problem.g_h[a] - problem.gap_h[a],
    };
    let boundary = (0..mesh.n_vertices()).filter(|&a| mesh.on_boundary[a]);
    let g = boundary.map(height).fold(0.0_f64, |m, h| m.max(h.abs()));
    let f = (load.iter().zip(&problem.mass)).fold(0.0_f64, |m, (l, w)| m.max(l.abs() / w));
    let own = g + f * d2 / (8.0 * mu);
    match own > 0.0 {
        true => own.max(u.iter().fold(0.0_f64, |m, x| m.max(x.abs()))),
        false => 0.0,
    }
}

impl Describe for Action {
    fn fields(&self) -> Vec<Field<'_>> {
        let mut fields = vec![Field::new("lambda", Place::Vertices, &self.lambda)];
        if !self.lambda2.is_empty() {
            fields.push(Field::new("lambda2", Place::Vertices, &self.lambda2));
        }
        fields
    }

    fn attributes(&self) -> Vec<Attribute> {
        let c = &self.checks;
        vec![
            ("total_force", self.total.into()),
            ("contact_area", self.contact_area.into()),
            ("check_prop12", c.prop12.into()),
            ("check_negative_lambda", c.negative_lambda.into()),
            ("check_complementarity", c.complementarity.into()),
            ("check_negative_gap", c.negative_gap.into()),
            ("check_resolution", c.resolution.into()),
            ("check_membrane_resolution", c.membrane_resolution().into()),
            ("check_tolerance", TOLERANCE.into()),
        ]
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::assembly::Quadrature;
    use crate::contact::{Obstacle, SolverStats};
    use crate::expr::Expr;
    use crate::mesh::{Diagonal, Mesh};
    use crate::problem::Data;

    #[test]
    fn verify_fails_exactly_beyond_its_limits() {
        let ok = Checks {
            prop12: TOLERANCE,
            negative_lambda: 0.0,
            complementarity: 0.0,
            negative_gap: 0.0,
            resolution: RESOLUTION,
            noise: 1.0,
            noisiest: ([0.5, 0.25], 1e-3),
            loads: 1e3,
            values: [1.0, 3.0],
            own_noise: 1.0,
            sizes: [1.0, 0.0],
            noises: [ROUNDOFF, ROUNDOFF],
        };
        assert_eq!(ok.verify(), Ok(()));
        let failed = Checks {
            complementarity: 2.0 * TOLERANCE,
            ..ok
        };
        let what = "the complementarity (4.8)";
        assert_eq!(
            failed.verify(),
            Err(CheckError::Failed {
                what,
                value: 2.0 * TOLERANCE
            })
        );
        // Unresolved even were each u_ib exact to its own size: the data's scale is blamed; resolved
        // then (own_noise at most RESOLUTION of the loads): the cancellation in computing the u_ib.
        for (own_noise, cancelled) in [(2.0, None), (1.0, Some([1.0, 3.0]))] {
            let unresolved = Checks {
                resolution: 2.0 * RESOLUTION,
                own_noise,
                ..ok
            };
            assert_eq!(
                unresolved.verify(),
                Err(CheckError::Unresolved {
                    noise: 1.0,
                    loads: 1e3,
                    cancelled,
                    small_cell: None
                })
            );
        }
        // … unless the vertex of the largest round-off has a dual cell far smaller than the others.
        let tiny = Checks {
            resolution: 2.0 * RESOLUTION,
            noisiest: ([0.5, 0.25], 1e-9),
            ..ok
        };
        let error = tiny.verify().unwrap_err();
        assert!(matches!(
            error,
            CheckError::Unresolved {
                small_cell: Some(_),
                ..
            }
        ));
        assert!(error
            .to_string()
            .contains("at the vertex (0.5, 0.25), whose dual cell is 1e-9 of the largest"));
        // Membrane 2 of a size such that the round-off of its values is twice the limit; one of
        // size 0 (its data all 0) is not checked.
        let noise = ROUNDOFF;
        let size = noise / (2.0 * RESOLUTION);
        let small = Checks {
            sizes: [0.0, size],
            ..ok
        };
        let which = 2;
        assert_eq!(
            small.verify(),
            Err(CheckError::MembraneUnresolved { which, noise, size })
        );
        assert_eq!(
            Checks {
                sizes: [2.0 * size, 0.0],
                ..ok
            }
            .verify(),
            Ok(())
        );
        for nan in [
            Checks {
                negative_lambda: f64::NAN,
                ..ok
            },
            Checks {
                resolution: f64::INFINITY,
                ..ok
            },
        ] {
            assert_eq!(nan.verify(), Err(CheckError::NotFinite));
        }
    }

    #[test]
    fn the_action_and_its_checks_follow_their_formulas() {
        // Arbitrary fields (not a solution) on a small mesh, against (4.5) and the checks'
        // definitions evaluated here vertex by vertex.
        let mesh = Mesh::rectangle([0.0, 0.0], [1.0, 1.0], 4, 4, Diagonal::Left).unwrap();
        let e = |s: &str| Expr::parse(s).unwrap();
        let data = Data::new([2.0, 3.0], e("1 + x"), e("y"), e("0"), Quadrature { degree: 2 }).unwrap();
        let p = DiscreteProblem::new(mesh, &data).unwrap();
        let n = p.mesh.n_vertices();
        let u1: Vec<f64> = (0..n).map(|a| (a as f64 * 0.7).sin()).collect();
        let u2: Vec<f64> = (0..n).map(|a| (a as f64 * 0.3).cos() - 0.5).collect();
        let gap: Vec<f64> = u1.iter().zip(&u2).map(|(a, b)| a - b).collect();
        let contact: Vec<bool> = (0..n).map(|a| a % 3 == 0).collect();
        let obstacle = Obstacle {
            gap: gap.clone(),
            lambda: vec![0.0; n],
            contact: contact.clone(),
            stats: SolverStats::default(),
        };
        let action = Action::compute(
            &p,
            &Solution {
                u1: u1.clone(),
                u2: u2.clone(),
                obstacle,
                rigid: false,
                transfers: Vec::new(),
            },
        );
        let k = &p.stiffness;
        let wmax = gap.iter().fold(0.0_f64, |m, w| m.max(w.abs()));
        let (mut prop12, mut negative, mut compl, mut total, mut area) =
            (0.0_f64, 0.0_f64, 0.0_f64, 0.0, 0.0);
        let (mut noise, mut own_noise, mut loads) = (0.0_f64, 0.0_f64, 0.0_f64);
        for a in (0..n).filter(|&a| !p.mesh.on_boundary[a]) {
            let m = p.mass[a];
            let (mut k1, mut k2, mut size) = (0.0, 0.0, p.load1[a].abs() + p.load2[a].abs());
            let mut own = size;
            for (b, v) in k.row(a) {
                k1 += 2.0 * v * u1[b];
                k2 += 3.0 * v * u2[b];
                // The size u_ib is computed from: max(|u1|, |u2|) + 2 |u1 − u2|.
                let computed = u1[b].abs().max(u2[b].abs()) + 2.0 * gap[b].abs();
                size += (2.0 * v).abs() * computed + (3.0 * v).abs() * computed;
                own += (2.0 * v * u1[b]).abs() + (3.0 * v * u2[b]).abs();
            }
            let (l1, l2) = ((k1 - p.load1[a]) / m, (p.load2[a] - k2) / m);
            assert!((action.lambda[a] - l1).abs() < 1e-13 && (action.lambda2[a] - l2).abs() < 1e-13);
            prop12 = prop12.max((l1 - l2).abs() * m / size);
            negative = negative.max(-l1 * m / size);
            compl = compl.max((l1 * m).abs() / size * gap[a].abs() / wmax);
            total += l1 * m;
            area += if contact[a] { m } else { 0.0 };
            noise = noise.max(ROUNDOFF * size / m);
            own_noise = own_noise.max(ROUNDOFF * own / m);
            loads = loads.max((p.load1[a].abs() + p.load2[a].abs()) / m);
        }
        let c = &action.checks;
        let close = |x: f64, y: f64| assert!((x - y).abs() <= 1e-13 * y.abs().max(1e-300), "{x} against {y}");
        close(c.prop12, prop12);
        close(c.negative_lambda, negative);
        close(c.complementarity, compl);
        close(c.negative_gap, -gap.iter().fold(0.0_f64, |m, &w| m.min(w)) / wmax);
        close(action.total, total);
        close(action.contact_area, area);
        close(c.resolution, noise / loads);
        close(c.own_noise, own_noise);
        assert!(prop12 > 0.1 && negative > 0.0 && c.negative_gap > 0.0 && area > 0.0);
    }
}
