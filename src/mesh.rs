//! Conforming triangulations T_h of a polygon ω: built-in meshes, checks, the boundary ∂ω,
//! and P1 interpolation from one mesh to another (for warm starts).

use std::fmt;

/// A triangle mesh with counter-clockwise triangles and its boundary vertices.
#[derive(Debug, Clone)]
pub struct Mesh {
    pub points: Vec<[f64; 2]>,
    pub triangles: Vec<[usize; 3]>,
    /// `on_boundary[a]`: vertex a lies on ∂ω (an endpoint of an edge with one triangle).
    pub on_boundary: Vec<bool>,
}

/// Why a set of points and triangles is not a valid mesh.
#[derive(Debug, Clone, PartialEq)]
pub enum MeshError {
    Empty,
    NotFinite {
        vertex: usize,
    },
    VertexIndex {
        triangle: usize,
        index: usize,
    },
    Degenerate {
        triangle: usize,
        area: f64,
    },
    DuplicateVertex {
        first: usize,
        second: usize,
    },
    UnusedVertex {
        vertex: usize,
    },
    NonManifoldEdge {
        a: usize,
        b: usize,
        count: usize,
    },
    Inverted {
        triangle: usize,
        neighbour: usize,
    },
    HangingNode {
        vertex: usize,
    },
    Disconnected {
        components: usize,
    },
    NoInteriorVertex,
    TooLarge {
        vertices: usize,
        needed_gb: f64,
        available_gb: f64,
    },
}

impl fmt::Display for MeshError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            MeshError::Empty => write!(f, "the mesh has no triangles"),
            MeshError::NotFinite { vertex } => write!(f, "vertex {vertex} has a non-finite coordinate"),
            MeshError::VertexIndex { triangle, index } => {
                write!(f, "triangle {triangle} refers to vertex {index}, which does not exist")
            }
            MeshError::Degenerate { triangle, area } => {
                write!(f, "triangle {triangle} has zero area ({area:e}) or repeats a vertex")
            }
            MeshError::DuplicateVertex { first, second } => {
                write!(f, "vertices {first} and {second} have the same coordinates")
            }
            MeshError::UnusedVertex { vertex } => write!(f, "vertex {vertex} belongs to no triangle"),
            MeshError::NonManifoldEdge { a, b, count } => {
                write!(f, "edge ({a}, {b}) is shared by {count} triangles")
            }
            MeshError::Inverted { triangle, neighbour } => write!(
                f,
                "triangle {triangle} overlaps its neighbour {neighbour}: it is inverted (folded mesh)"
            ),
            MeshError::HangingNode { vertex } => write!(
                f,
                "vertex {vertex} lies inside an edge of another triangle: a hanging node (non-conforming mesh)"
            ),
            MeshError::Disconnected { components } => {
                write!(f, "the mesh has {components} separate components; ω must be connected")
            }
            MeshError::NoInteriorVertex => write!(f, "the mesh has no interior vertex: nothing to solve"),
            MeshError::TooLarge {
                vertices,
                needed_gb,
                available_gb,
            } => write!(
                f,
                "{vertices} vertices need about {needed_gb:.1} GB of memory, but only {available_gb:.1} GB \
                 are available: use a coarser mesh"
            ),
        }
    }
}

impl std::error::Error for MeshError {}

/// Peak memory of a run per mesh vertex, with a margin: measured at 1.05M vertices, 1.9 GB for a
/// solve with nested iteration and the written result, 2.6 GB with `--flux`.
const BYTES_PER_VERTEX: f64 = 2700.0;

/// Fails early, with an estimate, when a mesh of `vertices` vertices would not fit in the memory
/// available now (`MemAvailable` of /proc/meminfo; no check where that cannot be read).
pub fn check_memory(vertices: usize) -> Result<(), MeshError> {
    let available = std::fs::read_to_string("/proc/meminfo").ok().and_then(|s| {
        let line = s.lines().find(|l| l.starts_with("MemAvailable:"))?;
        line.split_whitespace()
            .nth(1)?
            .parse::<f64>()
            .ok()
            .map(|kb| kb * 1024.0)
    });
    let needed = vertices as f64 * BYTES_PER_VERTEX;
    match available {
        Some(available) if needed > available => Err(MeshError::TooLarge {
            vertices,
            needed_gb: needed / 1e9,
            available_gb: available / 1e9,
        }),
        _ => Ok(()),
    }
}

/// Twice the signed area of the triangle (p, q, r).
#[inline]
pub fn orient(p: [f64; 2], q: [f64; 2], r: [f64; 2]) -> f64 {
    (q[0] - p[0]) * (r[1] - p[1]) - (q[1] - p[1]) * (r[0] - p[0])
}

/// Diagonal of each rectangle cell, as in `dolfinx.mesh.DiagonalType`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Deserialize, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Diagonal {
    Right,
    Left,
    Crossed,
}

impl Mesh {
    /// Checks a mesh read or built from points and triangles and orients its triangles
    /// counter-clockwise. Rejects everything that is not a conforming triangulation of a
    /// connected polygon with at least one interior vertex.
    pub fn new(points: Vec<[f64; 2]>, mut triangles: Vec<[usize; 3]>) -> Result<Self, MeshError> {
        if triangles.is_empty() {
            return Err(MeshError::Empty);
        }
        if let Some(vertex) = points.iter().position(|p| !p[0].is_finite() || !p[1].is_finite()) {
            return Err(MeshError::NotFinite { vertex });
        }
        let n = points.len();
        let diameter = bounding_diameter(&points);
        let mut used = vec![false; n];
        for (t, tri) in triangles.iter_mut().enumerate() {
            for &index in tri.iter() {
                if index >= n {
                    return Err(MeshError::VertexIndex { triangle: t, index });
                }
                used[index] = true;
            }
            let area = orient(points[tri[0]], points[tri[1]], points[tri[2]]);
            if area.abs() <= 1e-13 * diameter * diameter
                || tri[0] == tri[1]
                || tri[1] == tri[2]
                || tri[0] == tri[2]
            {
                return Err(MeshError::Degenerate {
                    triangle: t,
                    area: 0.5 * area,
                });
            }
            if area < 0.0 {
                tri.swap(1, 2);
            }
        }
        let mut sorted: Vec<usize> = (0..n).collect();
        sorted.sort_by(|&a, &b| points[a].partial_cmp(&points[b]).unwrap());
        for w in sorted.windows(2) {
            if points[w[0]] == points[w[1]] {
                return Err(MeshError::DuplicateVertex {
                    first: w[0].min(w[1]),
                    second: w[0].max(w[1]),
                });
            }
        }

        if let Some(vertex) = used.iter().position(|u| !u) {
            return Err(MeshError::UnusedVertex { vertex });
        }

        // Edges: each is shared by one (boundary) or two (interior) triangles. Half-edges are
        // grouped by their smaller vertex (a counting sort), then matched by the larger one.
        let mut start = vec![0usize; n + 1];
        for tri in &triangles {
            for k in 0..3 {
                start[tri[k].min(tri[(k + 1) % 3]) + 1] += 1;
            }
        }
        for a in 0..n {
            start[a + 1] += start[a];
        }
        let mut fill = start.clone();
        let mut half = vec![(0usize, 0usize); 3 * triangles.len()];
        for (t, tri) in triangles.iter().enumerate() {
            for k in 0..3 {
                let (a, b) = (tri[k], tri[(k + 1) % 3]);
                half[fill[a.min(b)]] = (a.max(b), t);
                fill[a.min(b)] += 1;
            }
        }
        let mut on_boundary = vec![false; n];
        let mut boundary_edges = Vec::new();
        let mut parent: Vec<usize> = (0..triangles.len()).collect();
        for a in 0..n {
            let group = &mut half[start[a]..start[a + 1]];
            group.sort_unstable();
            for edge in group.chunk_by(|x, y| x.0 == y.0) {
                let b = edge[0].0;
                match edge {
                    [_] => {
                        on_boundary[a] = true;
                        on_boundary[b] = true;
                        boundary_edges.push((a, b));
                    }
                    [(_, t), (_, s)] => {
                        // Counter-clockwise neighbours traverse a shared edge in opposite directions.
                        if traverses(&triangles[*t], a, b) == traverses(&triangles[*s], a, b) {
                            return Err(MeshError::Inverted {
                                triangle: *s,
                                neighbour: *t,
                            });
                        }
                        union(&mut parent, *t, *s);
                    }
                    _ => {
                        return Err(MeshError::NonManifoldEdge {
                            a,
                            b,
                            count: edge.len(),
                        })
                    }
                }
            }
        }
        // A hanging node is a vertex lying inside a boundary edge of the triangle set.
        if let Some(vertex) = hanging_node(&points, &boundary_edges, diameter) {
            return Err(MeshError::HangingNode { vertex });
        }
        let components = (0..triangles.len())
            .filter(|&t| find(&mut parent, t) == t)
            .count();
        if components > 1 {
            return Err(MeshError::Disconnected { components });
        }
        if on_boundary.iter().all(|&b| b) {
            return Err(MeshError::NoInteriorVertex);
        }
        Ok(Mesh {
            points,
            triangles,
            on_boundary,
        })
    }

    /// The rectangle [x0, x1] × [y0, y1] with nx × ny cells, with the vertices and triangles of
    /// `dolfinx.mesh.create_rectangle` (vertex numbering row by row, crossed midpoints last).
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

    pub fn n_vertices(&self) -> usize {
        self.points.len()
    }

    /// The vertices of triangle t.
    #[inline]
    pub fn corners(&self, t: usize) -> [[f64; 2]; 3] {
        let [a, b, c] = self.triangles[t];
        [self.points[a], self.points[b], self.points[c]]
    }

    /// The area of triangle t.
    #[inline]
    pub fn area(&self, t: usize) -> f64 {
        let [p, q, r] = self.corners(t);
        0.5 * orient(p, q, r)
    }

    /// The mesh size h: the largest triangle diameter.
    pub fn h(&self) -> f64 {
        (0..self.triangles.len())
            .map(|t| {
                let [p, q, r] = self.corners(t);
                dist(p, q).max(dist(q, r)).max(dist(r, p))
            })
            .fold(0.0, f64::max)
    }

    /// |ω|.
    pub fn measure(&self) -> f64 {
        (0..self.triangles.len()).map(|t| self.area(t)).sum()
    }

    /// The interior vertices V_h, in increasing order.
    pub fn interior(&self) -> Vec<usize> {
        (0..self.n_vertices()).filter(|&a| !self.on_boundary[a]).collect()
    }

    /// The edges of the mesh as sorted vertex pairs, each once, with their triangles.
    pub fn edges(&self) -> Vec<(usize, usize)> {
        let mut e: Vec<(usize, usize)> = self
            .triangles
            .iter()
            .flat_map(|t| (0..3).map(move |k| (t[k].min(t[(k + 1) % 3]), t[k].max(t[(k + 1) % 3]))))
            .collect();
        e.sort_unstable();
        e.dedup();
        e
    }
}

/// P1 interpolation from a coarse mesh onto the vertices of a fine one: each fine vertex is
/// located in the coarse mesh (or, outside it, at the nearest triangle) with its barycentric
/// coordinates. Its transpose restricts nodal loads: Pᵀ(f, φ_a)_a = (f, φ_A)_A exactly when the
/// meshes are nested, since then every coarse hat function is a combination of fine ones.
pub struct Prolongation {
    coarse_vertices: usize,
    weights: Vec<([usize; 3], [f64; 3])>,
}

impl Prolongation {
    pub fn new(fine: &Mesh, coarse: &Mesh) -> Self {
        let locator = Locator::new(coarse);
        let weights = fine
            .points
            .iter()
            .map(|&p| {
                let (t, bary) = locator.locate(coarse, p);
                (coarse.triangles[t], bary)
            })
            .collect();
        Prolongation {
            coarse_vertices: coarse.n_vertices(),
            weights,
        }
    }

    /// The fine P1 interpolant of the coarse P1 field `values`.
    pub fn apply(&self, values: &[f64]) -> Vec<f64> {
        (self.weights.iter())
            .map(|(tri, bary)| (0..3).map(|k| bary[k] * values[tri[k]]).sum())
            .collect()
    }

    /// Pᵀ `fine`: a fine nodal load restricted to the coarse vertices.
    pub fn restrict(&self, fine: &[f64]) -> Vec<f64> {
        let mut coarse = vec![0.0; self.coarse_vertices];
        for ((tri, bary), f) in self.weights.iter().zip(fine) {
            for k in 0..3 {
                coarse[tri[k]] += bary[k] * f;
            }
        }
        coarse
    }
}

fn dist(p: [f64; 2], q: [f64; 2]) -> f64 {
    (p[0] - q[0]).hypot(p[1] - q[1])
}

fn centroid(points: &[[f64; 2]], t: &[usize; 3]) -> [f64; 2] {
    let s = t
        .iter()
        .fold([0.0, 0.0], |s, &v| [s[0] + points[v][0], s[1] + points[v][1]]);
    [s[0] / 3.0, s[1] / 3.0]
}

fn bounding_diameter(points: &[[f64; 2]]) -> f64 {
    let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
    for p in points {
        for k in 0..2 {
            lo[k] = lo[k].min(p[k]);
            hi[k] = hi[k].max(p[k]);
        }
    }
    dist(lo, hi)
}

/// Whether the counter-clockwise triangle visits a then b as consecutive vertices.
fn traverses(tri: &[usize; 3], a: usize, b: usize) -> bool {
    (0..3).any(|k| tri[k] == a && tri[(k + 1) % 3] == b)
}

fn find(parent: &mut [usize], mut i: usize) -> usize {
    while parent[i] != i {
        parent[i] = parent[parent[i]];
        i = parent[i];
    }
    i
}

fn union(parent: &mut [usize], a: usize, b: usize) {
    let (ra, rb) = (find(parent, a), find(parent, b));
    if ra != rb {
        parent[ra.max(rb)] = ra.min(rb);
    }
}

/// A boundary vertex strictly inside another boundary edge (checked with a bucket grid).
fn hanging_node(points: &[[f64; 2]], boundary_edges: &[(usize, usize)], diameter: f64) -> Option<usize> {
    let mut vertices: Vec<usize> = boundary_edges.iter().flat_map(|&(a, b)| [a, b]).collect();
    vertices.sort_unstable();
    vertices.dedup();
    let grid = Buckets::new(vertices.iter().map(|&v| points[v]), vertices.len());
    for &(a, b) in boundary_edges {
        let (p, q) = (points[a], points[b]);
        let len = dist(p, q);
        for i in grid.near_box(min2(p, q), max2(p, q)) {
            let v = vertices[i];
            if v == a || v == b {
                continue;
            }
            let r = points[v];
            let along = ((r[0] - p[0]) * (q[0] - p[0]) + (r[1] - p[1]) * (q[1] - p[1])) / (len * len);
            if along > 0.0 && along < 1.0 && orient(p, q, r).abs() <= 1e-10 * len * diameter.max(len) {
                return Some(v);
            }
        }
    }
    None
}

fn min2(p: [f64; 2], q: [f64; 2]) -> [f64; 2] {
    [p[0].min(q[0]), p[1].min(q[1])]
}

fn max2(p: [f64; 2], q: [f64; 2]) -> [f64; 2] {
    [p[0].max(q[0]), p[1].max(q[1])]
}

/// A uniform grid of buckets over a bounding box, holding item indices by box overlap.
struct Buckets {
    lo: [f64; 2],
    cell: [f64; 2],
    dims: [usize; 2],
    start: Vec<usize>,
    items: Vec<usize>,
}

impl Buckets {
    /// Buckets for points, about one per bucket.
    fn new(points: impl Iterator<Item = [f64; 2]> + Clone, count: usize) -> Self {
        Self::from_boxes(points.map(|p| (p, p)), count)
    }

    fn from_boxes(boxes: impl Iterator<Item = ([f64; 2], [f64; 2])> + Clone, count: usize) -> Self {
        let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
        for (a, b) in boxes.clone() {
            lo = min2(lo, a);
            hi = max2(hi, b);
        }
        let side = (count.max(1) as f64).sqrt().ceil() as usize;
        let dims = [side.max(1), side.max(1)];
        let cell = [
            ((hi[0] - lo[0]) / dims[0] as f64).max(f64::MIN_POSITIVE),
            ((hi[1] - lo[1]) / dims[1] as f64).max(f64::MIN_POSITIVE),
        ];
        let mut grid = Buckets {
            lo,
            cell,
            dims,
            start: vec![0; dims[0] * dims[1] + 1],
            items: Vec::new(),
        };
        for (a, b) in boxes.clone() {
            for c in grid.cells(a, b) {
                grid.start[c + 1] += 1;
            }
        }
        for c in 0..dims[0] * dims[1] {
            grid.start[c + 1] += grid.start[c];
        }
        let mut fill = grid.start.clone();
        grid.items = vec![0; grid.start[dims[0] * dims[1]]];
        for (i, (a, b)) in boxes.enumerate() {
            for c in grid.cells(a, b) {
                grid.items[fill[c]] = i;
                fill[c] += 1;
            }
        }
        grid
    }

    fn index(&self, p: [f64; 2], k: usize) -> usize {
        (((p[k] - self.lo[k]) / self.cell[k]).floor().max(0.0) as usize).min(self.dims[k] - 1)
    }

    fn cells(&self, a: [f64; 2], b: [f64; 2]) -> impl Iterator<Item = usize> {
        let (i0, i1, j0, j1) = (
            self.index(a, 0),
            self.index(b, 0),
            self.index(a, 1),
            self.index(b, 1),
        );
        let nx = self.dims[0];
        (j0..=j1).flat_map(move |j| (i0..=i1).map(move |i| j * nx + i))
    }

    fn near_box(&self, a: [f64; 2], b: [f64; 2]) -> impl Iterator<Item = usize> + '_ {
        self.cells(a, b)
            .flat_map(move |c| self.items[self.start[c]..self.start[c + 1]].iter().copied())
    }
}

/// Point location in a mesh: the triangle containing a point and its barycentric coordinates.
struct Locator {
    grid: Buckets,
}

impl Locator {
    fn new(mesh: &Mesh) -> Self {
        let boxes = (0..mesh.triangles.len()).map(|t| {
            let [p, q, r] = mesh.corners(t);
            (min2(min2(p, q), r), max2(max2(p, q), r))
        });
        Locator {
            grid: Buckets::from_boxes(boxes, mesh.triangles.len()),
        }
    }

    fn locate(&self, mesh: &Mesh, p: [f64; 2]) -> (usize, [f64; 3]) {
        let mut best = (0, [1.0, 0.0, 0.0], f64::NEG_INFINITY);
        let candidates = self.grid.near_box(p, p);
        let search: Box<dyn Iterator<Item = usize>> = if self.grid.near_box(p, p).next().is_some() {
            Box::new(candidates)
        } else {
            Box::new(0..mesh.triangles.len())
        };
        for t in search {
            let b = barycentric(mesh.corners(t), p);
            let worst = b[0].min(b[1]).min(b[2]);
            if worst > best.2 {
                best = (t, b, worst);
                if worst >= -1e-12 {
                    break;
                }
            }
        }
        // Outside every triangle (a point of a finer boundary): clamp to the closest one.
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

/// Drops unused vertices and renumbers the rest, keeping their order.
fn compact(points: Vec<[f64; 2]>, triangles: Vec<[usize; 3]>) -> (Vec<[f64; 2]>, Vec<[usize; 3]>) {
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
        assert_eq!(m.triangles.len(), 24);
        assert_eq!(m.interior().len(), 3 * 2);
        assert!((m.measure() - 2.0).abs() < 1e-14);
        let c = Mesh::rectangle([0.0, 0.0], [1.0, 1.0], 2, 2, Diagonal::Crossed).unwrap();
        assert_eq!(
            (c.n_vertices(), c.triangles.len(), c.interior().len()),
            (13, 16, 5)
        );
    }

    #[test]
    fn l_shape_has_three_quadrants() {
        let m = Mesh::l_shape(8, Diagonal::Right, 1.0).unwrap();
        assert!((m.measure() - 3.0).abs() < 1e-13);
        assert_eq!(m.triangles.len(), 3 * 32);
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

    #[test]
    fn checks_reject_bad_meshes() {
        let sq = vec![[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0], [0.5, 0.5]];
        let fan = vec![[0, 1, 4], [1, 2, 4], [2, 3, 4], [3, 0, 4]];
        assert!(Mesh::new(sq.clone(), fan.clone()).is_ok());
        let mut flipped = fan.clone();
        flipped[1] = [1, 4, 2];
        assert!(
            Mesh::new(sq.clone(), flipped).is_ok(),
            "orientation alone is normalised"
        );
        let mut folded = sq.clone();
        folded[4] = [1.2, 0.5];
        assert!(matches!(
            Mesh::new(folded, fan.clone()),
            Err(MeshError::Inverted { .. })
        ));
        let mut dup = sq.clone();
        dup.push([0.5, 0.5]);
        assert!(matches!(
            Mesh::new(dup, fan.clone()),
            Err(MeshError::DuplicateVertex { first: 4, second: 5 })
        ));
        let mut flat = fan.clone();
        flat[0] = [0, 1, 0];
        assert!(matches!(
            Mesh::new(sq.clone(), flat),
            Err(MeshError::Degenerate { triangle: 0, .. })
        ));
        assert!(matches!(
            Mesh::new(sq.clone(), vec![[0, 1, 4]]),
            Err(MeshError::UnusedVertex { .. })
        ));
        let mut bad_index = fan.clone();
        bad_index[0][2] = 9;
        assert!(matches!(
            Mesh::new(sq.clone(), bad_index),
            Err(MeshError::VertexIndex { .. })
        ));
        // Two fans side by side sharing no edge: disconnected.
        let mut two = sq.clone();
        two.extend(sq.iter().map(|p| [p[0] + 3.0, p[1]]));
        let mut tris = fan.clone();
        tris.extend(fan.iter().map(|t| t.map(|v| v + 5)));
        assert!(matches!(
            Mesh::new(two, tris),
            Err(MeshError::Disconnected { components: 2 })
        ));
        // Hanging node: split the right triangle's neighbour only.
        let pts = vec![
            [0.0, 0.0],
            [1.0, 0.0],
            [1.0, 1.0],
            [0.0, 1.0],
            [2.0, 0.5],
            [1.0, 0.5],
        ];
        let tris = vec![[0, 1, 3], [1, 2, 3], [1, 4, 5], [5, 4, 2]];
        assert!(matches!(
            Mesh::new(pts, tris),
            Err(MeshError::HangingNode { vertex: 5 })
        ));
        assert!(matches!(
            Mesh::new(sq[..4].to_vec(), vec![[0, 1, 2], [0, 2, 3]]),
            Err(MeshError::NoInteriorVertex)
        ));
    }

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
    fn restriction_of_nested_loads_is_exact() {
        // (f, φ_A) on the coarse mesh = Pᵀ (f, φ_a) on its uniform refinement, for every diagonal.
        for diagonal in [Diagonal::Right, Diagonal::Left, Diagonal::Crossed] {
            let coarse = Mesh::rectangle([0.0, 0.0], [1.0, 2.0], 3, 2, diagonal).unwrap();
            let fine = Mesh::rectangle([0.0, 0.0], [1.0, 2.0], 6, 4, diagonal).unwrap();
            let f = crate::expr::Expr::parse("x*y + 1").unwrap();
            let quad = crate::assembly::Quadrature { degree: 4 };
            let direct = crate::assembly::load(&coarse, &f, quad).unwrap();
            let restricted =
                Prolongation::new(&fine, &coarse).restrict(&crate::assembly::load(&fine, &f, quad).unwrap());
            for (a, b) in direct.iter().zip(&restricted) {
                assert!((a - b).abs() < 1e-14, "{a} vs {b}");
            }
        }
    }
}
