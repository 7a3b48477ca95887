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
//! Each local problem is solved in two steps: a particular solution along a path through all the
//! cells of the patch, round each triangle's barycentre and on across the edges at a to the next
//! triangle (the flux from a cell into the next is what the cells before it leave), then the
//! divergence-free correction curl ψ, ψ a P1 function on S_h|ω_a vanishing on the closed part of
//! ∂ω_a. Curls of P1 functions are constant on each cell and ‖curl ψ‖ = ‖∇ψ‖, so the
//! correction solves the P1 stiffness system of S_h|ω_a: 2k + 1 unknowns at an interior vertex
//! with k triangles (a, the k midpoints of its edges, the k barycentres), 2k + 2 at a boundary one
//! (2k + 2F where ω_a is F fans that touch only at a: ψ(a) is one unknown per fan).
//! The system depends on the geometry only: one factorization serves both membranes.
//!
//! The fluxes are never held on the whole of S_h: the patches are solved block by block along a
//! Z-order curve of the vertices (`Sweep`), each patch's share of a triangle's cells is added
//! to the triangle's τ_i (block after block, in a block in the order of the triangle's corners,
//! so that it does not depend on the threads), and once the patches of its three vertices are
//! solved, τ_i is handed to the caller and dropped.

use crate::assembly::gradients;
use crate::mesh::{orient, DualMesh, Mesh, Stars};
use crate::parallel;
use std::ops::Range;

/// No neighbour across an edge: the edge lies on ∂ω.
pub const ON_BOUNDARY: u32 = u32::MAX;

/// The triangles around each vertex and the neighbour across each edge, for the patch problems,
/// and the order in which the patches are solved.
pub struct Patches {
    stars: Stars,
    /// Across edge j = `(t[j], t[j + 1])` of each triangle: the neighbour, or [`ON_BOUNDARY`] on ∂ω.
    pub neighbour: Vec<[u32; 3]>,
    sweep: Sweep,
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
                    .map_or(ON_BOUNDARY, |(s, _)| s as u32)
            })
        });
        Patches {
            sweep: Sweep::new(mesh),
            stars,
            neighbour,
        }
    }

    /// The triangles containing `a`, with a's position in each.
    pub fn around(&self, a: usize) -> impl Iterator<Item = (usize, usize)> + '_ {
        self.stars.around(a)
    }
}

/// Vertices per block of the sweep: the patches of a block are solved in parallel.
const BLOCK: usize = 1 << 13;

/// Vertices per piece of a block handed to one thread.
const PATCHES: usize = 1 << 7;

/// The vertices along a Z-order curve of their coordinates, cut into blocks of [`BLOCK`]: a
/// triangle's three vertices lie in the same or nearby blocks whatever the mesh's numbering, so
/// that few triangles wait for the patches of a later block.
struct Sweep {
    /// The vertices in the order of the curve.
    order: Vec<u32>,
    /// The position of each vertex in `order`.
    rank: Vec<u32>,
    /// For each block, the triangles whose first vertex (in `order`) lies in it.
    entering: Vec<Vec<u32>>,
}

impl Sweep {
    fn new(mesh: &Mesh) -> Self {
        let n = mesh.n_vertices();
        let bounds = mesh.bounding_box();
        let mut keyed: Vec<(u64, u32)> = (mesh.points.iter().enumerate())
            .map(|(a, p)| (z_order(bounds, *p), a as u32))
            .collect();
        parallel::sort(&mut keyed);
        let order: Vec<u32> = keyed.into_iter().map(|(_, a)| a).collect();
        let mut rank = vec![0u32; n];
        for (r, &a) in order.iter().enumerate() {
            rank[a as usize] = r as u32;
        }
        let mut entering = vec![Vec::new(); n.div_ceil(BLOCK)];
        for (t, tri) in mesh.triangles().enumerate() {
            let first = tri.iter().map(|&a| rank[a]).min().expect("three corners");
            entering[first as usize / BLOCK].push(t as u32);
        }
        Sweep {
            order,
            rank,
            entering,
        }
    }

    /// The block of vertex `a`.
    fn block(&self, a: usize) -> usize {
        self.rank[a] as usize / BLOCK
    }
}

/// The key of `p` on a Z-order curve over the box [lo, hi]: the bits of its two coordinates,
/// scaled to 32 bits, interleaved.
fn z_order((lo, hi): ([f64; 2], [f64; 2]), p: [f64; 2]) -> u64 {
    let spread = |x: f64, k: usize| -> u64 {
        let unit = ((x - lo[k]) / (hi[k] - lo[k])).clamp(0.0, 1.0);
        let mut v = (unit * f64::from(u32::MAX)) as u64;
        v = (v | (v << 16)) & 0x0000_ffff_0000_ffff;
        v = (v | (v << 8)) & 0x00ff_00ff_00ff_00ff;
        v = (v | (v << 4)) & 0x0f0f_0f0f_0f0f_0f0f;
        v = (v | (v << 2)) & 0x3333_3333_3333_3333;
        (v | (v << 1)) & 0x5555_5555_5555_5555
    };
    spread(p[0], 0) | (spread(p[1], 1) << 1)
}

/// The data of the local problems of one membrane.
pub struct Membrane<'a> {
    /// μ_i.
    pub mu: f64,
    /// u_ih at the vertices.
    pub u: &'a [f64],
    /// ±λ_a − c_{i,a} at every vertex: the constant part of the divergence on D_a.
    pub on_dual_cell: &'a [f64],
}

/// What the local problems take of the loads on the six cells of one triangle.
pub trait CellPairings {
    /// ∫_κ f_i φ_j for the cell κ = 6t + `c` of the triangle t and the three vertices j of t
    /// (in order), for membrane `i`.
    fn f_phi(&self, c: usize, i: usize) -> [f64; 3];
}

/// The normal fluxes of τ on the six cells 6t … 6t + 5 of one triangle t, edge k of a cell from
/// its corner k to k + 1 (the convention of [`crate::flux::Flux`]), for each membrane.
pub type TriangleFlux = [[[f64; 3]; 6]; 2];

/// τ_i = Σ_a τ_{i,a} for each membrane, triangle by triangle: `on_triangle(t, loads of t, τ on t's
/// cells)` for every triangle t, in parallel, its values in the order of the triangles. The loads
/// of each triangle are computed when its first patch comes and dropped with it: `loads(range,
/// out)` pushes those of a range of triangles to `out`.
pub fn equilibrate<L: CellPairings + Send + Sync, R: Default + Send>(
    (mesh, dual, patches): (&Mesh, &DualMesh, &Patches),
    membranes: &[Membrane],
    loads: impl Fn(Range<usize>, &mut Vec<L>) + Sync + Send,
    on_triangle: impl Fn(usize, &L, &TriangleFlux) -> R + Sync + Send,
) -> Vec<R> {
    let sweep = &patches.sweep;
    let mut values: Vec<R> = std::iter::repeat_with(R::default)
        .take(mesh.n_triangles())
        .collect();
    let mut window = Window::new(mesh.n_triangles());
    for (j, entering) in sweep.entering.iter().enumerate() {
        // Asked to stop: the values so far, which the run discards.
        if crate::progress::cancelled() {
            break;
        }
        window.enter(entering, &loads);
        let block = &sweep.order[j * BLOCK..((j + 1) * BLOCK).min(sweep.order.len())];
        // Each piece's patches' shares, star after star, and where each vertex's star begins.
        let shares: Vec<(Vec<TriangleFlux>, Vec<usize>)> =
            parallel::map_with(block.len(), PATCHES, Patch::default, |work, range| {
                let triangles = block[range.clone()]
                    .iter()
                    .map(|&a| patches.stars.len(a as usize))
                    .sum();
                let (mut out, mut starts) = (Vec::with_capacity(triangles), Vec::with_capacity(range.len()));
                for &a in &block[range] {
                    starts.push(out.len());
                    work.build(mesh, dual, patches, a as usize);
                    out.resize(out.len() + work.star.len(), [[[0.0; 3]; 6]; 2]);
                    let at = out.len() - work.star.len();
                    let of = |t: usize| window.loads_of(t);
                    work.solve(mesh, (a as usize, membranes), of, &mut out[at..]);
                }
                (out, starts)
            });
        let share_of = |a: usize, t: usize| -> &TriangleFlux {
            let i = sweep.rank[a] as usize - j * BLOCK;
            let (out, starts) = &shares[i / PATCHES];
            let position =
                (patches.around(a).position(|(s, _)| s == t)).expect("a triangle around each of its corners");
            &out[starts[i % PATCHES] + position]
        };
        for (t, value) in window.complete((mesh, sweep, j), share_of, &on_triangle) {
            values[t] = value;
        }
    }
    values
}

/// The triangles whose patches are not all solved, each in a slot: its loads and τ_i on its
/// cells so far, the shares of its corners' patches added block after block (in a block, in the
/// order of its corners), so that τ_i does not depend on the threads. A slot freed by a triangle
/// that leaves is taken by one that enters: nothing is moved.
struct Window<L> {
    /// The triangle in each slot, or [`FREE`].
    triangles: Vec<u32>,
    loads: Vec<L>,
    tau: Vec<TriangleFlux>,
    /// The slot of each triangle in the window.
    slot: Vec<u32>,
    free: Vec<u32>,
}

/// A slot of the [`Window`] without a triangle.
const FREE: u32 = u32::MAX;

impl<L: Send + Sync> Window<L> {
    fn new(triangles: usize) -> Self {
        Window {
            triangles: Vec::new(),
            loads: Vec::new(),
            tau: Vec::new(),
            slot: vec![FREE; triangles],
            free: Vec::new(),
        }
    }

    /// Takes in the triangles `entering` with their loads, computed in parallel by runs.
    fn enter(&mut self, entering: &[u32], loads: &(impl Fn(Range<usize>, &mut Vec<L>) + Sync)) {
        let runs = runs(entering);
        let computed = parallel::map(runs.len(), 1, |k| {
            let mut out = Vec::with_capacity(runs[k.start].len());
            loads(runs[k.start].clone(), &mut out);
            out
        });
        for (&t, l) in entering.iter().zip(computed.into_iter().flatten()) {
            let k = match self.free.pop() {
                Some(k) => {
                    (self.triangles[k as usize], self.loads[k as usize]) = (t, l);
                    self.tau[k as usize] = [[[0.0; 3]; 6]; 2];
                    k
                }
                None => {
                    self.triangles.push(t);
                    self.loads.push(l);
                    self.tau.push([[[0.0; 3]; 6]; 2]);
                    (self.triangles.len() - 1) as u32
                }
            };
            self.slot[t as usize] = k;
        }
    }

    /// The loads of the triangle t, in the window.
    fn loads_of(&self, t: usize) -> &L {
        &self.loads[self.slot[t] as usize]
    }

    /// Adds the shares of the patches of block `j` (`share_of(a, t)`: vertex a's on triangle t),
    /// and hands the triangles whose last patch that was to `on_triangle`, in parallel; they
    /// leave the window.
    fn complete<'s, R: Send>(
        &mut self,
        (mesh, sweep, j): (&Mesh, &Sweep, usize),
        share_of: impl Fn(usize, usize) -> &'s TriangleFlux + Sync,
        on_triangle: &(impl Fn(usize, &L, &TriangleFlux) -> R + Sync),
    ) -> Vec<(usize, R)> {
        let (triangles, loads) = (&self.triangles, &self.loads);
        let done = parallel::map_mut(&mut self.tau, PATCHES, |base, tau| {
            let mut done = Vec::new();
            for (k, tau) in (base..).zip(tau) {
                let t = triangles[k];
                if t == FREE {
                    continue;
                }
                let (t, tri) = (t as usize, mesh.triangle(t as usize));
                for a in tri.into_iter().filter(|&a| sweep.block(a) == j) {
                    let share = share_of(a, t);
                    for (tau, share) in tau.as_flattened_mut().iter_mut().zip(share.as_flattened()) {
                        for (x, y) in tau.iter_mut().zip(share) {
                            *x += y;
                        }
                    }
                }
                if tri.iter().all(|&a| sweep.block(a) <= j) {
                    done.push((k, t, on_triangle(t, &loads[k], tau)));
                }
            }
            done
        });
        let done: Vec<(usize, usize, R)> = done.into_iter().flatten().collect();
        for &(k, _, _) in &done {
            self.triangles[k] = FREE;
            self.free.push(k as u32);
        }
        done.into_iter().map(|(_, t, r)| (t, r)).collect()
    }
}

/// The increasing triangles `t` as runs of consecutive ones, each of at most [`PATCHES`].
fn runs(t: &[u32]) -> Vec<Range<usize>> {
    let mut runs: Vec<Range<usize>> = Vec::new();
    for &t in t {
        match runs.last_mut() {
            Some(run) if run.end == t as usize && run.len() < PATCHES => run.end += 1,
            _ => runs.push(t as usize..t as usize + 1),
        }
    }
    runs
}

/// One cell of S_h in a patch, with what its local problems need of its geometry.
#[derive(Clone, Copy, Default)]
struct Cell {
    area: f64,
    /// The stream-function unknown at each corner; where ψ is held at 0, the extra row
    /// [`Patch::unknowns`] of the stream system, which is assembled but never solved.
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

/// The workspace of one patch, reused from vertex to vertex.
#[derive(Default)]
struct Patch {
    /// The triangles around a (with a's position in each) and a's neighbours, in order.
    star: Vec<(usize, usize)>,
    others: Vec<usize>,
    cells: Vec<Cell>,
    /// The triangles of the star (positions in `star`) along the chain ([`Patch::chain`]), and
    /// where each of its pieces begins and ends.
    chain: Vec<usize>,
    pieces: Vec<Range<usize>>,
    /// The piece of the chain each triangle of the star lies in.
    piece_of: Vec<usize>,
    /// Whether the patch touches ∂ω, where the chain's pieces begin.
    grounded: bool,
    unknowns: usize,
    /// The P1 stiffness matrix of S_h|ω_a on the stream unknowns and the extra row of the held
    /// corners (row length `unknowns + 1`), its leading block factorized (LLᵀ).
    factor: Vec<f64>,
    flux: Vec<[f64; 3]>,
    /// The divergence of τ_{i,a} integrated over each cell.
    divergence: Vec<f64>,
    /// The stream system's right-hand sides, one column of `unknowns + 1` per membrane.
    rhs: Vec<f64>,
    /// The gradients of the hat functions of each triangle of the star.
    hats: Vec<[[f64; 2]; 3]>,
    /// μ_i ∇u_ih on each triangle of the star, for each membrane.
    grad_u: Vec<[[f64; 2]; 2]>,
}

impl Patch {
    /// The cells, chain and stream-function system of the patch of `a`.
    fn build(&mut self, mesh: &Mesh, dual: &DualMesh, patches: &Patches, a: usize) {
        let (mut star, mut others) = (std::mem::take(&mut self.star), std::mem::take(&mut self.others));
        star.clear();
        star.extend(patches.around(a));
        others.clear();
        others.extend((star.iter()).flat_map(|&(t, k)| [1, 2].map(|d| mesh.triangle(t)[(k + d) % 3])));
        others.sort_unstable();
        others.dedup();
        self.chain(patches, &star);
        self.unknowns = self.pieces.len() + others.len() + star.len();
        self.cells(mesh, dual, a, &star, &others);
        self.factorize();
        (self.star, self.others) = (star, others);
    }

    /// The six cells of S_h in each triangle of the `star` of `a` (`others` a's neighbours, in
    /// order): their geometry, φ_a on them and their stream unknowns (a once per piece of the
    /// chain — where ω_a's fans touch only at a, ψ(a) is free in each —, the edge midpoints at a,
    /// the centroids).
    fn cells(&mut self, mesh: &Mesh, dual: &DualMesh, a: usize, star: &[(usize, usize)], others: &[usize]) {
        let at_a = self.pieces.len();
        let midpoint_unknown = |v: usize| at_a + others.binary_search(&v).expect("a neighbour of a");
        let held = self.unknowns;
        self.cells.clear();
        self.hats.clear();
        for (i, &(t, k)) in star.iter().enumerate() {
            let tri = mesh.triangle(t);
            self.hats.push(gradients(mesh.corners(t)));
            let grad_phi = self.hats[i][k];
            let (centre, piece) = (at_a + others.len() + i, self.piece_of[i]);
            for (c, p) in dual.cells_of(t).into_iter().enumerate() {
                let j = c / 2;
                let (v, w) = if c % 2 == 0 {
                    (tri[j], tri[(j + 1) % 3])
                } else {
                    (tri[j], tri[(j + 2) % 3])
                };
                // The corners of cell c: [v, m_vw, g] or [v, g, m_wv] (DualMesh).
                let vertex = if v == a { (piece, 1.0) } else { (held, 0.0) };
                let mid = if v == a {
                    (midpoint_unknown(w), 0.5)
                } else if w == a {
                    (midpoint_unknown(v), 0.5)
                } else {
                    (held, 0.0)
                };
                let centroid = (centre, 1.0 / 3.0);
                let corners3 = if c % 2 == 0 {
                    [vertex, mid, centroid]
                } else {
                    [vertex, centroid, mid]
                };
                let area = 0.5 * orient(p[0], p[1], p[2]);
                let phi = corners3.map(|x| x.1);
                let centroid = [0, 1].map(|k| (p[0][k] + p[1][k] + p[2][k]) / 3.0);
                self.cells.push(Cell {
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
    }

    /// The triangles of the `star` in the order of a path through all the cells of the patch:
    /// each triangle followed by its neighbour across its edge ab at a (b the next corner after
    /// a), the cells of each along [`chain_cells`]. Around an interior vertex one piece, from the
    /// first triangle round to the last; at a boundary vertex one piece per fan, from a triangle
    /// whose edge ca at a lies on ∂ω to one whose edge ab does.
    fn chain(&mut self, patches: &Patches, star: &[(usize, usize)]) {
        let next = |i: usize| {
            let (t, k) = star[i];
            let s = patches.neighbour[t][k];
            (s != ON_BOUNDARY).then(|| {
                star.iter()
                    .position(|&(r, _)| r == s as usize)
                    .expect("in the patch")
            })
        };
        let on_boundary = |&(t, k): &(usize, usize)| patches.neighbour[t][(k + 2) % 3] == ON_BOUNDARY;
        self.chain.clear();
        self.pieces.clear();
        self.grounded = star.iter().any(on_boundary);
        let starts = star
            .iter()
            .enumerate()
            .filter(|(_, c)| !self.grounded || on_boundary(c));
        for (first, _) in starts.take(if self.grounded { star.len() } else { 1 }) {
            let begin = self.chain.len();
            let mut i = Some(first);
            while let Some(j) = i.filter(|&j| j != first || self.chain.len() == begin) {
                self.chain.push(j);
                i = next(j);
            }
            self.pieces.push(begin..self.chain.len());
        }
        self.piece_of.clear();
        self.piece_of.resize(star.len(), 0);
        for (p, piece) in self.pieces.iter().enumerate() {
            for &j in &self.chain[piece.clone()] {
                self.piece_of[j] = p;
            }
        }
        assert_eq!(
            self.chain.len(),
            star.len(),
            "the star of a vertex is one cycle or fans"
        );
    }

    /// Assembles and factorizes the P1 stiffness matrix of S_h|ω_a on the stream unknowns.
    fn factorize(&mut self) {
        let row = self.unknowns + 1;
        self.factor.clear();
        self.factor.resize(row * row, 0.0);
        for cell in &self.cells {
            let (g, k) = (cell.hat, cell.stream);
            for p in 0..3 {
                for q in 0..3 {
                    self.factor[k[p] * row + k[q]] += cell.area * (g[p][0] * g[q][0] + g[p][1] * g[q][1]);
                }
            }
        }
        cholesky(&mut self.factor, self.unknowns, row);
    }

    /// τ_{i,a} for each membrane i on the cells of each triangle of the star, in the star's order,
    /// in `out`. One solve of the stream-function system takes all membranes' right-hand sides.
    fn solve<'l, L: CellPairings + 'l>(
        &mut self,
        mesh: &Mesh,
        (a, membranes): (usize, &[Membrane]),
        loads: impl Fn(usize) -> &'l L,
        out: &mut [TriangleFlux],
    ) {
        let (cells, n, m) = (self.cells.len(), self.unknowns, membranes.len());
        self.flux.clear();
        self.flux.resize(m * cells, [0.0; 3]);
        self.rhs.clear();
        self.rhs.resize((n + 1) * m, 0.0);
        self.grad_u.clear();
        self.grad_u
            .extend(self.star.iter().zip(&self.hats).map(|(&(t, _), g)| {
                let tri = mesh.triangle(t);
                std::array::from_fn(|i| match membranes.get(i) {
                    Some(m) => [0, 1].map(|k| m.mu * (0..3).map(|j| g[j][k] * m.u[tri[j]]).sum::<f64>()),
                    None => [0.0; 2],
                })
            }));
        for (i, membrane) in membranes.iter().enumerate() {
            self.particular(a, membrane, i, &loads);
        }
        for column in self.rhs.chunks_exact_mut(n + 1) {
            cholesky_solve(&self.factor, n + 1, &mut column[..n]);
            column[n] = 0.0;
        }
        let (fluxes, psis) = (self.flux.chunks_exact(cells), self.rhs.chunks_exact(n + 1));
        for (i, (flux, psi)) in fluxes.zip(psis).enumerate() {
            let triangles = self.cells.chunks_exact(6).zip(flux.chunks_exact(6));
            for (out, (cells, flux)) in out.iter_mut().zip(triangles) {
                for (out, (cell, flux)) in out[i].iter_mut().zip(cells.iter().zip(flux)) {
                    let psi = cell.stream.map(|k| psi[k]);
                    // The flux of curl ψ through the edge from corner e to e + 1.
                    *out = std::array::from_fn(|e| flux[e] + psi[(e + 1) % 3] - psi[e]);
                }
            }
        }
    }

    /// A particular solution τ_p of membrane `m`'s divergence constraint on the patch of `a`
    /// (column `i` of the workspace's fluxes), and the right-hand side of its correction
    /// min ‖q + τ_p + curl ψ‖, q = Π_RT(φ_a μ ∇u_h), in column `i` of the stream system's.
    fn particular<'l, L: CellPairings + 'l>(
        &mut self,
        a: usize,
        m: &Membrane,
        i: usize,
        loads: impl Fn(usize) -> &'l L,
    ) {
        let (cells, row) = (self.cells.len(), self.unknowns + 1);
        let flux = &mut self.flux[i * cells..(i + 1) * cells];
        self.divergence.clear();
        self.divergence.resize(cells, 0.0);
        // The divergence, integrated over each cell.
        let (on_dual_cell, triangles) = (m.on_dual_cell[a], self.cells.chunks_exact(6));
        for ((&(t, position), du), (cells, d)) in
            (self.star.iter().zip(&self.grad_u)).zip(triangles.zip(self.divergence.chunks_exact_mut(6)))
        {
            let (loads, du) = (loads(t), du[i]);
            for (c, (cell, d)) in cells.iter().zip(d).enumerate() {
                let g = cell.grad_phi;
                *d = loads.f_phi(c, i)[position] - cell.area * (du[0] * g[0] + du[1] * g[1]);
                if cell.own {
                    *d += cell.area * on_dual_cell;
                }
            }
        }
        // Along each piece of the chain, the flux out of a cell into the next is what the cells
        // so far leave: from ∂ω at a boundary vertex (which takes in the piece's whole
        // divergence), from nothing around an interior vertex, where the last cell's flux would
        // close the cycle with the round-off of a zero sum, and is left out.
        for piece in &self.pieces {
            let cells_of =
                |&j: &usize| chain_cells(self.star[j].1).map(|(c, entry, exit)| (6 * j + c, entry, exit));
            let along = || self.chain[piece.clone()].iter().flat_map(cells_of);
            let mut s = match self.grounded {
                true => -along().map(|(node, _, _)| self.divergence[node]).sum::<f64>(),
                false => 0.0,
            };
            for (node, entry, exit) in along() {
                flux[node][entry] = -s;
                s += self.divergence[node];
                flux[node][exit] = s;
            }
            if !self.grounded {
                let (last, _, exit) = along().last().expect("a cell");
                flux[last][exit] = 0.0;
            }
        }
        let rhs = &mut self.rhs[i * row..(i + 1) * row];
        let triangles = self.cells.chunks_exact(6).zip(flux.chunks_exact(6));
        for (du, (cells, flux)) in self.grad_u.iter().zip(triangles) {
            let du = du[i];
            for (cell, flux) in cells.iter().zip(flux) {
                let q = cell.phi_edge.map(|e| du[0] * e[1] - du[1] * e[0]);
                let total: [f64; 3] = std::array::from_fn(|e| q[e] + flux[e]);
                let v = [0, 1].map(|k| (0..3).map(|e| total[e] * cell.at_centroid[e][k]).sum::<f64>());
                for (g, &k) in cell.hat.iter().zip(&cell.stream) {
                    // curl φ = (∂_y φ, −∂_x φ), constant on the cell.
                    rhs[k] -= cell.area * (g[1] * v[0] - g[0] * v[1]);
                }
            }
        }
    }
}

/// The six cells of a triangle along the chain through the patch of its corner k, each with the
/// edge the chain enters it by and the edge it leaves by: from the cell at a on edge ca round the
/// barycentre to the cell at a on edge ab ([`DualMesh`]: cell 2j is [v_j, m_{j,j+1}, g], cell
/// 2j + 1 is [v_j, g, m_{j+2,j}], edge e from corner e to e + 1).
fn chain_cells(k: usize) -> [(usize, usize, usize); 6] {
    let (b, c) = ((k + 1) % 3, (k + 2) % 3);
    [
        (2 * k + 1, 2, 1),
        (2 * c, 1, 2),
        (2 * c + 1, 0, 1),
        (2 * b, 1, 2),
        (2 * b + 1, 0, 1),
        (2 * k, 1, 0),
    ]
}

/// In-place Cholesky factorization LLᵀ of the leading n×n block of the SPD row-major matrix `m`
/// with rows of length `row` (its lower triangle).
fn cholesky(m: &mut [f64], n: usize, row: usize) {
    for j in 0..n {
        let (row_j, below) = m[j * row..].split_at_mut(row);
        let d = row_j[j] - dot(&row_j[..j], &row_j[..j]);
        debug_assert!(d > 0.0, "the stream-function system is positive definite");
        let d = d.sqrt();
        row_j[j] = d;
        for row_i in below.chunks_exact_mut(row).take(n - 1 - j) {
            row_i[j] = (row_i[j] - dot(&row_i[..j], &row_j[..j])) / d;
        }
    }
}

/// Solves LLᵀx = b in place with the factor of [`cholesky`] (rows of length `row`), n = b.len().
fn cholesky_solve(l: &[f64], row: usize, b: &mut [f64]) {
    let n = b.len();
    for (i, r) in l.chunks_exact(row).take(n).enumerate() {
        b[i] = (b[i] - dot(&r[..i], &b[..i])) / r[i];
    }
    // Lᵀ by rows of L: x_i once known leaves the equations above it.
    for (i, r) in l.chunks_exact(row).take(n).enumerate().rev() {
        b[i] /= r[i];
        let x = b[i];
        for (b, l) in b[..i].iter_mut().zip(&r[..i]) {
            *b -= l * x;
        }
    }
}

/// x · y, summed in order.
fn dot(x: &[f64], y: &[f64]) -> f64 {
    x.iter().zip(y).map(|(x, y)| x * y).sum()
}
