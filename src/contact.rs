//! The reduced discrete variational inequality (3.4) on K_gh = {v1h − v2h ≥ 0 at the vertices}.
//!
//! For constant μ1, μ2 the discrete energy Σ_i μ_i/2 |∇u_ih|² − (f_i, u_ih) separates exactly in
//!   v = (μ1 u1 + μ2 u2)/(μ1 + μ2)   and   w = u1 − u2:
//!   (μ1+μ2)/2 |∇v|² − (f1 + f2, v)  +  μ*/2 |∇w|² − (f_w, w),
//! with μ* = μ1μ2/(μ1+μ2), f_w = (μ2 f1 − μ1 f2)/(μ1+μ2), v = μ1 g_h/(μ1+μ2) and w = g_h on ∂ω,
//! and the only constraint w(a) ≥ 0 at the interior vertices. So (3.4) is one Poisson solve for v
//! and one scalar obstacle problem for w. Multiplying the two equations of (4.5) by μ2 and μ1 and
//! subtracting shows that the obstacle problem's residual is the action: μ*(K w)_a − (f_w, φ_a)
//! = λ_a m_a, with m_a = ∫φ_a.
//!
//! The obstacle problem is solved by the primal–dual active-set method (a semismooth Newton method
//! for min(w_a, λ_a) = 0): A = {a : λ_a − c_a w_a > 0}, w = 0 on A, the equation off A, repeated
//! until A no longer changes, which is then the exact solution of (3.4) up to round-off.

use crate::assembly::{self, Quadrature, Stiffness};
use crate::expr::Expr;
use crate::linear::{Factorization, InteriorSystem};
use crate::mesh::Mesh;
use std::fmt;
use std::time::Instant;

/// The data of problem (1.1): tensions, loads and the boundary height of membrane 1.
#[derive(Debug, Clone)]
pub struct Data {
    pub mu1: f64,
    pub mu2: f64,
    pub f1: Expr,
    pub f2: Expr,
    pub g: Expr,
    pub quadrature: Quadrature,
}

/// Why a discrete problem could not be set up or solved.
#[derive(Debug, Clone, PartialEq)]
pub enum SolveError {
    Tension {
        name: &'static str,
        value: f64,
    },
    NotFinite {
        name: &'static str,
        point: [f64; 2],
        value: f64,
    },
    NegativeBoundaryHeight {
        point: [f64; 2],
        value: f64,
    },
    IterationCap {
        iterations: usize,
        changed: usize,
    },
    NotPositiveDefinite,
}

impl fmt::Display for SolveError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            SolveError::Tension { name, value } => {
                write!(f, "{name} = {value} must be a positive number")
            }
            SolveError::NotFinite { name, point, value } => write!(
                f,
                "{name} is {value} at ({}, {}): every datum must be finite in ω",
                point[0], point[1]
            ),
            SolveError::NegativeBoundaryHeight { point, value } => write!(
                f,
                "g = {value} < 0 at the boundary vertex ({}, {}): the paper requires g ≥ 0 on ∂ω",
                point[0], point[1]
            ),
            SolveError::IterationCap { iterations, changed } => write!(
                f,
                "the active-set method did not converge in {iterations} iterations \
                 ({changed} vertices changed in the last one); raise solver.max_iterations"
            ),
            SolveError::NotPositiveDefinite => {
                write!(f, "the stiffness matrix is not positive definite")
            }
        }
    }
}

impl std::error::Error for SolveError {}

/// The discrete problem (3.4) on one mesh: K, m_a, the loads and g_h.
pub struct DiscreteProblem {
    pub mesh: Mesh,
    pub stiffness: Stiffness,
    /// m_a = ∫φ_a.
    pub mass: Vec<f64>,
    /// (f1, φ_a) and (f2, φ_a) at every vertex.
    pub load1: Vec<f64>,
    pub load2: Vec<f64>,
    /// g_h: g at the boundary vertices, 0 inside.
    pub g_h: Vec<f64>,
    pub mu1: f64,
    pub mu2: f64,
    pub setup_seconds: f64,
}

impl DiscreteProblem {
    pub fn new(mesh: Mesh, data: &Data) -> Result<Self, SolveError> {
        let start = Instant::now();
        for (name, value) in [("mu1", data.mu1), ("mu2", data.mu2)] {
            if !(value > 0.0 && value.is_finite()) {
                return Err(SolveError::Tension { name, value });
            }
        }
        let mut g_h = vec![0.0; mesh.n_vertices()];
        for (a, p) in mesh.points.iter().enumerate() {
            if mesh.on_boundary[a] {
                let value = data.g.eval(p[0], p[1]);
                if !value.is_finite() {
                    return Err(SolveError::NotFinite {
                        name: "g",
                        point: *p,
                        value,
                    });
                }
                if value < 0.0 {
                    return Err(SolveError::NegativeBoundaryHeight { point: *p, value });
                }
                g_h[a] = value;
            }
        }
        let load = |name, f: &Expr| {
            assembly::load(&mesh, f, data.quadrature).map_err(|e| SolveError::NotFinite {
                name,
                point: e.point,
                value: e.value,
            })
        };
        let load1 = load("f1", &data.f1)?;
        let load2 = load("f2", &data.f2)?;
        let stiffness = Stiffness::assemble(&mesh);
        let mass = assembly::lumped_mass(&mesh);
        Ok(DiscreteProblem {
            mesh,
            stiffness,
            mass,
            load1,
            load2,
            g_h,
            mu1: data.mu1,
            mu2: data.mu2,
            setup_seconds: start.elapsed().as_secs_f64(),
        })
    }
}

/// Options of the active-set method.
#[derive(Debug, Clone, Copy)]
pub struct SolverOptions {
    pub max_iterations: usize,
}

impl Default for SolverOptions {
    fn default() -> Self {
        SolverOptions { max_iterations: 200 }
    }
}

/// What the solver did.
#[derive(Debug, Clone, Default)]
pub struct SolverStats {
    /// Active-set iterations (linear solves of the obstacle problem).
    pub iterations: usize,
    /// Size of the active set after each iteration.
    pub active_sizes: Vec<usize>,
    /// Number of vertices entering or leaving the active set in each iteration.
    pub changes: Vec<usize>,
    pub symbolic_seconds: f64,
    /// Seconds in numeric factorizations and in triangular solves, summed over threads.
    pub numeric_seconds: f64,
    pub solve_seconds: f64,
    /// Wall-clock seconds of the whole solve (symbolic analysis included).
    pub wall_seconds: f64,
    pub factorizations: usize,
    pub unknowns: usize,
    pub factor_nnz: usize,
}

/// The solution w of the obstacle problem, with its multiplier and contact set.
#[derive(Debug, Clone)]
pub struct Obstacle {
    /// w = u1h − u2h at every vertex.
    pub gap: Vec<f64>,
    /// λ_a = r_a / m_a at interior vertices (0 on ∂ω).
    pub multiplier: Vec<f64>,
    /// Interior vertices where the membranes touch (the final active set).
    pub contact: Vec<bool>,
    pub stats: SolverStats,
}

/// The solution (u1h, u2h) of (3.4), with the obstacle problem's w = u1h − u2h, its multiplier,
/// the contact set and the solver statistics.
#[derive(Debug, Clone)]
pub struct Solution {
    pub u1: Vec<f64>,
    pub u2: Vec<f64>,
    pub obstacle: Obstacle,
}

/// An initial guess of the gap w and the multiplier λ at every vertex, e.g. a coarser mesh's
/// solution interpolated here (nested iteration).
#[derive(Debug, Clone)]
pub struct Guess {
    pub gap: Vec<f64>,
    pub multiplier: Vec<f64>,
}

impl Guess {
    /// The gap and multiplier on `coarse`, interpolated onto `fine`.
    pub fn interpolate(fine: &Mesh, coarse: &Mesh, gap: &[f64], multiplier: &[f64]) -> Guess {
        Guess {
            gap: fine.interpolate_from(coarse, gap),
            multiplier: fine.interpolate_from(coarse, multiplier),
        }
    }
}

/// Solves (3.4): the Poisson problem for v on one thread while the obstacle problem for w runs on
/// another (they share the symbolic analysis), then u1 = v + μ2/(μ1+μ2) w, u2 = v − μ1/(μ1+μ2) w.
pub fn solve(
    problem: &DiscreteProblem,
    warm: Option<&Guess>,
    options: SolverOptions,
) -> Result<Solution, SolveError> {
    let start = Instant::now();
    let (mu1, mu2) = (problem.mu1, problem.mu2);
    let system = InteriorSystem::new(&problem.stiffness, &problem.mesh.on_boundary);
    let symbolic_seconds = start.elapsed().as_secs_f64();
    let (v, obstacle) = std::thread::scope(|scope| {
        let v = scope.spawn(|| {
            // v: (μ1+μ2) K v = F1 + F2 inside, v = μ1 g_h/(μ1+μ2) on ∂ω.
            let bc: Vec<f64> = problem.g_h.iter().map(|g| mu1 * g / (mu1 + mu2)).collect();
            let rhs = system_rhs(
                &system,
                problem,
                &|a| problem.load1[a] + problem.load2[a],
                mu1 + mu2,
                &bc,
            );
            let mut stats = SolverStats::default();
            let mut factor = system.factorization();
            factorize(&mut factor, &vec![false; system.n()], &mut stats)?;
            let x = solve_with(&mut factor, &rhs, &vec![false; system.n()], &mut stats);
            Ok::<_, SolveError>((scatter(&system, &x, &bc), stats))
        });
        let w = obstacle(problem, &system, warm, options);
        (v.join().expect("the v thread does not panic"), w)
    });
    let (v, v_stats) = v?;
    let mut obstacle = obstacle?;
    let stats = &mut obstacle.stats;
    stats.symbolic_seconds = symbolic_seconds;
    stats.numeric_seconds += v_stats.numeric_seconds;
    stats.solve_seconds += v_stats.solve_seconds;
    stats.factorizations += v_stats.factorizations;
    stats.wall_seconds = start.elapsed().as_secs_f64();
    let (c1, c2) = (mu2 / (mu1 + mu2), mu1 / (mu1 + mu2));
    let w = &obstacle.gap;
    let u1 = v.iter().zip(w).map(|(v, w)| v + c1 * w).collect();
    let u2 = v.iter().zip(w).map(|(v, w)| v - c2 * w).collect();
    Ok(Solution { u1, u2, obstacle })
}

/// Solves the obstacle problem alone: μ* K w ≥ f_w, w ≥ 0 at interior vertices, w = g_h on ∂ω,
/// with complementarity, by primal–dual active sets. With a `warm` guess the first active set is
/// {λ_a − c_a w_a > 0} of the guess; without, the method starts from no contact. This is all a
/// coarse level of nested iteration needs.
pub fn solve_obstacle(
    problem: &DiscreteProblem,
    warm: Option<&Guess>,
    options: SolverOptions,
) -> Result<Obstacle, SolveError> {
    let start = Instant::now();
    let system = InteriorSystem::new(&problem.stiffness, &problem.mesh.on_boundary);
    let symbolic_seconds = start.elapsed().as_secs_f64();
    let mut obstacle = obstacle(problem, &system, warm, options)?;
    obstacle.stats.symbolic_seconds = symbolic_seconds;
    obstacle.stats.wall_seconds = start.elapsed().as_secs_f64();
    Ok(obstacle)
}

fn obstacle(
    problem: &DiscreteProblem,
    system: &InteriorSystem,
    warm: Option<&Guess>,
    options: SolverOptions,
) -> Result<Obstacle, SolveError> {
    let (mu1, mu2) = (problem.mu1, problem.mu2);
    let mu_star = mu1 * mu2 / (mu1 + mu2);
    let k = &problem.stiffness;
    let n = system.n();
    let mut stats = SolverStats {
        unknowns: n,
        factor_nnz: system.factor_nnz(),
        ..Default::default()
    };
    let f_w = |a: usize| (mu2 * problem.load1[a] - mu1 * problem.load2[a]) / (mu1 + mu2);
    let rhs = system_rhs(system, problem, &f_w, mu_star, &problem.g_h);
    let diag: Vec<f64> = system.vertices.iter().map(|&a| k.diagonal(a)).collect();
    let mut active: Vec<bool> = match warm {
        Some(guess) => (system.vertices.iter().zip(&diag))
            .map(|(&a, d)| guess.multiplier[a] * problem.mass[a] - mu_star * d * guess.gap[a] > 0.0)
            .collect(),
        None => vec![false; n],
    };
    let mut factor = system.factorization();
    loop {
        if stats.iterations == options.max_iterations {
            return Err(SolveError::IterationCap {
                iterations: stats.iterations,
                changed: stats.changes.last().copied().unwrap_or(0),
            });
        }
        stats.iterations += 1;
        factorize(&mut factor, &active, &mut stats)?;
        let w_int = solve_with(&mut factor, &rhs, &active, &mut stats);
        let w = scatter(system, &w_int, &problem.g_h);
        // λ_a m_a = μ*(K w)_a − (f_w, φ_a); the active-set update compares λ_a with c_a w_a,
        // c_a = μ* K_aa / m_a, i.e. r_a with μ* K_aa w_a.
        let mut residual = vec![0.0; n];
        let mut changed = 0;
        let mut next = vec![false; n];
        for (i, &a) in system.vertices.iter().enumerate() {
            residual[i] = mu_star * k.row_dot(a, &w) - f_w(a);
            next[i] = residual[i] - mu_star * diag[i] * w_int[i] > 0.0;
            changed += usize::from(next[i] != active[i]);
        }
        stats.changes.push(changed);
        stats.active_sizes.push(next.iter().filter(|&&x| x).count());
        if changed == 0 {
            let nv = problem.mesh.n_vertices();
            let (mut multiplier, mut contact) = (vec![0.0; nv], vec![false; nv]);
            for (i, &a) in system.vertices.iter().enumerate() {
                multiplier[a] = residual[i] / problem.mass[a];
                contact[a] = active[i];
            }
            return Ok(Obstacle {
                gap: w,
                multiplier,
                contact,
                stats,
            });
        }
        active = next;
    }
}

fn factorize(factor: &mut Factorization, held: &[bool], stats: &mut SolverStats) -> Result<(), SolveError> {
    let t = Instant::now();
    if factor
        .factorize(held)
        .map_err(|_| SolveError::NotPositiveDefinite)?
    {
        stats.factorizations += 1;
    }
    stats.numeric_seconds += t.elapsed().as_secs_f64();
    Ok(())
}

/// Solves with the held unknowns fixed at 0.
fn solve_with(factor: &mut Factorization, b: &[f64], held: &[bool], stats: &mut SolverStats) -> Vec<f64> {
    let t = Instant::now();
    let mut x: Vec<f64> = b
        .iter()
        .zip(held)
        .map(|(b, h)| if *h { 0.0 } else { *b })
        .collect();
    factor.solve(&mut x);
    stats.solve_seconds += t.elapsed().as_secs_f64();
    x
}

/// b_I/scale − K_IB x_B in interior numbering.
fn system_rhs(
    system: &InteriorSystem,
    problem: &DiscreteProblem,
    load: &dyn Fn(usize) -> f64,
    scale: f64,
    bc: &[f64],
) -> Vec<f64> {
    let on_boundary = &problem.mesh.on_boundary;
    system
        .vertices
        .iter()
        .map(|&a| {
            let lift: f64 = problem
                .stiffness
                .row(a)
                .filter(|(b, _)| on_boundary[*b])
                .map(|(b, v)| v * bc[b])
                .sum();
            load(a) / scale - lift
        })
        .collect()
}

/// The vertex field with interior values `x` and boundary values `bc`.
fn scatter(system: &InteriorSystem, x: &[f64], bc: &[f64]) -> Vec<f64> {
    let mut u = bc.to_vec();
    for (i, &a) in system.vertices.iter().enumerate() {
        u[a] = x[i];
    }
    u
}
