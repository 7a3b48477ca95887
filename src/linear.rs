//! Sparse Cholesky solves for the Dirichlet problem on the interior vertices, with some vertices
//! held fixed (the active set): faer's supernodal LLᵀ, symbolic analysis once per mesh.
//!
//! A held vertex a keeps its row and column in the pattern with only the diagonal K_aa, so the
//! pattern, and hence the symbolic factorization, never changes with the active set. Several
//! [`Factorization`]s can share one [`InteriorSystem`] (e.g. on two threads).

use crate::assembly::Stiffness;
use dyn_stack::{MemBuffer, MemStack};
use faer::sparse::linalg::cholesky::{
    factorize_symbolic_cholesky, CholeskySymbolicParams, LltRef, SymbolicCholesky, SymmetricOrdering,
};
use faer::sparse::{SparseColMatRef, SymbolicSparseColMatRef};
use faer::{Conj, MatMut, Par, Side};

/// The interior block K_II (lower triangle, CSC in interior numbering) and its symbolic analysis.
pub struct InteriorSystem {
    /// Interior vertex of each unknown.
    pub vertices: Vec<usize>,
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
        let mut unknown = vec![usize::MAX; k.n()];
        let mut vertices = Vec::new();
        for (a, &b) in on_boundary.iter().enumerate() {
            if !b {
                unknown[a] = vertices.len();
                vertices.push(a);
            }
        }
        let n = vertices.len();
        let mut col_ptr = Vec::with_capacity(n + 1);
        let mut row_idx = Vec::new();
        let mut k_val = Vec::new();
        col_ptr.push(0);
        for &a in &vertices {
            let j = unknown[a];
            for (b, v) in k.row(a) {
                let i = unknown[b];
                if i != usize::MAX && i >= j {
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
        InteriorSystem {
            vertices,
            col_ptr,
            row_idx,
            k_val,
            symbolic,
        }
    }

    pub fn n(&self) -> usize {
        self.vertices.len()
    }

    /// Number of nonzeros in the Cholesky factor.
    pub fn factor_nnz(&self) -> usize {
        self.symbolic.len_val()
    }

    /// Workspace for numeric factorizations of this system.
    pub fn factorization(&self) -> Factorization<'_> {
        let scratch = self
            .symbolic
            .factorize_numeric_llt_scratch::<f64>(Par::Seq, Default::default())
            .or(self.symbolic.solve_in_place_scratch::<f64>(1, Par::Seq));
        Factorization {
            system: self,
            val: self.k_val.clone(),
            factor: vec![0.0; self.symbolic.len_val()],
            buffer: MemBuffer::new(scratch),
            held: None,
        }
    }
}

/// A numeric factorization of K_II with some unknowns held (reduced to their diagonal).
pub struct Factorization<'a> {
    system: &'a InteriorSystem,
    val: Vec<f64>,
    factor: Vec<f64>,
    buffer: MemBuffer,
    held: Option<Vec<bool>>,
}

impl Factorization<'_> {
    /// Factorizes with the unknowns in `held` reduced to their diagonal; skipped when the
    /// current factorization already has that held set. Returns whether it factorized.
    pub fn factorize(&mut self, held: &[bool]) -> Result<bool, NotPositiveDefinite> {
        if self.held.as_deref() == Some(held) {
            return Ok(false);
        }
        let s = self.system;
        let n = s.n();
        for j in 0..n {
            for p in s.col_ptr[j]..s.col_ptr[j + 1] {
                let i = s.row_idx[p];
                self.val[p] = if i != j && (held[i] || held[j]) {
                    0.0
                } else {
                    s.k_val[p]
                };
            }
        }
        let a = SparseColMatRef::new(
            SymbolicSparseColMatRef::new_checked(n, n, &s.col_ptr, None, &s.row_idx),
            &self.val,
        );
        s.symbolic
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

    /// Solves the factorized system in place.
    pub fn solve(&mut self, rhs: &mut [f64]) {
        let n = self.system.n();
        let llt = LltRef::new(&self.system.symbolic, &self.factor);
        llt.solve_in_place_with_conj(
            Conj::No,
            MatMut::from_column_major_slice_mut(rhs, n, 1),
            Par::Seq,
            MemStack::new(&mut self.buffer),
        );
    }
}
