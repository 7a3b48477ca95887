//! The dual submesh S_h of Section 4.2: each triangle K of T_h cut into six by its medians. The
//! two sub-triangles at a vertex a of K form D_a ∩ K, so the barycentric dual cells D_a are unions
//! of cells of S_h, meas(D_a) = ∫φ_a (Remark 11), and a field constant on each D_a (such as λ_h) is
//! cell data here. The flux t_ih (4.13) lives on S_h too.

use super::Mesh;

/// The submesh S_h: each triangle cut into six by its medians; the two sub-triangles at vertex a
/// form D_a ∩ K, so a field constant on each D_a is cell data here.
#[derive(Debug, Clone)]
pub struct DualMesh {
    /// Vertices of T_h, then edge midpoints, then barycentres.
    pub points: Vec<[f64; 2]>,
    /// Six counter-clockwise cells per triangle of T_h, the two of each vertex a of K in a row.
    pub triangles: Vec<[usize; 3]>,
    /// The vertex a of T_h whose cell D_a contains each sub-triangle.
    pub owner: Vec<usize>,
}

impl DualMesh {
    /// S_h of `mesh`.
    pub fn new(mesh: &Mesh) -> Self {
        let edges = mesh.edges();
        let n = mesh.n_vertices();
        let mut points = mesh.points.clone();
        points.extend(edges.iter().map(|&(a, b)| {
            let (p, q) = (mesh.points[a], mesh.points[b]);
            [0.5 * (p[0] + q[0]), 0.5 * (p[1] + q[1])]
        }));
        let midpoint = |a: usize, b: usize| n + edges.binary_search(&(a.min(b), a.max(b))).unwrap();
        let mut triangles = Vec::with_capacity(6 * mesh.triangles.len());
        let mut owner = Vec::with_capacity(6 * mesh.triangles.len());
        for (t, tri) in mesh.triangles.iter().enumerate() {
            let [p, q, r] = mesh.corners(t);
            let centre = points.len();
            points.push([(p[0] + q[0] + r[0]) / 3.0, (p[1] + q[1] + r[1]) / 3.0]);
            for k in 0..3 {
                let (a, b, c) = (tri[k], tri[(k + 1) % 3], tri[(k + 2) % 3]);
                triangles.push([a, midpoint(a, b), centre]);
                triangles.push([a, centre, midpoint(c, a)]);
                owner.extend([a, a]);
            }
        }
        DualMesh {
            points,
            triangles,
            owner,
        }
    }

    /// The barycentric coordinates, in its triangle K, of the corners of cell s of S_h: cell 2k is
    /// [v_k, m_{k,k+1}, g], cell 2k + 1 is [v_k, g, m_{k+2,k}] (the order of `new`).
    pub fn frame(s: usize) -> [[f64; 3]; 3] {
        let k = (s % 6) / 2;
        let vertex = |j: usize| std::array::from_fn(|i| f64::from(u8::from(i == j)));
        let mid = |a: usize, b: usize| {
            std::array::from_fn(|i| 0.5 * f64::from(u8::from(i == a) + u8::from(i == b)))
        };
        let centre = [1.0 / 3.0; 3];
        if s.is_multiple_of(2) {
            [vertex(k), mid(k, (k + 1) % 3), centre]
        } else {
            [vertex(k), centre, mid(k, (k + 2) % 3)]
        }
    }

    /// The field Σ_a v_a χ_{D_a}, constant on each dual cell, as cell data of S_h.
    pub fn cell_field(&self, values: &[f64]) -> Vec<f64> {
        self.owner.iter().map(|&a| values[a]).collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::{orient, Diagonal};

    #[test]
    fn dual_cells_have_the_lumped_masses() {
        let mesh = Mesh::rectangle([0.0, 0.0], [1.0, 2.0], 3, 5, Diagonal::Right).unwrap();
        let dual = DualMesh::new(&mesh);
        assert_eq!(dual.triangles.len(), 6 * mesh.triangles.len());
        let mass = crate::assembly::lumped_mass(&mesh);
        let mut area = vec![0.0; mesh.n_vertices()];
        for (t, &a) in dual.triangles.iter().zip(&dual.owner) {
            let s = 0.5 * orient(dual.points[t[0]], dual.points[t[1]], dual.points[t[2]]);
            assert!(s > 0.0, "sub-triangles are counter-clockwise");
            area[a] += s;
        }
        for (a, m) in area.iter().zip(mass) {
            assert!((a - m).abs() < 1e-15);
        }
    }

    #[test]
    fn the_frame_gives_each_cell_corner_in_its_triangle() {
        let mesh = Mesh::rectangle([0.0, 0.0], [1.0, 2.0], 3, 2, Diagonal::Crossed).unwrap();
        let dual = DualMesh::new(&mesh);
        for (s, cell) in dual.triangles.iter().enumerate() {
            let k = mesh.corners(s / 6);
            for (c, b) in DualMesh::frame(s).iter().enumerate() {
                let x = [0, 1].map(|i| (0..3).map(|j| b[j] * k[j][i]).sum::<f64>());
                let p = dual.points[cell[c]];
                assert!(
                    (x[0] - p[0]).abs() + (x[1] - p[1]).abs() < 1e-15,
                    "cell {s}, corner {c}"
                );
            }
        }
    }
}
