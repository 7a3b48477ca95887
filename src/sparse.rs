//! Sparse matrices by rows with 32-bit indices: the stiffness matrix K, the interpolations between
//! the levels of a hierarchy of meshes, and the coarse operators of multigrid. One home for the
//! storage every O(n) kernel reads: 12 bytes per entry, rows sorted by column.

use crate::parallel;
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

/// Empty room for the part `rows` of a matrix with up to `per_row` entries per row, to be
/// [joined](Csr::joined) to the other parts. Parts are small enough for the allocator to reuse
/// their memory from one matrix to the next.
pub(crate) fn part_room(rows: &Range<usize>, per_row: usize) -> RowsPart {
    (
        Vec::with_capacity(rows.len()),
        Vec::with_capacity(per_row * rows.len()),
        Vec::with_capacity(per_row * rows.len()),
    )
}

/// Why a matrix cannot be stored with 32-bit positions.
fn fits(n: usize, what: &str) -> u32 {
    u32::try_from(n).unwrap_or_else(|_| panic!("{what} {n} exceed 2³² (the memory guard stops such meshes)"))
}

impl Csr {
    /// The matrix of `n` rows and `cols` columns made by rows: `rows`(range, part) pushes the rows
    /// of each range to its part (made in the room of [`part_room`] for up to `per_row` entries
    /// per row), the ranges in parallel.
    pub(crate) fn by_rows(
        n: usize,
        cols: usize,
        per_row: usize,
        rows: impl Fn(Range<usize>, &mut RowsPart) + Sync + Send,
    ) -> Self {
        Csr::by_rows_with(n, cols, per_row, || (), |(), range, part| rows(range, part))
    }

    /// As [`Csr::by_rows`], with scratch room made by `room` once per thread's run of pieces.
    pub(crate) fn by_rows_with<S>(
        n: usize,
        cols: usize,
        per_row: usize,
        room: impl Fn() -> S + Sync + Send,
        rows: impl Fn(&mut S, Range<usize>, &mut RowsPart) + Sync + Send,
    ) -> Self {
        let parts = parallel::map_with(n, parallel::PIECE, room, |scratch, range| {
            let mut part = part_room(&range, per_row);
            rows(scratch, range, &mut part);
            part
        });
        Csr::joined(parts, cols)
    }

    /// The matrix of the rows of consecutive parts, the first part's rows first, with `cols`
    /// columns; the parts copied in parallel.
    pub(crate) fn joined(parts: Vec<RowsPart>, cols: usize) -> Self {
        let offsets = |len: fn(&RowsPart) -> usize| -> Vec<usize> {
            (parts.iter())
                .scan(0, |start, part| {
                    let this = *start;
                    *start += len(part);
                    Some(this)
                })
                .collect()
        };
        let (first_rows, first_entries) = (offsets(|p| p.0.len()), offsets(|p| p.1.len()));
        let rows: usize = parts.iter().map(|p| p.0.len()).sum();
        let nnz = fits(parts.iter().map(|p| p.1.len()).sum(), "entries") as usize;
        let (mut row_ptr, mut col, mut val) = (vec![0u32; rows + 1], vec![0u32; nnz], vec![0.0; nnz]);
        parallel::map_parts2(&mut col, &mut val, &first_entries, |k, col, val| {
            col.copy_from_slice(&parts[k].1);
            val.copy_from_slice(&parts[k].2);
        });
        parallel::map_parts2(&mut row_ptr[1..], &mut [0u8; 0], &first_rows, |k, ends, _| {
            let start = first_entries[k] as u32;
            for (end, &e) in ends.iter_mut().zip(&parts[k].0) {
                *end = start + e;
            }
        });
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

    /// The transpose. Its rows are filled in parallel, in pieces: each piece of rows of the
    /// transpose (columns of this matrix) reads only the pieces of this matrix's rows whose
    /// columns reach it (few, on a mesh numbered along a curve), and writes its own entries.
    pub fn transpose(&self) -> Csr {
        let piece = parallel::PIECE;
        let mut count = vec![0u32; self.cols + 1];
        for &j in &self.col {
            count[j as usize + 1] += 1;
        }
        for j in 0..self.cols {
            count[j + 1] += count[j];
        }
        // The columns each piece of rows reaches.
        let reach = parallel::map(self.rows(), piece, |rows| {
            let entries = &self.col[self.row_ptr[rows.start] as usize..self.row_ptr[rows.end] as usize];
            let least = entries.iter().min().map_or(u32::MAX, |&j| j);
            (least, entries.iter().max().map_or(0, |&j| j + 1))
        });
        let (mut col, mut val) = (vec![0u32; self.nnz()], vec![0.0; self.nnz()]);
        let starts: Vec<usize> = (0..self.cols.div_ceil(piece).max(1))
            .map(|k| count[(k * piece).min(self.cols)] as usize)
            .collect();
        parallel::map_parts2(&mut col, &mut val, &starts, |k, col, val| {
            let columns = k * piece..((k + 1) * piece).min(self.cols);
            let first = count[columns.start];
            let mut next: Vec<u32> = count[columns.clone()].iter().map(|&c| c - first).collect();
            let touching = (reach.iter().enumerate())
                .filter(|(_, &(lo, hi))| (lo as usize) < columns.end && hi as usize > columns.start);
            for (p, _) in touching {
                for i in p * piece..((p + 1) * piece).min(self.rows()) {
                    let (cols, vals) = self.row(i);
                    for (&j, &v) in cols.iter().zip(vals) {
                        if let Some(slot) = (j as usize)
                            .checked_sub(columns.start)
                            .and_then(|k| next.get_mut(k))
                        {
                            (col[*slot as usize], val[*slot as usize]) = (i as u32, v);
                            *slot += 1;
                        }
                    }
                }
            }
        });
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
    fn parts_join_to_the_matrix() {
        // The tridiagonal matrix (−1, 2, −1) of 9 rows, made in three parts.
        let n = 9;
        let parts = parallel::map(n, 4, |rows| {
            let (mut ends, mut col, mut val) = part_room(&rows, 3);
            for i in rows {
                for j in i.saturating_sub(1)..(i + 2).min(n) {
                    col.push(j as u32);
                    val.push(if i == j { 2.0 } else { -1.0 });
                }
                ends.push(col.len() as u32);
            }
            (ends, col, val)
        });
        assert_eq!(parts.len(), 3);
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
    fn the_transpose_in_pieces_is_the_transpose() {
        // Rows near their columns, as on a mesh numbered along a curve, and a few far ones, over
        // several pieces of rows and columns.
        let piece = parallel::PIECE;
        let (rows, cols) = (3 * piece + 17, 2 * piece + 5);
        let mut part = (Vec::new(), Vec::new(), Vec::new());
        for i in 0..rows {
            let near = i * cols / rows;
            let mut row: Vec<usize> = vec![near.saturating_sub(1), near, (near + 1).min(cols - 1)];
            if i % 97 == 0 {
                row.push((i * 7919) % cols);
            }
            row.sort_unstable();
            row.dedup();
            for j in row {
                part.1.push(j as u32);
                part.2.push((i * cols + j) as f64 + 0.5);
            }
            part.0.push(part.1.len() as u32);
        }
        let a = Csr::joined(vec![part], cols);
        let t = a.transpose();
        assert_eq!((t.rows(), t.cols(), t.nnz()), (cols, rows, a.nnz()));
        for i in 0..rows {
            for (&j, &v) in a.row(i).0.iter().zip(a.row(i).1) {
                assert_eq!(t.get(j as usize, i), v, "({j}, {i})");
            }
        }
        for j in 0..cols {
            assert!(t.row(j).0.windows(2).all(|w| w[0] < w[1]), "row {j} sorted");
        }
    }
}
