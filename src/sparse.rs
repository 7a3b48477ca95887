//! Sparse matrices by rows with 32-bit indices: the stiffness matrix K, the interpolations between
//! the levels of a hierarchy of meshes, and the coarse operators of multigrid. One home for the
//! storage every O(n) kernel reads: 12 bytes per entry, rows sorted by column.

use std::ops::Range;

/// Entries below this times their row's diagonal entry are left out of K and of the Galerkin
/// operators of multigrid: couplings that vanish exactly but for the round-off of summing the
/// contributions of two triangles (see [`crate::assembly::Stiffness`]).
pub(crate) const NEGLIGIBLE: f64 = 1e-14;

/// A sparse matrix by rows with 32-bit column numbers, each row sorted by column; for square
/// operators also the position of each row's diagonal entry (for the Gauss–Seidel sweeps of
/// multigrid).
#[derive(Debug, Clone, Default)]
pub struct Csr {
    pub(crate) row_ptr: Vec<u32>,
    pub(crate) col: Vec<u32>,
    pub(crate) val: Vec<f64>,
    pub(crate) cols: usize,
    /// Where row i's diagonal entry is (where it would be when it has none); empty for the
    /// interpolations.
    pub(crate) diag: Vec<u32>,
}

/// Consecutive rows of a matrix: where each row ends (counted from the part's first entry), the
/// columns and the values.
pub(crate) type RowsPart = (Vec<u32>, Vec<u32>, Vec<f64>);

/// Empty room for the part `rows` of a matrix of `n` rows with up to `per_row` entries each, to
/// be [joined](Csr::joined) to the other part: the first part's room holds the entries of
/// both, so that joining copies the second part once and moves nothing (growing a vector of
/// hundreds of megabytes moves its pages, which cost more than the rows took to compute). Room
/// not written is never touched, so it takes no memory.
pub(crate) fn part_room(rows: &Range<usize>, n: usize, per_row: usize) -> RowsPart {
    let entries = per_row * if rows.start == 0 { n } else { rows.len() };
    (
        Vec::with_capacity(rows.len()),
        Vec::with_capacity(entries),
        Vec::with_capacity(entries),
    )
}

/// Why a matrix cannot be stored with 32-bit positions.
fn fits(n: usize, what: &str) -> u32 {
    u32::try_from(n).unwrap_or_else(|_| panic!("{what} {n} exceed 2³² (the memory guard stops such meshes)"))
}

impl Csr {
    /// The matrix of the rows of two parts (made e.g. on two threads, in the room of
    /// [`part_room`]), the first part's rows first, with `cols` columns.
    pub(crate) fn joined(
        [(first, mut col, mut val), (second, col2, val2)]: [RowsPart; 2],
        cols: usize,
    ) -> Self {
        let mut row_ptr = Vec::with_capacity(first.len() + second.len() + 1);
        row_ptr.push(0);
        row_ptr.extend(&first);
        fits(col.len() + col2.len(), "entries");
        let start = col.len() as u32;
        row_ptr.extend(second.iter().map(|&end| start + end));
        col.extend(col2);
        val.extend(val2);
        Csr {
            row_ptr,
            col,
            val,
            cols,
            ..Default::default()
        }
        .checked()
    }

    /// The number of rows.
    pub fn rows(&self) -> usize {
        self.row_ptr.len() - 1
    }

    /// The number of columns.
    pub fn cols(&self) -> usize {
        self.cols
    }

    /// The number of stored entries.
    pub fn nnz(&self) -> usize {
        self.col.len()
    }

    /// Row i: its columns and values.
    #[inline]
    pub fn row(&self, i: usize) -> (&[u32], &[f64]) {
        let r = self.row_ptr[i] as usize..self.row_ptr[i + 1] as usize;
        (&self.col[r.clone()], &self.val[r])
    }

    /// The entry (i, j), 0 off the pattern.
    pub fn get(&self, i: usize, j: usize) -> f64 {
        let (cols, vals) = self.row(i);
        cols.binary_search(&(j as u32)).map_or(0.0, |p| vals[p])
    }

    /// The diagonal entry a_ii of a square operator (K, a coarse operator of multigrid).
    #[inline]
    pub fn diagonal(&self, i: usize) -> f64 {
        let d = self.diag[i] as usize;
        if d < self.row_ptr[i + 1] as usize && self.col[d] as usize == i {
            self.val[d]
        } else {
            0.0
        }
    }

    /// Finds the diagonal entries.
    pub(crate) fn with_diagonal(mut self) -> Self {
        self.diag = (0..self.rows())
            .map(|i| {
                let (cols, _) = self.row(i);
                self.row_ptr[i] + cols.partition_point(|&j| (j as usize) < i) as u32
            })
            .collect();
        self
    }

    /// Σ_j a_ij x_j.
    #[inline]
    pub fn row_dot(&self, i: usize, x: &[f64]) -> f64 {
        self.gather(self.row_ptr[i] as usize..self.row_ptr[i + 1] as usize, x)
    }

    /// Row i split at its diagonal entry (rows of a square operator that have one): the positions
    /// of the entries before it, its own, and those after it.
    #[inline(always)]
    pub(crate) fn split(&self, i: usize) -> (Range<usize>, usize, Range<usize>) {
        let (start, d, end) = (
            self.row_ptr[i] as usize,
            self.diag[i] as usize,
            self.row_ptr[i + 1] as usize,
        );
        debug_assert_eq!(self.col[d] as usize, i, "row {i} has its diagonal entry");
        (start..d, d, d + 1..end)
    }

    /// Σ_k a_k x_{col_k} over the entries at the positions `part` (part of a row): the inner loop
    /// of every sweep, without bounds checks on x (a third of a product's time).
    #[inline(always)]
    pub(crate) fn gather(&self, part: Range<usize>, x: &[f64]) -> f64 {
        let (cols, vals) = (&self.col[part.clone()], &self.val[part]);
        assert!(x.len() >= self.cols, "a vector of the matrix's columns");
        let mut s = 0.0;
        for (&j, &v) in cols.iter().zip(vals) {
            debug_assert!((j as usize) < self.cols);
            // SAFETY: every column number of a Csr is below its `cols` (asserted by
            // `Csr::checked` when it is made; nothing changes them after), and x has at least
            // `cols` entries (asserted above).
            s += v * unsafe { *x.get_unchecked(j as usize) };
        }
        s
    }

    /// The positions of `part` (part of a row) whose columns are at least `base`: its end, as
    /// the columns are sorted.
    #[inline(always)]
    pub(crate) fn part_at_or_above(&self, part: Range<usize>, base: usize) -> Range<usize> {
        match part.clone().next() {
            Some(p) if (self.col[p] as usize) < base => {
                part.start + self.col[part.clone()].partition_point(|&j| (j as usize) < base)..part.end
            }
            _ => part,
        }
    }

    /// The positions of `part` whose columns are below `end`: its start.
    #[inline(always)]
    pub(crate) fn part_below(&self, part: Range<usize>, end: usize) -> Range<usize> {
        match part.clone().next_back() {
            Some(p) if self.col[p] as usize >= end => {
                part.start..part.start + self.col[part.clone()].partition_point(|&j| (j as usize) < end)
            }
            _ => part,
        }
    }

    /// Σ_k a_k x_{col_k − base} over the positions `part`, whose columns lie in
    /// base..base + x.len() (x holds one block of a vector): [`Csr::gather`] on a block.
    #[inline(always)]
    pub(crate) fn gather_from(&self, part: Range<usize>, x: &[f64], base: usize) -> f64 {
        let (cols, vals) = self.block_part(part, x, base);
        let mut s = 0.0;
        for (&j, &v) in cols.iter().zip(vals) {
            // SAFETY: base ≤ j < base + x.len() for every column of the part (`block_part`).
            s += v * unsafe { *x.get_unchecked(j as usize - base) };
        }
        s
    }

    /// [`Csr::gather_from`] in reverse order (the nearest column right of the diagonal last).
    #[inline(always)]
    pub(crate) fn gather_from_rev(&self, part: Range<usize>, x: &[f64], base: usize) -> f64 {
        let (cols, vals) = self.block_part(part, x, base);
        let mut s = 0.0;
        for (&j, &v) in cols.iter().zip(vals).rev() {
            // SAFETY: as in `gather_from`.
            s += v * unsafe { *x.get_unchecked(j as usize - base) };
        }
        s
    }

    /// The columns and values at `part`, asserted to lie in base..base + x.len() (the columns
    /// of a row are sorted: its first and last tell).
    #[inline(always)]
    fn block_part(&self, part: Range<usize>, x: &[f64], base: usize) -> (&[u32], &[f64]) {
        let (cols, vals) = (&self.col[part.clone()], &self.val[part]);
        if let (Some(&first), Some(&last)) = (cols.first(), cols.last()) {
            assert!(
                first as usize >= base && (last as usize) < base + x.len(),
                "columns within the block"
            );
        }
        (cols, vals)
    }

    /// Asserts that every column number is below `cols`, which [`Csr::gather`] relies on, and
    /// gives back the room of vectors grown entry by entry (up to half of it).
    pub(crate) fn checked(mut self) -> Self {
        self.row_ptr.shrink_to_fit();
        self.col.shrink_to_fit();
        self.val.shrink_to_fit();
        assert!(
            self.col.iter().all(|&j| (j as usize) < self.cols),
            "column numbers in range"
        );
        assert_eq!(self.row_ptr.last().map(|&e| e as usize), Some(self.col.len()));
        self
    }

    /// The transpose: its two halves of rows filled on two threads, each into its own part of
    /// the entries (both read all of this matrix, each writes half of the transpose).
    pub fn transpose(&self) -> Csr {
        let mut count = vec![0u32; self.cols + 1];
        for &j in &self.col {
            count[j as usize + 1] += 1;
        }
        for j in 0..self.cols {
            count[j + 1] += count[j];
        }
        let (mut col, mut val) = (vec![0u32; self.nnz()], vec![0.0; self.nnz()]);
        // Rows `rows` of the transpose into their entries `col` and `val`.
        let fill = |rows: Range<usize>, col: &mut [u32], val: &mut [f64]| {
            let first = count[rows.start];
            let mut next: Vec<u32> = count[rows.clone()].iter().map(|&c| c - first).collect();
            for i in 0..self.rows() {
                let (cols, vals) = self.row(i);
                for (&j, &v) in cols.iter().zip(vals) {
                    let slot = (j as usize).checked_sub(rows.start).and_then(|k| next.get_mut(k));
                    if let Some(p) = slot {
                        col[*p as usize] = i as u32;
                        val[*p as usize] = v;
                        *p += 1;
                    }
                }
            }
        };
        let mid = self.cols / 2;
        let split = count[mid] as usize;
        let ((col0, col1), (val0, val1)) = (col.split_at_mut(split), val.split_at_mut(split));
        crate::assembly::both(
            self.nnz() >= crate::assembly::SMALL,
            || fill(0..mid, col0, val0),
            || fill(mid..self.cols, col1, val1),
        );
        Csr {
            row_ptr: count,
            col,
            val,
            cols: self.rows(),
            diag: Vec::new(),
        }
        .checked()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parts_made_in_their_room_join_without_growing() {
        // The tridiagonal matrix (−1, 2, −1) of 9 rows, made in two parts.
        let n = 9;
        let parts = crate::assembly::in_two_halves(n, |rows| {
            let (mut ends, mut col, mut val) = part_room(&rows, n, 3);
            for i in rows {
                for j in i.saturating_sub(1)..(i + 2).min(n) {
                    col.push(j as u32);
                    val.push(if i == j { 2.0 } else { -1.0 });
                }
                ends.push(col.len() as u32);
            }
            (ends, col, val)
        });
        let entries = parts[0].1.len() + parts[1].1.len();
        assert!(parts[0].1.capacity() >= entries && parts[0].2.capacity() >= entries);
        let a = Csr::joined(parts, n);
        assert_eq!((a.rows(), a.cols(), a.nnz()), (n, n, 3 * n - 2));
        for i in 0..n {
            for j in 0..n {
                let expected = match i.abs_diff(j) {
                    0 => 2.0,
                    1 => -1.0,
                    _ => 0.0,
                };
                assert_eq!(a.get(i, j), expected, "({i}, {j})");
            }
        }
    }

    #[test]
    fn the_transpose_on_two_threads_is_the_transpose() {
        // 300 × 200 with about 60 entries per row (above the size that splits the work).
        let (rows, cols) = (300, 200);
        let mut part = (Vec::new(), Vec::new(), Vec::new());
        for i in 0..rows {
            for j in (0..cols).filter(|j| (i * 7 + j * 13) % 10 < 3) {
                part.1.push(j as u32);
                part.2.push((i * cols + j) as f64 + 0.5);
            }
            part.0.push(part.1.len() as u32);
        }
        let a = Csr::joined([part, (Vec::new(), Vec::new(), Vec::new())], cols);
        assert!(a.nnz() >= crate::assembly::SMALL);
        let t = a.transpose();
        assert_eq!((t.rows(), t.cols(), t.nnz()), (cols, rows, a.nnz()));
        for i in 0..rows {
            for j in 0..cols {
                assert_eq!(t.get(j, i), a.get(i, j), "({j}, {i})");
            }
        }
        for j in 0..cols {
            assert!(t.row(j).0.windows(2).all(|w| w[0] < w[1]), "row {j} sorted");
        }
    }
}
