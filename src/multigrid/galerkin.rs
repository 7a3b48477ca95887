//! The truncated Galerkin operators Ã_{l+1} = P̃_lᵀ Ã_l P̃_l of a held set (see the module
//! [`crate::multigrid`]): the products, the coarse unknowns kept, and the rows a held set changes.

use crate::parallel;
use crate::sparse::{Csr, RowsPart, NEGLIGIBLE};

/// The Galerkin product P̃ᵀ A P̃, P̃ = D P E with D zeroing the rows i of P where `alive[i]` is
/// false and E the columns J where `kept[J]` is false (`pt` = Pᵀ): row by row over the
/// coarse unknowns with a dense accumulator (Gustavson's method), pieces of rows in parallel.
/// Rows not kept are empty.
/// With `base` = (B, dirty), the rows not `dirty` are copied from B instead (rows that the
/// truncation leaves as they are in B: see [`Hierarchy::preconditioner`]).
pub(super) fn galerkin(
    a: &Csr,
    p: &Csr,
    pt: &Csr,
    alive: &[bool],
    kept: &[bool],
    base: Option<(&Csr, &[bool])>,
) -> Csr {
    let product = Product {
        a,
        p,
        pt,
        alive,
        kept,
        base,
    };
    let nc = pt.rows();
    // Room for as many entries per row as the finer operator has, and one more.
    let per_row = a.nnz() / a.rows().max(1) + 1;
    let room = || product.room();
    Csr::by_rows_with(nc, nc, per_row, room, |room, rows, part| {
        product.rows(room, rows, part)
    })
    .with_diagonal()
}

/// The arguments of [`galerkin`].
#[derive(Clone, Copy)]
struct Product<'a> {
    a: &'a Csr,
    p: &'a Csr,
    pt: &'a Csr,
    alive: &'a [bool],
    kept: &'a [bool],
    base: Option<(&'a Csr, &'a [bool])>,
}

/// The marker of a coarse column that E drops: never a row number (the rows of a [`Csr`] number
/// fewer than 2³² − 2).
const NOT_KEPT: u32 = u32::MAX - 1;

impl Product<'_> {
    /// The accumulator of the rows (see [`Product::rows`]): per coarse column the row whose sum it
    /// last entered, or NOT_KEPT (a column of E's zeros, so that one load decides both), and that
    /// sum. Made once per thread's run of pieces: the rows are distinct, so a column's marker
    /// from another piece never matches.
    fn room(self) -> (Vec<u32>, Vec<f64>) {
        let marker = (self.kept.iter())
            .map(|&k| if k { u32::MAX } else { NOT_KEPT })
            .collect();
        (marker, vec![0.0; self.pt.rows()])
    }

    /// Rows `rows` of [`galerkin`], pushed to `part`, with the accumulator of [`Product::room`].
    fn rows(
        self,
        (marker, acc): &mut (Vec<u32>, Vec<f64>),
        rows: std::ops::Range<usize>,
        (ends, col, val): &mut RowsPart,
    ) {
        let Product {
            a,
            p,
            pt,
            alive,
            kept,
            base,
        } = self;
        for big_i in rows {
            let start = col.len();
            if let Some((b, _)) = base.filter(|(_, dirty)| !dirty[big_i]) {
                let (cols, vals) = b.row(big_i);
                col.extend_from_slice(cols);
                val.extend_from_slice(vals);
            } else if kept[big_i] {
                let row = big_i as u32;
                let (fine, weights) = pt.row(big_i);
                for (&i, &w) in fine.iter().zip(weights) {
                    let i = i as usize;
                    if !alive[i] {
                        continue;
                    }
                    let (ks, avals) = a.row(i);
                    for (&k, &a) in ks.iter().zip(avals) {
                        let k = k as usize;
                        if !alive[k] {
                            continue;
                        }
                        let f = w * a;
                        let (js, pvals) = p.row(k);
                        for (&j, &q) in js.iter().zip(pvals) {
                            let j = j as usize;
                            match marker[j] {
                                m if m == row => acc[j] += f * q,
                                NOT_KEPT => {}
                                _ => {
                                    marker[j] = row;
                                    acc[j] = f * q;
                                    col.push(j as u32);
                                }
                            }
                        }
                    }
                }
                col[start..].sort_unstable();
                let diagonal = if marker[big_i] == row {
                    acc[big_i].abs()
                } else {
                    0.0
                };
                let mut end = start;
                for q in start..col.len() {
                    let j = col[q];
                    if acc[j as usize].abs() > NEGLIGIBLE * diagonal {
                        col[end] = j;
                        val.push(acc[j as usize]);
                        end += 1;
                    }
                }
                col.truncate(end);
            }
            ends.push(col.len() as u32);
        }
    }
}

/// The coarse rows of the truncated Galerkin operator P̃ᵀ Ã P̃ that may differ from the base's
/// P̃_bᵀ B P̃_b, given the finer rows that may (`finer_dirty`: rows of Ã that differ from B's, or
/// whose unknown is live in one and not the other), the coarse unknowns `kept` now and those the
/// base skips. A term P̃_iI Ã_ik P̃_kJ of row I can differ only if I or J is kept in one and not the
/// other, or i or k is a dirty finer row: so the dirty coarse rows are those whose kept status
/// changed and those of the coarse unknowns whose interpolation reaches a dirty finer row, a
/// finer row coupled (in B's pattern, which is Ã's on the rows that do not differ) to a dirty
/// row, or to a finer unknown that a changed coarse unknown J interpolates to. Away from the held
/// set this is nothing: the truncated operators are the base's but near it, and are recomputed
/// only there.
pub(super) fn dirty_rows(
    b: &Csr,
    p: &Csr,
    pt: &Csr,
    finer_dirty: &[bool],
    kept: &[bool],
    base_skip: &[bool],
) -> Vec<bool> {
    // Finer unknowns whose row or status may differ, or that a changed coarse unknown reaches,
    // the finer rows coupled to one, and the coarse rows that interpolate to those: gathers, in
    // parallel.
    let changed: Vec<bool> = kept.iter().zip(base_skip).map(|(&k, &s)| k == s).collect();
    let reach = parallel::collect(b.rows(), |k| {
        finer_dirty[k] || p.row(k).0.iter().any(|&j| changed[j as usize])
    });
    let near = parallel::collect(b.rows(), |i| {
        reach[i] || b.row(i).0.iter().any(|&k| reach[k as usize])
    });
    parallel::collect(pt.rows(), |j| {
        changed[j] || pt.row(j).0.iter().any(|&i| near[i as usize])
    })
}

/// The coarse unknowns kept below the live (`alive`) unknowns of a level: those that give one of
/// them a weight above [`KEEP_WEIGHT`] in the interpolation P (rows of `pt` = Pᵀ). On nested meshes these are the
/// coarse vertices that are live fine vertices (weight 1; the other fine vertices take 1/2 from
/// two coarse ones): truncation drops the coarse unknowns held on the fine level. Each kept
/// column of P̃ then has a row where its weight exceeds the sum of the others' (the weights of a
/// row sum to 1), so P̃ has full rank, and the Galerkin operators stay positive definite down to
/// the coarsest, which Cholesky solves. Keeping every coarse function whose truncation is not
/// zero would not: two of them can both reduce to the same fine hat function (a free fine
/// vertex amid held ones), and the coarse matrix is then singular.
pub(super) fn kept(pt: &Csr, alive: &[bool]) -> Vec<bool> {
    parallel::collect(pt.rows(), |j| {
        let (fine, weights) = pt.row(j);
        (fine.iter().zip(weights)).any(|(&i, &w)| alive[i as usize] && w > KEEP_WEIGHT)
    })
}

/// The weight above which a coarse unknown is kept: more than 1/2 (what the rank argument needs),
/// by a margin against round-off only: on nested meshes the weights are 0, 1/2 and 1, and on
/// meshes that are not nested a wider margin leaves coarse vertices with no fine vertex that near
/// them out of the coarse space (with 0.6, CG's iterations on a disk's generated levels grew
/// about 1.8× per refinement: 34, 56, 101 from 16k to 263k vertices).
pub(super) const KEEP_WEIGHT: f64 = 0.5 + 1e-6;
