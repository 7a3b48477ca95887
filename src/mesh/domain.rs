//! Domains given by their boundary — a polygon with holes, a disk or an annulus — meshed to a
//! size h by constrained Delaunay refinement (the `spade` crate), and the circles of a curved
//! boundary, onto which uniform refinement ([`Mesh::refined`]) places new boundary vertices.

use super::{boundary_is_simple, builtin::compact, orient, Mesh, MeshError};
use spade::{AngleLimit, ConstrainedDelaunayTriangulation, Point2, RefinementParameters, Triangulation};
use std::f64::consts::PI;

/// A domain ω given by its boundary.
#[derive(Debug, Clone, PartialEq)]
pub enum Domain {
    /// A polygon (vertices in order, either orientation) with polygonal holes.
    Polygon {
        /// The outer boundary.
        boundary: Vec<[f64; 2]>,
        /// The holes, each inside the boundary, disjoint from it and from each other.
        holes: Vec<Vec<[f64; 2]>>,
    },
    /// The disk of `radius` around `centre`, or the annulus inner_radius < r < radius.
    Disk {
        /// The centre.
        centre: [f64; 2],
        /// The outer radius.
        radius: f64,
        /// The radius of the hole, for an annulus.
        inner_radius: Option<f64>,
    },
}

/// The units in the last place of the largest coordinate a mesh size must span at least.
const RESOLUTION: f64 = 65536.0;

/// The areas h² of the triangles of a mesh size h that double precision computes to full
/// precision, with room for the products of a mesh's checks and of the estimator (smaller ones
/// are subnormal or 0: a disk of radius 1e-160 was refused as "overlapping itself").
const AREAS: std::ops::RangeInclusive<f64> = 1e-306..=1e306;

/// Whether an area (or a length squared) lies where double precision computes areas to full
/// precision (1e-306 … 1e306); the error says why not, after "lie" or "lies".
pub fn check_area(area: f64) -> Result<(), String> {
    match AREAS.contains(&area) {
        true => Ok(()),
        false => Err(format!(
            "outside the range double precision computes areas in ({:e} to {:e}): state the \
             case in other units of length",
            AREAS.start(),
            AREAS.end()
        )),
    }
}

/// The smallest angle spade's refinement keeps (above 30° it may not terminate).
const ANGLE_LIMIT_DEG: f64 = 25.0;

/// The area of an equilateral triangle of side h, per h²: the area bound of the refinement.
const EQUILATERAL: f64 = 0.433_012_701_892_219_3;

/// Vertices per area/h² of the meshes built here, from above (measured: 1.79–1.83 on disks and
/// polygons from 7k to 3.6M vertices, `examples/mesh_timing.rs`): the memory guard's estimate.
const VERTICES_PER_AREA: f64 = 2.0;

/// The same, as measured.
const VERTICES_MEASURED: f64 = 1.8;

impl Domain {
    /// Checks the geometry; errors name the key: at least three vertices per ring, finite
    /// coordinates, rings that neither cross nor touch themselves or each other, holes inside
    /// the boundary and not inside another hole; radii positive, the inner one below the outer.
    pub fn check(&self) -> Result<(), String> {
        match self {
            Domain::Disk {
                centre,
                radius,
                inner_radius,
            } => {
                if !centre.iter().all(|c| c.is_finite()) {
                    return Err(format!("key 'mesh.centre' = {centre:?}: need finite coordinates"));
                }
                if !(*radius > 0.0 && radius.is_finite()) {
                    return Err(format!("key 'mesh.radius' = {radius}: need a positive radius"));
                }
                match inner_radius {
                    Some(r) if !(*r > 0.0 && r < radius) => Err(format!(
                        "key 'mesh.inner_radius' = {r}: need 0 < inner_radius < radius = {radius}"
                    )),
                    _ => Ok(()),
                }
            }
            Domain::Polygon { boundary, holes } => check_polygon(boundary, holes),
        }
    }

    /// |ω|.
    pub fn area(&self) -> f64 {
        self.area_in(1.0)
    }

    /// The area in units of h² (the lengths divided by h before they are multiplied, so that
    /// neither underflows nor overflows where the ratio is of a mesh's size).
    fn area_in(&self, h: f64) -> f64 {
        let scaled = |ring: &[[f64; 2]]| -> Vec<[f64; 2]> { ring.iter().map(|p| p.map(|x| x / h)).collect() };
        match self {
            Domain::Disk {
                radius, inner_radius, ..
            } => PI * ((radius / h).powi(2) - inner_radius.map_or(0.0, |r| (r / h).powi(2))),
            Domain::Polygon { boundary, holes } => {
                ring_area(&scaled(boundary)).abs()
                    - holes.iter().map(|r| ring_area(&scaled(r)).abs()).sum::<f64>()
            }
        }
    }

    /// An estimate (from above) of the vertices of the mesh of size h, for the memory guard.
    /// The boundary points are counted, not made: the estimate costs no memory.
    pub fn estimated_vertices(&self, h: f64) -> usize {
        let rings = match self {
            Domain::Polygon { boundary, holes } => (std::iter::once(boundary).chain(holes))
                .flat_map(|ring| (0..ring.len()).map(|k| pieces(ring[k], ring[(k + 1) % ring.len()], h)))
                .fold(0usize, usize::saturating_add),
            Domain::Disk {
                radius, inner_radius, ..
            } => (std::iter::once(*radius).chain(*inner_radius))
                .map(|r| circle_points(r, h))
                .fold(0usize, usize::saturating_add),
        };
        ((VERTICES_PER_AREA * self.area_in(h)).min(1e18) as usize).saturating_add(rings)
    }

    /// Whether coordinates of this domain resolve the mesh size h: h must span at least
    /// 65 536 units in the last place of the largest coordinate, or the mesh's vertices
    /// (rounded to what f64 can hold there) would be too coarse a lattice for its triangles, or
    /// triangles of size h would have areas outside 1e-306 … 1e306 (`AREAS`).
    pub fn check_size(&self, h: f64) -> Result<(), String> {
        let largest = match self {
            Domain::Polygon { boundary, .. } => {
                boundary.iter().flatten().fold(0.0_f64, |m, c| m.max(c.abs()))
            }
            Domain::Disk { centre, radius, .. } => centre[0].abs().max(centre[1].abs()) + radius,
        };
        let unit = largest * f64::EPSILON;
        check_area(h * h)
            .map_err(|e| format!("h = {h:e}: the areas of triangles of this size (about h²) lie {e}"))?;
        if h < RESOLUTION * unit {
            return Err(format!(
                "h = {h:e} is too small for coordinates as large as {largest:e}: double precision \
                 resolves them to {unit:.1e}, and h needs at least {RESOLUTION} times that \
                 (move the domain nearer the origin)"
            ));
        }
        Ok(())
    }

    /// What a generated mesh's check found at `at`: a feature of the domain too small to mesh at
    /// its size (`why`: what double precision made of the triangles there), with a polygon's
    /// vertex nearest it.
    fn feature(&self, at: [f64; 2], why: &str) -> MeshError {
        let distance = |p: &[f64; 2]| (p[0] - at[0]).hypot(p[1] - at[1]);
        let remove = match self {
            Domain::Polygon { boundary, holes } => (std::iter::once(boundary).chain(holes).flatten())
                .min_by(|p, q| distance(p).total_cmp(&distance(q)))
                .map_or("remove the vertex".into(), |p| {
                    format!("remove the polygon's vertex nearest it, {},", super::Point(*p))
                }),
            Domain::Disk { .. } => "use a smaller h".into(),
        };
        MeshError::Generation(format!(
            "the domain has a feature near {} too small to mesh at its size ({why} to round-off): \
             {remove} or widen the feature",
            super::Point(at)
        ))
    }

    /// The circles ∂ω lies on (none for a polygon).
    pub fn curves(&self) -> Curves {
        match self {
            Domain::Polygon { .. } => Curves::default(),
            Domain::Disk {
                centre,
                radius,
                inner_radius,
            } => Curves {
                circles: std::iter::once(*radius)
                    .chain(*inner_radius)
                    .map(|r| (*centre, r))
                    .collect(),
            },
        }
    }

    /// The boundary rings with vertices at most h apart: the polygon's edges split evenly, or
    /// points evenly spaced on the circles (at least six).
    fn rings(&self, h: f64) -> Vec<Vec<[f64; 2]>> {
        match self {
            Domain::Polygon { boundary, holes } => std::iter::once(boundary)
                .chain(holes)
                .map(|ring| split_ring(ring, h))
                .collect(),
            Domain::Disk {
                centre,
                radius,
                inner_radius,
            } => std::iter::once(*radius)
                .chain(*inner_radius)
                .map(|r| {
                    let m = circle_points(r, h);
                    (0..m)
                        .map(|k| {
                            let t = 2.0 * PI * k as f64 / m as f64;
                            [centre[0] + r * t.cos(), centre[1] + r * t.sin()]
                        })
                        .collect()
                })
                .collect(),
        }
    }

    /// The domain in coordinates (x − origin)/unit.
    fn relative(&self, origin: [f64; 2], unit: f64) -> Domain {
        let moved = |p: &[f64; 2]| [(p[0] - origin[0]) / unit, (p[1] - origin[1]) / unit];
        match self {
            Domain::Polygon { boundary, holes } => Domain::Polygon {
                boundary: boundary.iter().map(moved).collect(),
                holes: (holes.iter()).map(|h| h.iter().map(moved).collect()).collect(),
            },
            Domain::Disk {
                centre,
                radius,
                inner_radius,
            } => Domain::Disk {
                centre: moved(centre),
                radius: radius / unit,
                inner_radius: inner_radius.map(|r| r / unit),
            },
        }
    }

    /// The domain of a triangulation, a polygon with holes (its rings of boundary edges, the one
    /// of the largest area the outer boundary), and the size h at which [`Domain::mesh`] gives
    /// about as many vertices (1.8 per area/h², as measured). None where the boundary
    /// touches itself at a vertex (two rings through it: no polygon with holes).
    pub fn of_mesh(mesh: &Mesh) -> Option<(Domain, f64)> {
        // The boundary edges, directed as their counter-clockwise triangles traverse them.
        let mut edges: Vec<(usize, usize)> = Vec::new();
        for t in mesh.triangles() {
            for k in 0..3 {
                let (a, b) = (t[k], t[(k + 1) % 3]);
                if mesh.on_boundary[a] && mesh.on_boundary[b] {
                    edges.push((a, b));
                }
            }
        }
        // An edge traversed once: (a, b) without (b, a).
        edges.sort_unstable();
        let has = |e: (usize, usize)| edges.binary_search(&e).is_ok();
        let mut next = vec![usize::MAX; mesh.n_vertices()];
        for &(a, b) in edges.iter().filter(|&&(a, b)| !has((b, a))) {
            if next[a] != usize::MAX {
                return None;
            }
            next[a] = b;
        }
        let mut rings: Vec<Vec<[f64; 2]>> = Vec::new();
        let mut seen = vec![false; mesh.n_vertices()];
        for start in (0..mesh.n_vertices()).filter(|&a| next[a] != usize::MAX) {
            let mut ring = Vec::new();
            let mut a = start;
            while !seen[a] {
                seen[a] = true;
                ring.push(mesh.points[a]);
                a = next[a];
            }
            if !ring.is_empty() {
                rings.push(ring);
            }
        }
        let outer = (0..rings.len())
            .max_by(|&i, &j| ring_area(&rings[i]).abs().total_cmp(&ring_area(&rings[j]).abs()))?;
        let boundary = rings.swap_remove(outer);
        let h = (VERTICES_MEASURED * mesh.measure() / mesh.n_vertices() as f64).sqrt();
        Some((
            Domain::Polygon {
                boundary,
                holes: rings,
            },
            h,
        ))
    }

    /// The domain as the coarser levels of multigrid and nested iteration see it at mesh size
    /// `size`: a polygon's rings simplified to within size/8 (Douglas–Peucker: boundary features
    /// below a coarse cell do not hold its vertices), holes that vanish dropped; a disk as it is.
    /// Where the simplified polygon is not simple (a hole near a narrow boundary feature), the
    /// polygon as it is.
    pub fn coarsened(&self, size: f64) -> Domain {
        let Domain::Polygon { boundary, holes } = self else {
            return self.clone();
        };
        let tolerance = size / 8.0;
        let boundary = simplified(boundary, tolerance);
        let holes = (holes.iter())
            .map(|h| simplified(h, tolerance))
            .filter(|h| h.len() >= 3)
            .collect();
        let coarse = Domain::Polygon { boundary, holes };
        match coarse.check() {
            Ok(()) => coarse,
            Err(_) => self.clone(),
        }
    }

    /// The mesh of size h: boundary vertices at most h apart (a polygon's closer where a feature
    /// nearby needs it), triangles of area at most that of the equilateral triangle of side h and
    /// angles of at least 25° where the boundary allows (spade's Delaunay refinement). The domain
    /// must have passed [`Domain::check`].
    pub fn mesh(&self, h: f64) -> Result<Mesh, MeshError> {
        // The mesh is made relative to a point of the domain (a disk's centre, a polygon's first
        // vertex where that moves every vertex exactly) in units of a power of two near its
        // extent, so that it is the same wherever the domain lies and whatever its size, and
        // spade's predicates see numbers near 1.
        let (origin, extent) = match self {
            Domain::Disk { centre, radius, .. } => (*centre, *radius),
            Domain::Polygon { boundary, holes } => {
                let points = || std::iter::once(boundary).chain(holes).flatten();
                // Per axis, the first vertex's coordinate where every difference from it is exact
                // in double precision (always within a factor 2 of it, Sterbenz; for coordinates
                // of few binary digits anywhere), else 0: the vertices stay as given.
                let o = [0, 1].map(|k| {
                    let c = boundary[0][k];
                    match points().all(|p| exact_difference(p[k], c)) {
                        true => c,
                        false => 0.0,
                    }
                });
                let far = points().fold(0.0_f64, |m, p| {
                    m.max((p[0] - o[0]).abs()).max((p[1] - o[1]).abs())
                });
                (o, far)
            }
        };
        let unit = 2f64.powi(extent.log2().round() as i32);
        let (relative, h) = (self.relative(origin, unit), h / unit);
        let rings = relative.rings(h);
        let mut points: Vec<Point2<f64>> = Vec::new();
        let mut edges = Vec::new();
        for ring in &rings {
            let start = points.len();
            points.extend(ring.iter().map(|p| Point2::new(p[0], p[1])));
            edges.extend((0..ring.len()).map(|k| [start + k, start + (k + 1) % ring.len()]));
        }
        let cdt =
            Cdt::bulk_load_cdt(points, edges).map_err(|e| MeshError::Generation(format!("spade: {e}")))?;
        // A polygon's edges are split where a feature closer than h needs smaller triangles (kept
        // whole, a hole 3e-4 from the outer boundary at h = 0.05 left slivers of 0.3°), unless
        // that takes more vertices than the budget (a feature far narrower than h): then they are
        // kept whole. A circle's chords stay whole, so that every boundary vertex lies on it.
        let budget = 4 * relative.estimated_vertices(h) + 1000;
        let split = matches!(self, Domain::Polygon { .. });
        let (cdt, outer) = (split.then(|| refined(&cdt, h, budget, true)).flatten())
            .or_else(|| refined(&cdt, h, budget, false))
            .ok_or_else(|| {
                MeshError::Generation(
                    "the Delaunay refinement did not finish within its vertex budget".into(),
                )
            })?;
        let triangles = (cdt.inner_faces())
            .filter(|f| !outer[f.fix().index()])
            .map(|f| f.vertices().map(|v| v.fix().index()))
            .collect();
        let points = (cdt.vertices())
            .map(|v| {
                [
                    v.position().x * unit + origin[0],
                    v.position().y * unit + origin[1],
                ]
            })
            .collect();
        let (points, triangles) = compact(points, triangles);
        // What the checks of a mesh find here is a feature of the domain or a size h it cannot have.
        let feature = |at: [f64; 2], why: &str| self.feature(at, why);
        Mesh::new(points, triangles).map_err(|e| match e {
            MeshError::Degenerate { at, .. } => feature(at, "a triangle there is flat"),
            MeshError::HangingNode { at, .. } => {
                feature(at, "a vertex there lies on another triangle's edge")
            }
            MeshError::Overlap { at, .. } => feature(at, "the triangles there overlap"),
            MeshError::NoInteriorVertex => MeshError::Generation(
                "h is too coarse for the domain: its mesh has no interior vertex; use a smaller h".into(),
            ),
            e => e,
        })
    }
}

/// The constrained triangulation of the boundary rings.
type Cdt = ConstrainedDelaunayTriangulation<Point2<f64>>;

/// `cdt` refined to size h by spade's Delaunay refinement, its constraint (boundary) edges split
/// where needed if `split`, with the faces outside ω marked; none if it needs more than `budget`
/// added vertices.
fn refined(cdt: &Cdt, h: f64, budget: usize, split: bool) -> Option<(Cdt, Vec<bool>)> {
    let parameters = RefinementParameters::new()
        .with_max_allowed_area(EQUILATERAL * h * h)
        .with_angle_limit(AngleLimit::from_deg(ANGLE_LIMIT_DEG))
        .exclude_outer_faces(true)
        .with_max_additional_vertices(budget);
    let parameters = match split {
        true => parameters,
        false => parameters.keep_constraint_edges(),
    };
    let mut cdt = cdt.clone();
    let result = cdt.refine(parameters);
    if !result.refinement_complete {
        return None;
    }
    let mut outer = vec![false; cdt.num_all_faces()];
    for f in &result.excluded_faces {
        outer[f.index()] = true;
    }
    Some((cdt, outer))
}

/// The circles on which parts of ∂ω lie, as (centre, radius).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Curves {
    circles: Vec<([f64; 2], f64)>,
}

impl Curves {
    /// Where the new vertex of the boundary edge pq goes: its midpoint, projected onto the circle
    /// p and q lie on, if any — so that refined meshes converge to the curved domain.
    pub fn boundary_midpoint(&self, p: [f64; 2], q: [f64; 2]) -> [f64; 2] {
        let m = [0.5 * (p[0] + q[0]), 0.5 * (p[1] + q[1])];
        // Within 1e-9 r, or the round-off of coordinates as large as |c| + r.
        let on = |x: [f64; 2], c: [f64; 2], r: f64| {
            let roundoff = 8.0 * f64::EPSILON * (c[0].abs().max(c[1].abs()) + r);
            ((x[0] - c[0]).hypot(x[1] - c[1]) - r).abs() <= (1e-9 * r).max(roundoff)
        };
        match self.circles.iter().find(|&&(c, r)| on(p, c, r) && on(q, c, r)) {
            Some(&(c, r)) => {
                let d = (m[0] - c[0]).hypot(m[1] - c[1]);
                [c[0] + (m[0] - c[0]) * r / d, c[1] + (m[1] - c[1]) * r / d]
            }
            None => m,
        }
    }
}

/// The signed area of a closed polygon (shoelace, about its first vertex: far from the origin,
/// terms about the origin would cancel).
fn ring_area(ring: &[[f64; 2]]) -> f64 {
    (1..ring.len())
        .map(|k| orient(ring[0], ring[k], ring[(k + 1) % ring.len()]))
        .sum::<f64>()
        * 0.5
}

/// Whether a − b is exact in double precision (the error term of Knuth's TwoSum is 0).
fn exact_difference(a: f64, b: f64) -> bool {
    let d = a - b;
    let virtual_b = a - d;
    let virtual_a = d + virtual_b;
    (a - virtual_a) + (virtual_b - b) == 0.0
}

/// The pieces of length at most h that the edge pq is split into (at least one).
fn pieces(p: [f64; 2], q: [f64; 2], h: f64) -> usize {
    ((super::dist(p, q) / h).ceil().min(1e9) as usize).max(1)
}

/// The points at most h apart evenly spaced on a circle of radius r (at least six).
fn circle_points(r: f64, h: f64) -> usize {
    ((2.0 * PI * r / h).ceil().min(1e9) as usize).max(6)
}

/// The closed ring simplified by Douglas–Peucker: the vertices kept are the first, the one
/// farthest from it, and recursively the one farthest from the chord between two kept ones while
/// more than `tolerance` from it.
fn simplified(ring: &[[f64; 2]], tolerance: f64) -> Vec<[f64; 2]> {
    let n = ring.len();
    let at = |k: usize| ring[k % n];
    let far = (0..n)
        .max_by(|&i, &j| super::dist(ring[0], ring[i]).total_cmp(&super::dist(ring[0], ring[j])))
        .unwrap_or(0);
    let mut keep = vec![false; n];
    keep[0] = true;
    keep[far] = true;
    let mut pieces = vec![(0, far), (far, n)];
    while let Some((i, j)) = pieces.pop() {
        let (p, q) = (at(i), at(j));
        let farthest = (i + 1..j)
            .map(|k| (k, distance_to_segment(at(k), p, q)))
            .max_by(|a, b| a.1.total_cmp(&b.1));
        if let Some((k, d)) = farthest.filter(|&(_, d)| d > tolerance) {
            debug_assert!(d.is_finite());
            keep[k] = true;
            pieces.push((i, k));
            pieces.push((k, j));
        }
    }
    (0..n).filter(|&k| keep[k]).map(|k| ring[k]).collect()
}

/// The distance from p to the segment qr.
fn distance_to_segment(p: [f64; 2], q: [f64; 2], r: [f64; 2]) -> f64 {
    let (d, e) = ([r[0] - q[0], r[1] - q[1]], [p[0] - q[0], p[1] - q[1]]);
    let length2 = d[0] * d[0] + d[1] * d[1];
    let t = if length2 > 0.0 {
        ((e[0] * d[0] + e[1] * d[1]) / length2).clamp(0.0, 1.0)
    } else {
        0.0
    };
    super::dist(p, [q[0] + t * d[0], q[1] + t * d[1]])
}

/// The ring with each edge split evenly into pieces of length at most h.
fn split_ring(ring: &[[f64; 2]], h: f64) -> Vec<[f64; 2]> {
    let mut out = Vec::new();
    for (k, &p) in ring.iter().enumerate() {
        let q = ring[(k + 1) % ring.len()];
        let pieces = pieces(p, q, h);
        out.extend((0..pieces).map(|i| {
            let t = i as f64 / pieces as f64;
            [p[0] + t * (q[0] - p[0]), p[1] + t * (q[1] - p[1])]
        }));
    }
    out
}

/// Whether p lies inside the closed polygon (crossing number; p is not on it).
fn inside(p: [f64; 2], ring: &[[f64; 2]]) -> bool {
    let mut odd = false;
    for k in 0..ring.len() {
        let (a, b) = (ring[k], ring[(k + 1) % ring.len()]);
        if (a[1] > p[1]) != (b[1] > p[1]) && p[0] < a[0] + (p[1] - a[1]) * (b[0] - a[0]) / (b[1] - a[1]) {
            odd = !odd;
        }
    }
    odd
}

/// The name of ring k in messages: the boundary, or hole k (from 1).
fn ring_name(k: usize) -> String {
    match k {
        0 => "'mesh.boundary'".into(),
        k => format!("'mesh.holes' (hole {k})"),
    }
}

fn check_polygon(boundary: &[[f64; 2]], holes: &[Vec<[f64; 2]>]) -> Result<(), String> {
    let rings: Vec<&[[f64; 2]]> = std::iter::once(boundary)
        .chain(holes.iter().map(Vec::as_slice))
        .collect();
    let (mut points, mut edges, mut ring_of) = (Vec::new(), Vec::new(), Vec::new());
    for (k, ring) in rings.iter().enumerate() {
        if ring.len() < 3 {
            return Err(format!(
                "key {} has {} vertices: a polygon needs at least 3",
                ring_name(k),
                ring.len()
            ));
        }
        if let Some(p) = ring.iter().find(|p| !(p[0].is_finite() && p[1].is_finite())) {
            return Err(format!("key {}: the vertex {p:?} is not finite", ring_name(k)));
        }
        if let Some(i) = (0..ring.len()).find(|&i| ring[i] == ring[(i + 1) % ring.len()]) {
            return Err(format!(
                "key {}: the vertex {:?} is repeated",
                ring_name(k),
                ring[i]
            ));
        }
        let start = points.len();
        points.extend_from_slice(ring);
        edges.extend((0..ring.len()).map(|i| (start + i, start + (i + 1) % ring.len())));
        ring_of.extend(std::iter::repeat_n(k, ring.len()));
    }
    if let Err(MeshError::BoundaryCrossing { first, second }) = boundary_is_simple(&points, &edges) {
        let (a, b) = (ring_of[first.0], ring_of[second.0]);
        let at = |(i, j): (usize, usize)| format!("{:?}–{:?}", points[i], points[j]);
        return Err(if a == b {
            format!(
                "key {}: the edges {} and {} meet: the polygon must not intersect or touch itself",
                ring_name(a),
                at(first),
                at(second)
            )
        } else {
            format!(
                "key {} touches or crosses key {} (edges {} and {}): holes must lie strictly inside the boundary and apart",
                ring_name(b.max(a)),
                ring_name(a.min(b)),
                at(first),
                at(second)
            )
        });
    }
    for (k, hole) in holes.iter().enumerate() {
        if !inside(hole[0], boundary) {
            return Err(format!(
                "key {} lies outside key 'mesh.boundary'",
                ring_name(k + 1)
            ));
        }
        if let Some(j) = (0..holes.len()).find(|&j| j != k && inside(hole[0], &holes[j])) {
            return Err(format!(
                "key {} lies inside key {}",
                ring_name(k + 1),
                ring_name(j + 1)
            ));
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn square_with_hole() -> Domain {
        Domain::Polygon {
            boundary: vec![[0.0, 0.0], [2.0, 0.0], [2.0, 1.0], [1.0, 1.5], [0.0, 1.0]],
            holes: vec![vec![[0.5, 0.3], [0.5, 0.7], [0.9, 0.5]]],
        }
    }

    /// The difference is exact where it is representable: within a factor 2 (Sterbenz), of few
    /// binary digits across 0, or far apart in scale only when the bits fit.
    #[test]
    fn exact_differences_are_told_from_rounded_ones() {
        for (a, b) in [
            (1.5, -0.25),
            (3.0, 1.0),
            (1e16, 1e16 - 2.0),
            (-1.0, 1.0),
            (0.7, 0.4),
        ] {
            assert!(exact_difference(a, b), "{a} − {b}");
        }
        for (a, b) in [
            (1.0, 2f64.powi(-60)),
            (2f64.powi(60), 1.0),
            (0.1, 1e-20),
            (1.0, 0.1),
        ] {
            assert!(!exact_difference(a, b), "{a} − {b}");
        }
    }

    #[test]
    fn polygon_with_hole_has_the_polygons_area() {
        let d = square_with_hole();
        d.check().unwrap();
        let exact = 2.0 + 0.5 - 0.5 * 0.4 * 0.4;
        assert!((d.area() - exact).abs() < 1e-14);
        for h in [0.2, 0.05] {
            let m = d.mesh(h).unwrap();
            assert!((m.measure() - exact).abs() < 1e-13, "{}", m.measure());
            // Triangles about as large as asked (those at the boundary may exceed the area bound).
            let largest = (0..m.n_triangles()).map(|t| m.area(t)).fold(0.0, f64::max);
            assert!(
                largest <= 1.5 * EQUILATERAL * h * h && m.h() <= 1.5 * h,
                "{largest}, {}",
                m.h()
            );
            assert!(
                m.n_vertices() <= d.estimated_vertices(h),
                "{} vertices",
                m.n_vertices()
            );
            // No triangle in the hole.
            let hole = [[0.5, 0.3], [0.5, 0.7], [0.9, 0.5]];
            assert!((0..m.n_triangles()).all(|t| {
                let [p, q, r] = m.corners(t);
                !inside([(p[0] + q[0] + r[0]) / 3.0, (p[1] + q[1] + r[1]) / 3.0], &hole)
            }));
        }
    }

    /// The smallest angle of the mesh's triangles, in degrees.
    fn smallest_angle(m: &Mesh) -> f64 {
        let angle = |p: [f64; 2], q: [f64; 2], r: [f64; 2]| {
            let (a, b) = ([q[0] - p[0], q[1] - p[1]], [r[0] - p[0], r[1] - p[1]]);
            (a[0] * b[1] - a[1] * b[0])
                .atan2(a[0] * b[0] + a[1] * b[1])
                .abs()
                .to_degrees()
        };
        (0..m.n_triangles())
            .flat_map(|t| {
                let [p, q, r] = m.corners(t);
                [angle(p, q, r), angle(q, r, p), angle(r, p, q)]
            })
            .fold(180.0, f64::min)
    }

    #[test]
    fn a_hole_close_to_the_boundary_leaves_no_slivers() {
        let square = vec![[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]];
        let hole = |gap: f64| vec![[0.3, gap], [0.7, gap], [0.7, 0.4], [0.3, 0.4]];
        let near = Domain::Polygon {
            boundary: square.clone(),
            holes: vec![hole(3e-4)],
        };
        near.check().unwrap();
        let m = near.mesh(0.05).unwrap();
        assert!(smallest_angle(&m) >= 20.0, "{}°", smallest_angle(&m));
        assert!((m.measure() - (1.0 - 0.4 * (0.4 - 3e-4))).abs() < 1e-13);
        // Far narrower than h, the gap would take more vertices than the budget: the boundary
        // edges are kept whole and the mesh still made, with slivers.
        let narrowest = Domain::Polygon {
            boundary: square,
            holes: vec![hole(1e-8)],
        };
        let m = narrowest.mesh(0.05).unwrap();
        assert!(m.n_vertices() <= narrowest.estimated_vertices(0.05));
        assert!((m.measure() - (1.0 - 0.4 * (0.4 - 1e-8))).abs() < 1e-13);
    }

    #[test]
    fn disk_and_annulus_vertices_lie_on_their_circles() {
        let d = Domain::Disk {
            centre: [1.0, -1.0],
            radius: 2.0,
            inner_radius: Some(0.5),
        };
        d.check().unwrap();
        let m = d.mesh(0.2).unwrap();
        let c = d.curves();
        for (a, p) in m.points.iter().enumerate() {
            let r = (p[0] - 1.0).hypot(p[1] + 1.0);
            assert_eq!(
                m.on_boundary[a],
                (r - 2.0).abs() < 1e-12 || (r - 0.5).abs() < 1e-12
            );
        }
        // A boundary edge's new vertex goes onto its circle; an interior edge's stays at its middle.
        let q = c.boundary_midpoint([3.0, -1.0], [1.0, 1.0]);
        assert!(((q[0] - 1.0).hypot(q[1] + 1.0) - 2.0).abs() < 1e-14);
        assert_eq!(c.boundary_midpoint([1.0, -1.0], [2.0, -1.0]), [1.5, -1.0]);
    }

    #[test]
    fn bad_polygons_are_refused_with_the_key() {
        let check = |boundary: Vec<[f64; 2]>, holes: Vec<Vec<[f64; 2]>>| {
            Domain::Polygon { boundary, holes }.check().unwrap_err()
        };
        let square = vec![[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]];
        let bowtie = vec![[0.0, 0.0], [1.0, 1.0], [1.0, 0.0], [0.0, 1.0]];
        assert!(check(bowtie, vec![]).contains("must not intersect"));
        assert!(check(square[..2].to_vec(), vec![]).contains("2 vertices"));
        let outside = vec![[2.0, 2.0], [3.0, 2.0], [2.0, 3.0]];
        assert!(check(square.clone(), vec![outside]).contains("outside"));
        let touching = vec![[0.0, 0.5], [0.5, 0.4], [0.5, 0.6]];
        assert!(check(square.clone(), vec![touching]).contains("touches or crosses key 'mesh.boundary'"));
        let (big, small) = (
            vec![[0.2, 0.2], [0.8, 0.2], [0.5, 0.8]],
            vec![[0.45, 0.4], [0.55, 0.4], [0.5, 0.5]],
        );
        assert!(check(square, vec![big, small]).contains("inside key 'mesh.holes' (hole 1)"));
        let disk = |radius, inner_radius| Domain::Disk {
            centre: [0.0, 0.0],
            radius,
            inner_radius,
        };
        assert!(disk(0.0, None).check().unwrap_err().contains("'mesh.radius' = 0"));
        assert!(disk(1.0, Some(1.0)).check().unwrap_err().contains("inner_radius"));
    }
}
