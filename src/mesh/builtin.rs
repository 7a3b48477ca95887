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
        let on_boundary = (0..points.len())
            .map(|v| grid_index(v, nx, ny).is_some_and(|(ix, iy)| ix == 0 || ix == nx || iy == 0 || iy == ny))
            .collect();
        Mesh::constructed(points, triangles, on_boundary)
    }

    /// The L-shaped domain (−1, 1)² \ [0, 1] × [−1, 0] with n × n cells on the full square (n even).
    /// With `grading` β > 1 the vertices are pulled towards the re-entrant corner (0, 0) (Remark 10):
    /// a vertex at max-norm distance r moves radially to distance r^β, so cells near the corner have
    /// size ~ h r^(1−1/β); β = 1 is the uniform mesh. The boundary is mapped onto itself.
    pub fn l_shape(n: usize, diagonal: Diagonal, grading: f64) -> Result<Self, MeshError> {
        let n = n + n % 2;
        let (mut points, triangles) = rectangle_raw([-1.0, -1.0], [1.0, 1.0], n, n, diagonal);
        // The outer square and the two edges of the cut, x = 0 for y ≤ 0 and y = 0 for x ≥ 0.
        let (h, outer) = (n / 2, |i: usize| i == 0 || i == n);
        let on_boundary: Vec<bool> = (0..points.len())
            .map(|v| {
                grid_index(v, n, n).is_some_and(|(ix, iy)| {
                    outer(ix) || outer(iy) || (ix == h && iy <= h) || (iy == h && ix >= h)
                })
            })
            .collect();
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
        let used = used_vertices(points.len(), &kept);
        let on_boundary = (on_boundary.into_iter().zip(&used))
            .filter(|(_, &u)| u)
            .map(|(b, _)| b)
            .collect();
        let (points, triangles) = compact(points, kept);
        Mesh::constructed(points, triangles, on_boundary)
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
    let used = used_vertices(points.len(), &triangles);
    let mut new_index = vec![usize::MAX; points.len()];
    let mut kept = Vec::new();
    for ((v, p), _) in points.into_iter().enumerate().zip(&used).filter(|(_, &u)| u) {
        new_index[v] = kept.len();
        kept.push(p);
    }
    let triangles = triangles.into_iter().map(|t| t.map(|v| new_index[v])).collect();
    (kept, triangles)
}

/// Whether each of `n` vertices is a corner of one of `triangles`.
fn used_vertices(n: usize, triangles: &[[usize; 3]]) -> Vec<bool> {
    let mut used = vec![false; n];
    for &v in triangles.iter().flatten() {
        used[v] = true;
    }
    used
}

/// The grid position (ix, iy) of vertex v of [`rectangle_raw`]'s nx × ny cells, or `None` for a
/// cell centre of the crossed diagonals (numbered after the grid).
fn grid_index(v: usize, nx: usize, ny: usize) -> Option<(usize, usize)> {
    (v < (nx + 1) * (ny + 1)).then(|| (v % (nx + 1), v / (nx + 1)))
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

    /// The built-in meshes skip [`Mesh::new`]'s checks: they are what it makes of the same
    /// vertices and triangles, boundary included.
    #[test]
    fn built_in_meshes_are_what_the_checks_make_of_them() {
        let checked = |m: &Mesh| {
            let triangles = m.triangles().map(|t| t.map(|v| v)).collect();
            Mesh::new(m.points.clone(), triangles).unwrap()
        };
        let same = |m: &Mesh| {
            let c = checked(m);
            assert_eq!(m.points, c.points);
            assert!(m.triangles().eq(c.triangles()));
            assert_eq!(m.on_boundary, c.on_boundary);
        };
        // Without an interior vertex both refuse the mesh.
        assert!(matches!(
            Mesh::rectangle([0.0, 0.0], [1.0, 1.0], 1, 1, Diagonal::Right),
            Err(MeshError::NoInteriorVertex)
        ));
        for diagonal in [Diagonal::Right, Diagonal::Left, Diagonal::Crossed] {
            for (nx, ny) in [(2, 2), (2, 3), (5, 4), (7, 7)] {
                same(&Mesh::rectangle([-1.0, 0.5], [2.0, 3.0], nx, ny, diagonal).unwrap());
            }
            for (n, grading) in [(4, 1.0), (6, 1.0), (7, 1.0), (8, 2.0), (12, 1.5)] {
                same(&Mesh::l_shape(n, diagonal, grading).unwrap());
            }
        }
    }

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
