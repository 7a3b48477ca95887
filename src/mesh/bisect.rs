//! Newest-vertex bisection (NVB): local refinement for adaptivity that keeps the mesh conforming
//! and its triangles in finitely many similarity classes (so their angles stay bounded below).
//!
//! Labelling: in every triangle `[a, b, c]` (counter-clockwise) `a` is the newest vertex and `bc`
//! the refinement edge. Bisecting `[a, b, c]` at the midpoint `m` of `bc` gives `[m, c, a]` and
//! `[m, a, b]`: counter-clockwise, the newest vertex `m` first, so their refinement edges are the
//! parent's other edges `ca` and `ab`. A mesh that did not come from bisection (built in, from
//! spade, from a file) gets its first labelling from [`Mesh::longest_edge_labelled`].

use super::{Curves, Mesh, MeshError};

impl Mesh {
    /// The same mesh with every triangle rotated so that its longest edge is its refinement edge
    /// (of equal lengths, the edge with the smaller vertex pair): the initial labelling for
    /// [`Mesh::bisected`]. Neighbours sharing their longest edge then bisect it together.
    pub fn longest_edge_labelled(&self) -> Mesh {
        let length2 = |p: usize, q: usize| {
            let (x, y) = (self.points[p], self.points[q]);
            (x[0] - y[0]).powi(2) + (x[1] - y[1]).powi(2)
        };
        let triangles = (self.triangles())
            .map(|t| {
                // The edge opposite t[k], as (length², smaller, larger vertex).
                let key = |k: usize| {
                    let (p, q) = (t[(k + 1) % 3], t[(k + 2) % 3]);
                    (length2(p, q), p.min(q), p.max(q))
                };
                let k = (0..3)
                    .max_by(|&i, &j| {
                        let ((li, pi, qi), (lj, pj, qj)) = (key(i), key(j));
                        li.total_cmp(&lj).then((pj, qj).cmp(&(pi, qi)))
                    })
                    .expect("three edges");
                [t[k], t[(k + 1) % 3], t[(k + 2) % 3]]
            })
            .collect();
        let mut labelled = Mesh::from_parts(self.points.clone(), triangles, self.on_boundary.clone());
        labelled.groups = self.groups.clone();
        labelled
    }

    /// Newest-vertex bisection of the `marked` triangles (one flag per triangle) and of as many
    /// others as keep the mesh conforming: the refinement edges of the marked triangles are
    /// marked, then the refinement edge of every triangle with a marked edge, until none is added;
    /// each marked edge gets a new vertex — at its midpoint, or where `curves` place it on ∂ω —
    /// and each triangle is bisected at its refinement edge, and each child again if its
    /// refinement edge is marked. The vertices of `self` keep their numbers, the new ones follow
    /// (in the order of [`Mesh::edges`]); the children follow the labelling of the module.
    pub fn bisected(&self, marked: &[bool], curves: &Curves) -> Result<Mesh, MeshError> {
        assert_eq!(marked.len(), self.n_triangles(), "one flag per triangle");
        let edges = EdgeTable::new(self);
        let split = edges.closure(marked);
        let mut points = self.points.clone();
        let mut mid = vec![None; split.len()];
        for (e, _) in split.iter().enumerate().filter(|(_, &s)| s) {
            let (p, q) = (self.points[edges.ends[e].0], self.points[edges.ends[e].1]);
            mid[e] = Some(points.len());
            points.push(if edges.on_boundary(e) {
                curves.boundary_midpoint(p, q)
            } else {
                [0.5 * (p[0] + q[0]), 0.5 * (p[1] + q[1])]
            });
        }
        let mut triangles = Vec::with_capacity(self.n_triangles() + 2 * (points.len() - self.n_vertices()));
        // The triangle of `self` each new triangle lies in, for the physical groups.
        let mut parent = Vec::new();
        for (k, (t, &[bc, ca, ab])) in self.triangles().zip(&edges.of_triangle).enumerate() {
            let before = triangles.len();
            match mid[bc] {
                None => triangles.push(t),
                Some(m) => {
                    let [first, second] = children(t, m);
                    for (child, e) in [(first, ca), (second, ab)] {
                        match mid[e] {
                            Some(m) => triangles.extend(children(child, m)),
                            None => triangles.push(child),
                        }
                    }
                }
            }
            if self.groups.is_some() {
                parent.extend(std::iter::repeat_n(k, triangles.len() - before));
            }
        }
        let mesh = Mesh::new(points, triangles)?;
        Ok(match self.groups() {
            None => mesh,
            Some(groups) => {
                // A boundary edge of the new mesh is a boundary edge of `self` or half of one.
                let halves: Vec<((usize, usize), (usize, usize))> = (0..edges.ends.len())
                    .filter(|&e| edges.on_boundary(e))
                    .flat_map(|e| {
                        let (a, b) = edges.ends[e];
                        match mid[e] {
                            None => vec![((a, b), (a, b))],
                            Some(m) => vec![((a, m), (a, b)), ((m, b), (a, b))],
                        }
                    })
                    .collect();
                let derived = groups.derived(parent.into_iter(), halves.into_iter());
                mesh.with_groups(derived)
            }
        })
    }
}

/// The children of `[a, b, c]` bisected at the vertex `m` of its refinement edge `bc`.
fn children([a, b, c]: [usize; 3], m: usize) -> [[usize; 3]; 2] {
    [[m, c, a], [m, a, b]]
}

/// The edges of a mesh, numbered in the order of [`Mesh::edges`], with the triangles on each.
struct EdgeTable {
    /// The vertices of each edge, smaller first.
    ends: Vec<(usize, usize)>,
    /// `of_triangle[t][k]`: the edge of triangle t opposite its vertex k (k = 0: the refinement edge).
    of_triangle: Vec<[usize; 3]>,
    /// The triangles on edge e are `triangle[start[e]..start[e + 1]]`.
    start: Vec<usize>,
    triangle: Vec<usize>,
}

impl EdgeTable {
    /// Groups the triangles' edges by their smaller vertex (a counting sort), then by the larger
    /// one: linear in the size of the mesh.
    fn new(mesh: &Mesh) -> Self {
        let opposite = |t: [usize; 3], k: usize| {
            let (p, q) = (t[(k + 1) % 3], t[(k + 2) % 3]);
            (p.min(q), p.max(q))
        };
        let mut first = vec![0usize; mesh.n_vertices() + 1];
        for t in mesh.triangles() {
            for k in 0..3 {
                first[opposite(t, k).0 + 1] += 1;
            }
        }
        for a in 0..mesh.n_vertices() {
            first[a + 1] += first[a];
        }
        let mut fill = first.clone();
        let mut half = vec![(0usize, 0usize); 3 * mesh.n_triangles()];
        for (t, tri) in mesh.triangles().enumerate() {
            for k in 0..3 {
                let (a, b) = opposite(tri, k);
                half[fill[a]] = (b, 3 * t + k);
                fill[a] += 1;
            }
        }
        let mut table = EdgeTable {
            ends: Vec::with_capacity(half.len() / 2 + 1),
            of_triangle: vec![[0; 3]; mesh.n_triangles()],
            start: Vec::with_capacity(half.len() / 2 + 2),
            triangle: Vec::with_capacity(half.len()),
        };
        for a in 0..mesh.n_vertices() {
            let group = &mut half[first[a]..first[a + 1]];
            group.sort_unstable();
            for edge in group.chunk_by(|x, y| x.0 == y.0) {
                let e = table.ends.len();
                table.ends.push((a, edge[0].0));
                table.start.push(table.triangle.len());
                for &(_, h) in edge {
                    table.of_triangle[h / 3][h % 3] = e;
                    table.triangle.push(h / 3);
                }
            }
        }
        table.start.push(table.triangle.len());
        table
    }

    /// Whether edge e lies on ∂ω: it has one triangle.
    fn on_boundary(&self, e: usize) -> bool {
        self.start[e + 1] - self.start[e] == 1
    }

    /// The edges to bisect: the refinement edges of the marked triangles and, repeatedly, of every
    /// triangle with an edge to bisect (a work list: each edge is added once).
    fn closure(&self, marked: &[bool]) -> Vec<bool> {
        let mut split = vec![false; self.ends.len()];
        let mut work: Vec<usize> = (marked.iter().zip(&self.of_triangle))
            .filter(|(&m, _)| m)
            .map(|(_, edges)| edges[0])
            .collect();
        while let Some(e) = work.pop() {
            if !split[e] {
                split[e] = true;
                work.extend(
                    (self.triangle[self.start[e]..self.start[e + 1]].iter()).map(|&t| self.of_triangle[t][0]),
                );
            }
        }
        split
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::{Diagonal, Domain};
    use std::collections::HashMap;

    /// The coordinates of the vertices, sorted.
    fn vertex_set(m: &Mesh) -> Vec<[u64; 2]> {
        let mut v: Vec<[u64; 2]> = m.points.iter().map(|p| p.map(f64::to_bits)).collect();
        v.sort_unstable();
        v
    }

    /// The smallest angle of the mesh's triangles.
    fn min_angle(m: &Mesh) -> f64 {
        (0..m.n_triangles())
            .map(|t| min_angle_of(m.corners(t)))
            .fold(f64::INFINITY, f64::min)
    }

    fn min_angle_of(p: [[f64; 2]; 3]) -> f64 {
        (0..3)
            .map(|k| {
                let (o, q, r) = (p[k], p[(k + 1) % 3], p[(k + 2) % 3]);
                let (u, v) = ([q[0] - o[0], q[1] - o[1]], [r[0] - o[0], r[1] - o[1]]);
                (u[0] * v[1] - u[1] * v[0]).abs().atan2(u[0] * v[0] + u[1] * v[1])
            })
            .fold(f64::INFINITY, f64::min)
    }

    /// Bisects and checks the result against the labelling convention, found independently from
    /// coordinates (on polygons, where new vertices are exact midpoints): the old vertices keep
    /// their numbers, and every triangle of `coarse` is replaced by its children `[m, c, a]`,
    /// `[m, a, b]` (recursively) exactly when the midpoint m of its refinement edge bc is a vertex.
    fn bisect_and_check(coarse: &Mesh, marked: &[bool]) -> Mesh {
        let fine = coarse.bisected(marked, &Curves::default()).unwrap();
        assert_eq!(fine.points[..coarse.n_vertices()], coarse.points[..]);
        let index: HashMap<[u64; 2], usize> = (fine.points.iter().enumerate())
            .map(|(i, p)| (p.map(f64::to_bits), i))
            .collect();
        let mut expected = Vec::new();
        let mut stack: Vec<[usize; 3]> = coarse.triangles().collect();
        while let Some([a, b, c]) = stack.pop() {
            let (p, q) = (fine.points[b], fine.points[c]);
            match index.get(&[0.5 * (p[0] + q[0]), 0.5 * (p[1] + q[1])].map(f64::to_bits)) {
                Some(&m) => stack.extend([[m, c, a], [m, a, b]]),
                None => expected.push([a, b, c]),
            }
        }
        let mut got: Vec<[usize; 3]> = fine.triangles().collect();
        got.sort_unstable();
        expected.sort_unstable();
        assert_eq!(got, expected);
        fine
    }

    /// The L-shaped domain (−1, 1)² \ [0, 1] × [−1, 0] meshed by spade to size h, labelled.
    fn l_shape(h: f64) -> Mesh {
        let boundary = vec![
            [-1.0, -1.0],
            [0.0, -1.0],
            [0.0, 0.0],
            [1.0, 0.0],
            [1.0, 1.0],
            [-1.0, 1.0],
        ];
        let domain = Domain::Polygon {
            boundary,
            holes: vec![],
        };
        domain.mesh(h).unwrap().longest_edge_labelled()
    }

    #[test]
    fn longest_edge_labelling_makes_the_longest_edge_the_refinement_edge() {
        let mesh = l_shape(0.3);
        let mut rotated = mesh.clone();
        rotated.triangles.iter_mut().for_each(|t| t.rotate_left(1));
        assert_eq!(rotated.longest_edge_labelled().triangles, mesh.triangles);
        assert_eq!(
            (mesh.points.clone(), mesh.on_boundary.clone()),
            (rotated.points, rotated.on_boundary)
        );
        let d = |p: usize, q: usize| crate::mesh::dist(mesh.points[p], mesh.points[q]);
        for [a, b, c] in mesh.triangles() {
            assert!(d(b, c) >= d(a, b) && d(b, c) >= d(c, a));
        }
        // Two longest edges of exactly equal length, 12 and 02: the smaller pair, 02, wins.
        for triangle in [[0, 1, 2], [1, 2, 0], [2, 0, 1]] {
            let isosceles = Mesh {
                points: vec![[0.0, 0.0], [1.0, 0.0], [0.5, 2.0]],
                triangles: vec![triangle],
                on_boundary: vec![true; 3],
                groups: None,
            };
            assert_eq!(isosceles.longest_edge_labelled().triangles, [[1, 2, 0]]);
        }
    }

    #[test]
    fn bisecting_all_twice_is_uniform_refinement() {
        for diagonal in [Diagonal::Right, Diagonal::Left, Diagonal::Crossed] {
            let coarse = Mesh::rectangle([0.0, 0.0], [1.0, 1.0], 4, 4, diagonal).unwrap();
            let uniform = coarse.refined(&Curves::default()).unwrap();
            let mut mesh = coarse.longest_edge_labelled();
            for _ in 0..2 {
                mesh = bisect_and_check(&mesh, &vec![true; mesh.n_triangles()]);
            }
            assert_eq!(mesh.n_triangles(), 4 * coarse.n_triangles());
            assert!((mesh.measure() - uniform.measure()).abs() < 1e-14);
            assert_eq!(vertex_set(&mesh), vertex_set(&uniform), "{diagonal:?}");
        }
    }

    #[test]
    fn one_marked_triangle_changes_a_few() {
        // Bisects the triangle nearest to `target` among those `chosen`: the triangles added, and
        // the triangles that were not in `mesh`.
        let changed = |mesh: &Mesh, chosen: &dyn Fn(usize) -> bool, target: [f64; 2]| {
            let distance = |t: usize| {
                let [p, q, r] = mesh.corners(t);
                (p[0] + q[0] + r[0] - 3.0 * target[0]).hypot(p[1] + q[1] + r[1] - 3.0 * target[1])
            };
            let nearest = (0..mesh.n_triangles())
                .filter(|&t| chosen(t))
                .min_by(|&s, &t| distance(s).total_cmp(&distance(t)))
                .unwrap();
            let mut marked = vec![false; mesh.n_triangles()];
            marked[nearest] = true;
            let fine = bisect_and_check(mesh, &marked);
            assert!((fine.measure() - mesh.measure()).abs() <= 1e-14 * mesh.measure());
            let mut old: Vec<[usize; 3]> = mesh.triangles().collect();
            old.sort_unstable();
            let new = (fine.triangles())
                .filter(|t| old.binary_search(t).is_err())
                .count();
            (fine.n_triangles() - mesh.n_triangles(), new)
        };
        let square = |n| {
            let mesh = Mesh::rectangle([0.0, 0.0], [1.0, 1.0], n, n, Diagonal::Right).unwrap();
            mesh.longest_edge_labelled()
        };
        // The marked triangle and its partner across the diagonal, each in two.
        assert_eq!(changed(&square(8), &|_| true, [0.45, 0.55]), (2, 4));
        assert_eq!(changed(&square(64), &|_| true, [0.45, 0.55]), (2, 4));
        // A triangle whose neighbour across its refinement edge has another refinement edge: the
        // closure has to bisect the neighbour twice, and maybe more.
        for h in [0.1, 0.02] {
            let mesh = l_shape(h);
            let pair = |p: usize, q: usize| (p.min(q), p.max(q));
            let (mut refinement, mut all) = (HashMap::new(), HashMap::new());
            for t in mesh.triangles() {
                *refinement.entry(pair(t[1], t[2])).or_insert(0) += 1;
                for k in 0..3 {
                    *all.entry(pair(t[k], t[(k + 1) % 3])).or_insert(0) += 1;
                }
            }
            let lone = |t: usize| {
                let e = pair(mesh.triangle(t)[1], mesh.triangle(t)[2]);
                refinement[&e] == 1 && all[&e] == 2
            };
            let (added, new) = changed(&mesh, &lone, [-0.45, 0.55]);
            assert!((3..=8).contains(&added) && new <= 2 * added, "{added}, {new}");
        }
    }

    #[test]
    fn refinement_towards_the_corner_keeps_the_angles() {
        let mut mesh = l_shape(0.3);
        // NVB bisects each triangle into finitely many similarity classes, all among its first
        // few generations: the smallest angle any refinement can reach.
        let mut bound = f64::INFINITY;
        let mut generation: Vec<[usize; 3]> = mesh.triangles().collect();
        let mut points = mesh.points.clone();
        for _ in 0..5 {
            let mut next = Vec::new();
            for t in generation {
                bound = bound.min(min_angle_of(t.map(|a| points[a])));
                let (p, q) = (points[t[1]], points[t[2]]);
                points.push([0.5 * (p[0] + q[0]), 0.5 * (p[1] + q[1])]);
                next.extend(children(t, points.len() - 1));
            }
            generation = next;
        }
        let corner = (mesh.points.iter()).position(|&p| p == [0.0, 0.0]).unwrap();
        let largest_at_corner = |m: &Mesh| {
            (0..m.n_triangles())
                .filter(|&t| m.triangle(t).contains(&corner))
                .map(|t| m.area(t))
                .fold(0.0, f64::max)
        };
        let (initial, initial_at_corner) = (min_angle(&mesh), largest_at_corner(&mesh));
        let mut angles = Vec::new();
        for _ in 0..20 {
            let marked: Vec<bool> = mesh.triangles().map(|t| t.contains(&corner)).collect();
            mesh = bisect_and_check(&mesh, &marked);
            angles.push(min_angle(&mesh));
        }
        let last = angles[19];
        assert!(
            last >= bound - 1e-12 && last >= initial / 2.0,
            "{angles:?}, {bound}, {initial}"
        );
        let early = angles[..5].iter().fold(f64::INFINITY, |a, &b| a.min(b));
        assert!((last - early).abs() < 1e-12, "{angles:?}");
        // Each step bisects each triangle at the corner at least once.
        assert!(largest_at_corner(&mesh) <= initial_at_corner / f64::powi(2.0, 20));
        assert!((mesh.measure() - 3.0).abs() < 1e-13);
    }

    #[test]
    fn new_boundary_vertices_lie_on_the_circles() {
        let annulus = Domain::Disk {
            centre: [1.0, -1.0],
            radius: 2.0,
            inner_radius: Some(0.5),
        };
        let radius = |p: [f64; 2]| (p[0] - 1.0).hypot(p[1] + 1.0);
        let mut mesh = annulus.mesh(0.4).unwrap().longest_edge_labelled();
        let mut on_circles = [0, 0];
        for round in 0..4 {
            // Every other triangle at the boundary, and a few inside.
            let marked: Vec<bool> = (mesh.triangles().enumerate())
                .map(|(t, tri)| {
                    ((t + round) % 2 == 0 && tri.iter().any(|&a| mesh.on_boundary[a])) || t % 7 == 0
                })
                .collect();
            let fine = mesh.bisected(&marked, &annulus.curves()).unwrap();
            assert_eq!(fine.points[..mesh.n_vertices()], mesh.points[..]);
            for a in mesh.n_vertices()..fine.n_vertices() {
                let r = radius(fine.points[a]);
                let circle = [(r - 2.0).abs() <= 2e-12, (r - 0.5).abs() <= 0.5e-12];
                assert_eq!(
                    fine.on_boundary[a],
                    circle[0] || circle[1],
                    "vertex {a} at r = {r}"
                );
                on_circles[0] += circle[0] as usize;
                on_circles[1] += circle[1] as usize;
            }
            mesh = fine;
        }
        assert!(on_circles[0] > 20 && on_circles[1] > 10, "{on_circles:?}");
    }
}
