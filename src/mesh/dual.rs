//! The dual submesh S_h of Section 4.2: each triangle K of T_h cut into six by its medians. The
//! two sub-triangles at a vertex a of K form D_a ∩ K, so the barycentric dual cells D_a are unions
//! of cells of S_h, meas(D_a) = ∫φ_a (Remark 11), and a field constant on each D_a (such as λ_h) is
//! cell data here. The flux t_ih (4.13) lives on S_h too.
//!
//! S_h is never stored: its points, cells and owners are computed on demand from T_h and its edge
//! numbering ([`Edges`], 28 bytes per vertex of T_h), so that a mesh of millions of vertices costs
//! no 6n points and 12n cells.

use super::Mesh;

/// The edges of T_h, numbered as S_h numbers their midpoints: in the lexicographic order of their
/// endpoints (a, b), a < b.
#[derive(Debug, Clone)]
pub struct Edges {
    /// The endpoints (a, b), a < b, of each edge.
    ends: Vec<[u32; 2]>,
    /// `first[a]..first[a + 1]`: the edges (a, b), a < b, of each vertex a.
    first: Vec<u32>,
}

impl Edges {
    /// The edges of `mesh`, in O(n): the edges (a, b), a < b, grouped by a, each group sorted
    /// (a vertex has a few neighbours) and deduplicated.
    pub fn new(mesh: &Mesh) -> Self {
        let n = mesh.n_vertices();
        let index = |v: usize| u32::try_from(v).expect("fewer than 2³² edges and vertices");
        let (start, mut larger) = super::by_smaller_vertex(n, mesh.triangles(), |_, b| index(b));
        for a in 0..n {
            larger[start[a]..start[a + 1]].sort_unstable();
        }
        let neighbours = |a: usize| (larger[start[a]..start[a + 1]].chunk_by(|x, y| x == y)).map(|b| b[0]);
        let mut first = Vec::with_capacity(n + 1);
        first.push(0);
        for a in 0..n {
            first.push(first[a] + index(neighbours(a).count()));
        }
        let mut ends = Vec::with_capacity(first[n] as usize);
        ends.extend((0..n).flat_map(|a| neighbours(a).map(move |b| [index(a), b])));
        Edges { ends, first }
    }

    /// The number of edges.
    pub fn count(&self) -> usize {
        self.ends.len()
    }

    /// The endpoints (a, b), a < b, of edge e.
    pub fn ends(&self, e: usize) -> [usize; 2] {
        self.ends[e].map(|v| v as usize)
    }

    /// The edge joining the vertices a and b (a binary search among the few edges of a vertex).
    pub fn between(&self, a: usize, b: usize) -> usize {
        let (a, b) = (a.min(b) as u32, a.max(b) as u32);
        let [first, end] = [a, a + 1].map(|v| self.first[v as usize] as usize);
        let group = &self.ends[first..end];
        first + (group.binary_search_by_key(&b, |e| e[1])).expect("an edge of the mesh")
    }
}

/// The submesh S_h of a mesh T_h, computed on demand. Its points are the vertices of T_h, then the
/// edge midpoints (in the order of [`Edges`]), then the barycentres (in the order of the
/// triangles); its cells are six counter-clockwise cells per triangle K, the two of each vertex a
/// of K in a row (cell 6t + 2k is [v_k, m_{k,k+1}, g], cell 6t + 2k + 1 is [v_k, g, m_{k+2,k}]; see
/// [`DualMesh::frame`]), so the two cells at a form D_a ∩ K and a field constant on each D_a is
/// cell data here.
#[derive(Debug, Clone, Copy)]
pub struct DualMesh<'a> {
    mesh: &'a Mesh,
    edges: &'a Edges,
}

impl<'a> DualMesh<'a> {
    /// S_h of `mesh`, whose edges are `edges`.
    pub fn new(mesh: &'a Mesh, edges: &'a Edges) -> Self {
        assert_eq!(edges.first.len(), mesh.n_vertices() + 1, "the edges of this mesh");
        DualMesh { mesh, edges }
    }

    /// T_h.
    pub fn mesh(&self) -> &'a Mesh {
        self.mesh
    }

    /// The edges of T_h.
    pub fn edges(&self) -> &'a Edges {
        self.edges
    }

    /// The number of points: vertices, edges and triangles of T_h.
    pub fn n_points(&self) -> usize {
        self.mesh.n_vertices() + self.edges.count() + self.mesh.n_triangles()
    }

    /// The number of cells: six per triangle of T_h.
    pub fn n_cells(&self) -> usize {
        6 * self.mesh.n_triangles()
    }

    /// Point p: a vertex of T_h, an edge midpoint or a barycentre.
    pub fn point(&self, p: usize) -> [f64; 2] {
        let (n, e) = (self.mesh.n_vertices(), self.edges.count());
        if p < n {
            self.mesh.points[p]
        } else if p < n + e {
            let [a, b] = self.edges.ends(p - n);
            midpoint(self.mesh.points[a], self.mesh.points[b])
        } else {
            barycentre(self.mesh.corners(p - n - e))
        }
    }

    /// The points of cell s, counter-clockwise.
    pub fn cell(&self, s: usize) -> [usize; 3] {
        let (t, k) = (s / 6, (s % 6) / 2);
        let n = self.mesh.n_vertices();
        let tri = self.mesh.triangle(t);
        let centre = n + self.edges.count() + t;
        if s.is_multiple_of(2) {
            [tri[k], n + self.edges.between(tri[k], tri[(k + 1) % 3]), centre]
        } else {
            [tri[k], centre, n + self.edges.between(tri[(k + 2) % 3], tri[k])]
        }
    }

    /// The corners of cell s (the points of [`DualMesh::cell`], from its triangle alone).
    pub fn corners(&self, s: usize) -> [[f64; 2]; 3] {
        cell_corners(self.mesh.corners(s / 6), s % 6)
    }

    /// The corners of the six cells 6t … 6t + 5 of the triangle t, from one reading of its
    /// corners (the same points as [`DualMesh::corners`]).
    pub fn cells_of(&self, t: usize) -> [[[f64; 2]; 3]; 6] {
        let v = self.mesh.corners(t);
        std::array::from_fn(|c| cell_corners(v, c))
    }

    /// The vertex a of T_h whose cell D_a contains cell s.
    pub fn owner(&self, s: usize) -> usize {
        self.mesh.triangle(s / 6)[(s % 6) / 2]
    }

    /// The barycentric coordinates, in its triangle K, of the corners of cell s of S_h: cell 2k is
    /// [v_k, m_{k,k+1}, g], cell 2k + 1 is [v_k, g, m_{k+2,k}].
    pub fn frame(s: usize) -> [[f64; 3]; 3] {
        Self::FRAMES[s % 6]
    }

    /// [`DualMesh::frame`] of the six cells of a triangle.
    pub const FRAMES: [[[f64; 3]; 3]; 6] = {
        let mut frames = [[[0.0; 3]; 3]; 6];
        let centre = [1.0 / 3.0; 3];
        let mut c = 0;
        while c < 6 {
            let k = c / 2;
            let (mut vertex, mut mid) = ([0.0; 3], [0.0; 3]);
            vertex[k] = 1.0;
            mid[k] = 0.5;
            if c % 2 == 0 {
                mid[(k + 1) % 3] = 0.5;
                frames[c] = [vertex, mid, centre];
            } else {
                mid[(k + 2) % 3] = 0.5;
                frames[c] = [vertex, centre, mid];
            }
            c += 1;
        }
        frames
    };
}

/// The corners of cell c (0 … 5) of the triangle with corners `v`: cell 2k is [v_k, m_{k,k+1}, g],
/// cell 2k + 1 is [v_k, g, m_{k+2,k}].
fn cell_corners(v: [[f64; 2]; 3], c: usize) -> [[f64; 2]; 3] {
    let k = c / 2;
    let centre = barycentre(v);
    if c.is_multiple_of(2) {
        [v[k], midpoint(v[k], v[(k + 1) % 3]), centre]
    } else {
        [v[k], centre, midpoint(v[(k + 2) % 3], v[k])]
    }
}

/// The midpoint of pq (the same bits for qp: floating-point addition commutes).
pub(crate) fn midpoint(p: [f64; 2], q: [f64; 2]) -> [f64; 2] {
    [0.5 * (p[0] + q[0]), 0.5 * (p[1] + q[1])]
}

/// The barycentre of a triangle.
pub(crate) fn barycentre([p, q, r]: [[f64; 2]; 3]) -> [f64; 2] {
    [(p[0] + q[0] + r[0]) / 3.0, (p[1] + q[1] + r[1]) / 3.0]
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::{orient, Diagonal};

    #[test]
    fn dual_cells_have_the_lumped_masses() {
        let mesh = Mesh::rectangle([0.0, 0.0], [1.0, 2.0], 3, 5, Diagonal::Right).unwrap();
        let edges = Edges::new(&mesh);
        let dual = DualMesh::new(&mesh, &edges);
        assert_eq!(dual.n_cells(), 6 * mesh.n_triangles());
        let mass = crate::assembly::lumped_mass(&mesh);
        let mut area = vec![0.0; mesh.n_vertices()];
        for s in 0..dual.n_cells() {
            let [p, q, r] = dual.cell(s).map(|v| dual.point(v));
            let a = 0.5 * orient(p, q, r);
            assert!(a > 0.0, "sub-triangles are counter-clockwise");
            area[dual.owner(s)] += a;
        }
        for (a, m) in area.iter().zip(mass) {
            assert!((a - m).abs() < 1e-15);
        }
    }

    #[test]
    fn the_frame_gives_each_cell_corner_in_its_triangle() {
        let mesh = Mesh::rectangle([0.0, 0.0], [1.0, 2.0], 3, 2, Diagonal::Crossed).unwrap();
        let edges = Edges::new(&mesh);
        let dual = DualMesh::new(&mesh, &edges);
        for s in 0..dual.n_cells() {
            let k = mesh.corners(s / 6);
            for (c, b) in DualMesh::frame(s).iter().enumerate() {
                let x = [0, 1].map(|i| (0..3).map(|j| b[j] * k[j][i]).sum::<f64>());
                let p = dual.point(dual.cell(s)[c]);
                assert!(
                    (x[0] - p[0]).abs() + (x[1] - p[1]).abs() < 1e-15,
                    "cell {s}, corner {c}"
                );
            }
        }
    }

    /// S_h built explicitly, as it was once stored: the points, cells and owners it must give.
    fn explicit(mesh: &Mesh) -> (Vec<[f64; 2]>, Vec<[usize; 3]>, Vec<usize>) {
        let edges = mesh.edges();
        let n = mesh.n_vertices();
        let mut points = mesh.points.clone();
        points.extend(edges.iter().map(|&(a, b)| {
            let (p, q) = (mesh.points[a], mesh.points[b]);
            [0.5 * (p[0] + q[0]), 0.5 * (p[1] + q[1])]
        }));
        let midpoint = |a: usize, b: usize| n + edges.binary_search(&(a.min(b), a.max(b))).unwrap();
        let (mut triangles, mut owner) = (Vec::new(), Vec::new());
        for (t, tri) in mesh.triangles().enumerate() {
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
        (points, triangles, owner)
    }

    #[test]
    fn the_lazy_submesh_is_the_explicit_one_bit_for_bit() {
        let square = Mesh::rectangle([0.0, 0.0], [1.0, 2.0], 4, 3, Diagonal::Crossed).unwrap();
        let disk = crate::case::Case::read(std::path::Path::new("data/cases/disk_contact.toml"))
            .unwrap()
            .mesh()
            .unwrap();
        for mesh in [square, disk] {
            let edges = Edges::new(&mesh);
            let dual = DualMesh::new(&mesh, &edges);
            let (points, cells, owners) = explicit(&mesh);
            assert_eq!(dual.n_points(), points.len());
            assert_eq!(dual.n_cells(), cells.len());
            for (p, x) in points.iter().enumerate() {
                assert_eq!(dual.point(p).map(f64::to_bits), x.map(f64::to_bits), "point {p}");
            }
            for (s, (cell, &a)) in cells.iter().zip(&owners).enumerate() {
                assert_eq!((dual.cell(s), dual.owner(s)), (*cell, a), "cell {s}");
                let corners = cell.map(|v| points[v].map(f64::to_bits));
                assert_eq!(dual.corners(s).map(|x| x.map(f64::to_bits)), corners, "cell {s}");
            }
        }
    }
}
