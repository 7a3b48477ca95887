//! Whether the case's rule resolves the loads (docs/a-posteriori.md §11).
//!
//! η takes the pairings (f_i, φ_a)_κ of the loads on the cells κ of S_h by the case's rule as
//! exact. Pairings off by δ_{i,a} would change the data of the patch problems as the quadrature
//! defect does, and by the lift of §4(c') change η by about
//!
//! ```text
//! η_data = (Σ_i ‖∇z_i‖² / μ_i)^½,   K z_i = δ_i at the interior vertices, z_i = 0 on ∂ω,
//! ```
//!
//! which this module estimates with δ measured against a finer rule: on each triangle K the case's
//! rule on K and on K's six cells give two values of ∫_K f_i; where they agree to `AGREE` (or to the
//! round-off of the cells' geometry, on a mesh far from the origin: `agreement`) the
//! load counts as resolved on K (δ = 0 there); elsewhere each cell is integrated again by the
//! highest rule on its four halves. An estimate, not a bound: a load whose features fall between
//! the points of every rule is not seen.

use super::TriangleLoads;
use crate::assembly::{gradients, Quadrature};
use crate::contact;
use crate::datum::{self, Pieces};
use crate::mesh::{DualMesh, Mesh};
use crate::parallel::{self, PIECE};
use crate::problem::DiscreteProblem;

/// Relative agreement of the two values of ∫_K f_i within which the load counts as resolved on K.
const AGREE: f64 = 1e-9;

/// The round-off of the cells' geometry, in units of ε max|x| / h_K (see [`agreement`]).
const GEOMETRY_ROUND_OFF: f64 = 64.0;

/// η_data up to this share of η: the loads count as resolved, and η as a bound.
pub const RESOLVED: f64 = 1e-2;

/// The residual of the lifts' solves, relative to their loads' (an estimate to a few per cent needs
/// no more).
const LIFT_RESIDUAL: f64 = 1e-3;

/// What the case's rule misses of the loads, by a finer rule where it may miss anything.
#[derive(Debug, Clone)]
pub struct Resolution {
    /// (Σ_i ‖∇z_i‖²_K / μ_i)^½ on each triangle K.
    pub indicator: Vec<f64>,
    /// η_data.
    pub total: f64,
    /// The triangles checked by the finer rule.
    pub checked: usize,
    /// The centroid of the triangle of the largest indicator, if any is above 0.
    pub worst: Option<[f64; 2]>,
}

/// δ on one triangle: for each membrane, the change of (f_i, φ_j) over its six cells, j its
/// vertices in order.
type Change = [[f64; 3]; 2];

impl Resolution {
    /// The check of the loads `f` (one per membrane, of tensions `mu`) of `problem`, whose
    /// pairings on the cells of S_h by the case's rule, summed over each triangle, are `sums` (for the
    /// vertices j of s's triangle); the lifts by `solve` (of [`contact::with_poisson`]).
    pub(super) fn check(
        (problem, dual): (&DiscreteProblem, &DualMesh),
        f: [&Pieces; 2],
        mu: &[f64],
        sums: &[TriangleLoads],
        solve: &mut contact::PoissonSolve,
    ) -> Resolution {
        let mesh = &problem.mesh;
        let changes: Vec<Option<Change>> =
            parallel::collect_by_blocks(mesh.n_triangles(), PIECE, |range, out| {
                datum::visit(
                    &problem.data.quadrature,
                    |t| mesh.corners(t),
                    |t| t,
                    range,
                    f,
                    |t, points, values| {
                        let tolerance = agreement(mesh.corners(t));
                        let agree = (0..mu.len()).all(|i| {
                            let on_k: f64 = points.iter().zip(values[i]).map(|(p, f)| p.weight * f).sum();
                            let on_cells: f64 = sums[t].f_phi[i].iter().sum();
                            (on_cells - on_k).abs() <= tolerance * sums[t].size[i]
                        });
                        out.push((!agree).then(|| finer(mesh, dual, t, f, &sums[t].f_phi)));
                    },
                )
            });
        let z = lifts(problem, solve, &changes, mu.len());
        let squares = parallel::collect(mesh.n_triangles(), |t| {
            let (g, tri, area) = (gradients(mesh.corners(t)), mesh.triangle(t), mesh.area(t));
            let grad2 = |z: &[f64]| {
                let d = [0, 1].map(|k| (0..3).map(|j| g[j][k] * z[tri[j]]).sum::<f64>());
                area * (d[0] * d[0] + d[1] * d[1])
            };
            z.iter().zip(mu).map(|(z, mu)| grad2(z) / mu).sum::<f64>()
        });
        let worst = (0..squares.len()).max_by(|&s, &t| squares[s].total_cmp(&squares[t]));
        let centroid = |t: usize| {
            let c = mesh.corners(t);
            [0, 1].map(|k| (c[0][k] + c[1][k] + c[2][k]) / 3.0)
        };
        Resolution {
            total: squares.iter().sum::<f64>().sqrt(),
            indicator: squares.iter().map(|x| x.sqrt()).collect(),
            checked: changes.iter().filter(|c| c.is_some()).count(),
            worst: worst.filter(|&t| squares[t] > 0.0).map(centroid),
        }
    }
}

/// The relative agreement the two values of ∫_K f_i can reach on the triangle of `corners`:
/// [`AGREE`], or the round-off of the cells' geometry where it is larger. The corners of the cells
/// (edge midpoints, centroid) are rounded to the absolute scale of the coordinates, ε max|x|, which
/// is ε max|x| / h_K of K's size: on a mesh far from the origin the cells' areas, and with them
/// the sum over the cells even of a constant load, differ from K's by more than [`AGREE`].
fn agreement(corners: [[f64; 2]; 3]) -> f64 {
    let scale = corners.iter().flatten().fold(0.0_f64, |m, x| m.max(x.abs()));
    let shortest = (0..3)
        .map(|e| crate::mesh::dist(corners[e], corners[(e + 1) % 3]))
        .fold(f64::INFINITY, f64::min);
    AGREE.max(GEOMETRY_ROUND_OFF * f64::EPSILON * scale / shortest)
}

/// z_i with K z_i = δ_i (the changes summed at each interior vertex), for `m` membranes; 0 where
/// nothing changed.
fn lifts(
    problem: &DiscreteProblem,
    solve: &mut contact::PoissonSolve,
    changes: &[Option<Change>],
    m: usize,
) -> Vec<Vec<f64>> {
    let mesh = &problem.mesh;
    let mut delta = vec![vec![0.0; mesh.n_vertices()]; m];
    for (t, change) in changes.iter().enumerate() {
        for (delta, change) in delta.iter_mut().zip(change.iter().flatten()) {
            for (a, c) in mesh.triangle(t).into_iter().zip(change) {
                if !mesh.on_boundary[a] {
                    delta[a] += c;
                }
            }
        }
    }
    if changes.iter().all(Option::is_none) {
        return delta;
    }
    (delta.iter())
        .map(|d| solve(d, LIFT_RESIDUAL).expect("the stiffness matrix of a valid mesh is positive definite"))
        .collect()
}

/// δ on the triangle t: (f_i, φ_j) on its six cells by the highest rule on each cell's four
/// halves, less `on_cells` (the case's rule on the cells).
fn finer(mesh: &Mesh, dual: &DualMesh, t: usize, f: [&Pieces; 2], on_cells: &Change) -> Change {
    let halves: Vec<[[f64; 2]; 3]> = (6 * t..6 * t + 6).flat_map(|s| halved(dual.corners(s))).collect();
    let (g, p0) = (gradients(mesh.corners(t)), mesh.corners(t)[0]);
    // φ_j(x) = φ_j(p0) + ∇φ_j · (x − p0).
    let phi = |x: [f64; 2]| -> [f64; 3] {
        std::array::from_fn(|j| {
            f64::from(u8::from(j == 0)) + g[j][0] * (x[0] - p0[0]) + g[j][1] * (x[1] - p0[1])
        })
    };
    let mut change: Change = [[0.0; 3]; 2];
    let rule = Quadrature {
        degree: Quadrature::MAX_DEGREE,
    };
    datum::visit(
        &rule,
        |c| halves[c],
        |_| t,
        0..halves.len(),
        f,
        |_, points, values| {
            for (change, values) in change.iter_mut().zip(values) {
                for (p, v) in points.iter().zip(values) {
                    for (c, phi) in change.iter_mut().zip(phi(p.x)) {
                        *c += p.weight * v * phi;
                    }
                }
            }
        },
    );
    for (change, on_cells) in change.iter_mut().zip(on_cells) {
        for (c, v) in change.iter_mut().zip(on_cells) {
            *c -= v;
        }
    }
    change
}

/// The four triangles of the midpoint subdivision of `p`.
fn halved(p: [[f64; 2]; 3]) -> [[[f64; 2]; 3]; 4] {
    let mid = |a: usize, b: usize| [0.5 * (p[a][0] + p[b][0]), 0.5 * (p[a][1] + p[b][1])];
    let (m01, m12, m20) = (mid(0, 1), mid(1, 2), mid(2, 0));
    [
        [p[0], m01, m20],
        [m01, p[1], m12],
        [m20, m12, p[2]],
        [m01, m12, m20],
    ]
}
