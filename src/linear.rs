//! Sparse Cholesky solves for the Dirichlet problem on the interior vertices, with some vertices
//! held fixed (the active set): faer's supernodal LLᵀ, symbolic analysis once per mesh.
//!
//! The fill-reducing ordering is computed once per mesh (AMD on K_II). Held vertices (w_a = 0) are
//! dropped from the system: the reduced matrix K_FF on the free unknowns is factorized in the
//! ordering of K_II restricted to them, which is still fill-reducing and cheaper than K_II (a
//! contact region cuts the separators). Several [`Factorization`]s can share one
//! [`InteriorSystem`] (e.g. on two threads).

use crate::assembly::Stiffness;
use dyn_stack::{MemBuffer, MemStack};
use faer::perm::PermRef;
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

    /// An empty factorization of this system.
    pub fn factorization(&self) -> Factorization<'_> {
        Factorization {
            system: self,
            reduced: None,
            factor: Vec::new(),
            buffer: MemBuffer::new(dyn_stack::StackReq::EMPTY),
            held: None,
        }
    }

    /// K_FF for the free unknowns (`free[k]` is the unknown of reduced index k) with its symbolic
    /// analysis in the restricted ordering; `None` when nothing is held (K_II itself is used).
    fn reduce(&self, held: &[bool]) -> Option<Reduced> {
        if !held.iter().any(|&h| h) {
            return None;
        }
        let n = self.n();
        let mut index = vec![usize::MAX; n];
        let mut free = Vec::new();
        for (i, &h) in held.iter().enumerate() {
            if !h {
                index[i] = free.len();
                free.push(i);
            }
        }
        let (mut col_ptr, mut row_idx, mut val) = (vec![0], Vec::new(), Vec::new());
        for &j in &free {
            for p in self.col_ptr[j]..self.col_ptr[j + 1] {
                let i = index[self.row_idx[p]];
                if i != usize::MAX {
                    row_idx.push(i);
                    val.push(self.k_val[p]);
                }
            }
            col_ptr.push(row_idx.len());
        }
        let m = free.len();
        let order = self.symbolic.perm().expect("AMD gives an ordering").arrays().0;
        let forward: Vec<usize> = order
            .iter()
            .map(|&i| index[i])
            .filter(|&i| i != usize::MAX)
            .collect();
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

/// The system restricted to the free unknowns.
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
    reduced: Option<Reduced>,
    factor: Vec<f64>,
    buffer: MemBuffer,
    held: Option<Vec<bool>>,
}

impl Factorization<'_> {
    /// Factorizes K_FF, F the unknowns not `held`; skipped when the current factorization already
    /// has that held set. Returns whether it factorized.
    pub fn factorize(&mut self, held: &[bool]) -> Result<bool, NotPositiveDefinite> {
        if self.held.as_deref() == Some(held) {
            return Ok(false);
        }
        let s = self.system;
        self.reduced = s.reduce(held);
        let (symbolic, col_ptr, row_idx, val) = match &self.reduced {
            Some(r) => (&r.symbolic, &r.col_ptr, &r.row_idx, &r.val),
            None => (&s.symbolic, &s.col_ptr, &s.row_idx, &s.k_val),
        };
        let m = col_ptr.len() - 1;
        self.factor.resize(symbolic.len_val(), 0.0);
        let scratch = symbolic
            .factorize_numeric_llt_scratch::<f64>(Par::Seq, Default::default())
            .or(symbolic.solve_in_place_scratch::<f64>(1, Par::Seq));
        self.buffer = MemBuffer::new(scratch);
        let a = SparseColMatRef::new(
            SymbolicSparseColMatRef::new_checked(m, m, col_ptr, None, row_idx),
            val,
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
        let s = self.system;
        match &self.reduced {
            None => {
                let llt = LltRef::new(&s.symbolic, &self.factor);
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
