//! The H(div)-conforming flux reconstruction t_ih of Section 4.2: lowest-order Raviart–Thomas on
//! the submesh S_h (4.12), with the normal flux (4.13) t_ih·n = −μ_i ∂_n u_ih|_K on the edges of S_h
//! inside a triangle K. On the halves of the edges of T_h, which (4.13) leaves free, t_ih·n is the
//! mean of −μ_i ∂_n u_ih over the two triangles sharing the edge (one triangle's on ∂ω), so that
//! the normal flux is single-valued and t_ih ∈ H(div).
//!
//! The edges of S_h inside D_a carry ∇u_ih of one triangle from both sides, and ∂D_a is made of
//! them, so ∫_{D_a} div t_ih = −μ_i ∫_{∂D_a} ∂_n u_ih = μ_i ∫∇u_ih·∇φ_a (4.18). By (4.5) this is the
//! local conservation behind Lemma 17:
//!   ∫_{D_a} div t_1h = (f1, φ_a) + λ_a meas(D_a),   ∫_{D_a} div t_2h = (f2, φ_a) − λ_a meas(D_a).

use crate::action::Action;
use crate::assembly::gradients;
use crate::contact::Solution;
use crate::mesh::{orient, DualMesh, Mesh};
use crate::problem::{DiscreteProblem, Which};
use crate::result::{Attribute, Describe, Field, Place};

/// t_ih on S_h by its degrees of freedom.
#[derive(Debug, Clone)]
pub struct Flux {
    /// ∫_e t_ih·n over the edges of each cell of S_h, n outward; edge k runs from the cell's
    /// vertex k to vertex k + 1.
    pub edge_flux: Vec<[f64; 3]>,
}

impl Flux {
    /// t_ih for the P1 field `u` with tension `mu` (`dual` = S_h of `mesh`).
    pub fn reconstruct(mesh: &Mesh, dual: &DualMesh, u: &[f64], mu: f64) -> Flux {
        // −μ ∇u_h on each triangle, and the mean over the triangles sharing each edge of T_h.
        let flux: Vec<[f64; 2]> = (0..mesh.n_triangles())
            .map(|t| {
                let g = gradients(mesh.corners(t));
                let tri = mesh.triangle(t);
                [0, 1].map(|k| -mu * (0..3).map(|i| g[i][k] * u[tri[i]]).sum::<f64>())
            })
            .collect();
        let edges = dual.edges();
        let edge = |t: usize, k: usize| edges.between(mesh.triangle(t)[k], mesh.triangle(t)[(k + 1) % 3]);
        let (mut sum, mut count) = (vec![[0.0; 2]; edges.count()], vec![0.0; edges.count()]);
        for (t, f) in flux.iter().enumerate() {
            for k in 0..3 {
                let e = edge(t, k);
                sum[e] = [sum[e][0] + f[0], sum[e][1] + f[1]];
                count[e] += 1.0;
            }
        }
        let mean = |t: usize, k: usize| {
            let e = edge(t, k);
            [sum[e][0] / count[e], sum[e][1] / count[e]]
        };
        // S_h lists six cells per triangle: [a, m_ab, c] then [a, c, m_ca] for each vertex a of K
        // (see DualMesh); the half of ∂K is edge 0 of the first and edge 2 of the second.
        let edge_flux = (0..dual.n_cells())
            .map(|s| {
                let (t, k) = (s / 6, (s % 6) / 2);
                let half = if s % 2 == 0 {
                    (0, mean(t, k))
                } else {
                    (2, mean(t, (k + 2) % 3))
                };
                let p = dual.corners(s);
                [0, 1, 2].map(|j| {
                    let q = if j == half.0 { half.1 } else { flux[t] };
                    let (a, b) = (p[j], p[(j + 1) % 3]);
                    // The outward normal of a counter-clockwise cell, times the edge length.
                    q[0] * (b[1] - a[1]) - q[1] * (b[0] - a[0])
                })
            })
            .collect();
        Flux { edge_flux }
    }

    /// div t_ih on each cell of S_h (a constant): Σ_k F_k / |κ|.
    pub fn divergence(&self, dual: &DualMesh) -> Vec<f64> {
        (self.edge_flux.iter().enumerate())
            .map(|(s, f)| {
                let p = dual.corners(s);
                (f[0] + f[1] + f[2]) / (0.5 * orient(p[0], p[1], p[2]))
            })
            .collect()
    }

    /// t_ih at the centroid of each cell of S_h: Σ_k F_k ψ_k with ψ_k(x) = (x − p_{k+2})/(2|κ|),
    /// the basis function of edge k (unit flux through it, none through the others).
    pub fn at_centroids(&self, dual: &DualMesh) -> Vec<[f64; 2]> {
        (self.edge_flux.iter().enumerate())
            .map(|(s, f)| {
                let p = dual.corners(s);
                let c = [0, 1].map(|i| (p[0][i] + p[1][i] + p[2][i]) / 3.0);
                let two_area = orient(p[0], p[1], p[2]);
                [0, 1].map(|i| (0..3).map(|k| f[k] * (c[i] - p[(k + 2) % 3][i]) / two_area).sum())
            })
            .collect()
    }

    /// ∫_{D_a} div t_ih at every vertex a.
    pub fn over_dual_cells(&self, mesh: &Mesh, dual: &DualMesh) -> Vec<f64> {
        let mut total = vec![0.0; mesh.n_vertices()];
        for (s, f) in self.edge_flux.iter().enumerate() {
            total[dual.owner(s)] += f[0] + f[1] + f[2];
        }
        total
    }
}

/// The fluxes of the membranes (t_1h and t_2h, or t_h above a rigid obstacle), with the relative
/// defects of their local conservation (Lemma 17).
#[derive(Debug, Clone)]
pub struct Fluxes {
    /// t_ih, one per membrane of [`DiscreteProblem::membranes`].
    pub t: Vec<Flux>,
    /// max_a |∫_{D_a} div t_ih − (f_i, φ_a) ∓ λ_a m_a| over the interior vertices, relative to the
    /// largest size s_a of the terms of (4.5) at a vertex (see `Checks::prop12`).
    pub conservation: Vec<f64>,
    /// Which membrane each flux is of.
    which: Vec<Which>,
}

impl Fluxes {
    /// Reconstructs t_ih (4.13) on S_h and checks its local conservation at every interior vertex:
    /// ∫_{D_a} div t_1h = (f1, φ_a) + λ_a m_a and ∫_{D_a} div t_2h = (f2, φ_a) − λ_a m_a
    /// (Lemma 17; above an obstacle the first alone, with f), relative to the largest term summed.
    pub fn reconstruct(
        problem: &DiscreteProblem,
        dual: &DualMesh,
        solution: &Solution,
        action: &Action,
    ) -> Fluxes {
        let mesh = &problem.mesh;
        let membranes = problem.membranes([&solution.u1, &solution.u2]);
        // The terms of μ_i ∫∇u_ih·∇φ_a cancel down to O(h²): round-off is relative to them, and
        // λ_a's to those of both membranes (it is computed from membrane 1, Prop. 12), so each
        // defect is relative to the largest s_a of `Checks::prop12` — also when one membrane's
        // own terms vanish (u2 ≡ 0 without contact).
        let scale = (0..mesh.n_vertices())
            .filter(|&a| !mesh.on_boundary[a])
            .map(|a| {
                let terms: f64 = (problem.stiffness.row(a))
                    .map(|(b, k)| membranes.iter().map(|m| (m.mu * k * m.u[b]).abs()).sum::<f64>())
                    .sum();
                terms + problem.load_size(a)
            })
            .fold(f64::MIN_POSITIVE, f64::max);
        let (t, conservation) = (membranes.iter())
            .map(|m| {
                let flux = Flux::reconstruct(mesh, dual, m.u, m.mu);
                let total = flux.over_dual_cells(mesh, dual);
                let defect = (0..mesh.n_vertices())
                    .filter(|&a| !mesh.on_boundary[a])
                    .map(|a| (total[a] - m.load[a] - m.sign * action.lambda[a] * problem.mass[a]).abs())
                    .fold(0.0_f64, f64::max);
                (flux, defect / scale)
            })
            .unzip();
        Fluxes {
            t,
            conservation,
            which: membranes.iter().map(|m| m.which).collect(),
        }
    }

    /// Writes t_ih at the centroids of the cells of S_h and div t_ih as cell data (`t1_x`,
    /// `t1_y`, `div_t1`, …; `t_x`, `t_y`, `div_t` above an obstacle).
    pub fn fields(&self, dual: &DualMesh) -> Vec<Field<'static>> {
        (self.t.iter().zip(&self.which))
            .flat_map(|(flux, which)| {
                let t = flux.at_centroids(dual);
                let name = |names| which.named(names);
                [
                    Field::owned(
                        name(["t1_x", "t2_x", "t_x"]),
                        Place::DualCells,
                        t.iter().map(|v| v[0]).collect(),
                    ),
                    Field::owned(
                        name(["t1_y", "t2_y", "t_y"]),
                        Place::DualCells,
                        t.iter().map(|v| v[1]).collect(),
                    ),
                    Field::owned(
                        name(["div_t1", "div_t2", "div_t"]),
                        Place::DualCells,
                        flux.divergence(dual),
                    ),
                ]
            })
            .collect()
    }

    /// The summary's line: the local conservation of each flux.
    pub fn summary(&self) -> String {
        let names: Vec<&str> = self.which.iter().map(|w| w.named(["t1h", "t2h", "th"])).collect();
        let defects: Vec<String> = self.conservation.iter().map(|d| format!("{d:.2e}")).collect();
        format!(
            "flux        {} on the dual submesh; their local conservation on the dual cells: relative defect {}\n",
            names.join(", "),
            defects.join(", ")
        )
    }
}

impl Describe for Fluxes {
    fn attributes(&self) -> Vec<Attribute> {
        (self.which.iter().zip(&self.conservation))
            .map(|(w, &d)| {
                let name = w.named(["flux_conservation_1", "flux_conservation_2", "flux_conservation"]);
                (name, d.into())
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::assembly::Stiffness;
    use crate::mesh::{Diagonal, Edges};
    use std::collections::HashMap;

    fn setting() -> (Mesh, Edges, Vec<f64>) {
        let mesh = Mesh::rectangle([0.0, 0.0], [1.0, 2.0], 5, 7, Diagonal::Crossed).unwrap();
        let edges = Edges::new(&mesh);
        let u = mesh
            .points
            .iter()
            .map(|p| (3.0 * p[0]).sin() + p[0] * p[1] * p[1])
            .collect();
        (mesh, edges, u)
    }

    #[test]
    fn the_normal_flux_is_single_valued() {
        let (mesh, edges, u) = setting();
        let dual = DualMesh::new(&mesh, &edges);
        let flux = Flux::reconstruct(&mesh, &dual, &u, 1.5);
        let mut seen: HashMap<(usize, usize), f64> = HashMap::new();
        let mut interior = 0;
        for (s, f) in flux.edge_flux.iter().enumerate() {
            let cell = dual.cell(s);
            for k in 0..3 {
                let (a, b) = (cell[k], cell[(k + 1) % 3]);
                if let Some(other) = seen.remove(&(b, a)) {
                    assert!((other + f[k]).abs() < 1e-14, "edge {a}–{b}: {other} vs {}", f[k]);
                    interior += 1;
                } else {
                    seen.insert((a, b), f[k]);
                }
            }
        }
        assert!(interior > 9 * mesh.n_triangles() - mesh.n_vertices());
    }

    #[test]
    fn a_linear_field_gives_its_exact_flux() {
        let mesh = Mesh::rectangle([0.0, 0.0], [1.0, 1.0], 4, 3, Diagonal::Left).unwrap();
        let edges = Edges::new(&mesh);
        let dual = DualMesh::new(&mesh, &edges);
        let u: Vec<f64> = mesh
            .points
            .iter()
            .map(|p| 1.0 + 2.0 * p[0] - 3.0 * p[1])
            .collect();
        let flux = Flux::reconstruct(&mesh, &dual, &u, 2.0);
        for t in flux.at_centroids(&dual) {
            assert!((t[0] + 4.0).abs() < 1e-12 && (t[1] - 6.0).abs() < 1e-12, "{t:?}");
        }
        assert!(flux.divergence(&dual).iter().all(|d| d.abs() < 1e-11));
    }

    #[test]
    fn divergence_over_a_dual_cell_is_the_stiffness_row() {
        // ∫_{D_a} div t_h = μ ∫∇u_h·∇φ_a (4.18) at every interior vertex.
        let (mesh, edges, u) = setting();
        let dual = DualMesh::new(&mesh, &edges);
        let flux = Flux::reconstruct(&mesh, &dual, &u, 1.5);
        let k = Stiffness::assemble(&mesh);
        let total = flux.over_dual_cells(&mesh, &dual);
        for a in (0..mesh.n_vertices()).filter(|&a| !mesh.on_boundary[a]) {
            let expected = 1.5 * k.row_dot(a, &u);
            assert!(
                (total[a] - expected).abs() < 1e-12,
                "vertex {a}: {} vs {expected}",
                total[a]
            );
        }
    }
}
