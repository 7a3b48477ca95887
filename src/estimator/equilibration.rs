//! The patch-equilibrated fluxes τ_i of docs/a-posteriori.md §7(c) (Braess–Schöberl,
//! Ern–Vohralík, here in RT0 on the submesh S_h of Section 4.2). For every vertex a of T_h, on the
//! cells of S_h in the patch ω_a = supp φ_a:
//!
//! ```text
//! τ_{i,a} = argmin ‖Π_RT(φ_a μ_i ∇u_ih) + τ‖_{ω_a}   over τ ∈ RT0(S_h|ω_a),  τ·n = 0 on ∂ω_a \ ∂ω,
//! div τ = Π(f_i φ_a) − μ_i ∇u_ih·∇φ_a ± λ_a χ_{D_a} − c_{i,a} χ_{D_a}   on each cell κ ⊂ ω_a,
//! ```
//!
//! (+ for membrane 1, − for membrane 2; c_{i,a} the quadrature defect of the loads, §4(c)). At an
//! interior vertex the divergence has zero mean by (4.5) — the definition of λ_a by the lumped
//! pairing (4.3) — and at a boundary vertex the flux through ∂ω is free. Since Σ_a φ_a = 1,
//! τ_i = Σ_a τ_{i,a} lies in H(div, ω) with div τ_i = Π f_i ± λ_h − c_i on every cell.
//!
//! Each local problem is solved in two steps: a particular solution by a sweep over a spanning
//! tree of the patch's cells (the flux through each tree link is what the cells beyond it need),
//! then the divergence-free correction curl ψ, ψ a P1 function on S_h|ω_a vanishing on the closed
//! part of ∂ω_a. Curls of P1 functions are constant on each cell and ‖curl ψ‖ = ‖∇ψ‖, so the
//! correction solves the P1 stiffness system of S_h|ω_a: 2k + 1 unknowns at an interior vertex
//! with k triangles (a, the k midpoints of its edges, the k barycentres), 2k + 2 at a boundary one.
//! The system depends on the geometry only: one factorization serves both membranes.

use crate::assembly::gradients;
use crate::flux::Flux;
use crate::mesh::{orient, DualMesh, Mesh, Stars};
use crate::parallel::{self, PIECE};
use std::sync::atomic::{AtomicU64, Ordering::Relaxed};

/// No neighbour (a boundary edge) or no stream-function unknown (a vertex of S_h where ψ = 0).
const NONE: usize = usize::MAX;

/// The triangles around each vertex and the neighbour across each edge, for the patch problems,
/// and the vertices in classes whose patches share no cell of S_h.
pub struct Patches {
    stars: Stars,
    /// Across edge j = `(t[j], t[j + 1])` of each triangle: the neighbour, or NONE on ∂ω.
    pub neighbour: Vec<[usize; 3]>,
    /// Classes of vertices no two of which share a triangle (a greedy colouring in vertex
    /// order), each in increasing order.
    classes: Vec<Vec<u32>>,
}

impl Patches {
    /// The patches of `mesh`.
    pub fn new(mesh: &Mesh) -> Self {
        let stars = Stars::new(mesh);
        // Across edge (a, b) of t: the other triangle around a that has b (T_h is conforming,
        // so there is at most one).
        let neighbour = parallel::collect(mesh.n_triangles(), |t| {
            let tri = mesh.triangle(t);
            [0, 1, 2].map(|j| {
                let (a, b) = (tri[j], tri[(j + 1) % 3]);
                (stars.around(a))
                    .find(|&(s, _)| s != t && mesh.triangle(s).contains(&b))
                    .map_or(NONE, |(s, _)| s)
            })
        });
        Patches {
            classes: classes(mesh, &stars),
            stars,
            neighbour,
        }
    }

    /// The triangles containing `a`, with a's position in each.
    pub fn around(&self, a: usize) -> impl Iterator<Item = (usize, usize)> + '_ {
        self.stars.around(a)
    }
}

/// The vertices of `mesh` coloured greedily in order, each the first colour none of the
/// vertices of its triangles has: the classes of each colour.
fn classes(mesh: &Mesh, stars: &Stars) -> Vec<Vec<u32>> {
    let mut colour = vec![u32::MAX; mesh.n_vertices()];
    let mut classes: Vec<Vec<u32>> = Vec::new();
    let mut taken = Vec::new();
    for a in 0..mesh.n_vertices() {
        taken.clear();
        taken.resize(classes.len() + 1, false);
        for (t, _) in stars.around(a) {
            for b in mesh.triangle(t) {
                if let Some(c) = taken.get_mut(colour[b] as usize) {
                    *c = true;
                }
            }
        }
        let c = taken
            .iter()
            .position(|&t| !t)
            .expect("one colour more than the classes");
        colour[a] = c as u32;
        if c == classes.len() {
            classes.push(Vec::new());
        }
        classes[c].push(a as u32);
    }
    classes
}

/// The data of the local problems of one membrane.
pub struct Membrane<'a> {
    /// μ_i.
    pub mu: f64,
    /// u_ih at the vertices.
    pub u: &'a [f64],
    /// ∫_κ f_i φ_j on every cell κ of S_h, for the three vertices j of its triangle (in order).
    pub f_phi: &'a (dyn Fn(usize) -> [f64; 3] + Sync),
    /// ±λ_a − c_{i,a} at every vertex: the constant part of the divergence on D_a.
    pub on_dual_cell: &'a [f64],
}

/// τ_i = Σ_a τ_{i,a} for each membrane, by their normal fluxes on the cells of S_h (the
/// convention of [`Flux`]).
pub fn equilibrate(mesh: &Mesh, dual: &DualMesh, patches: &Patches, membranes: &[Membrane]) -> Vec<Flux> {
    let grad_u: Vec<[[f64; 2]; 2]> = parallel::collect(mesh.n_triangles(), |t| {
        let g = gradients(mesh.corners(t));
        let tri = mesh.triangle(t);
        let mut grad = [[0.0; 2]; 2];
        for (grad, m) in grad.iter_mut().zip(membranes) {
            *grad = [0, 1].map(|k| m.mu * (0..3).map(|j| g[j][k] * m.u[tri[j]]).sum::<f64>());
        }
        grad
    });
    // Each patch adds into the fluxes of its cells (a cell belongs to the patches of its
    // triangle's three vertices); the patches of one class share no cell and run in parallel,
    // the classes one after the other, so that each cell sums its terms in the same order on
    // any number of threads.
    let tau: Vec<Vec<[AtomicU64; 3]>> = (membranes.iter())
        .map(|_| parallel::collect(dual.n_cells(), |_| Default::default()))
        .collect();
    for class in &patches.classes {
        parallel::map_with(class.len(), PIECE, Patch::default, |work, range| {
            for &a in &class[range] {
                work.build(mesh, dual, patches, a as usize);
                work.solve(a as usize, membranes, |t, i| grad_u[t][i], &tau);
            }
        });
    }
    // In place: [AtomicU64; 3] and [f64; 3] have the same size, so the collect reuses the room.
    (tau.into_iter())
        .map(|tau| Flux {
            edge_flux: (tau.into_iter())
                .map(|f| f.map(|f| f64::from_bits(f.into_inner())))
                .collect(),
        })
        .collect()
}

/// One cell of S_h in a patch, with what its local problems need of its geometry.
#[derive(Clone, Copy, Default)]
struct Cell {
    /// Its index in S_h.
    index: usize,
    /// Its triangle of T_h, and the position of a in it.
    triangle: usize,
    position: usize,
    area: f64,
    /// The stream-function unknown at each corner, or NONE.
    stream: [usize; 3],
    /// The gradients of the cell's three P1 hat functions (one per corner).
    hat: [[f64; 2]; 3],
    /// Edge e (corner e to e + 1) times the mean of φ_a on it: the flux of φ_a v through the
    /// edge, for v constant, is v × this (the cross product).
    phi_edge: [[f64; 2]; 3],
    /// The RT0 basis function of edge e at the centroid, (c − p_{e+2}) / (2|κ|).
    at_centroid: [[f64; 2]; 3],
    /// Whether the cell lies in D_a.
    own: bool,
    /// ∇φ_a on the triangle.
    grad_phi: [f64; 2],
}

/// A link of the patch's cell graph: two (node, edge) sides; node `ground` stands for ∂ω.
#[derive(Clone, Copy)]
struct Link([(usize, usize); 2]);

/// The workspace of one patch, reused from vertex to vertex.
#[derive(Default)]
struct Patch {
    /// The triangles around a (with a's position in each) and a's neighbours, in order.
    star: Vec<(usize, usize)>,
    others: Vec<usize>,
    cells: Vec<Cell>,
    links: Vec<Link>,
    /// Node = cell index in the patch, or `cells.len()` for the ground (∂ω).
    ground: bool,
    /// Spanning tree: BFS order and the link to the parent of each node.
    order: Vec<usize>,
    parent: Vec<usize>,
    adjacency: Vec<Vec<usize>>,
    seen: Vec<bool>,
    unknowns: usize,
    /// The P1 stiffness matrix of S_h|ω_a on the stream unknowns, factorized (LLᵀ).
    factor: Vec<f64>,
    flux: Vec<[f64; 3]>,
    accumulated: Vec<f64>,
    /// The stream system's right-hand sides, one column of `unknowns` per membrane.
    rhs: Vec<f64>,
}

impl Patch {
    /// The cells, links, spanning tree and stream-function system of the patch of `a`.
    fn build(&mut self, mesh: &Mesh, dual: &DualMesh, patches: &Patches, a: usize) {
        let (mut star, mut others) = (std::mem::take(&mut self.star), std::mem::take(&mut self.others));
        star.clear();
        star.extend(patches.around(a));
        others.clear();
        others.extend((star.iter()).flat_map(|&(t, k)| [1, 2].map(|d| mesh.triangle(t)[(k + d) % 3])));
        others.sort_unstable();
        others.dedup();
        let midpoint_unknown = |v: usize| 1 + others.binary_search(&v).expect("a neighbour of a");
        self.cells.clear();
        for (i, &(t, k)) in star.iter().enumerate() {
            let tri = mesh.triangle(t);
            let grad_phi = gradients(mesh.corners(t))[k];
            let centre = 1 + others.len() + i;
            for c in 0..6 {
                let j = c / 2;
                let (v, w) = if c % 2 == 0 {
                    (tri[j], tri[(j + 1) % 3])
                } else {
                    (tri[j], tri[(j + 2) % 3])
                };
                // The corners of cell c: [v, m_vw, g] or [v, g, m_wv] (DualMesh).
                let vertex = (usize::from(v != a) * NONE, f64::from(u8::from(v == a)));
                let mid = if v == a {
                    (midpoint_unknown(w), 0.5)
                } else if w == a {
                    (midpoint_unknown(v), 0.5)
                } else {
                    (NONE, 0.0)
                };
                let centroid = (centre, 1.0 / 3.0);
                let corners3 = if c % 2 == 0 {
                    [vertex, mid, centroid]
                } else {
                    [vertex, centroid, mid]
                };
                let index = 6 * t + c;
                let p = dual.corners(index);
                let area = 0.5 * orient(p[0], p[1], p[2]);
                let phi = corners3.map(|x| x.1);
                let centroid = [0, 1].map(|k| (p[0][k] + p[1][k] + p[2][k]) / 3.0);
                self.cells.push(Cell {
                    index,
                    triangle: t,
                    position: k,
                    area,
                    stream: corners3.map(|x| x.0),
                    hat: gradients(p),
                    phi_edge: std::array::from_fn(|e| {
                        let mean = 0.5 * (phi[e] + phi[(e + 1) % 3]);
                        [0, 1].map(|k| mean * (p[(e + 1) % 3][k] - p[e][k]))
                    }),
                    at_centroid: std::array::from_fn(|e| {
                        [0, 1].map(|k| (centroid[k] - p[(e + 2) % 3][k]) / (2.0 * area))
                    }),
                    own: v == a,
                    grad_phi,
                });
            }
        }
        self.links.clear();
        self.ground = false;
        let ground = self.cells.len();
        let local = |t: usize| star.iter().position(|&(s, _)| s == t).expect("in the patch");
        for (i, &(t, k)) in star.iter().enumerate() {
            let n = |c: usize| 6 * i + c;
            for j in 0..3 {
                self.links.push(Link([(n(2 * j), 2), (n(2 * j + 1), 0)]));
                self.links
                    .push(Link([(n(2 * j), 1), (n(2 * ((j + 1) % 3) + 1), 1)]));
            }
            // The halves of the edge ab (next after a) at a and at b; of ca at a and at c.
            let (at_a_ab, at_b_ab) = ((n(2 * k), 0), (n(2 * ((k + 1) % 3) + 1), 2));
            let (at_a_ca, at_c_ca) = ((n(2 * k + 1), 2), (n(2 * ((k + 2) % 3)), 0));
            match patches.neighbour[t][k] {
                NONE => {
                    self.links.push(Link([at_a_ab, (ground, 0)]));
                    self.links.push(Link([at_b_ab, (ground, 0)]));
                    self.ground = true;
                }
                s => {
                    let (ii, kk) = (local(s), star[local(s)].1);
                    self.links.push(Link([at_a_ab, (6 * ii + 2 * kk + 1, 2)]));
                    self.links.push(Link([at_b_ab, (6 * ii + 2 * ((kk + 2) % 3), 0)]));
                }
            }
            if patches.neighbour[t][(k + 2) % 3] == NONE {
                self.links.push(Link([at_a_ca, (ground, 0)]));
                self.links.push(Link([at_c_ca, (ground, 0)]));
                self.ground = true;
            }
        }
        self.spanning_tree();
        self.unknowns = 1 + others.len() + star.len();
        self.factorize();
        (self.star, self.others) = (star, others);
    }

    /// A breadth-first spanning tree of the cell graph, rooted at the ground when there is one.
    fn spanning_tree(&mut self) {
        let nodes = self.cells.len() + 1;
        self.adjacency.resize_with(nodes, Vec::new);
        for adj in &mut self.adjacency {
            adj.clear();
        }
        for (l, link) in self.links.iter().enumerate() {
            self.adjacency[link.0[0].0].push(l);
            self.adjacency[link.0[1].0].push(l);
        }
        let root = if self.ground { self.cells.len() } else { 0 };
        self.parent.clear();
        self.parent.resize(nodes, NONE);
        self.order.clear();
        self.order.push(root);
        let seen = &mut self.seen;
        seen.clear();
        seen.resize(nodes, false);
        seen[root] = true;
        let mut next = 0;
        while next < self.order.len() {
            let node = self.order[next];
            next += 1;
            for &l in &self.adjacency[node] {
                let other = self.links[l].other(node).0;
                if !seen[other] {
                    seen[other] = true;
                    self.parent[other] = l;
                    self.order.push(other);
                }
            }
        }
        debug_assert_eq!(self.order.len(), nodes - usize::from(!self.ground));
    }

    /// Assembles and factorizes the P1 stiffness matrix of S_h|ω_a on the stream unknowns.
    fn factorize(&mut self) {
        let n = self.unknowns;
        self.factor.clear();
        self.factor.resize(n * n, 0.0);
        for cell in &self.cells {
            let g = cell.hat;
            for p in 0..3 {
                for q in 0..3 {
                    let (i, j) = (cell.stream[p], cell.stream[q]);
                    if i != NONE && j != NONE {
                        self.factor[i * n + j] += cell.area * (g[p][0] * g[q][0] + g[p][1] * g[q][1]);
                    }
                }
            }
        }
        cholesky(&mut self.factor, n);
    }

    /// τ_{i,a} for each membrane i, added to `tau[i]`'s normal fluxes (f64 bits; no other patch
    /// adds to these cells meanwhile); `grad(t, i)` gives μ_i ∇u_ih on a triangle t. One solve of
    /// the stream-function system takes all membranes' right-hand sides.
    fn solve(
        &mut self,
        a: usize,
        membranes: &[Membrane],
        grad: impl Fn(usize, usize) -> [f64; 2],
        tau: &[Vec<[AtomicU64; 3]>],
    ) {
        let (cells, n, m) = (self.cells.len(), self.unknowns, membranes.len());
        self.flux.clear();
        self.flux.resize(m * cells, [0.0; 3]);
        self.rhs.clear();
        self.rhs.resize(n * m, 0.0);
        for (i, membrane) in membranes.iter().enumerate() {
            self.particular(a, membrane, |t| grad(t, i), i);
        }
        for column in self.rhs.chunks_exact_mut(n) {
            cholesky_solve(&self.factor, n, column);
        }
        for (i, tau) in tau.iter().enumerate() {
            let flux = &self.flux[i * cells..(i + 1) * cells];
            for (cell, flux) in self.cells.iter().zip(flux) {
                let psi = cell
                    .stream
                    .map(|k| if k == NONE { 0.0 } else { self.rhs[i * n + k] });
                for e in 0..3 {
                    // The flux of curl ψ through the edge from corner e to e + 1.
                    let f = flux[e] + psi[(e + 1) % 3] - psi[e];
                    let sum = &tau[cell.index][e];
                    sum.store((f64::from_bits(sum.load(Relaxed)) + f).to_bits(), Relaxed);
                }
            }
        }
    }

    /// A particular solution τ_p of membrane `m`'s divergence constraint on the patch of `a`
    /// (column `i` of the workspace's fluxes), and the right-hand side of its correction
    /// min ‖q + τ_p + curl ψ‖, q = Π_RT(φ_a μ ∇u_h), in column `i` of the stream system's.
    fn particular(&mut self, a: usize, m: &Membrane, grad: impl Fn(usize) -> [f64; 2], i: usize) {
        let (cells, n) = (self.cells.len(), self.unknowns);
        let nodes = cells + usize::from(self.ground);
        let flux = &mut self.flux[i * cells..(i + 1) * cells];
        self.accumulated.clear();
        self.accumulated.resize(nodes, 0.0);
        // The divergence, integrated over each cell.
        for (node, cell) in self.cells.iter().enumerate() {
            let (du, g) = (grad(cell.triangle), cell.grad_phi);
            let mut d = (m.f_phi)(cell.index)[cell.position] - cell.area * (du[0] * g[0] + du[1] * g[1]);
            if cell.own {
                d += cell.area * m.on_dual_cell[a];
            }
            self.accumulated[node] = d;
        }
        // Leaves first, each node's net outflow through its parent link.
        for &node in self.order.iter().skip(1).rev() {
            let link = self.links[self.parent[node]];
            let (mine, theirs) = link.sides(node);
            let out = self.accumulated[node];
            flux[node][mine.1] += out;
            if theirs.0 < cells {
                flux[theirs.0][theirs.1] -= out;
                self.accumulated[theirs.0] += out;
            }
        }
        for (cell, flux) in self.cells.iter().zip(flux.iter()) {
            let du = grad(cell.triangle);
            let q = cell.phi_edge.map(|e| du[0] * e[1] - du[1] * e[0]);
            let total: [f64; 3] = std::array::from_fn(|e| q[e] + flux[e]);
            let v = [0, 1].map(|k| (0..3).map(|e| total[e] * cell.at_centroid[e][k]).sum::<f64>());
            for (g, &k) in cell.hat.iter().zip(&cell.stream) {
                if k != NONE {
                    // curl φ = (∂_y φ, −∂_x φ), constant on the cell.
                    self.rhs[i * n + k] -= cell.area * (g[1] * v[0] - g[0] * v[1]);
                }
            }
        }
    }
}

impl Link {
    /// The far side of the link from `node`.
    fn other(&self, node: usize) -> (usize, usize) {
        self.sides(node).1
    }

    /// (the side at `node`, the other side).
    fn sides(&self, node: usize) -> ((usize, usize), (usize, usize)) {
        if self.0[0].0 == node {
            (self.0[0], self.0[1])
        } else {
            (self.0[1], self.0[0])
        }
    }
}

/// In-place Cholesky factorization LLᵀ of the SPD n×n row-major matrix `m` (lower triangle).
fn cholesky(m: &mut [f64], n: usize) {
    for j in 0..n {
        let d = m[j * n + j] - (0..j).map(|k| m[j * n + k] * m[j * n + k]).sum::<f64>();
        debug_assert!(d > 0.0, "the stream-function system is positive definite");
        let d = d.sqrt();
        m[j * n + j] = d;
        for i in j + 1..n {
            let s = m[i * n + j] - (0..j).map(|k| m[i * n + k] * m[j * n + k]).sum::<f64>();
            m[i * n + j] = s / d;
        }
    }
}

/// Solves LLᵀx = b in place with the factor of [`cholesky`].
fn cholesky_solve(l: &[f64], n: usize, b: &mut [f64]) {
    for i in 0..n {
        b[i] = (b[i] - (0..i).map(|k| l[i * n + k] * b[k]).sum::<f64>()) / l[i * n + i];
    }
    for i in (0..n).rev() {
        b[i] = (b[i] - (i + 1..n).map(|k| l[k * n + i] * b[k]).sum::<f64>()) / l[i * n + i];
    }
}
