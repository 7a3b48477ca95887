//! The smoother of the V-cycle: Gauss–Seidel sweeps in blocks of rows (hybrid Gauss–Seidel).

use crate::parallel;
use crate::sparse::Csr;
use std::borrow::Cow;

/// Levels are smoothed in blocks of at least about this many rows (one block below twice as many):
/// Gauss–Seidel within each block, the other blocks' unknowns read at their values from before
/// the sweep (hybrid Gauss–Seidel, block Jacobi between the blocks), so that the blocks can be
/// swept in parallel. The forward sweep before the coarse correction and the backward sweep after
/// it stay each other's adjoint, so the cycle stays symmetric. Meshes are numbered along a
/// Z-order curve (or by rows, built-in ones), so the blocks are compact parts of ω and few rows
/// couple across. Where they are strips of a row-by-row numbering a few grid lines wide, the
/// blocks grow until at most [`INTERFACE_SHARE`] of the rows couple across (16 grid lines). The
/// blocks depend on the level's matrix only, not on the threads: the numbers are the same swept on
/// one thread or many.
pub const BLOCK_ROWS: usize = 1 << 14;

/// The largest share of a level's rows that may couple to another block: on a mesh numbered by
/// rows, 2 of every 16 grid lines.
pub const INTERFACE_SHARE: f64 = 0.125;

/// One level of the V-cycle: its operator (level 0's is K itself), the vertices skipped (on the
/// boundary, held, or coarse ones not kept) and the blocks of its smoother.
pub(super) struct Level<'h> {
    pub(super) a: Cow<'h, Csr>,
    pub(super) skip: Vec<bool>,
    pub(super) blocks: Blocks,
}

/// The rows of a level in the blocks of its smoother: where each block begins and the rows
/// coupled to another block.
#[derive(Clone)]
pub(super) struct Blocks {
    pub(super) starts: Vec<usize>,
    pub(super) interface: Vec<u32>,
}

/// The values of x at the interface rows when a backward sweep starts (what each block reads of
/// the others).
#[derive(Clone, Copy)]
pub(super) struct Ghosts<'a> {
    interface: &'a [u32],
    values: &'a [f64],
}

impl Ghosts<'_> {
    /// x_j as the sweep started (j an interface row).
    fn at(&self, j: u32) -> f64 {
        self.values[self.interface.binary_search(&j).expect("a row coupled across")]
    }
}

impl Blocks {
    /// The blocks of the rows of `a`, of equal sizes: n / `block_rows` of them (at least one),
    /// or as many fewer (halved each time) as keep the interface within `share` of the rows.
    pub(super) fn new(a: &Csr, block_rows: usize, share: f64) -> Self {
        let n = a.rows();
        let mut rows = block_rows.max(1);
        loop {
            let blocks = Self::of_size(a, rows);
            let coupled = blocks.interface.len() as f64 / n.max(1) as f64;
            if coupled <= share || blocks.starts.len() == 1 {
                return blocks;
            }
            rows *= 2;
        }
    }

    /// The n / `block_rows` blocks (at least one) of the rows of `a`, of equal sizes. A row is
    /// coupled across if it has an entry in another block's columns or another block's row has
    /// one in its column: `a` is symmetric in its values but not always in its entries (an entry
    /// next to [`crate::sparse::NEGLIGIBLE`] times its row's diagonal may be kept in one row and
    /// left out of the other), and a sweep reads the values before the sweep of every column
    /// across.
    fn of_size(a: &Csr, block_rows: usize) -> Self {
        let n = a.rows();
        let count = (n / block_rows.max(1)).max(1);
        let starts: Vec<usize> = (0..count).map(|k| k * n / count).collect();
        let blocks = Blocks {
            starts,
            interface: Vec::new(),
        };
        let mut interface = parallel::map(n, parallel::PIECE, |rows| {
            let mut coupled = Vec::new();
            for i in rows {
                let own = blocks.of(i, n);
                let (cols, _) = a.row(i);
                // Sorted: all in the own block unless the first or the last is not.
                let inside = |j: Option<&u32>| j.is_none_or(|&j| own.contains(&(j as usize)));
                if inside(cols.first()) && inside(cols.last()) {
                    continue;
                }
                let across = cols.iter().filter(|&&j| !own.contains(&(j as usize)));
                let before = coupled.len();
                coupled.extend(across);
                if coupled.len() > before {
                    coupled.push(i as u32);
                }
            }
            coupled
        })
        .concat();
        interface.sort_unstable();
        interface.dedup();
        Blocks { interface, ..blocks }
    }

    /// The interface rows of block k.
    fn interface_of(&self, k: usize) -> &[u32] {
        let start = self.starts[k] as u32;
        let end = self.starts.get(k + 1).map_or(u32::MAX, |&e| e as u32);
        let first = self.interface.partition_point(|&i| i < start);
        let last = self.interface.partition_point(|&i| i < end);
        &self.interface[first..last]
    }

    /// The rows of the block of row i (of n).
    fn of(&self, i: usize, n: usize) -> std::ops::Range<usize> {
        let k = self.starts.partition_point(|&s| s <= i) - 1;
        self.starts[k]..self.starts.get(k + 1).copied().unwrap_or(n)
    }

    /// Σ_j a_ij x_j over the unknowns j of the other blocks than row i's.
    fn across(&self, a: &Csr, i: usize, x: &[f64]) -> f64 {
        let own = self.of(i, a.rows());
        let (cols, vals) = a.row(i);
        (cols.iter().zip(vals))
            .filter(|(&j, _)| !own.contains(&(j as usize)))
            .map(|(&j, &v)| v * x[j as usize])
            .sum()
    }
}

/// Pre-smoothing from x = 0 (forward, backward, … sweeps; the first in the level's blocks), and
/// the residual r = b − A x after it.
pub(super) fn presmooth(level: &Level, b: &[f64], x: &mut [f64], r: &mut [f64], sweeps: usize) {
    let (a, skip, blocks) = (&*level.a, &level.skip[..], &level.blocks);
    parallel::map_parts2(x, r, &blocks.starts, |k, x, r| {
        forward_from_zero(a, skip, b, blocks.starts[k], x, r)
    });
    // The couplings between the blocks, left out of the sweep: each block's rows, in parallel.
    let across = &*x;
    parallel::map_parts2(r, &mut [0u8; 0], &blocks.starts, |k, r, _| {
        let base = blocks.starts[k];
        for &i in blocks.interface_of(k).iter().filter(|&&i| !skip[i as usize]) {
            r[i as usize - base] -= blocks.across(a, i as usize, across);
        }
    });
    if sweeps > 1 {
        let none = Ghosts {
            interface: &[],
            values: &[],
        };
        for s in 1..sweeps {
            if s % 2 == 0 {
                forward(a, skip, b, x);
            } else {
                backward::<false>(a, skip, b, 0, x, &mut [], none);
            }
        }
        for i in 0..a.rows() {
            r[i] = if skip[i] { 0.0 } else { b[i] - a.row_dot(i, x) };
        }
    }
}

/// Post-smoothing, the adjoint of [`presmooth`] (its sweeps reversed, forward ↔ backward), so
/// that the cycle is symmetric: its last sweep is backward, in the level's blocks, reading the
/// other blocks at the values `ghost` keeps of them. With `AX`, ax = A x from it. Returns b·x on
/// the unknowns not skipped (summed over the blocks in order).
pub(super) fn postsmooth<const AX: bool>(
    level: &Level,
    b: &[f64],
    x: &mut [f64],
    ax: &mut [f64],
    ghost: &mut Vec<f64>,
    sweeps: usize,
) -> f64 {
    let (a, skip, blocks) = (&*level.a, &level.skip[..], &level.blocks);
    let none = Ghosts {
        interface: &[],
        values: &[],
    };
    for s in (1..sweeps).rev() {
        if s % 2 == 0 {
            backward::<false>(a, skip, b, 0, x, &mut [], none);
        } else {
            forward(a, skip, b, x);
        }
    }
    ghost.clear();
    ghost.extend(blocks.interface.iter().map(|&i| x[i as usize]));
    let ghost = Ghosts {
        interface: &blocks.interface,
        values: ghost,
    };
    let bx: f64 = parallel::map_parts2(x, ax, &blocks.starts, |k, x, ax| {
        backward::<AX>(a, skip, b, blocks.starts[k], x, ax, ghost)
    })
    .into_iter()
    .sum();
    if AX {
        // The rows coupled across: their products with the final x, each block's in parallel.
        let x = &*x;
        parallel::map_parts2(ax, &mut [0u8; 0], &blocks.starts, |k, ax, _| {
            let base = blocks.starts[k];
            for &i in blocks.interface_of(k).iter().filter(|&&i| !skip[i as usize]) {
                ax[i as usize - base] = a.row_dot(i as usize, x);
            }
        });
    }
    bx
}

/// A forward Gauss–Seidel sweep from x = 0 on the rows of one block (from `base`; x and r hold
/// the block's entries, row i at i − base), with the block's part of the residual r = b − A x
/// after it, reading each row up to its diagonal only: the entries left of it give x_i, and then,
/// read as the entries above the diagonal in column i (A is symmetric), the parts −a_ji x_i of the
/// earlier rows' residuals (row i's own residual is 0 after its update). One pass over half the
/// matrix instead of two over all of it. The other blocks' unknowns count as 0 here (they are 0
/// when their sweeps start); their couplings are added to r afterwards ([`presmooth`]).
fn forward_from_zero(a: &Csr, skip: &[bool], b: &[f64], base: usize, x: &mut [f64], r: &mut [f64]) {
    for li in 0..x.len() {
        let i = base + li;
        r[li] = 0.0;
        if skip[i] {
            x[li] = 0.0;
            continue;
        }
        let (lower, _, _) = a.split(i);
        let own = a.part_at_or_above(lower, base);
        let xi = (b[i] - a.gather_from(own.clone(), x, base)) * reciprocal(a.diagonal(i));
        x[li] = xi;
        for p in own {
            let j = a.col[p] as usize;
            if !skip[j] {
                r[j - base] -= a.val[p] * xi;
            }
        }
    }
}

/// 1/a_ii, the factor of a Gauss–Seidel update (0 where a_ii ≤ 0: the row is left as it is).
#[inline(always)]
fn reciprocal(a_ii: f64) -> f64 {
    if a_ii > 0.0 {
        1.0 / a_ii
    } else {
        0.0
    }
}

/// One forward Gauss–Seidel sweep on the unknowns not skipped.
fn forward(a: &Csr, skip: &[bool], b: &[f64], x: &mut [f64]) {
    for i in 0..a.rows() {
        if !skip[i] {
            x[i] += (b[i] - a.row_dot(i, x)) * reciprocal(a.diagonal(i));
        }
    }
}

/// One backward Gauss–Seidel sweep on the rows of one block (from `base`; x and ax hold the
/// block's entries), the other blocks' unknowns read from the `ghost` values; returns b·x
/// over the block after it. With `AX`, also ax = A x (0 where skipped) on the rows not coupled to
/// the other blocks ([`postsmooth`] completes those): row i's product is complete once x_i is
/// updated but for the unknowns j < i still to come, whose updates δ_j then add a_ij δ_j (read
/// from row j right of its diagonal, A being symmetric). No pass of its own.
fn backward<const AX: bool>(
    a: &Csr,
    skip: &[bool],
    b: &[f64],
    base: usize,
    x: &mut [f64],
    ax: &mut [f64],
    ghost: Ghosts,
) -> f64 {
    let end = base + x.len();
    let mut bx = 0.0;
    for li in (0..x.len()).rev() {
        let i = base + li;
        if skip[i] {
            if AX {
                ax[li] = 0.0;
            }
            continue;
        }
        let (lower, d, upper) = a.split(i);
        let (own_lower, own_upper) = (
            a.part_at_or_above(lower.clone(), base),
            a.part_below(upper.clone(), end),
        );
        let diagonal = a.val[d];
        // Off the chain of dependent rows: the update below multiplies.
        let inverse = reciprocal(diagonal);
        // The nearest entry right of the diagonal (the row just updated) last: a shorter chain.
        let mut s = a.gather_from(own_lower.clone(), x, base)
            + diagonal * x[li]
            + a.gather_from_rev(own_upper.clone(), x, base);
        for p in (lower.start..own_lower.start).chain(own_upper.end..upper.end) {
            s += a.val[p] * ghost.at(a.col[p]);
        }
        let delta = (b[i] - s) * inverse;
        x[li] += delta;
        bx += b[i] * x[li];
        if AX {
            ax[li] = s + diagonal * delta;
            for p in own_upper {
                let j = a.col[p] as usize;
                if !skip[j] {
                    ax[j - base] += a.val[p] * delta;
                }
            }
        }
    }
    bx
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The 1D Laplacian on 8 rows in two blocks of 4, with the coupling a_43 left out of row 4
    /// but a_34 kept in row 3 (as a value next to the threshold of negligible entries may be):
    /// row 4 is coupled across too, so the sweep of block 0 finds its value (a polygon meshed at
    /// h = 0.001 panicked with "a row coupled across").
    #[test]
    fn a_coupling_kept_in_one_row_only_couples_both_rows_across() {
        let n: usize = 8;
        let (mut row_ptr, mut col, mut val) = (vec![0u32], Vec::new(), Vec::new());
        for i in 0..n {
            for j in i.saturating_sub(1)..(i + 2).min(n) {
                if (i, j) != (4, 3) {
                    col.push(j as u32);
                    val.push(if i == j { 2.0 } else { -1.0 });
                }
            }
            row_ptr.push(col.len() as u32);
        }
        let a = Csr {
            row_ptr,
            col,
            val,
            cols: n,
            ..Default::default()
        }
        .with_diagonal();
        let blocks = Blocks::of_size(&a, 4);
        assert_eq!(blocks.starts, [0, 4]);
        assert_eq!(blocks.interface, [3, 4]);
        let level = Level {
            a: Cow::Owned(a),
            skip: vec![false; n],
            blocks,
        };
        let (b, mut x, mut ax, mut r) = (vec![1.0; n], vec![0.0; n], vec![0.0; n], vec![0.0; n]);
        presmooth(&level, &b, &mut x, &mut r, 1);
        postsmooth::<true>(&level, &b, &mut x, &mut ax, &mut Vec::new(), 1);
        assert!(x.iter().all(|v| v.is_finite() && *v > 0.0), "{x:?}");
    }
}
