//! P1 transfer between two meshes of the same domain: interpolation from a coarse mesh onto a
//! fine one, and its transpose, which restricts nodal loads.

use super::{max2, min2, orient, Buckets, Mesh, Stars};
use crate::sparse::Csr;
use std::sync::OnceLock;

/// P1 interpolation from a coarse mesh onto the vertices of a fine one: each fine vertex is
/// located in the coarse mesh (or, outside it, at the nearest triangle) with its barycentric
/// coordinates, the rows of a sparse matrix P (fine vertices × coarse vertices; weights that are
/// zero but for round-off left out). Its transpose restricts nodal loads: Pᵀ(f, φ_a)_a =
/// (f, φ_A)_A exactly when the meshes are nested, since then every coarse hat function is a
/// combination of fine ones. Multigrid interpolates its corrections with the same P.
#[derive(Debug, Clone)]
pub struct Prolongation {
    matrix: Csr,
    /// Pᵀ, made when first asked for (multigrid's restriction and Galerkin products).
    transposed: OnceLock<Csr>,
}

/// Barycentric weights below this are left out of P (round-off of coordinates that are 0 on
/// nested meshes).
const WEIGHT_EPS: f64 = 1e-12;

impl Prolongation {
    /// The interpolation from `coarse` onto the vertices of `fine`.
    pub fn new(fine: &Mesh, coarse: &Mesh) -> Self {
        let locator = Locator::new(coarse);
        // The fine vertices in pieces, in parallel; consecutive vertices are mostly near each
        // other, so the last one's triangle is tried first.
        let matrix = Csr::by_rows(
            fine.n_vertices(),
            coarse.n_vertices(),
            3,
            |range, (ends, col, val)| {
                let mut hint = 0;
                for &p in &fine.points[range] {
                    let (t, bary) = locator.locate(p, hint);
                    hint = t;
                    let mut row = [0, 1, 2].map(|k| (coarse.triangle(t)[k], bary[k]));
                    row.sort_unstable_by_key(|e| e.0);
                    for (j, w) in row.into_iter().filter(|e| e.1.abs() > WEIGHT_EPS) {
                        col.push(j as u32);
                        val.push(w);
                    }
                    ends.push(col.len() as u32);
                }
            },
        );
        Prolongation {
            matrix,
            transposed: OnceLock::new(),
        }
    }

    /// P.
    pub fn matrix(&self) -> &Csr {
        &self.matrix
    }

    /// Pᵀ, made once.
    pub fn transposed(&self) -> &Csr {
        self.transposed.get_or_init(|| self.matrix.transpose())
    }

    /// The number of coarse vertices (the columns of P).
    pub fn coarse_vertices(&self) -> usize {
        self.matrix.cols()
    }

    /// The fine P1 interpolant of the coarse P1 field `values`.
    pub fn apply(&self, values: &[f64]) -> Vec<f64> {
        (0..self.matrix.rows())
            .map(|a| self.matrix.row_dot(a, values))
            .collect()
    }

    /// Pᵀ `fine`: a fine nodal load restricted to the coarse vertices.
    pub fn restrict(&self, fine: &[f64]) -> Vec<f64> {
        let mut coarse = vec![0.0; self.coarse_vertices()];
        for (a, f) in fine.iter().enumerate() {
            let (cols, weights) = self.matrix.row(a);
            for (&b, &w) in cols.iter().zip(weights) {
                coarse[b as usize] += w * f;
            }
        }
        coarse
    }
}

/// Point location in a mesh: the triangle containing a point and its barycentric coordinates.
/// Tried in turn: the triangle of the previous point and those around its corners, the nearest
/// corner first (consecutive vertices are mostly near each other), the triangles around the
/// nearest vertex (on nested meshes every finer vertex is a vertex or an edge midpoint of this
/// mesh, so this finds it), and the triangles whose bounding boxes hold the point (their buckets
/// built at the first point that needs them).
struct Locator<'m> {
    mesh: &'m Mesh,
    vertices: Buckets,
    stars: Stars,
    boxes: OnceLock<Buckets>,
}

impl<'m> Locator<'m> {
    fn new(mesh: &'m Mesh) -> Self {
        let (vertices, stars) = crate::parallel::join(
            || Buckets::new(mesh.points.iter().copied(), mesh.n_vertices()),
            || Stars::new(mesh),
        );
        Locator {
            mesh,
            vertices,
            stars,
            boxes: OnceLock::new(),
        }
    }

    /// The triangle that holds p (the triangle `hint` if it does), with p's barycentric
    /// coordinates there; outside every triangle (a point of a finer curved boundary), the
    /// nearest miss clamped.
    fn locate(&self, p: [f64; 2], hint: usize) -> (usize, [f64; 3]) {
        let mesh = self.mesh;
        let mut best = (0, [1.0, 0.0, 0.0], f64::NEG_INFINITY);
        // Whether t holds p (then it is the answer), keeping the nearest miss in `best`.
        let mut holds = |t: usize| {
            let b = barycentric(mesh.corners(t), p);
            let worst = b[0].min(b[1]).min(b[2]);
            if worst > best.2 {
                best = (t, b, worst);
            }
            worst >= -1e-12
        };
        let distance = |a: &usize| {
            let q = mesh.points[*a];
            (q[0] - p[0]).powi(2) + (q[1] - p[1]).powi(2)
        };
        let found = (hint < mesh.n_triangles()
            && (holds(hint) || {
                // The stars of the hint's corners, the nearest corner's first.
                let mut corners = mesh.triangle(hint);
                corners.sort_unstable_by(|a, b| distance(a).total_cmp(&distance(b)));
                corners
                    .into_iter()
                    .any(|a| self.stars.around(a).any(|(t, _)| holds(t)))
            }))
            || (self.vertices.around(p))
                .min_by(|a, b| distance(a).total_cmp(&distance(b)))
                .is_some_and(|a| self.stars.around(a).any(|(t, _)| holds(t)))
            || {
                let boxes = self.boxes.get_or_init(|| {
                    let boxes = (0..mesh.n_triangles()).map(|t| {
                        let [p, q, r] = mesh.corners(t);
                        (min2(min2(p, q), r), max2(max2(p, q), r))
                    });
                    Buckets::from_boxes(boxes, mesh.n_triangles())
                });
                let mut candidates = boxes.near_box(p, p).peekable();
                if candidates.peek().is_some() {
                    candidates.any(&mut holds)
                } else {
                    (0..mesh.n_triangles()).any(&mut holds)
                }
            };
        if found {
            return (best.0, best.1);
        }
        let b = best.1.map(|v| v.max(0.0));
        let s: f64 = b.iter().sum();
        (best.0, b.map(|v| v / s))
    }
}

fn barycentric([p, q, r]: [[f64; 2]; 3], x: [f64; 2]) -> [f64; 3] {
    let area = orient(p, q, r);
    let l1 = orient(x, q, r) / area;
    let l2 = orient(p, x, r) / area;
    [l1, l2, 1.0 - l1 - l2]
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::mesh::Diagonal;

    #[test]
    fn interpolation_reproduces_linear_fields() {
        let coarse = Mesh::rectangle([0.0, 0.0], [1.0, 1.0], 3, 3, Diagonal::Left).unwrap();
        let fine = Mesh::rectangle([0.0, 0.0], [1.0, 1.0], 7, 5, Diagonal::Crossed).unwrap();
        let f = |p: [f64; 2]| 2.0 * p[0] - 3.0 * p[1] + 1.0;
        let v: Vec<f64> = coarse.points.iter().map(|&p| f(p)).collect();
        let p = Prolongation::new(&fine, &coarse);
        let w = p.apply(&v);
        for (p, w) in fine.points.iter().zip(w) {
            assert!((w - f(*p)).abs() < 1e-12);
        }
    }

    #[test]
    fn nested_vertices_are_found_without_the_box_search() {
        // Every vertex of the finer mesh is a vertex or an edge midpoint of the coarser one: the
        // star of the nearest vertex (with no hint) or of the hint's corners holds it.
        let coarse = Mesh::rectangle([0.0, 0.0], [1.0, 2.0], 5, 3, Diagonal::Right).unwrap();
        let fine = Mesh::rectangle([0.0, 0.0], [1.0, 2.0], 10, 6, Diagonal::Right).unwrap();
        let locator = Locator::new(&coarse);
        let mut hint = usize::MAX;
        for &p in &fine.points {
            for start in [usize::MAX, hint] {
                let (t, b) = locator.locate(p, start);
                assert!(b.iter().all(|&w| w >= -1e-12), "{p:?} in triangle {t}: {b:?}");
                let q = (0..2).map(|k| (0..3).map(|j| b[j] * coarse.corners(t)[j][k]).sum::<f64>());
                assert!(q.zip(p).all(|(q, p)| (q - p).abs() < 1e-14), "{p:?}");
                hint = t;
            }
        }
        assert!(locator.boxes.get().is_none(), "the bounding boxes were searched");
    }

    #[test]
    fn vertices_outside_the_coarser_mesh_are_interpolated_from_the_nearest_triangle() {
        // The refined disk's new boundary vertices lie on the circle, outside the coarser
        // polygon: their weights (clamped) are still a partition of unity, as every row's.
        let mut disk = crate::case::Case::read(std::path::Path::new("data/cases/disk_contact.toml")).unwrap();
        disk.refine = 1;
        let (fine, coarser) = disk.hierarchy(true, Default::default()).unwrap();
        let p = Prolongation::new(&fine, &coarser[0]);
        let outside = (0..fine.n_vertices())
            .filter(|&a| {
                let (_, w) = p.matrix().row(a);
                assert!((w.iter().sum::<f64>() - 1.0).abs() < 1e-12 && w.iter().all(|&w| w > 0.0));
                fine.on_boundary[a] && w.len() > 1
            })
            .count();
        assert!(outside > 10, "{outside} boundary vertices between coarse ones");
    }

    /// (f, φ_A) on `coarse` equals Pᵀ (f, φ_a) on `fine` when the meshes are nested: the
    /// degree-4 rule is exact for f φ on both.
    pub(crate) fn assert_loads_restrict_exactly(coarse: &Mesh, fine: &Mesh, f: &str) {
        let f = crate::expr::Expr::parse(f).unwrap();
        let quad = crate::assembly::Quadrature { degree: 4 };
        let direct = crate::assembly::load(coarse, &f, quad).unwrap();
        let restricted =
            Prolongation::new(fine, coarse).restrict(&crate::assembly::load(fine, &f, quad).unwrap());
        for (a, b) in direct.iter().zip(&restricted) {
            assert!((a - b).abs() < 1e-14, "{a} vs {b}");
        }
    }

    #[test]
    fn restriction_of_nested_loads_is_exact() {
        // On a rectangle and its uniform refinement, for every diagonal.
        for diagonal in [Diagonal::Right, Diagonal::Left, Diagonal::Crossed] {
            let coarse = Mesh::rectangle([0.0, 0.0], [1.0, 2.0], 3, 2, diagonal).unwrap();
            let fine = Mesh::rectangle([0.0, 0.0], [1.0, 2.0], 6, 4, diagonal).unwrap();
            assert_loads_restrict_exactly(&coarse, &fine, "x*y + 1");
        }
    }
}
