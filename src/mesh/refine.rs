//! Uniform refinement: each triangle into four by its edge midpoints, new boundary vertices on
//! the curves of ∂ω. The coarse vertices keep their numbers, so a hierarchy of refined meshes is
//! nested (exactly on polygons), and [`super::Prolongation`] restricts loads exactly there.

use super::{Curves, Mesh, MeshError};

impl Mesh {
    /// The uniform refinement: the vertices of `self`, then one per edge (in the order of
    /// [`Mesh::edges`]) at its midpoint — for a boundary edge, where `curves` place it — and four
    /// triangles per triangle, counter-clockwise as their parent.
    pub fn refined(&self, curves: &Curves) -> Result<Mesh, MeshError> {
        let n = self.n_vertices();
        let mut half: Vec<(usize, usize)> = (self.triangles())
            .flat_map(|t| (0..3).map(move |k| (t[k].min(t[(k + 1) % 3]), t[k].max(t[(k + 1) % 3]))))
            .collect();
        half.sort_unstable();
        let mut edges = Vec::with_capacity(half.len() / 2 + 1);
        let mut points = self.points.clone();
        for group in half.chunk_by(|a, b| a == b) {
            let (a, b) = group[0];
            let (p, q) = (self.points[a], self.points[b]);
            points.push(if group.len() == 1 {
                curves.boundary_midpoint(p, q)
            } else {
                [0.5 * (p[0] + q[0]), 0.5 * (p[1] + q[1])]
            });
            edges.push((a, b));
        }
        let mid = |a: usize, b: usize| n + edges.binary_search(&(a.min(b), a.max(b))).expect("an edge");
        let mut triangles = Vec::with_capacity(4 * self.n_triangles());
        for [a, b, c] in self.triangles() {
            let (ab, bc, ca) = (mid(a, b), mid(b, c), mid(c, a));
            triangles.extend([[a, ab, ca], [ab, b, bc], [ca, bc, c], [ab, bc, ca]]);
        }
        let fine = Mesh::new(points, triangles)?;
        Ok(match self.groups() {
            None => fine,
            Some(groups) => {
                // Each child keeps its parent's surface, each half of a boundary edge its curve.
                let halves = (groups.boundary_edges()).flat_map(|((a, b), _)| {
                    let m = mid(a, b);
                    [((a, m), (a, b)), ((m, b), (a, b))]
                });
                let parent = (0..4 * self.n_triangles()).map(|t| t / 4);
                let derived = groups.derived(parent, halves);
                fine.with_groups(derived)
            }
        })
    }
}

impl Mesh {
    /// The same mesh with its vertices numbered along a Z-order (Morton) curve and its triangles
    /// sorted by their smallest vertex: neighbours get near numbers, which keeps assembly and the
    /// Cholesky factorization in cache (meshes from spade and refinement number their vertices in
    /// the order they were made, scattered over ω).
    pub fn renumbered(&self) -> Mesh {
        let (lo, hi) = self
            .points
            .iter()
            .fold(([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]), |(lo, hi), p| {
                (super::min2(lo, *p), super::max2(hi, *p))
            });
        let scale =
            |x: f64, k: usize| ((x - lo[k]) / (hi[k] - lo[k]).max(f64::MIN_POSITIVE) * 65535.0) as u32;
        let key = |p: [f64; 2]| spread(scale(p[0], 0)) | (spread(scale(p[1], 1)) << 1);
        let mut order: Vec<usize> = (0..self.n_vertices()).collect();
        order.sort_by_key(|&a| (key(self.points[a]), a));
        let mut new = vec![0; order.len()];
        for (i, &a) in order.iter().enumerate() {
            new[a] = i;
        }
        let renamed: Vec<[usize; 3]> = self.triangles().map(|t| t.map(|a| new[a])).collect();
        let mut by_triangle: Vec<usize> = (0..renamed.len()).collect();
        by_triangle.sort_by_key(|&t| {
            let t = renamed[t];
            (*t.iter().min().expect("three vertices"), t[0], t[1])
        });
        let mut mesh = Mesh::from_parts(
            order.iter().map(|&a| self.points[a]).collect(),
            by_triangle.iter().map(|&t| renamed[t]).collect(),
            order.iter().map(|&a| self.on_boundary[a]).collect(),
        );
        if let Some(groups) = self.groups() {
            mesh = mesh.with_groups(groups.renumbered(&new, &by_triangle));
        }
        mesh
    }
}

/// The bits of x spread to the even positions of a u32 (for Morton keys of 16-bit coordinates).
fn spread(x: u32) -> u32 {
    let mut x = x & 0xffff;
    x = (x | (x << 8)) & 0x00ff_00ff;
    x = (x | (x << 4)) & 0x0f0f_0f0f;
    x = (x | (x << 2)) & 0x3333_3333;
    (x | (x << 1)) & 0x5555_5555
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::{Diagonal, Domain};

    #[test]
    fn refining_a_rectangle_gives_the_finer_rectangle() {
        let coarse = Mesh::rectangle([0.0, 0.0], [1.0, 2.0], 3, 2, Diagonal::Right).unwrap();
        let fine = coarse.refined(&Curves::default()).unwrap();
        let direct = Mesh::rectangle([0.0, 0.0], [1.0, 2.0], 6, 4, Diagonal::Right).unwrap();
        assert_eq!(fine.n_vertices(), direct.n_vertices());
        assert_eq!(fine.n_triangles(), 4 * coarse.n_triangles());
        assert_eq!(fine.points[..coarse.n_vertices()], coarse.points[..]);
        assert!((fine.h() - direct.h()).abs() < 1e-15);
        let key = |m: &Mesh| {
            let mut t: Vec<Vec<[u64; 2]>> = (m.triangles())
                .map(|t| {
                    let mut v: Vec<[u64; 2]> = t.iter().map(|&a| m.points[a].map(f64::to_bits)).collect();
                    v.sort_unstable();
                    v
                })
                .collect();
            t.sort_unstable();
            t
        };
        assert_eq!(key(&fine), key(&direct));
    }

    #[test]
    fn refined_disks_converge_to_the_disk_at_rate_two() {
        let disk = Domain::Disk {
            centre: [0.0, 0.0],
            radius: 1.0,
            inner_radius: None,
        };
        let mut mesh = disk.mesh(0.3).unwrap();
        let defect = |m: &Mesh| std::f64::consts::PI - m.measure();
        let mut previous = defect(&mesh);
        for _ in 0..4 {
            mesh = mesh.refined(&disk.curves()).unwrap();
            let d = defect(&mesh);
            // Each halving of h divides π − |ω_h| by 4 (the chords' segments: h³ each, 1/h of them).
            assert!(d > 0.0 && (previous / d - 4.0).abs() < 0.05, "{previous} / {d}");
            previous = d;
        }
    }

    #[test]
    fn refined_meshes_nest_and_restrict_loads_exactly() {
        let domain = Domain::Polygon {
            boundary: vec![[0.0, 0.0], [2.0, 0.0], [1.0, 1.0], [0.0, 1.0]],
            holes: vec![vec![[0.3, 0.3], [0.6, 0.3], [0.4, 0.6]]],
        };
        let coarse = domain.mesh(0.25).unwrap();
        let fine = coarse.refined(&domain.curves()).unwrap();
        assert!((fine.measure() - coarse.measure()).abs() < 1e-14);
        crate::mesh::transfer::tests::assert_loads_restrict_exactly(&coarse, &fine, "x*y - 2*y + 1");
    }

    #[test]
    fn renumbering_keeps_the_mesh_and_brings_neighbours_together() {
        let disk = Domain::Disk {
            centre: [0.0, 0.0],
            radius: 1.0,
            inner_radius: Some(0.2),
        };
        let mesh = disk.mesh(0.05).unwrap().refined(&disk.curves()).unwrap();
        let renumbered = mesh.renumbered();
        let spread =
            |m: &Mesh| m.edges().iter().map(|&(a, b)| b - a).sum::<usize>() as f64 / m.edges().len() as f64;
        assert!(
            spread(&renumbered) < 0.2 * spread(&mesh),
            "{} vs {}",
            spread(&renumbered),
            spread(&mesh)
        );
        // The same triangles, by coordinates, and the same boundary.
        let key = |m: &Mesh| {
            let mut t: Vec<[[u64; 2]; 3]> = (m.triangles())
                .map(|t| {
                    let mut v = t.map(|a| m.points[a].map(f64::to_bits));
                    v.sort_unstable();
                    v
                })
                .collect();
            t.sort_unstable();
            t
        };
        assert_eq!(key(&mesh), key(&renumbered));
        let boundary = |m: &Mesh| {
            let mut b: Vec<[u64; 2]> = (0..m.n_vertices())
                .filter(|&a| m.on_boundary[a])
                .map(|a| m.points[a].map(f64::to_bits))
                .collect();
            b.sort_unstable();
            b
        };
        assert_eq!(boundary(&mesh), boundary(&renumbered));
        let again = Mesh::new(renumbered.points.clone(), renumbered.triangles().collect()).unwrap();
        assert_eq!(again.on_boundary, renumbered.on_boundary);
    }
}
