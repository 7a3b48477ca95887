//! Sparse Cholesky solves for the Dirichlet problem on the interior vertices, with some vertices
//! held fixed (the active set): faer's supernodal LLᵀ, symbolic analysis once per mesh.
//!
//! The fill-reducing ordering is computed once per mesh (AMD on K_II). Held vertices (w_a = 0) are
//! dropped from the system: the reduced matrix K_FF on the free unknowns is factorized in the
//! ordering of K_II restricted to them, which is still fill-reducing and cheaper than K_II (a
//! contact region cuts the separators). The symbolic analysis of K_FF is kept while the held set
//! changes near the free boundary only: its pattern leaves out just the unknowns held deeper than
//! `MARGIN` graph steps inside the held set, and unknowns held in the pattern become decoupled
//! rows K_aa w_a = 0. Several [`Factorization`]s can share one [`InteriorSystem`] (e.g. on two
//! threads).

use crate::assembly::Stiffness;
use dyn_stack::{MemBuffer, MemStack};
use faer::perm::PermRef;
use faer::sparse::linalg::cholesky::{
    factorize_symbolic_cholesky, CholeskySymbolicParams, LltRef, SymbolicCholesky, SymmetricOrdering,
};
use faer::sparse::{SparseColMatRef, SymbolicSparseColMatRef};
use faer::{Conj, MatMut, Par, Side};

/// The interior unknowns of a Dirichlet problem and, for the direct solver, the interior block K_II
/// (lower triangle, CSC in interior numbering) with its symbolic analysis.
pub struct InteriorSystem {
    /// The vertex of each unknown, increasing.
    pub(crate) vertices: Vec<usize>,
    /// The unknown of each vertex ([`Unknown::HELD`] where the value is fixed).
    pub(crate) unknown: Vec<Unknown>,
    /// K_II and its analysis; `None` for the numbering alone ([`InteriorSystem::numbering`]).
    direct: Option<Direct>,
}

/// The number of an unknown, or [`Unknown::HELD`]: a vertex whose value is not an unknown (on ∂ω,
/// or off a band of vertices).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Unknown(u32);

impl Unknown {
    /// Not an unknown.
    pub const HELD: Unknown = Unknown(u32::MAX);

    /// Unknown number i.
    pub fn new(i: usize) -> Self {
        match u32::try_from(i) {
            Ok(i) if i != u32::MAX => Unknown(i),
            _ => panic!("unknown {i} exceeds 2³² − 1 (the memory guard stops such meshes)"),
        }
    }

    /// Its number, `None` when held.
    #[inline]
    pub fn index(self) -> Option<usize> {
        (self != Self::HELD).then_some(self.0 as usize)
    }
}

/// K_II (lower triangle, CSC) and its symbolic Cholesky analysis.
struct Direct {
    col_ptr: Vec<usize>,
    row_idx: Vec<usize>,
    k_val: Vec<f64>,
    symbolic: SymbolicCholesky<usize>,
}

/// The matrix is not positive definite (cannot happen for a valid mesh; reported, not panicked).
#[derive(Debug, Clone)]
pub struct NotPositiveDefinite;

impl InteriorSystem {
    /// Extracts K_II from K and runs the symbolic analysis (AMD ordering).
    pub fn new(k: &Stiffness, on_boundary: &[bool]) -> Self {
        let mut system = Self::numbering(on_boundary);
        system.direct = Some(Direct::new(k, &system.vertices, &system.unknown));
        system
    }

    /// The unknowns `vertices` (increasing) of K, every other vertex fixed, with K_II and its
    /// analysis; numbered in `unknown`, one entry per vertex, all [`Unknown::HELD`] on entry: room that
    /// the caller keeps for the next such system ([`InteriorSystem::into_scratch`]), so that
    /// making one costs O(unknowns), not O(vertices).
    pub fn on_vertices(k: &Stiffness, vertices: Vec<usize>, mut unknown: Vec<Unknown>) -> Self {
        for (i, &a) in vertices.iter().enumerate() {
            unknown[a] = Unknown::new(i);
        }
        let direct = Some(Direct::new(k, &vertices, &unknown));
        InteriorSystem {
            vertices,
            unknown,
            direct,
        }
    }

    /// The room of the numbering, all [`Unknown::HELD`] again.
    pub fn into_scratch(self) -> Vec<Unknown> {
        let mut unknown = self.unknown;
        for &a in &self.vertices {
            unknown[a] = Unknown::HELD;
        }
        unknown
    }

    /// The interior unknowns alone, without K_II and its analysis (for iterative solvers:
    /// [`Factorization`]s of it cannot be made).
    pub fn numbering(on_boundary: &[bool]) -> Self {
        let mut unknown = vec![Unknown::HELD; on_boundary.len()];
        let mut vertices = Vec::with_capacity(on_boundary.iter().filter(|&&b| !b).count());
        for (a, &b) in on_boundary.iter().enumerate() {
            if !b {
                unknown[a] = Unknown::new(vertices.len());
                vertices.push(a);
            }
        }
        InteriorSystem {
            vertices,
            unknown,
            direct: None,
        }
    }

    /// K_II and its analysis: only a system made by [`InteriorSystem::new`] has them.
    fn direct(&self) -> &Direct {
        (self.direct.as_ref()).expect("an InteriorSystem made by `new`, with its Cholesky analysis")
    }
}

impl Direct {
    /// K_II of K on the `vertices` (with `unknown` their numbers), and its analysis.
    fn new(k: &Stiffness, vertices: &[usize], unknown: &[Unknown]) -> Self {
        let n = vertices.len();
        let mut col_ptr = Vec::with_capacity(n + 1);
        let mut row_idx = Vec::new();
        let mut k_val = Vec::new();
        col_ptr.push(0);
        for &a in vertices {
            let j = unknown[a].index().expect("an unknown");
            for (b, v) in k.row(a) {
                if let Some(i) = unknown[b].index().filter(|&i| i >= j) {
                    row_idx.push(i);
                    k_val.push(v);
                }
            }
            col_ptr.push(row_idx.len());
        }
        let pattern = SymbolicSparseColMatRef::new_checked(n, n, &col_ptr, None, &row_idx);
        let symbolic = factorize_symbolic_cholesky(
            pattern,
            Side::Lower,
            SymmetricOrdering::Amd,
            CholeskySymbolicParams::default(),
        )
        .expect("symbolic Cholesky of a valid pattern");
        Direct {
            col_ptr,
            row_idx,
            k_val,
            symbolic,
        }
    }
}

impl InteriorSystem {
    /// The number of unknowns.
    pub fn n(&self) -> usize {
        self.vertices.len()
    }

    /// The right-hand side of the Dirichlet problem scale·K u = load inside, u = bc off the
    /// unknowns: load_a/scale − Σ_{b fixed} K_ab bc_b at each unknown a (the lift of bc).
    pub fn lifted_rhs(
        &self,
        k: &Stiffness,
        load: impl Fn(usize) -> f64,
        scale: f64,
        bc: impl Fn(usize) -> f64,
    ) -> Vec<f64> {
        (self.vertices.iter())
            .map(|&a| {
                let lift: f64 = (k.row(a))
                    .filter(|(b, _)| self.unknown[*b] == Unknown::HELD)
                    .map(|(b, v)| v * bc(b))
                    .sum();
                load(a) / scale - lift
            })
            .collect()
    }

    /// x on the unknowns, extended by 0 to every vertex.
    pub fn extended(&self, x: &[f64]) -> Vec<f64> {
        let mut u = vec![0.0; self.unknown.len()];
        self.place(x, &mut u);
        u
    }

    /// The values at the unknowns of a field on every vertex.
    pub fn gather(&self, u: &[f64]) -> Vec<f64> {
        self.vertices.iter().map(|&a| u[a]).collect()
    }

    /// The vertices a solver on every vertex skips: the fixed ones and the unknowns `held`.
    pub fn skipped(&self, held: &[bool]) -> Vec<bool> {
        let mut skip = vec![true; self.unknown.len()];
        for (i, &a) in self.vertices.iter().enumerate() {
            skip[a] = held[i];
        }
        skip
    }

    /// The vertex field with the values `x` at the unknowns and `bc` elsewhere.
    pub fn scatter(&self, x: &[f64], bc: &[f64]) -> Vec<f64> {
        let mut u = bc.to_vec();
        self.place(x, &mut u);
        u
    }

    /// u = x at the unknowns.
    fn place(&self, x: &[f64], u: &mut [f64]) {
        for (i, &a) in self.vertices.iter().enumerate() {
            u[a] = x[i];
        }
    }

    /// Number of nonzeros in the Cholesky factor.
    pub fn factor_nnz(&self) -> usize {
        self.direct.as_ref().map_or(0, |d| d.symbolic.len_val())
    }

    /// An empty factorization of this system.
    pub fn factorization(&self) -> Factorization<'_> {
        Factorization {
            system: self,
            reduced: None,
            pattern_set: false,
            analysed: None,
            values: Vec::new(),
            analyses: 0,
            factor: Vec::new(),
            buffer: MemBuffer::new(dyn_stack::StackReq::EMPTY),
            held: None,
        }
    }

    /// The unknowns held more than `margin` graph steps away from every free one: after k sweeps
    /// of relaxing the distance along the edges of K_II (both ways), every unknown within k steps
    /// of a free one has its exact distance, and the others keep an upper bound above k.
    fn deep(&self, held: &[bool], margin: usize) -> Vec<bool> {
        if !held.iter().any(|&h| h) {
            return vec![false; self.n()];
        }
        let d = self.direct();
        let mut dist: Vec<usize> = held.iter().map(|&h| if h { usize::MAX } else { 0 }).collect();
        for _ in 0..margin {
            for j in 0..self.n() {
                for &i in &d.row_idx[d.col_ptr[j]..d.col_ptr[j + 1]] {
                    dist[i] = dist[i].min(dist[j].saturating_add(1));
                    dist[j] = dist[j].min(dist[i].saturating_add(1));
                }
            }
        }
        dist.iter().map(|&k| k > margin).collect()
    }

    /// K restricted to the unknowns not `left_out`, with its symbolic analysis in the ordering
    /// of K_II restricted to them; `None` when none is left out (K_II itself is the pattern).
    fn reduce(&self, left_out: &[bool]) -> Option<Reduced> {
        if !left_out.iter().any(|&h| h) {
            return None;
        }
        let d = self.direct();
        let n = self.n();
        let mut index = vec![Unknown::HELD; n];
        let mut free = Vec::new();
        for (i, &h) in left_out.iter().enumerate() {
            if !h {
                index[i] = Unknown::new(free.len());
                free.push(i);
            }
        }
        let (mut col_ptr, mut row_idx, mut val) = (vec![0], Vec::new(), Vec::new());
        for &j in &free {
            for p in d.col_ptr[j]..d.col_ptr[j + 1] {
                if let Some(i) = index[d.row_idx[p]].index() {
                    row_idx.push(i);
                    val.push(d.k_val[p]);
                }
            }
            col_ptr.push(row_idx.len());
        }
        let m = free.len();
        let order = d.symbolic.perm().expect("AMD gives an ordering").arrays().0;
        let forward: Vec<usize> = order.iter().filter_map(|&i| index[i].index()).collect();
        let mut inverse = vec![0; m];
        for (k, &i) in forward.iter().enumerate() {
            inverse[i] = k;
        }
        let symbolic = factorize_symbolic_cholesky(
            SymbolicSparseColMatRef::new_checked(m, m, &col_ptr, None, &row_idx),
            Side::Lower,
            SymmetricOrdering::Custom(PermRef::new_checked(&forward, &inverse, m)),
            CholeskySymbolicParams::default(),
        )
        .expect("symbolic Cholesky of a valid pattern");
        Some(Reduced {
            free,
            col_ptr,
            row_idx,
            val,
            symbolic,
        })
    }
}

/// One Poisson solve with a Dirichlet lift: scale·K u = load at the vertices not `fixed`, u = bc
/// at the fixed ones.
pub fn dirichlet_solve(k: &Stiffness, fixed: &[bool], load: &[f64], scale: f64, bc: &[f64]) -> Vec<f64> {
    let system = InteriorSystem::new(k, fixed);
    let mut factor = system.factorization();
    factor
        .factorize(&vec![false; system.n()])
        .expect("the stiffness matrix of a valid mesh is positive definite");
    let mut x = system.lifted_rhs(k, |a| load[a], scale, |b| bc[b]);
    factor.solve(&mut x);
    system.scatter(&x, bc)
}

/// A sparse Cholesky factorization that owns its matrix: faer's supernodal LLᵀ with an AMD
/// ordering, as [`Factorization`], for a matrix given by its values alone (the coarsest level of
/// [`crate::multigrid`]).
pub struct Cholesky {
    n: usize,
    symbolic: SymbolicCholesky<usize>,
    factor: Vec<f64>,
    buffer: MemBuffer,
}

impl Cholesky {
    /// Factorizes the symmetric positive definite matrix of order `n` whose lower triangle is
    /// given by columns: rows `row_idx[col_ptr[j]..col_ptr[j + 1]]`, increasing, of column j.
    pub fn new(
        n: usize,
        col_ptr: &[usize],
        row_idx: &[usize],
        val: &[f64],
    ) -> Result<Self, NotPositiveDefinite> {
        let pattern = SymbolicSparseColMatRef::new_checked(n, n, col_ptr, None, row_idx);
        let symbolic = factorize_symbolic_cholesky(
            pattern,
            Side::Lower,
            SymmetricOrdering::Amd,
            CholeskySymbolicParams::default(),
        )
        .map_err(|_| NotPositiveDefinite)?;
        let scratch = symbolic
            .factorize_numeric_llt_scratch::<f64>(Par::Seq, Default::default())
            .or(symbolic.solve_in_place_scratch::<f64>(1, Par::Seq));
        let mut buffer = MemBuffer::new(scratch);
        let mut factor = vec![0.0; symbolic.len_val()];
        symbolic
            .factorize_numeric_llt(
                &mut factor,
                SparseColMatRef::new(pattern, val),
                Side::Lower,
                Default::default(),
                Par::Seq,
                MemStack::new(&mut buffer),
                Default::default(),
            )
            .map_err(|_| NotPositiveDefinite)?;
        Ok(Cholesky {
            n,
            symbolic,
            factor,
            buffer,
        })
    }

    /// Solves in place.
    pub fn solve(&mut self, x: &mut [f64]) {
        LltRef::new(&self.symbolic, &self.factor).solve_in_place_with_conj(
            Conj::No,
            MatMut::from_column_major_slice_mut(x, self.n, 1),
            Par::Seq,
            MemStack::new(&mut self.buffer),
        );
    }
}

/// Graph steps between the free unknowns and those left out of the pattern of K_FF.
const MARGIN: usize = 8;
/// A pattern is kept while it has at most this many times the unknowns of a fresh one.
const PATTERN_SLACK: f64 = 1.05;

/// K_II restricted to the unknowns of a pattern (`free[k]` is the unknown of index k).
struct Reduced {
    free: Vec<usize>,
    col_ptr: Vec<usize>,
    row_idx: Vec<usize>,
    val: Vec<f64>,
    symbolic: SymbolicCholesky<usize>,
}

/// A numeric factorization of K_II with some unknowns held at zero.
pub struct Factorization<'a> {
    system: &'a InteriorSystem,
    /// The pattern factorized: `Some` restricted, `None` all of K_II; `pattern_set` is false
    /// before the first factorization.
    reduced: Option<Reduced>,
    pattern_set: bool,
    /// The values factorized: K on the pattern with held unknowns decoupled.
    values: Vec<f64>,
    factor: Vec<f64>,
    buffer: MemBuffer,
    held: Option<Vec<bool>>,
    /// The held set the pattern was last chosen for.
    analysed: Option<Vec<bool>>,
    /// Symbolic analyses done (one per pattern).
    pub analyses: usize,
}

impl Factorization<'_> {
    /// Chooses the pattern for the held set `held`: the current one while it contains every free
    /// unknown and is not much larger than a fresh one, else a fresh one with its symbolic
    /// analysis. Sizes the factor storage. [`Self::factorize`] calls it; calling it first moves
    /// this work out of the numeric factorization (e.g. while another thread factorizes).
    pub fn analyse(&mut self, held: &[bool]) {
        let s = self.system;
        let left_out = s.deep(held, MARGIN);
        let fresh = left_out.iter().filter(|&&d| !d).count();
        let fits = self.pattern_set
            && match &self.reduced {
                None => s.n() as f64 <= PATTERN_SLACK * fresh as f64,
                Some(r) => {
                    let mut inside = vec![false; s.n()];
                    r.free.iter().for_each(|&i| inside[i] = true);
                    r.free.len() as f64 <= PATTERN_SLACK * fresh as f64
                        && (0..s.n()).all(|i| inside[i] || held[i])
                }
            };
        if !fits {
            self.reduced = s.reduce(&left_out);
            self.pattern_set = true;
            self.analyses += 1;
        }
        let symbolic = self
            .reduced
            .as_ref()
            .map_or(&s.direct().symbolic, |r| &r.symbolic);
        self.factor.resize(symbolic.len_val(), 0.0);
        self.analysed = Some(held.to_vec());
    }

    /// Factorizes K_FF, F the unknowns not `held`; skipped when the current factorization already
    /// has that held set. Returns whether it factorized.
    pub fn factorize(&mut self, held: &[bool]) -> Result<bool, NotPositiveDefinite> {
        if self.held.as_deref() == Some(held) {
            return Ok(false);
        }
        if self.analysed.as_deref() != Some(held) {
            self.analyse(held);
        }
        let s = self.system;
        let (symbolic, col_ptr, row_idx, val) = match &self.reduced {
            Some(r) => (&r.symbolic, &r.col_ptr, &r.row_idx, &r.val),
            None => {
                let d = s.direct();
                (&d.symbolic, &d.col_ptr, &d.row_idx, &d.k_val)
            }
        };
        let unknown = |k: usize| self.reduced.as_ref().map_or(k, |r| r.free[k]);
        // Held unknowns inside the pattern become decoupled rows K_aa w_a = 0.
        self.values.clear();
        for j in 0..col_ptr.len() - 1 {
            for p in col_ptr[j]..col_ptr[j + 1] {
                let i = row_idx[p];
                let decoupled = held[unknown(i)] || held[unknown(j)];
                self.values.push(if decoupled && i != j { 0.0 } else { val[p] });
            }
        }
        let m = col_ptr.len() - 1;
        let scratch = symbolic
            .factorize_numeric_llt_scratch::<f64>(Par::Seq, Default::default())
            .or(symbolic.solve_in_place_scratch::<f64>(1, Par::Seq));
        self.buffer = MemBuffer::new(scratch);
        let a = SparseColMatRef::new(
            SymbolicSparseColMatRef::new_checked(m, m, col_ptr, None, row_idx),
            &self.values,
        );
        symbolic
            .factorize_numeric_llt(
                &mut self.factor,
                a,
                Side::Lower,
                Default::default(),
                Par::Seq,
                MemStack::new(&mut self.buffer),
                Default::default(),
            )
            .map_err(|_| NotPositiveDefinite)?;
        self.held = Some(held.to_vec());
        Ok(true)
    }

    /// Solves the factorized system in place; held unknowns come out as zero.
    pub fn solve(&mut self, rhs: &mut [f64]) {
        let held = self.held.as_deref().expect("factorized before solving");
        for (r, &h) in rhs.iter_mut().zip(held) {
            if h {
                *r = 0.0;
            }
        }
        let s = self.system;
        match &self.reduced {
            None => {
                let llt = LltRef::new(&s.direct().symbolic, &self.factor);
                llt.solve_in_place_with_conj(
                    Conj::No,
                    MatMut::from_column_major_slice_mut(rhs, s.n(), 1),
                    Par::Seq,
                    MemStack::new(&mut self.buffer),
                );
            }
            Some(r) => {
                let mut x: Vec<f64> = r.free.iter().map(|&i| rhs[i]).collect();
                let llt = LltRef::new(&r.symbolic, &self.factor);
                llt.solve_in_place_with_conj(
                    Conj::No,
                    MatMut::from_column_major_slice_mut(&mut x, r.free.len(), 1),
                    Par::Seq,
                    MemStack::new(&mut self.buffer),
                );
                rhs.fill(0.0);
                for (&i, v) in r.free.iter().zip(x) {
                    rhs[i] = v;
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::{Diagonal, Mesh};

    /// max |(K x)_a − b_a| over the free unknowns, and max |x_a| over the held ones.
    fn residuals(k: &Stiffness, system: &InteriorSystem, held: &[bool], x: &[f64]) -> (f64, f64) {
        let mut u = vec![0.0; k.n()];
        for (i, &a) in system.vertices.iter().enumerate() {
            u[a] = x[i];
        }
        let (mut free, mut fixed) = (0.0_f64, 0.0_f64);
        for (i, &a) in system.vertices.iter().enumerate() {
            if held[i] {
                fixed = fixed.max(x[i].abs());
            } else {
                free = free.max((k.row_dot(a, &u) - 1.0).abs());
            }
        }
        (free, fixed)
    }

    #[test]
    fn a_pattern_serves_held_sets_that_move_near_the_free_boundary() {
        let mesh = Mesh::rectangle([0.0, 0.0], [1.0, 1.0], 40, 40, Diagonal::Right).unwrap();
        let k = Stiffness::assemble(&mesh);
        let system = InteriorSystem::new(&k, &mesh.on_boundary);
        let disk = |r: f64| -> Vec<bool> {
            (system.vertices.iter())
                .map(|&a| {
                    let p = mesh.points[a];
                    (p[0] - 0.5).hypot(p[1] - 0.5) < r
                })
                .collect()
        };
        let mut factor = system.factorization();
        // The held disk shrinks by a ring, then grows by one: the first pattern serves all three.
        for (r, analyses) in [(0.3, 1), (0.27, 1), (0.33, 1)] {
            let held = disk(r);
            assert!(factor.factorize(&held).unwrap());
            let mut x = vec![1.0; system.n()];
            factor.solve(&mut x);
            let (free, fixed) = residuals(&k, &system, &held, &x);
            assert!(free < 1e-12 && fixed == 0.0, "r = {r}: {free} {fixed}");
            assert_eq!(factor.analyses, analyses, "r = {r}");
        }
        // Freeing the centre of the disk, deep inside, needs a new pattern.
        let mut held = disk(0.33);
        let centre = (system.vertices.iter())
            .position(|&a| mesh.points[a] == [0.5, 0.5])
            .unwrap();
        held[centre] = false;
        factor.factorize(&held).unwrap();
        let mut x = vec![1.0; system.n()];
        factor.solve(&mut x);
        let (free, fixed) = residuals(&k, &system, &held, &x);
        assert!(free < 1e-12 && fixed == 0.0, "{free} {fixed}");
        assert_eq!(factor.analyses, 2);
    }
}
