//! Conforming triangulations T_h of a polygon ω: the checks that make a set of triangles one,
//! the boundary ∂ω, built-in meshes ([`builtin`]), meshes of polygons and disks ([`domain`]),
//! mesh files ([`file`](mod@file)), uniform refinement ([`refine`]), newest-vertex bisection
//! ([`bisect`]), the dual submesh S_h ([`dual`]) and P1 transfer between meshes ([`transfer`]).

pub mod bisect;
mod buckets;
pub mod builtin;
pub mod domain;
pub mod dual;
pub mod file;
pub mod groups;
mod msh;
pub mod refine;
pub mod transfer;

pub use builtin::Diagonal;
pub use domain::{Curves, Domain};
pub use dual::{DualMesh, Edges};
pub use groups::Groups;
pub use transfer::Prolongation;

use buckets::Buckets;
use std::fmt;
use std::path::Path;

/// A triangle mesh with counter-clockwise triangles and its boundary vertices.
#[derive(Debug, Clone, PartialEq)]
pub struct Mesh {
    /// The vertices.
    pub points: Vec<[f64; 2]>,
    /// The triangles, counter-clockwise, their vertex numbers in 32 bits (a third of the mesh's
    /// memory less than in 64; see [`Mesh::triangle`]).
    triangles: Vec<[u32; 3]>,
    /// `on_boundary[a]`: vertex a lies on ∂ω (an endpoint of an edge with one triangle).
    pub on_boundary: Vec<bool>,
    /// The physical groups of a Gmsh file, kept through refinement ([`Mesh::groups`]).
    groups: Option<Box<Groups>>,
}

/// Why a set of points and triangles is not a valid mesh.
#[allow(missing_docs)] // the variants are told by their messages
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
        /// Its centroid.
        at: [f64; 2],
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
    DuplicateTriangle {
        triangle: usize,
        first: usize,
    },
    HangingNode {
        vertex: usize,
        at: [f64; 2],
    },
    Overlap {
        vertex: usize,
        at: [f64; 2],
        turns: f64,
    },
    BoundaryCrossing {
        first: (usize, usize),
        second: (usize, usize),
    },
    Disconnected {
        components: usize,
        /// A vertex where two components meet, if any (they share no edge).
        joined_at: Option<usize>,
    },
    NoInteriorVertex,
    Generation(String),
    TooLarge {
        vertices: usize,
        needed_gb: f64,
        available_gb: f64,
        /// What bounds the memory available ([`available_memory`]).
        limit: &'static str,
    },
}

impl fmt::Display for MeshError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let names = Names {
            vertex: &|v| format!("vertex {v}"),
            triangle: &|t| format!("triangle {t}"),
        };
        f.write_str(&self.message(&names))
    }
}

/// A point as a message shows it: (x, y), each coordinate in its shortest form that reads back
/// exactly, in scientific notation when it is far from 1 (1e300, not 301 digits).
#[derive(Debug, Clone, Copy)]
pub struct Point(pub [f64; 2]);

impl fmt::Display for Point {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "({}, {})", Number(self.0[0]), Number(self.0[1]))
    }
}

/// A number as a message shows it: its shortest form that reads back exactly, in scientific
/// notation when it is far from 1 (1e-181, not 183 digits).
#[derive(Debug, Clone, Copy)]
pub struct Number(pub f64);

impl fmt::Display for Number {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let x = self.0;
        match x.abs() {
            a if a == 0.0 || (1e-4..1e16).contains(&a) || !a.is_finite() => write!(f, "{x}"),
            _ => write!(f, "{x:e}"),
        }
    }
}

/// How a message names a vertex and a triangle of the mesh.
struct Names<'a> {
    vertex: &'a dyn Fn(usize) -> String,
    triangle: &'a dyn Fn(usize) -> String,
}

/// The tags a mesh file gives its vertices and triangles (a Gmsh file's node and element tags),
/// in the order of the mesh's numbers.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Tags {
    /// The node tag of each vertex.
    pub nodes: Vec<u64>,
    /// The element tag of each triangle.
    pub triangles: Vec<u64>,
}

impl MeshError {
    /// The message, with the vertices and triangles named by the file's `tags` ("node 12",
    /// "triangle element 40") instead of their numbers from 0.
    pub fn with_tags(&self, tags: &Tags) -> String {
        let tag = |list: &[u64], i: usize| list.get(i).map_or(i.to_string(), u64::to_string);
        let names = Names {
            vertex: &|v| format!("node {}", tag(&tags.nodes, v)),
            triangle: &|t| format!("triangle element {}", tag(&tags.triangles, t)),
        };
        self.message(&names)
    }

    /// The message, naming vertices and triangles by `names`.
    fn message(&self, names: &Names) -> String {
        let (v, t) = (names.vertex, names.triangle);
        match self {
            MeshError::Empty => "the mesh has no triangles".into(),
            MeshError::NotFinite { vertex } => format!("{} has a non-finite coordinate", v(*vertex)),
            MeshError::VertexIndex { triangle, index } => {
                format!("{} refers to vertex {index}, which does not exist", t(*triangle))
            }
            MeshError::Degenerate { triangle, area, at } if area.is_finite() => format!(
                "{} (near {}) has zero area to round-off ({area:e}, at most 1e-13 of the mesh's \
                 diameter squared) or repeats a vertex",
                t(*triangle),
                Point(*at)
            ),
            MeshError::Degenerate { triangle, at, .. } => format!(
                "{} (near {}) has an area that overflows double precision: scale the mesh down",
                t(*triangle),
                Point(*at)
            ),
            MeshError::DuplicateVertex { first, second } => {
                format!("{} and {} have the same coordinates", v(*first), v(*second))
            }
            MeshError::UnusedVertex { vertex } => format!("{} belongs to no triangle", v(*vertex)),
            MeshError::NonManifoldEdge { a, b, count } => {
                format!(
                    "the edge from {} to {} is shared by {count} triangles",
                    v(*a),
                    v(*b)
                )
            }
            MeshError::DuplicateTriangle { triangle, first } => {
                format!("{} repeats {} (the same three vertices)", t(*triangle), t(*first))
            }
            MeshError::Inverted { triangle, neighbour } => format!(
                "{} overlaps its neighbour {}: it is inverted (folded mesh)",
                t(*triangle),
                t(*neighbour)
            ),
            MeshError::HangingNode { vertex, at } => format!(
                "{} (at {}) lies inside an edge of another triangle: a hanging node (non-conforming mesh)",
                v(*vertex),
                Point(*at)
            ),
            MeshError::Overlap { vertex, at, turns } => format!(
                "the triangles around {} (at {}) turn {turns:.3} times around it: the mesh overlaps itself",
                v(*vertex),
                Point(*at)
            ),
            MeshError::BoundaryCrossing { first, second } => format!(
                "the boundary edges {}–{} and {}–{} meet away from a shared vertex: the mesh \
                 overlaps itself",
                v(first.0),
                v(first.1),
                v(second.0),
                v(second.1)
            ),
            MeshError::Disconnected {
                components,
                joined_at: None,
            } => format!("the mesh has {components} separate components; ω must be connected"),
            MeshError::Disconnected {
                components,
                joined_at: Some(vertex),
            } => format!(
                "the mesh has {components} components that share no edge, two of them meeting only at \
                 {}; ω must be connected through edges",
                v(*vertex)
            ),
            MeshError::NoInteriorVertex => "the mesh has no interior vertex: nothing to solve".into(),
            MeshError::Generation(why) => format!("the mesh could not be generated: {why}"),
            // A count that saturated (e.g. 30 refinements) is past any memory.
            MeshError::TooLarge {
                vertices: usize::MAX, ..
            } => format!(
                "the mesh would have more than {:.1e} vertices: use a coarser mesh or fewer \
                 refinements",
                usize::MAX as f64
            ),
            MeshError::TooLarge {
                vertices,
                needed_gb,
                available_gb,
                limit,
            } => format!(
                "{vertices} vertices need about {needed_gb:.1} GB of memory, but only {available_gb:.1} GB \
                 are available ({limit}): use a coarser mesh"
            ),
        }
    }
}

impl std::error::Error for MeshError {}

/// Peak memory of a solve per mesh vertex with the multigrid solver, with a margin (the measured
/// peaks are in the README's speed section).
pub const MULTIGRID_BYTES_PER_VERTEX: f64 = 800.0;
/// The same with the direct solver (whose Cholesky factors grow like n log n).
pub const DIRECT_BYTES_PER_VERTEX: f64 = 2700.0;

/// What a run computes after the solve, whose peak the memory guard prices beside the solver's
/// (the solver's memory is freed by then: the run's peak is the larger of the two).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Postprocess {
    /// The fluxes t_ih (4.13) on the dual submesh.
    pub flux: bool,
    /// The a posteriori estimator.
    pub estimate: bool,
    /// ‖λ − λ_h‖_H⁻¹, a Cholesky solve on S_h (about six times the vertices).
    pub hminus1: bool,
}

impl Postprocess {
    /// Peak bytes per vertex after the solve, with a margin over the peaks measured at 512² and
    /// 1024² (default case, multigrid: 1.9 and 1.8 kB with the flux, 0.9 and 0.8 kB with the
    /// estimate, 2.0 and 2.0 kB with both).
    /// With ‖λ − λ_h‖_H⁻¹ (measured 5.3 and 5.6 kB at 256² and 512²), 6.5 kB whatever else.
    pub fn bytes_per_vertex(self) -> f64 {
        match (self.hminus1, self.flux, self.estimate) {
            (true, _, _) => 6500.0,
            (false, false, false) => 0.0,
            (false, true, false) => 2000.0,
            (false, false, true) => 1100.0,
            (false, true, true) => 2400.0,
        }
    }
}

/// Fails early, with an estimate, when a mesh of `vertices` vertices would not fit in the memory
/// this process may still use at `bytes_per_vertex` ([`available_memory`]; no check where none
/// of its bounds can be read).
pub fn check_memory(vertices: usize, bytes_per_vertex: f64) -> Result<(), MeshError> {
    let needed = vertices as f64 * bytes_per_vertex;
    match available_memory() {
        Some((available, limit)) if needed > available as f64 => Err(MeshError::TooLarge {
            vertices,
            needed_gb: needed / 1e9,
            available_gb: available as f64 / 1e9,
            limit,
        }),
        _ => Ok(()),
    }
}

/// The memory this process may still use, in bytes, and what bounds it: the least of the memory
/// available now (`MemAvailable` of /proc/meminfo), what the process's limits on its address space
/// and its data leave of them (`ulimit -v`, `ulimit -d`), and what the memory limits of its cgroup
/// and the groups above it leave (a container's or a batch job's: the usage less inactive file
/// pages counted as used); `None` where none can be read.
pub fn available_memory() -> Option<(u64, &'static str)> {
    let kb = |text: &str, key: &str| -> Option<u64> {
        let line = text.lines().find(|l| l.starts_with(key))?;
        Some(
            line.split_whitespace()
                .nth(1)?
                .parse::<u64>()
                .ok()?
                .saturating_mul(1024),
        )
    };
    let meminfo = std::fs::read_to_string("/proc/meminfo").ok();
    let status = std::fs::read_to_string("/proc/self/status").ok();
    let status = status.as_deref().unwrap_or("");
    let left = |resource, used: Option<u64>| {
        let limit = nix::sys::resource::getrlimit(resource).ok()?.0;
        (limit != nix::sys::resource::RLIM_INFINITY).then(|| limit.saturating_sub(used.unwrap_or(0)))
    };
    use nix::sys::resource::Resource;
    [
        (
            meminfo.as_deref().and_then(|m| kb(m, "MemAvailable:")),
            "free memory",
        ),
        (left(Resource::RLIMIT_AS, kb(status, "VmSize:")), "ulimit -v"),
        (left(Resource::RLIMIT_DATA, kb(status, "VmData:")), "ulimit -d"),
        (cgroup_left(), "the cgroup's memory limit"),
    ]
    .into_iter()
    .filter_map(|(bytes, limit)| Some((bytes?, limit)))
    .min_by_key(|&(bytes, _)| bytes)
}

/// What the memory limits of this process's cgroup and of the groups above it (a batch job's may
/// be set on its parent) leave, if any has one: the least over them of the limit less the memory
/// in use that the kernel cannot reclaim (the usage less its inactive file pages, as container
/// runtimes count a working set). cgroup v2: `memory.max`, `memory.current` and `memory.stat`'s
/// `inactive_file`, its hierarchy at /sys/fs/cgroup or, beside v1, /sys/fs/cgroup/unified; v1:
/// `memory.limit_in_bytes`, `memory.usage_in_bytes` and `total_inactive_file`.
fn cgroup_left() -> Option<u64> {
    let groups = std::fs::read_to_string("/proc/self/cgroup").ok()?;
    let read = |dir: &Path, file: &str| std::fs::read_to_string(dir.join(file)).ok();
    let left_in = |dir: &Path, [limit, used, inactive]: [&str; 3]| -> Option<u64> {
        let number = |file: &str| read(dir, file)?.trim().parse::<u64>().ok();
        // v1 writes "no limit" as a huge number, v2 as "max" (not a number).
        let limit = number(limit).filter(|&l| l < 1 << 60)?;
        let stat = read(dir, "memory.stat").unwrap_or_default();
        let inactive = (stat.lines())
            .find_map(|l| l.strip_prefix(inactive)?.trim().parse::<u64>().ok())
            .unwrap_or(0);
        Some(limit.saturating_sub(number(used).unwrap_or(0).saturating_sub(inactive)))
    };
    let v2 = (
        ["/sys/fs/cgroup", "/sys/fs/cgroup/unified"].as_slice(),
        ["memory.max", "memory.current", "inactive_file "],
    );
    let v1 = (
        ["/sys/fs/cgroup/memory"].as_slice(),
        [
            "memory.limit_in_bytes",
            "memory.usage_in_bytes",
            "total_inactive_file ",
        ],
    );
    (groups.lines())
        .filter_map(|line| {
            let mut parts = line.splitn(3, ':');
            let (id, controllers, path) = (parts.next()?, parts.next()?, parts.next()?);
            let (roots, files) = match (id, controllers.split(',').any(|c| c == "memory")) {
                ("0", _) => v2,
                (_, true) => v1,
                _ => return None,
            };
            let group = path.trim_start_matches('/');
            let root = roots.iter().map(Path::new).find(|r| r.join(group).is_dir())?;
            let dir = root.join(group);
            (dir.ancestors().take_while(|d| d.starts_with(root)))
                .filter_map(|d| left_in(d, files))
                .min()
        })
        .min()
}

/// Twice the signed area of the triangle (p, q, r).
#[inline]
pub fn orient(p: [f64; 2], q: [f64; 2], r: [f64; 2]) -> f64 {
    (q[0] - p[0]) * (r[1] - p[1]) - (q[1] - p[1]) * (r[0] - p[0])
}

/// The triangles around each vertex (its star), with the vertex's corner in each: for row-wise
/// assembly and point location.
pub struct Stars {
    start: Vec<u32>,
    /// 3 t + k for corner k of triangle t.
    corner: Vec<u32>,
}

impl Stars {
    /// The stars of the vertices of `mesh`.
    pub fn new(mesh: &Mesh) -> Self {
        let n = mesh.n_vertices();
        // Corners are numbered 3 t + k in 32 bits (the memory guard stops meshes long before).
        assert!(
            u32::try_from(3 * mesh.n_triangles()).is_ok(),
            "3 × triangles exceed 2³²"
        );
        let mut start = vec![0u32; n + 1];
        for t in mesh.triangles() {
            for a in t {
                start[a + 1] += 1;
            }
        }
        for a in 0..n {
            start[a + 1] += start[a];
        }
        let mut fill = start.clone();
        let mut corner = vec![0u32; 3 * mesh.n_triangles()];
        for (t, tri) in mesh.triangles().enumerate() {
            for (k, &a) in tri.iter().enumerate() {
                corner[fill[a] as usize] = (3 * t + k) as u32;
                fill[a] += 1;
            }
        }
        Stars { start, corner }
    }

    /// The number of triangles around vertex a.
    pub fn len(&self, a: usize) -> usize {
        (self.start[a + 1] - self.start[a]) as usize
    }

    /// The triangles t around vertex a, in increasing order, with a's corner k in each.
    #[inline]
    pub fn around(&self, a: usize) -> impl Iterator<Item = (usize, usize)> + '_ {
        let range = self.start[a] as usize..self.start[a + 1] as usize;
        self.corner[range]
            .iter()
            .map(|&c| (c as usize / 3, c as usize % 3))
    }

    /// The corners 3 t + k of the triangles t around vertex a (k: a's corner in t).
    #[inline]
    pub fn corners(&self, a: usize) -> impl Iterator<Item = usize> + '_ {
        let range = self.start[a] as usize..self.start[a + 1] as usize;
        self.corner[range].iter().map(|&c| c as usize)
    }
}

impl Mesh {
    /// Checks a mesh read or built from points and triangles and orients its triangles
    /// counter-clockwise. Rejects everything that is not a conforming triangulation of a
    /// connected polygon with at least one interior vertex: locally one-to-one (the triangles
    /// around an interior vertex turn once around it, around a boundary vertex less than once)
    /// and one-to-one on the boundary (no two boundary edges meet but at a shared vertex), which
    /// together make the triangles cover ω exactly once.
    pub fn new(points: Vec<[f64; 2]>, mut triangles: Vec<[usize; 3]>) -> Result<Self, MeshError> {
        let diameter = finite_and_numbered(&points, &triangles)?;
        let used = orient_triangles(&points, &mut triangles, diameter)?;
        distinct_vertices(&points)?;
        if let Some(vertex) = used.iter().position(|u| !u) {
            return Err(MeshError::UnusedVertex { vertex });
        }
        let (on_boundary, boundary_edges, (components, joined_at)) = match_edges(points.len(), &triangles)?;
        // A hanging node is a vertex lying inside a boundary edge of the triangle set.
        if let Some(vertex) = hanging_node(&points, &boundary_edges, diameter) {
            return Err(MeshError::HangingNode {
                vertex,
                at: points[vertex],
            });
        }
        if components > 1 {
            return Err(MeshError::Disconnected {
                components,
                joined_at,
            });
        }
        turns_once(&points, &triangles, &on_boundary)?;
        boundary_is_simple(&points, &boundary_edges)?;
        if on_boundary.iter().all(|&b| b) {
            return Err(MeshError::NoInteriorVertex);
        }
        Ok(Mesh::from_parts(points, triangles, on_boundary))
    }

    /// A triangulation valid by its construction (the built-in meshes), with its boundary
    /// vertices: its points checked finite and its triangles for area and turned
    /// counter-clockwise; [`Mesh::new`]'s checks of a triangulation from elsewhere, which the
    /// built-in meshes' tests run on them, are skipped (docs/performance.md).
    pub(super) fn constructed(
        points: Vec<[f64; 2]>,
        mut triangles: Vec<[usize; 3]>,
        on_boundary: Vec<bool>,
    ) -> Result<Self, MeshError> {
        let diameter = finite_and_numbered(&points, &triangles)?;
        orient_triangles(&points, &mut triangles, diameter)?;
        if on_boundary.iter().all(|&b| b) {
            return Err(MeshError::NoInteriorVertex);
        }
        Ok(Mesh::from_parts(points, triangles, on_boundary))
    }

    /// The mesh of a valid triangulation (made by [`Mesh::new`] or [`Mesh::constructed`], which check that its vertex
    /// numbers fit in 32 bits, or from the vertices of one).
    pub(crate) fn from_parts(
        points: Vec<[f64; 2]>,
        triangles: Vec<[usize; 3]>,
        on_boundary: Vec<bool>,
    ) -> Self {
        let triangles = triangles.into_iter().map(|t| t.map(|a| a as u32)).collect();
        Mesh {
            points,
            triangles,
            on_boundary,
            groups: None,
        }
    }

    /// The number of vertices.
    pub fn n_vertices(&self) -> usize {
        self.points.len()
    }

    /// The number of triangles.
    pub fn n_triangles(&self) -> usize {
        self.triangles.len()
    }

    /// The vertex numbers of triangle t, counter-clockwise.
    #[inline]
    pub fn triangle(&self, t: usize) -> [usize; 3] {
        self.triangles[t].map(|a| a as usize)
    }

    /// The vertex numbers of every triangle, in order.
    pub fn triangles(&self) -> impl ExactSizeIterator<Item = [usize; 3]> + Clone + '_ {
        self.triangles.iter().map(|t| t.map(|a| a as usize))
    }

    /// The corners (lowest, highest) of the smallest box holding the vertices.
    pub fn bounding_box(&self) -> ([f64; 2], [f64; 2]) {
        (self.points.iter()).fold(([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]), |(lo, hi), p| {
            (
                [lo[0].min(p[0]), lo[1].min(p[1])],
                [hi[0].max(p[0]), hi[1].max(p[1])],
            )
        })
    }

    /// The vertices of triangle t.
    #[inline]
    pub fn corners(&self, t: usize) -> [[f64; 2]; 3] {
        let [a, b, c] = self.triangle(t);
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
        let pieces = crate::parallel::map(self.n_triangles(), crate::parallel::PIECE, |range| {
            range.map(|t| self.diameter(t)).fold(0.0, f64::max)
        });
        pieces.into_iter().fold(0.0, f64::max)
    }

    /// The diameter of triangle t: its longest edge.
    pub fn diameter(&self, t: usize) -> f64 {
        let [p, q, r] = self.corners(t);
        dist(p, q).max(dist(q, r)).max(dist(r, p))
    }

    /// |ω|.
    pub fn measure(&self) -> f64 {
        (0..self.n_triangles()).map(|t| self.area(t)).sum()
    }

    /// The interior vertices V_h, in increasing order.
    #[cfg(test)]
    pub fn interior(&self) -> Vec<usize> {
        (0..self.n_vertices()).filter(|&a| !self.on_boundary[a]).collect()
    }

    /// The edges of the mesh as sorted vertex pairs, each once.
    pub fn edges(&self) -> Vec<(usize, usize)> {
        let mut e: Vec<(usize, usize)> = self
            .triangles()
            .flat_map(|t| (0..3).map(move |k| (t[k].min(t[(k + 1) % 3]), t[k].max(t[(k + 1) % 3]))))
            .collect();
        e.sort_unstable();
        e.dedup();
        e
    }
}

/// The diameter of the bounding box of `points`, once they are checked finite, there are
/// triangles, and vertex numbers fit in 32 bits (far beyond what the memory guard lets through:
/// an assertion rather than an error).
fn finite_and_numbered(points: &[[f64; 2]], triangles: &[[usize; 3]]) -> Result<f64, MeshError> {
    assert!(
        u32::try_from(points.len()).is_ok(),
        "vertex numbers fit in 32 bits"
    );
    if triangles.is_empty() {
        return Err(MeshError::Empty);
    }
    if let Some(vertex) = points.iter().position(|p| !p[0].is_finite() || !p[1].is_finite()) {
        return Err(MeshError::NotFinite { vertex });
    }
    Ok(bounding_diameter(points))
}

/// Checks every triangle for valid indices and a non-zero area, and turns it counter-clockwise.
/// Returns which vertices the triangles use.
fn orient_triangles(
    points: &[[f64; 2]],
    triangles: &mut [[usize; 3]],
    diameter: f64,
) -> Result<Vec<bool>, MeshError> {
    let n = points.len();
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
            let corners = tri.map(|v| points[v]);
            return Err(MeshError::Degenerate {
                triangle: t,
                area: 0.5 * area,
                at: [0, 1].map(|k| corners.iter().map(|p| p[k]).sum::<f64>() / 3.0),
            });
        }
        if area < 0.0 {
            tri.swap(1, 2);
        }
    }
    Ok(used)
}

/// No two vertices at the same place. The (finite) points sorted by place, then by number, as
/// integers that order as the coordinates do (−0 as 0): equal places are neighbours, and the pair
/// reported is the first in the order of the coordinates, lower number first.
fn distinct_vertices(points: &[[f64; 2]]) -> Result<(), MeshError> {
    let ordered = |x: f64| {
        let bits = (x + 0.0).to_bits();
        if bits >> 63 == 1 {
            !bits
        } else {
            bits | 1 << 63
        }
    };
    let mut sorted: Vec<([u64; 2], u32)> = (points.iter().enumerate())
        .map(|(a, p)| (p.map(ordered), a as u32))
        .collect();
    crate::parallel::sort(&mut sorted);
    for w in sorted.windows(2) {
        if w[0].0 == w[1].0 {
            return Err(MeshError::DuplicateVertex {
                first: w[0].1 as usize,
                second: w[1].1 as usize,
            });
        }
    }
    Ok(())
}

/// The half-edges of `triangles` grouped by their smaller vertex, in O(n) (a counting sort): group
/// a is `items[start[a]..start[a + 1]]`, with `item(t, b)` for each edge (a, b), a < b, of each
/// triangle t, in the order of the triangles.
fn by_smaller_vertex<T: Copy + Default>(
    n: usize,
    triangles: impl ExactSizeIterator<Item = [usize; 3]> + Clone,
    item: impl Fn(usize, usize) -> T,
) -> (Vec<usize>, Vec<T>) {
    let mut start = vec![0usize; n + 1];
    for tri in triangles.clone() {
        for k in 0..3 {
            start[tri[k].min(tri[(k + 1) % 3]) + 1] += 1;
        }
    }
    for a in 0..n {
        start[a + 1] += start[a];
    }
    let mut fill = start.clone();
    let mut items = vec![T::default(); 3 * triangles.len()];
    for (t, tri) in triangles.enumerate() {
        for k in 0..3 {
            let (a, b) = (tri[k], tri[(k + 1) % 3]);
            items[fill[a.min(b)]] = item(t, a.max(b));
            fill[a.min(b)] += 1;
        }
    }
    (start, items)
}

/// Two of the triangles sharing an edge (`edge`'s second entries) with the same three vertices.
fn duplicate(triangles: &[[usize; 3]], edge: &[(usize, usize)]) -> Result<(), MeshError> {
    let sorted = |t: usize| {
        let mut v = triangles[t];
        v.sort_unstable();
        v
    };
    for (i, &(_, t)) in edge.iter().enumerate() {
        if let Some(&(_, s)) = edge[i + 1..].iter().find(|&&(_, s)| sorted(s) == sorted(t)) {
            let (first, triangle) = (t.min(s), t.max(s));
            return Err(MeshError::DuplicateTriangle { triangle, first });
        }
    }
    Ok(())
}

/// The boundary vertices and edges of a triangle set, its number of components and a vertex
/// where two of them meet.
type EdgeMatch = (Vec<bool>, Vec<(usize, usize)>, (usize, Option<usize>));

/// Matches the edges: each is shared by one (boundary) or two (interior) triangles, traversed in
/// opposite directions. Half-edges are grouped by their smaller vertex (a counting sort), then
/// matched by the larger one. Returns the boundary vertices and edges, the number of components
/// of triangles joined by edges, and a vertex where two components meet, if any.
fn match_edges(n: usize, triangles: &[[usize; 3]]) -> Result<EdgeMatch, MeshError> {
    let (start, mut half) = by_smaller_vertex(n, triangles.iter().copied(), |t, b| (b, t));
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
                    duplicate(triangles, edge)?;
                    if traverses(&triangles[*t], a, b) == traverses(&triangles[*s], a, b) {
                        return Err(MeshError::Inverted {
                            triangle: *s,
                            neighbour: *t,
                        });
                    }
                    union(&mut parent, *t, *s);
                }
                _ => {
                    duplicate(triangles, edge)?;
                    return Err(MeshError::NonManifoldEdge {
                        a,
                        b,
                        count: edge.len(),
                    });
                }
            }
        }
    }
    let components = (0..triangles.len())
        .filter(|&t| find(&mut parent, t) == t)
        .count();
    // A vertex whose triangles lie in two components: where they meet.
    let mut component_at: Vec<Option<usize>> = vec![None; n];
    let mut joined_at = None;
    for (t, tri) in triangles.iter().enumerate() {
        let root = find(&mut parent, t);
        for &v in tri {
            match component_at[v] {
                Some(r) if r != root => joined_at = joined_at.or(Some(v)),
                _ => component_at[v] = Some(root),
            }
        }
    }
    Ok((on_boundary, boundary_edges, (components, joined_at)))
}

/// The angles of the triangles at each vertex sum to 2π at an interior vertex and to less at a
/// boundary vertex: the triangles around a vertex do not wrap around it twice.
fn turns_once(points: &[[f64; 2]], triangles: &[[usize; 3]], on_boundary: &[bool]) -> Result<(), MeshError> {
    let mut angle = vec![0.0_f64; points.len()];
    for tri in triangles {
        for k in 0..3 {
            let (p, q, r) = (points[tri[k]], points[tri[(k + 1) % 3]], points[tri[(k + 2) % 3]]);
            let (u, v) = ([q[0] - p[0], q[1] - p[1]], [r[0] - p[0], r[1] - p[1]]);
            angle[tri[k]] += (u[0] * v[1] - u[1] * v[0]).atan2(u[0] * v[0] + u[1] * v[1]);
        }
    }
    let full = 2.0 * std::f64::consts::PI;
    let bad = |(a, &s): &(usize, &f64)| {
        if on_boundary[*a] {
            s > full * (1.0 + 1e-9)
        } else {
            (s - full).abs() > 1e-9 * full
        }
    };
    match angle.iter().enumerate().find(bad) {
        Some((vertex, &s)) => Err(MeshError::Overlap {
            vertex,
            at: points[vertex],
            turns: s / full,
        }),
        None => Ok(()),
    }
}

/// No two boundary edges meet, but at a vertex they share (checked with a bucket grid).
fn boundary_is_simple(points: &[[f64; 2]], edges: &[(usize, usize)]) -> Result<(), MeshError> {
    let boxes = edges
        .iter()
        .map(|&(a, b)| (min2(points[a], points[b]), max2(points[a], points[b])));
    let grid = Buckets::from_boxes(boxes, edges.len());
    for (i, &(a, b)) in edges.iter().enumerate() {
        let (p, q) = (points[a], points[b]);
        for j in grid.near_box(min2(p, q), max2(p, q)).filter(|&j| j > i) {
            let (c, d) = edges[j];
            let shared = [c, d].iter().filter(|&&v| v == a || v == b).count();
            if shared == 0 && segments_meet(p, q, points[c], points[d]) {
                return Err(MeshError::BoundaryCrossing {
                    first: (a, b),
                    second: (c, d),
                });
            }
            // Two edges sharing a vertex overlap only when they run along each other.
            if shared == 1 {
                let (o, x) = if a == c || a == d { (a, b) } else { (b, a) };
                let y = if c == o { d } else { c };
                let (u, v) = (points[x], points[y]);
                let (po, pu, pv) = (
                    points[o],
                    [u[0] - points[o][0], u[1] - points[o][1]],
                    [v[0] - points[o][0], v[1] - points[o][1]],
                );
                if orient(po, u, v) == 0.0 && pu[0] * pv[0] + pu[1] * pv[1] > 0.0 {
                    return Err(MeshError::BoundaryCrossing {
                        first: (a, b),
                        second: (c, d),
                    });
                }
            }
        }
    }
    Ok(())
}

/// Whether the closed segments pq and rs have a point in common. Segments whose bounding boxes
/// are apart do not, whatever the signs of the orientations: along one line (a refined boundary
/// edge) those are round-off, and their signs can say that two pieces far apart cross.
fn segments_meet(p: [f64; 2], q: [f64; 2], r: [f64; 2], s: [f64; 2]) -> bool {
    let apart = |k: usize| p[k].max(q[k]) < r[k].min(s[k]) || r[k].max(s[k]) < p[k].min(q[k]);
    if apart(0) || apart(1) {
        return false;
    }
    let (d1, d2) = (orient(p, q, r), orient(p, q, s));
    let (d3, d4) = (orient(r, s, p), orient(r, s, q));
    if d1 * d2 < 0.0 && d3 * d4 < 0.0 {
        return true;
    }
    let on = |a: [f64; 2], b: [f64; 2], x: [f64; 2], d: f64| {
        d == 0.0
            && x[0] >= a[0].min(b[0])
            && x[0] <= a[0].max(b[0])
            && x[1] >= a[1].min(b[1])
            && x[1] <= a[1].max(b[1])
    };
    on(p, q, r, d1) || on(p, q, s, d2) || on(r, s, p, d3) || on(r, s, q, d4)
}

/// The points of a mesh file given in 3D, in their plane z = z₀ (every z within round-off of the
/// first: 10⁻¹² of the mesh's extent in x and y, and a few units of z₀'s last digit; a CAD kernel's
/// rotations leave z = 1e-16); `name(i)` names point i in the message where one leaves the plane.
pub(crate) fn planar(xyz: &[[f64; 3]], name: impl Fn(usize) -> String) -> Result<Vec<[f64; 2]>, String> {
    let z0 = xyz.first().map_or(0.0, |p| p[2]);
    let (low, high) = xyz.iter().fold(([f64::MAX; 2], [f64::MIN; 2]), |(l, h), p| {
        (min2(l, [p[0], p[1]]), max2(h, [p[0], p[1]]))
    });
    let extent = (high[0] - low[0]).max(high[1] - low[1]);
    let tolerance = 1e-12 * extent + 4.0 * f64::EPSILON * z0.abs();
    // NaN is no plane either.
    let within = |z: f64| (z - z0).abs() <= tolerance;
    match xyz.iter().position(|p| !within(p[2])) {
        Some(i) => Err(format!(
            "{} has z = {}, the first z = {z0}: the mesh must lie in a plane z = constant",
            name(i),
            xyz[i][2]
        )),
        None => Ok(xyz.iter().map(|p| [p[0], p[1]]).collect()),
    }
}

pub(crate) fn dist(p: [f64; 2], q: [f64; 2]) -> f64 {
    (p[0] - q[0]).hypot(p[1] - q[1])
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

pub(crate) fn min2(p: [f64; 2], q: [f64; 2]) -> [f64; 2] {
    [p[0].min(q[0]), p[1].min(q[1])]
}

pub(crate) fn max2(p: [f64; 2], q: [f64; 2]) -> [f64; 2] {
    [p[0].max(q[0]), p[1].max(q[1])]
}

#[cfg(test)]
mod tests {
    #[test]
    fn points_far_from_one_are_shown_in_scientific_notation() {
        assert_eq!(Point([0.5, 1e300]).to_string(), "(0.5, 1e300)");
        assert_eq!(Point([0.0, -2.5e-7]).to_string(), "(0, -2.5e-7)");
        assert_eq!(Point([123456.75, f64::NAN]).to_string(), "(123456.75, NaN)");
    }

    use super::*;

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
        let mut twice = fan.clone();
        twice.push([4, 2, 3]);
        assert_eq!(
            Mesh::new(sq.clone(), twice).unwrap_err(),
            MeshError::DuplicateTriangle {
                triangle: 4,
                first: 2
            }
        );
        // A duplicate of a triangle with no boundary edge: each of its edges is shared by three.
        let ring = vec![
            [0.0, 0.0],
            [1.0, 0.0],
            [1.0, 1.0],
            [0.0, 1.0],
            [0.3, 0.3],
            [0.7, 0.3],
            [0.5, 0.7],
        ];
        let mut inner = vec![
            [4, 5, 6],
            [0, 1, 5],
            [0, 5, 4],
            [1, 2, 5],
            [2, 6, 5],
            [2, 3, 6],
            [3, 4, 6],
            [3, 0, 4],
        ];
        assert!(Mesh::new(ring.clone(), inner.clone()).is_ok());
        inner.push([6, 4, 5]);
        assert_eq!(
            Mesh::new(ring, inner).unwrap_err(),
            MeshError::DuplicateTriangle {
                triangle: 8,
                first: 0
            }
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
        // −0 is the place of 0.
        let mut signed_zero = sq.clone();
        signed_zero.push([-0.0, 0.0]);
        assert!(matches!(
            Mesh::new(signed_zero, fan.clone()),
            Err(MeshError::DuplicateVertex { first: 0, second: 5 })
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
    }

    #[test]
    fn checks_reject_disconnected_and_hanging_meshes() {
        let sq = vec![[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0], [0.5, 0.5]];
        let fan = vec![[0, 1, 4], [1, 2, 4], [2, 3, 4], [3, 0, 4]];
        // Two fans side by side sharing no edge: disconnected.
        let mut two = sq.clone();
        two.extend(sq.iter().map(|p| [p[0] + 3.0, p[1]]));
        let mut tris = fan.clone();
        tris.extend(fan.iter().map(|t| t.map(|v| v + 5)));
        assert!(matches!(
            Mesh::new(two, tris),
            Err(MeshError::Disconnected {
                components: 2,
                joined_at: None
            })
        ));
        // The same two fans meeting at a corner: joined there only.
        let mut pinched = sq.clone();
        pinched.extend(sq[1..].iter().map(|p| [p[0] + 1.0, p[1] + 1.0]));
        let mut tris = fan.clone();
        tris.extend(fan.iter().map(|t| t.map(|v| if v == 0 { 2 } else { v + 4 })));
        assert_eq!(
            Mesh::new(pinched, tris).unwrap_err(),
            MeshError::Disconnected {
                components: 2,
                joined_at: Some(2)
            }
        );
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
            Err(MeshError::HangingNode { vertex: 5, .. })
        ));
        assert!(matches!(
            Mesh::new(sq[..4].to_vec(), vec![[0, 1, 2], [0, 2, 3]]),
            Err(MeshError::NoInteriorVertex)
        ));
    }

    /// Two pieces of one slanted edge of a hole after adaptive refinement (a case where `adapt`
    /// stopped with "boundary edges … meet"): on one line up to round-off and 0.006 apart, where
    /// the orientations' signs alone say that they cross; a segment across the line does meet.
    #[test]
    fn pieces_of_one_edge_do_not_meet() {
        let (p, q) = (
            [-0.004381416920996311, 0.15730704142195],
            [-0.003007977224667413, 0.15550036982429277],
        );
        let (r, s) = (
            [0.003859221256977079, 0.14646701183600658],
            [0.0024857815606481805, 0.14827368343366382],
        );
        assert!(!segments_meet(p, q, r, s) && !segments_meet(r, s, p, q));
        let (m, n) = (
            [0.5 * (p[0] + q[0]), 0.5 * (p[1] + q[1])],
            [q[1] - p[1], p[0] - q[0]],
        );
        let across = |t: f64| [m[0] + t * n[0], m[1] + t * n[1]];
        assert!(segments_meet(p, q, across(-1.0), across(1.0)));
    }
}
