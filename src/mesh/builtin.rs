//! Built-in meshes: the rectangle of `dolfinx.mesh.create_rectangle` and the L-shaped domain with
//! optional grading towards its re-entrant corner (Remark 10).

use super::{Mesh, MeshError};

/// Diagonal of each rectangle cell, as in `dolfinx.mesh.DiagonalType`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Deserialize, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Diagonal {
    /// From the lower left to the upper right corner.
    Right,
    /// From the lower right to the upper left corner.
    Left,
    /// Both, with a vertex at the cell centre.
    Crossed,
}

impl Mesh {
    /// The rectangle [x0, x1] × [y0, y1] with nx × ny cells, with the vertices and triangles of
    /// `dolfinx.mesh.create_rectangle` (vertex numbering row by row, crossed midpoints last).
    ///
    /// ```
    /// use membrane_contact::mesh::{Diagonal, Mesh};
    /// let mesh = Mesh::rectangle([0.0, 0.0], [2.0, 1.0], 4, 2, Diagonal::Right).unwrap();
    /// assert_eq!((mesh.n_vertices(), mesh.n_triangles()), (15, 16));
    /// ```
    pub fn rectangle(
        corner0: [f64; 2],
        corner1: [f64; 2],
        nx: usize,
        ny: usize,
        diagonal: Diagonal,
    ) -> Result<Self, MeshError> {
        let (points, triangles) = rectangle_raw(corner0, corner1, nx, ny, diagonal);
        Mesh::new(points, triangles)
    }

    /// The L-shaped domain (−1, 1)² \ [0, 1] × [−1, 0] with n × n cells on the full square (n even).
    /// With `grading` β > 1 the vertices are pulled towards the re-entrant corner (0, 0) (Remark 10):
    /// a vertex at max-norm distance r moves radially to distance r^β, so cells near the corner have
    /// size ~ h r^(1−1/β); β = 1 is the uniform mesh. The boundary is mapped onto itself.
    pub fn l_shape(n: usize, diagonal: Diagonal, grading: f64) -> Result<Self, MeshError> {
        let n = n + n % 2;
        let (mut points, triangles) = rectangle_raw([-1.0, -1.0], [1.0, 1.0], n, n, diagonal);
        let inside_cut = |p: [f64; 2]| p[0] > 1e-12 && p[1] < -1e-12;
        let kept: Vec<[usize; 3]> = triangles
            .into_iter()
            .filter(|t| {
                let c = centroid(&points, t);
                !inside_cut(c)
            })
            .collect();
        if grading != 1.0 {
            for p in points.iter_mut() {
                let r = p[0].abs().max(p[1].abs());
                if r > 0.0 {
                    let s = r.powf(grading) / r;
                    p[0] *= s;
                    p[1] *= s;
                }
            }
        }
        let (points, triangles) = compact(points, kept);
        Mesh::new(points, triangles)
    }
}

fn centroid(points: &[[f64; 2]], t: &[usize; 3]) -> [f64; 2] {
    let s = t
        .iter()
        .fold([0.0, 0.0], |s, &v| [s[0] + points[v][0], s[1] + points[v][1]]);
    [s[0] / 3.0, s[1] / 3.0]
}

/// Drops unused vertices and renumbers the rest, keeping their order.
pub(super) fn compact(points: Vec<[f64; 2]>, triangles: Vec<[usize; 3]>) -> (Vec<[f64; 2]>, Vec<[usize; 3]>) {
    let mut new_index = vec![usize::MAX; points.len()];
    for t in &triangles {
        for &v in t {
            new_index[v] = 0;
        }
    }
    let mut kept = Vec::new();
    for (v, p) in points.into_iter().enumerate() {
        if new_index[v] == 0 {
            new_index[v] = kept.len();
            kept.push(p);
        }
    }
    let triangles = triangles.into_iter().map(|t| t.map(|v| new_index[v])).collect();
    (kept, triangles)
}

fn rectangle_raw(
    c0: [f64; 2],
    c1: [f64; 2],
    nx: usize,
    ny: usize,
    diagonal: Diagonal,
) -> (Vec<[f64; 2]>, Vec<[usize; 3]>) {
    let (dx, dy) = ((c1[0] - c0[0]) / nx as f64, (c1[1] - c0[1]) / ny as f64);
    let mut points = Vec::with_capacity((nx + 1) * (ny + 1));
    for iy in 0..=ny {
        for ix in 0..=nx {
            points.push([c0[0] + dx * ix as f64, c0[1] + dy * iy as f64]);
        }
    }
    let mut triangles = Vec::with_capacity(2 * nx * ny);
    for iy in 0..ny {
        for ix in 0..nx {
            let v0 = iy * (nx + 1) + ix;
            let (v1, v2, v3) = (v0 + 1, v0 + nx + 1, v0 + nx + 2);
            match diagonal {
                Diagonal::Right => triangles.extend([[v0, v1, v3], [v0, v2, v3]]),
                Diagonal::Left => triangles.extend([[v0, v1, v2], [v1, v2, v3]]),
                Diagonal::Crossed => {
                    let vm = points.len();
                    points.push([c0[0] + dx * (ix as f64 + 0.5), c0[1] + dy * (iy as f64 + 0.5)]);
                    triangles.extend([[v0, v1, vm], [v0, v2, vm], [v1, v3, vm], [v2, v3, vm]]);
                }
            }
        }
    }
    (points, triangles)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rectangle_counts_and_boundary() {
        let m = Mesh::rectangle([0.0, 0.0], [2.0, 1.0], 4, 3, Diagonal::Right).unwrap();
        assert_eq!(m.n_vertices(), 20);
        assert_eq!(m.n_triangles(), 24);
        assert_eq!(m.interior().len(), 3 * 2);
        assert!((m.measure() - 2.0).abs() < 1e-14);
        let c = Mesh::rectangle([0.0, 0.0], [1.0, 1.0], 2, 2, Diagonal::Crossed).unwrap();
        assert_eq!((c.n_vertices(), c.n_triangles(), c.interior().len()), (13, 16, 5));
    }

    #[test]
    fn l_shape_has_three_quadrants() {
        let m = Mesh::l_shape(8, Diagonal::Right, 1.0).unwrap();
        assert!((m.measure() - 3.0).abs() < 1e-13);
        assert_eq!(m.n_triangles(), 3 * 32);
        let g = Mesh::l_shape(8, Diagonal::Right, 2.0).unwrap();
        assert!((g.measure() - 3.0).abs() < 1e-13);
        assert!(g.h() > m.h());
        // Grading shrinks the cells at the corner: the vertex next to it moves from 1/4 to 1/16.
        let nearest = |mesh: &Mesh| {
            mesh.points
                .iter()
                .map(|p| p[0].hypot(p[1]))
                .filter(|&r| r > 0.0)
                .fold(f64::MAX, f64::min)
        };
        assert!((nearest(&m) - 0.25).abs() < 1e-14 && (nearest(&g) - 0.0625).abs() < 1e-14);
    }
}
