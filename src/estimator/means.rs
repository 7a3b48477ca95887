//! The quadrature defect of the loads, lifted (docs/a-posteriori.md §4(c')). c_i, constant on
//! each dual cell D_a, is what the rule of degree q on T_h misses of the load on the cells of
//! S_h. Bounded by Friedrichs (§4(c)) it decays like h^½ where a load jumps across a curve off the
//! grid, while the error decays like h. Lifted, it costs one P1 Poisson solve per membrane:
//!
//! ```text
//! z_i ∈ X_0h:  (∇z_i, ∇φ_b) = (c_i, φ_b)  at every interior vertex b  (exact: c_i is piecewise constant),
//! ```
//!
//! and the patch equilibration of membrane i then takes μ_i ∇u_ih + ∇z_i for μ_i ∇u_ih and
//! f_i + c_i for f_i. The local problems stay compatible (the solve's equation at a, up to its
//! residual ρ_a m_a), the flux's divergence becomes Π f_i ± λ_h − ρ_i, and the quadrature defect
//! leaves the bound but for ρ_i, the solve's round-off, still bounded by Friedrichs.

use crate::contact;
use crate::mesh::{DualMesh, Mesh};
use crate::parallel;
use crate::problem::DiscreteProblem;

/// Σ_a |c_a| m_a below this fraction of Σ_a |(f, φ_a)| is round-off: no lift.
const ROUND_OFF: f64 = 1e-13;

/// The lifts' residual, relative to their loads' (see [`contact::with_poisson`]): what it leaves, ρ_i,
/// enters η by Friedrichs, at most this part of what the whole defect would have added (§4(c)),
/// and η agrees with a direct solve's to round-off (`make validate` compares them at 1e-9).
const LIFT_RESIDUAL: f64 = 1e-12;

/// The lifts z_i of the defects c_i and what the solves leave of them.
pub struct Lifted {
    /// z_i at every vertex (0 on ∂ω).
    pub z: Vec<Vec<f64>>,
    /// ρ_{i,a} = [(c_i, φ_a) − (∇z_i, ∇φ_a)] / m_a at the interior vertices, 0 at the boundary ones.
    pub rest: Vec<Vec<f64>>,
}

/// Lifts each of `defects` (c_i per vertex, 0 at the boundary vertices) by `solve` (of
/// [`contact::with_poisson`]); none where the defect is round-off of the loads (a load the rule
/// integrates exactly), which is then left to Friedrichs as it is.
pub fn lift(
    problem: &DiscreteProblem,
    dual: &DualMesh,
    defects: &[Vec<f64>],
    solve: &mut contact::PoissonSolve,
) -> Lifted {
    let (mesh, k) = (&problem.mesh, &problem.stiffness);
    let loads: f64 = (0..mesh.n_vertices()).map(|a| problem.load_size(a)).sum();
    let round_off = |c: &Vec<f64>| {
        let defect: f64 = c.iter().zip(&problem.mass).map(|(c, m)| (c * m).abs()).sum();
        defect <= ROUND_OFF * loads
    };
    let (z, rest) = (defects.iter())
        .map(|c| {
            let load = pairing(mesh, dual, c);
            let z = match round_off(c) {
                true => vec![0.0; mesh.n_vertices()],
                false => (solve(&load, LIFT_RESIDUAL))
                    .expect("the stiffness matrix of a valid mesh is positive definite"),
            };
            let rest = parallel::collect(mesh.n_vertices(), |a| match mesh.on_boundary[a] {
                true => 0.0,
                false => (load[a] - k.row_dot(a, &z)) / problem.mass[a],
            });
            (z, rest)
        })
        .unzip();
    Lifted { z, rest }
}

/// ∫_κ c φ_j for the three vertices j of the triangle of the cell s of S_h, c constant on each
/// dual cell: c_a |κ| φ_j(centroid of κ), a the owner of κ (φ_j is affine on κ).
pub fn on_cell(mesh: &Mesh, dual: &DualMesh, c: &[f64], s: usize) -> [f64; 3] {
    on_cells(mesh, dual, [c], s)[0]
}

/// [`on_cell`] for several fields `c` at once (the cell's geometry looked up once).
pub fn on_cells<const N: usize>(mesh: &Mesh, dual: &DualMesh, c: [&[f64]; N], s: usize) -> [[f64; 3]; N] {
    let (owner, area) = (dual.owner(s), mesh.area(s / 6));
    let phi = &PHI_AT_CENTROID[s % 6];
    c.map(|c| {
        let value = c[owner] * area / 6.0;
        phi.map(|phi| value * phi / 3.0)
    })
}

/// 3 φ_j at the centroid of cell c of a triangle (the sum of φ_j at its corners), j its vertices.
const PHI_AT_CENTROID: [[f64; 3]; 6] = {
    let mut phi = [[0.0; 3]; 6];
    let mut c = 0;
    while c < 6 {
        let frame = DualMesh::FRAMES[c];
        let mut j = 0;
        while j < 3 {
            phi[c][j] = frame[0][j] + frame[1][j] + frame[2][j];
            j += 1;
        }
        c += 1;
    }
    phi
};

/// (c, φ_b) at every vertex b: each triangle's three terms in parallel, added up in order.
fn pairing(mesh: &Mesh, dual: &DualMesh, c: &[f64]) -> Vec<f64> {
    let per_triangle = parallel::collect(mesh.n_triangles(), |t| {
        (6 * t..6 * t + 6).fold([0.0; 3], |sum, s| {
            let add = on_cell(mesh, dual, c, s);
            std::array::from_fn(|j| sum[j] + add[j])
        })
    });
    let mut load = vec![0.0; mesh.n_vertices()];
    for (tri, add) in mesh.triangles().zip(per_triangle) {
        for (b, v) in tri.into_iter().zip(add) {
            load[b] += v;
        }
    }
    load
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::{Diagonal, Edges};
    use crate::problem::Data;

    /// On a mesh of the L-shape with a defect that varies from cell to cell: the pairings of the
    /// cells of D_a sum to c_a m_a (Σ_j φ_j = 1), and the lift satisfies its equation to round-off.
    #[test]
    fn the_lift_solves_its_equation_and_the_pairing_is_exact() {
        let mesh = Mesh::rectangle([0.0, 0.0], [1.0, 2.0], 7, 5, Diagonal::Crossed).unwrap();
        let edges = Edges::new(&mesh);
        let dual = DualMesh::new(&mesh, &edges);
        let zero = || crate::expr::Expr::parse("0").unwrap();
        let quadrature = crate::assembly::Quadrature { degree: 2 };
        let data = Data::new([1.0, 1.0], zero(), zero(), zero(), quadrature).unwrap();
        let problem = DiscreteProblem::new(mesh.clone(), &data).unwrap();
        let c: Vec<f64> = (0..mesh.n_vertices())
            .map(|a| {
                if mesh.on_boundary[a] {
                    0.0
                } else {
                    ((a * 7919) % 13) as f64 - 6.0
                }
            })
            .collect();
        let mut per_cell = vec![0.0; mesh.n_vertices()];
        for s in 0..dual.n_cells() {
            per_cell[dual.owner(s)] += on_cell(&mesh, &dual, &c, s).iter().sum::<f64>();
        }
        for a in 0..mesh.n_vertices() {
            assert!((per_cell[a] - c[a] * problem.mass[a]).abs() < 1e-15, "vertex {a}");
        }
        let lifted = contact::with_poisson(&problem, &[], |solve| {
            lift(&problem, &dual, std::slice::from_ref(&c), solve)
        });
        assert!(lifted.z[0].iter().any(|z| z.abs() > 1e-3));
        assert!(
            lifted.rest[0].iter().all(|r| r.abs() < 1e-11),
            "{:?}",
            lifted.rest[0]
        );
    }
}
