//! Preconditioned conjugate gradients for K_FF x = b, K_FF the rows of a symmetric positive
//! definite matrix on its free unknowns (the others held at 0), apart from the preconditioner
//! ([`Preconditioner`]; multigrid's V-cycle in this program, [`crate::multigrid`]).
//!
//! CG stops when the residual r = b − K_FF x meets a [`Tolerance`] at every free unknown a: a
//! density |r_a| ≤ d m_a (in the units of λ_h = r_a/m_a, (4.5)), and when asked for, a
//! componentwise backward error (Oettli–Prager) |r_a| ≤ β (σ_a + floor(a)) with
//! σ = |K_FF| |x| + |b|: what the checks of a solution measure (`action::Checks`).

use crate::parallel::{self, PIECE};
use crate::sparse::Csr;

/// The matrix K_FF that CG solves with: the rows of a symmetric matrix on the unknowns not
/// `skip`ped, and the masses m_a that weigh its residual.
#[derive(Clone, Copy)]
pub struct Free<'a> {
    /// The matrix on all unknowns.
    pub matrix: &'a Csr,
    /// The unknowns held at 0 (on ∂ω, or in the active set).
    pub skip: &'a [bool],
    /// m_a = ∫φ_a.
    pub mass: &'a [f64],
}

/// z ≈ K_FF⁻¹ r, symmetric positive definite on the free unknowns.
pub trait Preconditioner {
    /// z = B r (0 on the held unknowns) and `kz` = K_FF z; returns r·z.
    fn precondition(&mut self, r: &[f64], z: &mut [f64], kz: &mut [f64]) -> f64;
}

/// Where CG stops: |r_a| ≤ min(density m_a, backward (σ_a + floor(a))) at every free unknown
/// a, with σ = |K_FF| |x| + |b| of the iterate x (renewed every 4 iterations and whenever the
/// bound seems met), but never below the round-off 16 ε σ_a of r_a itself.
///
/// The density bounds r as a load density (a relative ‖r‖₂ would leave up to √n times the
/// tolerance at a vertex). The backward tolerance bounds the componentwise backward error of x:
/// it is what the checks of a solution measure (relative to the terms of (4.5) at each vertex,
/// which σ_a bounds from below), so that a solution CG accepts passes them wherever the data put
/// those terms — also at a vertex where u_h and the loads are small beside a large boundary lift.
#[derive(Clone, Copy)]
pub struct Tolerance<'a> {
    /// The largest residual density max_a |r_a|/m_a.
    pub density: f64,
    /// When asked for, the largest componentwise backward error max_a |r_a|/(σ_a + floor(a)),
    /// with a floor per vertex: the sizes of the loads whose combination b holds, which the
    /// checks count (b may cancel them).
    pub backward: Option<(f64, &'a (dyn Fn(usize) -> f64 + Sync))>,
}

/// CG did not reach the tolerance within the iteration cap.
#[derive(Debug, Clone, PartialEq)]
pub struct NotConverged {
    /// Iterations done.
    pub iterations: usize,
    /// max_a |r_a|/m_a reached (see [`Tolerance`]).
    pub residual: f64,
    /// The density it was to reach.
    pub target: f64,
}

/// The round-off of a residual r_a = b_a − Σ_b K_ab x_b, relative to σ_a = |b_a| + Σ_b |K_ab x_b|:
/// a few units of f64's precision per term of a row of K.
const ROUNDOFF: f64 = 16.0 * f64::EPSILON;

/// CG renews σ every this many iterations (and when the bound is met).
const SIGMA_EVERY: usize = 4;

/// How often CG goes on from its iterate when the residual recomputed from b misses a backward
/// tolerance (the recursively updated residual drifts from it by round-off, and σ moves with x).
const RESTARTS: usize = 4;

impl Free<'_> {
    /// The number of unknowns (held ones included).
    pub fn n(&self) -> usize {
        self.matrix.rows()
    }

    /// r = b − K_FF x on the free unknowns, 0 on the held ones, with b given in r.
    pub fn residual(&self, r: &mut [f64], x: &[f64]) {
        parallel::map_mut(r, PIECE, |base, r| {
            for (k, r) in r.iter_mut().enumerate() {
                let i = base + k;
                *r = if self.skip[i] {
                    0.0
                } else {
                    *r - self.matrix.row_dot(i, x)
                };
            }
        });
    }

    /// max_a |r_a|/m_a over the free unknowns: r as a load density (NaN if some r_a is, so that
    /// CG does not stop on it).
    pub fn density(&self, r: &[f64]) -> f64 {
        let parts = parallel::map(r.len(), PIECE, |range| {
            range
                .filter(|&i| !self.skip[i])
                .fold(0.0, |m, i| max_density(m, r[i] / self.mass[i]))
        });
        parts.into_iter().fold(0.0, max_density)
    }

    /// The largest |r_i| the `tolerance` allows at each unknown (+∞ on the held ones) for the
    /// iterate x and its residual r (given times 1/`unscale`), from σ = |K_FF| |x| + |b|: never
    /// below the round-off [`ROUNDOFF`] σ_i of r_i (a density the data cannot resolve is left to
    /// the checks of the solution, which say so). Returns whether r meets them (not where r_i is
    /// NaN).
    fn limits(
        &self,
        tolerance: &Tolerance,
        r: &[f64],
        unscale: f64,
        x: &[f64],
        limit: &mut Vec<f64>,
    ) -> bool {
        limit.resize(self.n(), 0.0);
        let met = parallel::map_mut(limit, PIECE, |base, limit| {
            let mut met = true;
            for (k, limit) in limit.iter_mut().enumerate() {
                let i = base + k;
                if self.skip[i] {
                    *limit = f64::INFINITY;
                    continue;
                }
                let (cols, vals) = self.matrix.row(i);
                let (mut kx, mut size) = (0.0, 0.0);
                for (&j, &v) in cols.iter().zip(vals) {
                    let t = v * x[j as usize];
                    kx += t;
                    size += t.abs();
                }
                let r = r[i] * unscale;
                let sigma = size + (r + kx).abs();
                let density = tolerance.density * self.mass[i];
                let wanted = match &tolerance.backward {
                    Some((backward, floor)) => density.min(backward * (sigma + floor(i))),
                    None => density,
                };
                *limit = wanted.max(ROUNDOFF * sigma);
                met &= r.abs() <= *limit;
            }
            met
        });
        met.into_iter().all(|m| m)
    }
}

/// max(m, |d|), NaN once either is NaN (so that CG does not stop on it).
fn max_density(m: f64, d: f64) -> f64 {
    if d.is_nan() || m.is_nan() {
        f64::NAN
    } else {
        m.max(d.abs())
    }
}

/// Solves K_FF x = b (b taken) on the free unknowns of `a` by CG preconditioned by
/// `preconditioner`, from the guess `x` (its held entries are set to 0), until the residual
/// meets `tolerance` at every free unknown. With a backward tolerance the residual is recomputed
/// from b before CG and whenever CG's recursive one meets the bound, and CG goes on from x while
/// that true residual misses it, at most 4 times. With a density of 0, x = 0 when b = 0 on the
/// free unknowns. Returns the iterations.
pub fn conjugate_gradients(
    a: &Free,
    preconditioner: &mut impl Preconditioner,
    b: Vec<f64>,
    x: &mut [f64],
    tolerance: Tolerance,
    max_iterations: usize,
) -> Result<usize, NotConverged> {
    for (x, &skip) in x.iter_mut().zip(a.skip) {
        if skip {
            *x = 0.0;
        }
    }
    if tolerance.density == 0.0 && a.density(&b) == 0.0 {
        x.fill(0.0);
        return Ok(0);
    }
    let failed = |iterations: usize, r: &[f64]| NotConverged {
        iterations,
        residual: a.density(r),
        target: tolerance.density,
    };
    let mut limit = Vec::new();
    let restarts = if tolerance.backward.is_some() { RESTARTS } else { 0 };
    let mut iterations = 0;
    for _ in 0..=restarts {
        let mut r = b.clone();
        a.residual(&mut r, x);
        if a.limits(&tolerance, &r, 1.0, x, &mut limit) {
            return Ok(iterations);
        }
        let left = max_iterations - iterations;
        match iterate(a, preconditioner, r, x, &tolerance, &mut limit, left) {
            Ok(more) => iterations += more,
            Err((more, r)) => return Err(failed(iterations + more, &r)),
        }
        if tolerance.backward.is_none() {
            return Ok(iterations);
        }
    }
    let mut r = b;
    a.residual(&mut r, x);
    Err(failed(iterations, &r))
}

/// CG iterations from x with its residual r (which misses `limit`) until |r_a| ≤ limit_a at every
/// free unknown, r the recursively updated residual, the limits renewed from the x that meets
/// them. CG works on r scaled by a power of two that brings its largest entry near 1, so that no
/// product of two residual-sized numbers overflows or underflows whatever the units of the data
/// (the scaling is exact: the iterates are those of CG on r itself). Returns the iterations, or
/// those done and the residual reached.
///
/// K_FF of the search direction comes from the recurrence K p = K z + β K p_old, with K z from
/// the preconditioner: no matrix product of its own per iteration.
fn iterate(
    a: &Free,
    preconditioner: &mut impl Preconditioner,
    mut r: Vec<f64>,
    x: &mut [f64],
    tolerance: &Tolerance,
    limit: &mut Vec<f64>,
    max_iterations: usize,
) -> Result<usize, (usize, Vec<f64>)> {
    let largest = r.iter().fold(0.0_f64, |m, r| m.max(r.abs()));
    let scale = power_of_two_near(largest);
    let unscale = 1.0 / scale;
    parallel::map_mut(&mut r, PIECE, |_, r| r.iter_mut().for_each(|r| *r *= scale));
    let n = a.n();
    let (mut z, mut kz) = (vec![0.0; n], vec![0.0; n]);
    let mut rz = preconditioner.precondition(&r, &mut z, &mut kz);
    let (mut p, mut q) = (z.clone(), kz.clone());
    let mut pq = parallel::sum(n, PIECE, |range| range.map(|i| p[i] * q[i]).sum());
    let mut done = max_iterations;
    for iteration in 1..=max_iterations {
        let alpha = rz / pq;
        if !alpha.is_finite() {
            done = iteration - 1;
            break;
        }
        // x += α p (unscaled), r −= α q, and whether r meets the limits.
        let met = parallel::map_mut2(x, &mut r, PIECE, |base, x, r| {
            let mut met = true;
            for (k, (x, r)) in x.iter_mut().zip(r).enumerate() {
                let i = base + k;
                *x += alpha * p[i] * unscale;
                *r -= alpha * q[i];
                met &= r.abs() * unscale <= limit[i];
            }
            met
        });
        // σ moves with x: the bound is met only against σ of this x (and σ is renewed now and
        // then, so that CG stops once r is at its round-off).
        let renew = met.into_iter().all(|m| m) || iteration % SIGMA_EVERY == 0;
        if renew && a.limits(tolerance, &r, unscale, x, limit) {
            return Ok(iteration);
        }
        let rz_next = preconditioner.precondition(&r, &mut z, &mut kz);
        let beta = rz_next / rz;
        rz = rz_next;
        // p = z + β p, q = K z + β q, and p·q.
        let pqs = parallel::map_mut2(&mut p, &mut q, PIECE, |base, p, q| {
            let mut pq = 0.0;
            for (k, (p, q)) in p.iter_mut().zip(q).enumerate() {
                *p = z[base + k] + beta * *p;
                *q = kz[base + k] + beta * *q;
                pq += *p * *q;
            }
            pq
        });
        pq = pqs.into_iter().sum();
    }
    parallel::map_mut(&mut r, PIECE, |_, r| r.iter_mut().for_each(|r| *r *= unscale));
    Err((done, r))
}

/// The power of two nearest 1/`size` (1 for 0 or a non-finite size), within f64's normal range.
fn power_of_two_near(size: f64) -> f64 {
    if !(size.is_finite() && size > 0.0) {
        return 1.0;
    }
    let exponent = size.log2().round().clamp(-1000.0, 1000.0) as i32;
    2.0_f64.powi(-exponent)
}
