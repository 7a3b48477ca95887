//! Geometric multigrid for the Dirichlet P1 Laplacian on a hierarchy of meshes, as the
//! preconditioner of conjugate gradients: for K (the Poisson problem of v) and for
//! K_FF, the Laplacian on the free unknowns of the obstacle problem with the held (active) ones
//! fixed at zero (the linear solve of each primal–dual active-set step).
//!
//! ## Why
//! Sparse Cholesky costs O(n^1.5) time and O(n log n) memory on a 2-D mesh; a multigrid V-cycle
//! costs O(n) and reduces the error by a factor bounded away from 1 independently of h
//! (Hackbusch, *Multi-Grid Methods and Applications*, 1985, ch. 10; Bramble–Pasciak–Xu, *Math.
//! Comp.* 55, 1990, for V-cycles on nested P1 spaces without full regularity, e.g. the L-shape).
//! As the preconditioner of CG (the V-cycle is symmetric positive definite) the iterations to a
//! fixed reduction of the error are bounded independently of h, and CG's optimality makes them
//! fewer than the stationary iteration's.
//!
//! ## The V-cycle
//! Levels 0 (the mesh solved on) … L (the coarsest); `P_l` interpolates P1 functions of level
//! l + 1 onto level l (the [`Prolongation`] that nested iteration uses too). Everything works on
//! all vertices of each level, in the meshes' own numbering, with the boundary vertices skipped
//! like held ones (corrections vanish on ∂ω): level 0's operator is the problem's K itself, no
//! copy; the coarser ones are Galerkin products A_{l+1} = P_lᵀ A_l P_l. On nested P1 meshes
//! P_l is exact (every coarse hat function is a combination of fine ones), so the Galerkin
//! operator *is* the coarse stiffness matrix (rediscretisation; `galerkin_equals_rediscretisation`
//! checks it to round-off), and on meshes that are not nested (the coarse generated levels below a
//! disk) it is still the variational choice, which keeps the coarse correction an energy
//! projection. Galerkin products are also what truncation (below) needs. The coarsest level is
//! solved by sparse Cholesky ([`Cholesky`]).
//!
//! Smoothing: one forward Gauss–Seidel sweep before the coarse correction and one backward sweep
//! after (V(1,1)), so that the cycle is symmetric. Two sweeps each side, V(2,2), contract more
//! but cost more than they save under CG (measured, README). Each sweep is one pass over the matrix: the forward sweep starts from zero and reads
//! each row up to its diagonal only, scattering the residual for the restriction as it goes; the
//! backward sweep also yields K z, so that CG needs no product of its own (K p = K z + β K p_old).
//! On the levels of at least [`BLOCK_ROWS`] vertices the sweeps work in two blocks of rows
//! (hybrid Gauss–Seidel), and the transfers and CG's vector updates split the same way, so that
//! two cores can share the work when the other solve leaves the second one free; the sweeps are
//! bound by memory traffic, and each core brings its own.
//!
//! ## Truncation (the obstacle problem's K_FF)
//! The held unknowns are Dirichlet values on level 0: smoothing skips them, residuals there are
//! zero, and the interpolated corrections are cut off there. The coarse spaces are spanned by the
//! *truncated* coarse basis functions: P̃_0 = D_F P_0 E, with D_F zeroing the rows of held
//! unknowns, and the coarse operators are recomputed as Galerkin products Ã_1 = P̃_0ᵀ K P̃_0,
//! Ã_{l+1} = P̃_lᵀ Ã_l P̃_l for every held set (Kornhuber, *Numer. Math.* 69, 1994, monotone
//! multigrid; Gräser–Kornhuber, *J. Comput. Math.* 27, 2009, and truncated nonsmooth Newton
//! multigrid, DD XVIII, 2009). Then every coarse space is a subspace of the free space and the
//! coarse correction is the energy projection onto it: the cycle is a symmetric positive definite
//! preconditioner of K_FF. E keeps the coarse unknowns that give some live finer unknown a weight
//! above 1/2 — on nested meshes, the coarse vertices that are free fine vertices (the function `kept`):
//! this keeps P̃ of full rank, so that the coarse operators stay definite and the coarsest can be
//! factorized. The alternative of truncating the transfers but keeping the coarse operators of K
//! (no recomputation) is not variational, and its CG iterations grew with every refinement
//! (README). A hierarchy [`with_base`](Hierarchy::with_base) keeps the operators with the boundary
//! alone skipped (v's): those of a held set differ from them only in the coarse rows whose terms
//! reach a held fine unknown, and only those are computed again (the same numbers as a full
//! product).

use crate::assembly::{both, Stiffness};
use crate::linear::{Cholesky, NotPositiveDefinite};
use crate::mesh::Prolongation;
use crate::sparse::{part_room, Csr, NEGLIGIBLE};
use std::borrow::Cow;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::OnceLock;

/// Gauss–Seidel sweeps before and after the coarse correction (forward, backward, … before; the
/// reverse after, so that the cycle is symmetric).
const SWEEPS: usize = 1;

/// The Galerkin product P̃ᵀ A P̃, P̃ = D P E with D zeroing the rows i of P where `alive[i]` is
/// false and E the columns J where `kept[J]` is false (`pt` = Pᵀ): row by row over the
/// coarse unknowns with a dense accumulator (Gustavson's method), the two halves of the rows on
/// two threads. Rows not kept are empty.
/// With `base` = (B, dirty), the rows not `dirty` are copied from B instead (rows that the
/// truncation leaves as they are in B: see [`Hierarchy::preconditioner`]).
fn galerkin(a: &Csr, p: &Csr, pt: &Csr, alive: &[bool], kept: &[bool], base: Option<(&Csr, &[bool])>) -> Csr {
    let nc = pt.rows();
    let halves = crate::assembly::in_two_halves(nc, |rows| galerkin_rows(a, p, pt, alive, kept, base, rows));
    Csr::joined(halves, nc).with_diagonal()
}

/// The marker of a coarse column that E drops: never a row number (the rows of a [`Csr`] number
/// fewer than 2³² − 2).
const NOT_KEPT: u32 = u32::MAX - 1;

/// Rows `rows` of [`galerkin`].
fn galerkin_rows(
    a: &Csr,
    p: &Csr,
    pt: &Csr,
    alive: &[bool],
    kept: &[bool],
    base: Option<(&Csr, &[bool])>,
    rows: std::ops::Range<usize>,
) -> (Vec<u32>, Vec<u32>, Vec<f64>) {
    let nc = pt.rows();
    // Room for as many entries per row as the finer operator has, and one more.
    let (mut ends, mut col, mut val) = part_room(&rows, nc, a.nnz() / a.rows().max(1) + 1);
    // Per coarse column: the row whose sum it last entered, or NOT_KEPT (a column of E's zeros,
    // so that one load decides both), and that sum.
    let mut marker: Vec<u32> = kept
        .iter()
        .map(|&k| if k { u32::MAX } else { NOT_KEPT })
        .collect();
    let mut acc = vec![0.0; nc];
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
    (ends, col, val)
}

/// The multigrid hierarchy below one mesh: its stiffness matrix K and the interpolations below it,
/// all in the vertex numbering of their meshes. [`Hierarchy::preconditioner`] makes the V-cycle
/// for a set of skipped (boundary and held) vertices.
#[derive(Clone)]
pub struct Hierarchy<'h> {
    fine: &'h Csr,
    mass: &'h [f64],
    p: &'h [Prolongation],
    block_rows: usize,
    /// The boundary, and the coarse operators with it alone skipped (v's), made once when first
    /// needed, each with the coarse unknowns it skips.
    base: Option<(Vec<bool>, OnceLock<BaseLevels>)>,
    /// With a base: the transposed interpolations, made with the base's operators and kept for
    /// those of the held sets, and the blocks of the finest level's smoother.
    transposes: OnceLock<Vec<Csr>>,
    fine_blocks: OnceLock<Blocks>,
}

/// The coarse operators of a set of skipped unknowns, each with the coarse unknowns it skips.
type BaseLevels = Vec<(Csr, Vec<bool>)>;

impl<'h> Hierarchy<'h> {
    /// The hierarchy of the mesh of stiffness matrix `k` and masses m_a = ∫φ_a `mass` (which
    /// weigh CG's residual), with `p[l]` interpolating from level l + 1 onto level l (level 0:
    /// this mesh).
    pub fn new(k: &'h Stiffness, mass: &'h [f64], p: &'h [Prolongation]) -> Self {
        assert!(
            mass.len() == k.n() && mass.iter().all(|&m| m > 0.0),
            "a mass m_a > 0 at every vertex"
        );
        if let Some(p0) = p.first() {
            assert_eq!(
                p0.matrix().rows(),
                k.n(),
                "the first interpolation is onto this mesh"
            );
        }
        Hierarchy {
            fine: k.matrix(),
            mass,
            p,
            block_rows: BLOCK_ROWS,
            base: None,
            transposes: OnceLock::new(),
            fine_blocks: OnceLock::new(),
        }
    }

    /// Keeps the coarse operators with only the `boundary` skipped (v's): those of a held set
    /// (w's) are then computed again only near it, in the rows whose terms the held set changes,
    /// and v's borrow them. A hierarchy used for one or two sets of skipped unknowns does without
    /// (the kept operators would cost memory for no time).
    pub fn with_base(self, boundary: Vec<bool>) -> Self {
        Hierarchy {
            base: Some((boundary, OnceLock::new())),
            ..self
        }
    }

    /// Smooths the levels of at least `rows` vertices in two blocks (see [`BLOCK_ROWS`]).
    pub fn with_block_rows(self, rows: usize) -> Self {
        Hierarchy {
            block_rows: rows,
            ..self
        }
    }

    /// The number of levels.
    pub fn levels(&self) -> usize {
        self.p.len() + 1
    }

    /// The V-cycle for K_FF, F the vertices not `skip`ped (the boundary vertices and the held
    /// ones): the truncated coarse operators (Galerkin products) and the Cholesky factorization
    /// of the coarsest one.
    pub fn preconditioner(&self, skip: Vec<bool>) -> Result<Multigrid<'_>, NotPositiveDefinite> {
        assert_eq!(skip.len(), self.fine.rows());
        let blocks = |a: &Csr| Blocks::new(a, self.block_rows);
        let (operators, fine_blocks) = match &self.base {
            None => {
                let full = self.full(skip.clone(), None).into_iter();
                (full.map(|(a, s)| (Cow::Owned(a), s)).collect(), blocks(self.fine))
            }
            Some((boundary, base)) => {
                let base = base.get_or_init(|| self.full(boundary.clone(), Some(self.transposes())));
                let fine_blocks = self.fine_blocks.get_or_init(|| blocks(self.fine)).clone();
                (self.near_base(&skip, boundary, base), fine_blocks)
            }
        };
        let mut levels = vec![Work::new(skip, fine_blocks, false)];
        let mut coarse: Vec<Cow<'_, Csr>> = Vec::with_capacity(operators.len());
        for (a, skip) in operators {
            levels.push(Work::new(skip, blocks(&a), true));
            coarse.push(a);
        }
        let last = coarse.last().map_or(self.fine, |c| &**c);
        let coarsest = Coarsest::new(last, &levels.last().expect("a level").skip)?;
        Ok(Multigrid {
            fine: self.fine,
            mass: self.mass,
            p: self.p,
            coarse,
            levels,
            coarsest,
            sweeps: SWEEPS,
            second_core: None,
        })
    }

    /// The coarse operators for `skip` from the `base` ones (those of the `boundary` alone),
    /// each with the coarse unknowns it skips: the base's own where nothing differs from it,
    /// else its rows but where the held set changes them ([`dirty_rows`]), computed again.
    fn near_base<'b>(
        &'b self,
        skip: &[bool],
        boundary: &[bool],
        base: &'b BaseLevels,
    ) -> Vec<(Cow<'b, Csr>, Vec<bool>)> {
        // The finer level's rows that may differ from the base's, and its live unknowns.
        let mut dirty: Vec<bool> = skip.iter().zip(boundary).map(|(s, b)| s != b).collect();
        let mut alive: Vec<bool> = skip.iter().map(|&s| !s).collect();
        let mut out: Vec<(Cow<'b, Csr>, Vec<bool>)> = Vec::with_capacity(self.p.len());
        for (l, (p, (b, b_skip))) in self.p.iter().zip(base).enumerate() {
            let p = p.matrix();
            let kept = kept(p, &alive);
            let same = !dirty.iter().any(|&d| d) && kept.iter().zip(b_skip).all(|(&k, &s)| k != s);
            let a = if same {
                // The base's skipped set (v's): its operators themselves.
                dirty = vec![false; kept.len()];
                Cow::Borrowed(b)
            } else {
                let (finer, finer_base) = match l {
                    0 => (self.fine, self.fine),
                    _ => (&*out[l - 1].0, &base[l - 1].0),
                };
                let pt = &self.transposes()[l];
                dirty = dirty_rows(finer_base, p, pt, &dirty, &kept, b_skip);
                Cow::Owned(galerkin(finer, p, pt, &alive, &kept, Some((b, &dirty))))
            };
            out.push((a, kept.iter().map(|&k| !k).collect()));
            alive = kept;
        }
        out
    }

    /// The transposed interpolations of a hierarchy with a base, made once.
    fn transposes(&self) -> &[Csr] {
        (self.transposes).get_or_init(|| self.p.iter().map(|p| p.matrix().transpose()).collect())
    }

    /// The coarse operators for `skip` built in full, each with the coarse unknowns it skips,
    /// with the given `transposes` of the interpolations, or each made and dropped in turn.
    fn full(&self, mut skip: Vec<bool>, transposes: Option<&[Csr]>) -> BaseLevels {
        let mut out: BaseLevels = Vec::with_capacity(self.p.len());
        for (l, p) in self.p.iter().enumerate() {
            let (p, finer) = (p.matrix(), out.last().map_or(self.fine, |(c, _)| c));
            let alive: Vec<bool> = skip.iter().map(|&s| !s).collect();
            let kept = kept(p, &alive);
            let made;
            let pt = match transposes {
                Some(t) => &t[l],
                None => {
                    made = p.transpose();
                    &made
                }
            };
            let a = galerkin(finer, p, pt, &alive, &kept, None);
            skip = kept.iter().map(|&k| !k).collect();
            out.push((a, skip.clone()));
        }
        out
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
fn dirty_rows(
    b: &Csr,
    p: &Csr,
    pt: &Csr,
    finer_dirty: &[bool],
    kept: &[bool],
    base_skip: &[bool],
) -> Vec<bool> {
    // Finer unknowns whose row or status may differ, or that a changed coarse unknown reaches.
    let mut reach = finer_dirty.to_vec();
    let changed: Vec<bool> = kept.iter().zip(base_skip).map(|(&k, &s)| k == s).collect();
    for (j, _) in changed.iter().enumerate().filter(|(_, &c)| c) {
        for &k in pt.row(j).0 {
            reach[k as usize] = true;
        }
    }
    let mut dirty = changed;
    for i in 0..b.rows() {
        let (cols, _) = b.row(i);
        if reach[i] || cols.iter().any(|&k| reach[k as usize]) {
            for &big_j in p.row(i).0 {
                dirty[big_j as usize] = true;
            }
        }
    }
    dirty
}

/// The coarse unknowns kept below the live (`alive`) unknowns of a level: those that give one of
/// them a weight above [`KEEP_WEIGHT`] in the interpolation `p`. On nested meshes these are the
/// coarse vertices that are live fine vertices (weight 1; the other fine vertices take 1/2 from
/// two coarse ones): truncation drops the coarse unknowns held on the fine level. Each kept
/// column of P̃ then has a row where its weight exceeds the sum of the others' (the weights of a
/// row sum to 1), so P̃ has full rank, and the Galerkin operators stay positive definite down to
/// the coarsest, which Cholesky solves. Keeping every coarse function whose truncation is not
/// zero would not: two of them can both reduce to the same fine hat function (a free fine
/// vertex amid held ones), and the coarse matrix is then singular.
fn kept(p: &Csr, alive: &[bool]) -> Vec<bool> {
    let mut kept = vec![false; p.cols];
    for (i, _) in alive.iter().enumerate().filter(|(_, &a)| a) {
        let (cols, weights) = p.row(i);
        for (&j, &w) in cols.iter().zip(weights) {
            if w > KEEP_WEIGHT {
                kept[j as usize] = true;
            }
        }
    }
    kept
}

/// The weight above which a coarse unknown is kept: more than 1/2 (what the rank argument needs),
/// by a margin against round-off only: on nested meshes the weights are 0, 1/2 and 1, and on
/// meshes that are not nested a wider margin leaves coarse vertices with no fine vertex that near
/// them out of the coarse space (with 0.6, CG's iterations on a disk's generated levels grew
/// about 1.8× per refinement: 34, 56, 101 from 16k to 263k vertices).
const KEEP_WEIGHT: f64 = 0.5 + 1e-6;

/// The vectors of one level: the vertices skipped (on the boundary, held, or coarse ones not
/// kept), the blocks of its smoother, the iterate, the right-hand side and the residual.
/// (Level 0's iterate and right-hand side are CG's: it has no vectors of its own for them.)
struct Work {
    skip: Vec<bool>,
    blocks: Blocks,
    x: Vec<f64>,
    b: Vec<f64>,
    r: Vec<f64>,
}

impl Work {
    fn new(skip: Vec<bool>, blocks: Blocks, coarse: bool) -> Self {
        let (n, m) = (skip.len(), if coarse { skip.len() } else { 0 });
        Work {
            skip,
            blocks,
            x: vec![0.0; m],
            b: vec![0.0; m],
            r: vec![0.0; n],
        }
    }
}

/// Levels of at least this many vertices are smoothed in two blocks of rows, 0..n/2 and n/2..n:
/// Gauss–Seidel within each block, the other block's unknowns read at their values from before
/// the sweep (hybrid Gauss–Seidel, block Jacobi between the blocks), so that the two blocks can be
/// swept on two cores. The forward sweep before the coarse correction and the backward sweep
/// after it stay each other's adjoint, so the cycle stays symmetric. Meshes are numbered along a
/// Z-order curve (or by rows, built-in ones), so the two blocks are the two halves of ω and few
/// rows couple across. The blocks depend on the level's size only, not on the cores: the numbers
/// are the same swept on one thread or two.
pub const BLOCK_ROWS: usize = 1 << 17;

/// The rows of a level in the blocks of its smoother (one block below the hierarchy's
/// `block_rows`): where the second begins, the rows coupled to the other block, and their values
/// of x when a backward sweep starts (what each block reads of the other).
#[derive(Clone)]
struct Blocks {
    mid: usize,
    interface: Vec<u32>,
    ghost: Vec<f64>,
}

impl Blocks {
    fn new(a: &Csr, block_rows: usize) -> Self {
        let n = a.rows();
        let mid = if n >= block_rows.max(2) { n / 2 } else { n };
        let interface: Vec<u32> = (0..n)
            .filter(|&i| {
                let (cols, _) = a.row(i);
                match i < mid {
                    true => cols.last().is_some_and(|&j| j as usize >= mid),
                    false => cols.first().is_some_and(|&j| (j as usize) < mid),
                }
            })
            .map(|i| i as u32)
            .collect();
        Blocks {
            mid,
            ghost: vec![0.0; interface.len()],
            interface,
        }
    }

    /// Σ_j a_ij x_j over the unknowns j of the other block than row i's.
    fn across(&self, a: &Csr, i: usize, x: &[f64]) -> f64 {
        let (cols, vals) = a.row(i);
        (cols.iter().zip(vals))
            .filter(|(&j, _)| (j as usize >= self.mid) != (i >= self.mid))
            .map(|(&j, &v)| v * x[j as usize])
            .sum()
    }

    /// x_j of the other block as the backward sweep started (j an interface row).
    fn ghost(&self, j: u32) -> f64 {
        self.ghost[self.interface.binary_search(&j).expect("a row coupled across")]
    }
}

/// The coarsest level's Cholesky factorization, on its live unknowns.
struct Coarsest {
    /// The live unknowns.
    live: Vec<usize>,
    cholesky: Option<Cholesky>,
    buffer: Vec<f64>,
}

impl Coarsest {
    fn new(a: &Csr, skip: &[bool]) -> Result<Self, NotPositiveDefinite> {
        let live: Vec<usize> = (0..a.rows()).filter(|&i| !skip[i]).collect();
        let mut index = vec![usize::MAX; a.rows()];
        for (k, &i) in live.iter().enumerate() {
            index[i] = k;
        }
        // The lower triangle by columns is the upper triangle by rows (a is symmetric).
        let (mut col_ptr, mut row_idx, mut val) = (vec![0], Vec::new(), Vec::new());
        for &i in &live {
            let (cols, vals) = a.row(i);
            for (&j, &v) in cols.iter().zip(vals) {
                let j = j as usize;
                if j >= i && index[j] != usize::MAX {
                    row_idx.push(index[j]);
                    val.push(v);
                }
            }
            col_ptr.push(row_idx.len());
        }
        let cholesky = if live.is_empty() {
            None
        } else {
            Some(Cholesky::new(live.len(), &col_ptr, &row_idx, &val)?)
        };
        Ok(Coarsest {
            buffer: vec![0.0; live.len()],
            live,
            cholesky,
        })
    }

    /// x = A⁻¹ b on the live unknowns, 0 elsewhere.
    fn solve(&mut self, b: &[f64], x: &mut [f64]) {
        x.fill(0.0);
        let Some(cholesky) = &mut self.cholesky else {
            return;
        };
        for (y, &i) in self.buffer.iter_mut().zip(&self.live) {
            *y = b[i];
        }
        cholesky.solve(&mut self.buffer);
        for (&y, &i) in self.buffer.iter().zip(&self.live) {
            x[i] = y;
        }
    }
}

/// Where CG stops: |r_a| ≤ min(density m_a, backward (σ_a + floor(a))) at every free unknown
/// a, with m_a = ∫φ_a and σ = |K_FF| |x| + |b| of the iterate x (renewed every
/// 4 iterations and whenever the bound seems met), but never below the round-off
/// 16 ε σ_a of r_a itself.
///
/// The density bounds r as a load density, in the units of λ_h = r_a/m_a (4.5) (a relative
/// ‖r‖₂ would leave up to √n times the tolerance at a vertex). The backward tolerance bounds the
/// componentwise backward error of x (Oettli–Prager): it is what the checks of a solution
/// measure (`action::Checks`, relative to the terms of (4.5) at each vertex, which σ_a bounds
/// from below), so that a solution CG accepts passes them wherever the data put those terms —
/// also at a vertex where u_h and the loads are small beside a large boundary lift.
#[derive(Clone, Copy)]
pub struct Tolerance<'a> {
    /// The largest residual density max_a |r_a|/m_a.
    pub density: f64,
    /// When asked for, the largest componentwise backward error max_a |r_a|/(σ_a + floor(a)),
    /// with a floor per vertex: the sizes of the loads whose combination b holds, which the
    /// checks count (b may cancel them).
    pub backward: Option<(f64, &'a (dyn Fn(usize) -> f64 + Sync))>,
}

/// A [`Tolerance`] per unknown, with σ = |K_FF| |x| + |b| of a recent iterate x.
struct Bound<'t> {
    tolerance: Tolerance<'t>,
    sigma: Vec<f64>,
}

impl Bound<'_> {
    /// The largest |r_i| allowed: the tolerance, but never below the round-off of r_i itself
    /// ([`ROUNDOFF`] σ_i: a density the data cannot resolve is left to the checks of the
    /// solution, which say so).
    #[inline]
    fn at(&self, mass: &[f64], i: usize) -> f64 {
        let density = self.tolerance.density * mass[i];
        let wanted = match &self.tolerance.backward {
            Some((backward, floor)) => density.min(backward * (self.sigma[i] + floor(i))),
            None => density,
        };
        wanted.max(ROUNDOFF * self.sigma[i])
    }
}

/// The round-off of a residual r_a = b_a − Σ_b K_ab x_b, relative to σ_a = |b_a| + Σ_b |K_ab x_b|:
/// a few units of f64's precision per term of a row of K.
const ROUNDOFF: f64 = 16.0 * f64::EPSILON;

/// CG renews σ every this many iterations (and when the bound is met).
const SIGMA_EVERY: usize = 4;

/// How often CG goes on from its iterate when the residual recomputed from b misses a backward
/// tolerance (the recursively updated residual drifts from it by round-off, and σ moves with x).
const RESTARTS: usize = 4;

/// The power of two nearest 1/`size` (1 for 0 or a non-finite size), within f64's normal range.
fn power_of_two_near(size: f64) -> f64 {
    if !(size.is_finite() && size > 0.0) {
        return 1.0;
    }
    let exponent = size.log2().round().clamp(-1000.0, 1000.0) as i32;
    2.0_f64.powi(-exponent)
}

/// CG did not reach the tolerance within the iteration cap.
#[derive(Debug, Clone, PartialEq)]
pub struct NotConverged {
    /// Iterations done.
    pub iterations: usize,
    /// max_a |r_a|/m_a reached (see [`Tolerance`]).
    pub residual: f64,
    /// The density it was to reach.
    pub target: f64,
}

/// The V-cycle for one held set (see the module's documentation), and CG preconditioned by it.
pub struct Multigrid<'h> {
    fine: &'h Csr,
    mass: &'h [f64],
    p: &'h [Prolongation],
    /// Levels 1 … L's operators (those of the hierarchy's base where they are the same).
    coarse: Vec<Cow<'h, Csr>>,
    levels: Vec<Work>,
    coarsest: Coarsest,
    /// Gauss–Seidel sweeps before and after the coarse correction.
    pub sweeps: usize,
    /// When set, read at every CG iteration: whether the second core is free, to sweep the two
    /// blocks of the large levels side by side (see [`BLOCK_ROWS`]).
    pub second_core: Option<&'h AtomicBool>,
}

impl Multigrid<'_> {
    /// The number of vertices of level 0 (skipped ones included).
    pub fn n(&self) -> usize {
        self.fine.rows()
    }

    /// Whether vertex i of level 0 is skipped (on the boundary or held).
    #[inline]
    fn held(&self, i: usize) -> bool {
        self.levels[0].skip[i]
    }

    /// y = K_FF x on the free unknowns, 0 on the held ones.
    #[cfg(test)]
    fn apply(&self, x: &[f64], y: &mut [f64]) {
        let skip = &self.levels[0].skip;
        for (i, y) in y.iter_mut().enumerate() {
            *y = if skip[i] { 0.0 } else { self.fine.row_dot(i, x) };
        }
    }

    /// z = B r: one V-cycle from zero for the right-hand side r (read on the free unknowns);
    /// z is 0 on the held ones. Returns r·z.
    #[cfg(test)]
    fn precondition(&mut self, r: &[f64], z: &mut [f64]) -> f64 {
        self.cycle::<false>(0, r, z, &mut [], false)
    }

    /// The V-cycle on level l from x = 0 for the right-hand side b: x = B_l b, and with `AX`
    /// also ax = A_l x, from the last smoothing sweep; the blocks of the large levels on two
    /// threads when `parallel`. Returns b·x.
    fn cycle<const AX: bool>(
        &mut self,
        l: usize,
        b: &[f64],
        x: &mut [f64],
        ax: &mut [f64],
        parallel: bool,
    ) -> f64 {
        if l == self.levels.len() - 1 {
            self.coarsest.solve(b, x);
            if AX {
                // A x = b on the live unknowns (the coarsest solve is exact).
                for ((ax, &b), &skip) in ax.iter_mut().zip(b).zip(&self.levels[l].skip) {
                    *ax = if skip { 0.0 } else { b };
                }
            }
            return dot(b, x);
        }
        let a = if l == 0 { self.fine } else { &*self.coarse[l - 1] };
        presmooth(a, &mut self.levels[l], b, x, self.sweeps, parallel);
        let p = self.p[l].matrix();
        let (mut bc, mut xc) = {
            let (fine, coarse) = self.levels.split_at_mut(l + 1);
            let coarse = &mut coarse[0];
            restrict(p, &fine[l], &mut coarse.b, &mut coarse.r, parallel);
            (std::mem::take(&mut coarse.b), std::mem::take(&mut coarse.x))
        };
        self.cycle::<false>(l + 1, &bc, &mut xc, &mut [], parallel);
        let a = if l == 0 { self.fine } else { &*self.coarse[l - 1] };
        let work = &mut self.levels[l];
        prolong(p, &work.skip, work.blocks.mid, &xc, x, parallel);
        let bx = postsmooth::<AX>(a, work, b, x, ax, self.sweeps, parallel);
        let coarse = &mut self.levels[l + 1];
        std::mem::swap(&mut coarse.b, &mut bc);
        std::mem::swap(&mut coarse.x, &mut xc);
        bx
    }

    /// [`Multigrid::solve_to`] the density `tolerance` max_a |b_a|/m_a (over the free unknowns):
    /// the residual against the largest load density of b.
    pub fn solve(
        &mut self,
        b: Vec<f64>,
        x: &mut [f64],
        tolerance: f64,
        max_iterations: usize,
    ) -> Result<usize, NotConverged> {
        let density = tolerance * self.density(&b);
        self.solve_to(
            b,
            x,
            Tolerance {
                density,
                backward: None,
            },
            max_iterations,
        )
    }

    /// Solves K_FF x = b (b taken) on the free unknowns by CG preconditioned by the V-cycle, from
    /// the guess `x` (its held entries are set to 0), until the residual r = b − K_FF x meets
    /// `tolerance` at every free unknown (see [`Tolerance`]). With a backward tolerance the
    /// residual is recomputed from b before CG and whenever CG's recursive one meets the bound,
    /// and CG goes on from x while that true residual misses it, at most 4 times. With
    /// a density of 0, x = 0 when b = 0 on the free unknowns. Returns the iterations.
    pub fn solve_to(
        &mut self,
        b: Vec<f64>,
        x: &mut [f64],
        tolerance: Tolerance,
        max_iterations: usize,
    ) -> Result<usize, NotConverged> {
        for (i, x) in x.iter_mut().enumerate() {
            if self.held(i) {
                *x = 0.0;
            }
        }
        if tolerance.density == 0.0 && self.density(&b) == 0.0 {
            x.fill(0.0);
            return Ok(0);
        }
        let failed = |e: NotConverged| NotConverged {
            target: tolerance.density,
            ..e
        };
        let mut bound = Bound {
            tolerance,
            sigma: Vec::new(),
        };
        let Some(_) = tolerance.backward else {
            let mut r = b;
            self.residual(&mut r, x);
            return (self.iterate(r, x, &mut bound, max_iterations)).map_err(failed);
        };
        // The recursively updated residual drifts from the true one: CG goes on from x while
        // the true one misses the bound.
        let mut iterations = 0;
        for _ in 0..=RESTARTS {
            let mut r = b.clone();
            self.residual(&mut r, x);
            self.sigma(&r, 1.0, x, &mut bound.sigma);
            if self.meets(&r, |i| bound.at(self.mass, i)) {
                return Ok(iterations);
            }
            let left = max_iterations - iterations;
            iterations += match self.iterate(r, x, &mut bound, left) {
                Ok(more) => more,
                Err(e) => {
                    return Err(failed(NotConverged {
                        iterations: iterations + e.iterations,
                        ..e
                    }))
                }
            };
        }
        let mut r = b;
        self.residual(&mut r, x);
        Err(self.not_converged(iterations, &r, tolerance.density))
    }

    /// r = b − K_FF x on the free unknowns, 0 on the held ones, with b given in r.
    fn residual(&self, r: &mut [f64], x: &[f64]) {
        let (fine, skip, mid) = (self.fine, &self.levels[0].skip, self.levels[0].blocks.mid);
        let part = |base: usize, r: &mut [f64]| {
            for (li, r) in r.iter_mut().enumerate() {
                let i = base + li;
                *r = if skip[i] { 0.0 } else { *r - fine.row_dot(i, x) };
            }
        };
        let (r0, r1) = r.split_at_mut(mid);
        both(self.parallel(), || part(0, r0), || part(mid, r1));
    }

    /// σ = |K_FF| |x| + |b| on the free unknowns for the residual r = b − K_FF x (r given times
    /// 1/`unscale`): the scale of r's round-off and of the backward error (Oettli–Prager).
    fn sigma(&self, r: &[f64], unscale: f64, x: &[f64], sigma: &mut Vec<f64>) {
        let (fine, skip, mid) = (self.fine, &self.levels[0].skip, self.levels[0].blocks.mid);
        sigma.resize(self.n(), 0.0);
        let part = |base: usize, sigma: &mut [f64]| {
            for (li, sigma) in sigma.iter_mut().enumerate() {
                let i = base + li;
                if skip[i] {
                    continue;
                }
                let (cols, vals) = fine.row(i);
                let (mut kx, mut size) = (0.0, 0.0);
                for (&j, &v) in cols.iter().zip(vals) {
                    let t = v * x[j as usize];
                    kx += t;
                    size += t.abs();
                }
                *sigma = size + (r[i] * unscale + kx).abs();
            }
        };
        let (s0, s1) = sigma.split_at_mut(mid);
        both(self.parallel(), || part(0, s0), || part(mid, s1));
    }

    /// Whether |r_a| ≤ bound(a) at every free unknown (not where r_a is NaN).
    fn meets(&self, r: &[f64], bound: impl Fn(usize) -> f64) -> bool {
        (r.iter().enumerate()).all(|(i, r)| self.held(i) || r.abs() <= bound(i))
    }

    fn not_converged(&self, iterations: usize, r: &[f64], target: f64) -> NotConverged {
        NotConverged {
            iterations,
            residual: self.density(r),
            target,
        }
    }

    /// Whether the second core is free now (see [`Multigrid::second_core`]).
    fn parallel(&self) -> bool {
        self.second_core.is_some_and(|free| free.load(Ordering::Relaxed))
    }

    /// CG iterations from x with its residual r until |r_a| ≤ bound(a) at every free unknown, r
    /// the recursively updated residual, the bound's σ from the x that meets it. CG works on r
    /// scaled by a power of two that brings its largest entry near 1, so that no product of two residual-sized numbers
    /// overflows or underflows whatever the units of the data (the scaling is exact: the iterates
    /// are those of CG on r itself). Returns the iterations.
    ///
    /// K_FF of the search direction comes from the recurrence K p = K z + β K p_old, with K z
    /// from the V-cycle's last sweep: no matrix product of its own per iteration.
    fn iterate(
        &mut self,
        mut r: Vec<f64>,
        x: &mut [f64],
        bound: &mut Bound,
        max_iterations: usize,
    ) -> Result<usize, NotConverged> {
        if bound.sigma.is_empty() {
            self.sigma(&r, 1.0, x, &mut bound.sigma);
        }
        if self.meets(&r, |i| bound.at(self.mass, i)) {
            return Ok(0);
        }
        let largest = r.iter().fold(0.0_f64, |m, r| m.max(r.abs()));
        let scale = power_of_two_near(largest);
        let unscale = 1.0 / scale;
        for r in &mut r {
            *r *= scale;
        }
        let (n, mid) = (self.n(), self.levels[0].blocks.mid);
        let (mut z, mut kz) = (vec![0.0; n], vec![0.0; n]);
        let mut rz = self.cycle::<true>(0, &r, &mut z, &mut kz, self.parallel());
        let (mut p, mut q) = (z.clone(), kz.clone());
        let mut pq = dot(&p, &q);
        let mut done = max_iterations;
        for iteration in 1..=max_iterations {
            let alpha = rz / pq;
            if !alpha.is_finite() {
                done = iteration - 1;
                break;
            }
            let parallel = self.parallel();
            // x += α p (unscaled), r −= α q, and whether r meets the bound.
            let met = {
                let (skip, mass, bound) = (&self.levels[0].skip, self.mass, &*bound);
                let update = |base: usize, x: &mut [f64], r: &mut [f64]| {
                    let mut met = true;
                    for (li, (x, r)) in x.iter_mut().zip(r).enumerate() {
                        let i = base + li;
                        *x += alpha * p[i] * unscale;
                        *r -= alpha * q[i];
                        met &= skip[i] || r.abs() * unscale <= bound.at(mass, i);
                    }
                    met
                };
                let ((x0, x1), (r0, r1)) = (x.split_at_mut(mid), r.split_at_mut(mid));
                let (m0, m1) = both(parallel, || update(0, x0, r0), || update(mid, x1, r1));
                m0 && m1
            };
            // σ moves with x: the bound is met only against σ of this x (and σ is renewed now
            // and then, so that CG stops once r is at its round-off).
            if met || iteration % SIGMA_EVERY == 0 {
                self.sigma(&r, unscale, x, &mut bound.sigma);
                if self.meets(&r, |i| bound.at(self.mass, i) * scale) {
                    return Ok(iteration);
                }
            }
            let rz_next = self.cycle::<true>(0, &r, &mut z, &mut kz, parallel);
            let beta = rz_next / rz;
            rz = rz_next;
            // p = z + β p, q = K z + β q, and p·q.
            let update = |base: usize, p: &mut [f64], q: &mut [f64]| {
                let mut pq = 0.0;
                for (li, (p, q)) in p.iter_mut().zip(q).enumerate() {
                    *p = z[base + li] + beta * *p;
                    *q = kz[base + li] + beta * *q;
                    pq += *p * *q;
                }
                pq
            };
            let ((p0, p1), (q0, q1)) = (p.split_at_mut(mid), q.split_at_mut(mid));
            let (pq0, pq1) = both(parallel, || update(0, p0, q0), || update(mid, p1, q1));
            pq = pq0 + pq1;
        }
        for r in &mut r {
            *r *= unscale;
        }
        Err(self.not_converged(done, &r, f64::NAN))
    }
}

impl Multigrid<'_> {
    /// max_a |r_a|/m_a over the free unknowns: r as a load density (NaN if some r_a is, so that
    /// CG does not stop on it).
    pub fn density(&self, r: &[f64]) -> f64 {
        (r.iter().zip(self.mass).zip(&self.levels[0].skip))
            .filter(|(_, &skip)| !skip)
            .fold(0.0, |m, ((r, w), _)| max_density(m, r / w))
    }
}

/// max(m, |d|), NaN once either is NaN (so that CG does not stop on it).
fn max_density(m: f64, d: f64) -> f64 {
    if d.is_nan() || m.is_nan() {
        f64::NAN
    } else {
        m.max(d.abs())
    }
}

fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

/// Pre-smoothing from x = 0 (forward, backward, … sweeps; the first in the level's blocks), and
/// the residual r = b − A x after it, in the level's `r`.
fn presmooth(a: &Csr, work: &mut Work, b: &[f64], x: &mut [f64], sweeps: usize, parallel: bool) {
    let Work { skip, blocks, r, .. } = work;
    let (skip, mid) = (&skip[..], blocks.mid);
    {
        let ((x0, x1), (r0, r1)) = (x.split_at_mut(mid), r.split_at_mut(mid));
        both(
            parallel,
            || forward_from_zero(a, skip, b, 0, x0, r0),
            || forward_from_zero(a, skip, b, mid, x1, r1),
        );
    }
    // The couplings between the blocks, left out of the sweep.
    for &i in &blocks.interface {
        let i = i as usize;
        if !skip[i] {
            r[i] -= blocks.across(a, i, x);
        }
    }
    if sweeps > 1 {
        for s in 1..sweeps {
            if s % 2 == 0 {
                forward(a, skip, b, x);
            } else {
                backward::<false>(a, skip, b, 0, x, &mut [], blocks);
            }
        }
        for i in 0..a.rows() {
            r[i] = if skip[i] { 0.0 } else { b[i] - a.row_dot(i, x) };
        }
    }
}

/// Post-smoothing, the adjoint of [`presmooth`] (its sweeps reversed, forward ↔ backward), so
/// that the cycle is symmetric: its last sweep is backward, in the level's blocks. With `AX`,
/// ax = A x from it. Returns b·x on the unknowns not skipped.
fn postsmooth<const AX: bool>(
    a: &Csr,
    work: &mut Work,
    b: &[f64],
    x: &mut [f64],
    ax: &mut [f64],
    sweeps: usize,
    parallel: bool,
) -> f64 {
    let Work { skip, blocks, .. } = work;
    let (skip, mid) = (&skip[..], blocks.mid);
    for s in (1..sweeps).rev() {
        if s % 2 == 0 {
            backward::<false>(a, skip, b, 0, x, &mut [], blocks);
        } else {
            forward(a, skip, b, x);
        }
    }
    for (g, &i) in blocks.ghost.iter_mut().zip(&blocks.interface) {
        *g = x[i as usize];
    }
    let bx = {
        let (x0, x1) = x.split_at_mut(mid);
        let (ax0, ax1) = if AX {
            ax.split_at_mut(mid)
        } else {
            (&mut [][..], &mut [][..])
        };
        let blocks = &*blocks;
        let (bx0, bx1) = both(
            parallel,
            || backward::<AX>(a, skip, b, 0, x0, ax0, blocks),
            || backward::<AX>(a, skip, b, mid, x1, ax1, blocks),
        );
        bx0 + bx1
    };
    if AX {
        // The rows coupled across: their products with the final x.
        for &i in &blocks.interface {
            let i = i as usize;
            if !skip[i] {
                ax[i] = a.row_dot(i, x);
            }
        }
    }
    bx
}

/// b_c = Pᵀ r (r is 0 where skipped), by the rows of P: the first block's rows into `out`, the
/// second's into `second` (the coarse level's residual, free until its own smoothing), then added
/// (the same sums on one thread or two).
fn restrict(p: &Csr, fine: &Work, out: &mut [f64], second: &mut [f64], parallel: bool) {
    let (skip, r, mid) = (&fine.skip[..], &fine.r[..], fine.blocks.mid);
    let part = |rows: std::ops::Range<usize>, out: &mut [f64]| {
        out.fill(0.0);
        for i in rows.filter(|&i| !skip[i]) {
            let (cols, weights) = p.row(i);
            for (&j, &w) in cols.iter().zip(weights) {
                out[j as usize] += w * r[i];
            }
        }
    };
    if mid == r.len() {
        part(0..mid, out);
        return;
    }
    both(parallel, || part(0..mid, out), || part(mid..r.len(), second));
    for (o, s) in out.iter_mut().zip(&*second) {
        *o += s;
    }
}

/// x += P x_c on the unknowns not skipped, the blocks (from `mid`) on two threads when `parallel`.
fn prolong(p: &Csr, skip: &[bool], mid: usize, xc: &[f64], x: &mut [f64], parallel: bool) {
    let part = |base: usize, x: &mut [f64]| {
        for (li, x) in x.iter_mut().enumerate() {
            if !skip[base + li] {
                *x += p.row_dot(base + li, xc);
            }
        }
    };
    let (x0, x1) = x.split_at_mut(mid);
    both(parallel, || part(0, x0), || part(mid, x1));
}

/// A forward Gauss–Seidel sweep from x = 0 on the rows of one block (from `base`; x and r hold
/// the block's entries, row i at i − base), with the block's part of the residual r = b − A x
/// after it, reading each row up to its diagonal only: the entries left of it give x_i, and then,
/// read as the entries above the diagonal in column i (A is symmetric), the parts −a_ji x_i of the
/// earlier rows' residuals (row i's own residual is 0 after its update). One pass over half the
/// matrix instead of two over all of it. The other block's unknowns count as 0 here (they are 0
/// when its sweep starts); their couplings are added to r afterwards ([`presmooth`]).
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
/// block's entries), the other block's unknowns read from `blocks`' ghost values; returns b·x
/// over the block after it. With `AX`, also ax = A x (0 where skipped) on the rows not coupled to
/// the other block ([`postsmooth`] completes those): row i's product is complete once x_i is
/// updated but for the unknowns j < i still to come, whose updates δ_j then add a_ij δ_j (read
/// from row j right of its diagonal, A being symmetric). No pass of its own.
fn backward<const AX: bool>(
    a: &Csr,
    skip: &[bool],
    b: &[f64],
    base: usize,
    x: &mut [f64],
    ax: &mut [f64],
    blocks: &Blocks,
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
            s += a.val[p] * blocks.ghost(a.col[p]);
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
    use crate::linear::InteriorSystem;
    use crate::mesh::{Diagonal, Mesh};

    /// Meshes of n, n/2, … down to 4 cells per side, finest first, the interpolations between
    /// them, and K and the masses of the finest.
    struct Levels {
        meshes: Vec<Mesh>,
        prolongations: Vec<Prolongation>,
        k: Stiffness,
        mass: Vec<f64>,
    }

    impl Levels {
        fn hierarchy(&self) -> Hierarchy<'_> {
            Hierarchy::new(&self.k, &self.mass, &self.prolongations)
        }
    }

    /// [`Levels`] of the unit square.
    fn square(n: usize, diagonal: Diagonal) -> Levels {
        rectangle([1.0, 1.0], n, diagonal)
    }

    /// [`Levels`] of the rectangle (0, 0)–`corner`.
    fn rectangle(corner: [f64; 2], n: usize, diagonal: Diagonal) -> Levels {
        let meshes: Vec<Mesh> = std::iter::successors(Some(n), |&m| (m > 4).then_some(m / 2))
            .map(|m| Mesh::rectangle([0.0, 0.0], corner, m, m, diagonal).unwrap())
            .collect();
        let prolongations = meshes
            .windows(2)
            .map(|w| Prolongation::new(&w[0], &w[1]))
            .collect();
        let (k, mass) = (
            Stiffness::assemble(&meshes[0]),
            crate::assembly::lumped_mass(&meshes[0]),
        );
        Levels {
            meshes,
            prolongations,
            k,
            mass,
        }
    }

    /// A deterministic pseudo-random vector in [−1, 1].
    fn noise(n: usize, seed: u64) -> Vec<f64> {
        let mut s = seed.wrapping_mul(6_364_136_223_846_793_005).wrapping_add(1);
        (0..n)
            .map(|_| {
                s = s
                    .wrapping_mul(6_364_136_223_846_793_005)
                    .wrapping_add(1_442_695_040_888_963_407);
                (s >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0
            })
            .collect()
    }

    /// With nothing held, the coarse operators are the coarse meshes' stiffness matrices on their
    /// interior vertices (and empty rows on their boundary), on the unit square and on a rectangle
    /// of sides 0.3 and 0.7, where the couplings that vanish come out of the sums as round-off.
    #[test]
    fn galerkin_equals_rediscretisation() {
        let kinds = [Diagonal::Right, Diagonal::Left, Diagonal::Crossed];
        for (corner, diagonal) in [[1.0, 1.0], [0.3, 0.7]]
            .into_iter()
            .flat_map(|c| kinds.map(|d| (c, d)))
        {
            let levels = rectangle(corner, 16, diagonal);
            let (meshes, h) = (&levels.meshes, levels.hierarchy());
            let mg = h.preconditioner(meshes[0].on_boundary.clone()).unwrap();
            assert_eq!(mg.coarse.len(), 2);
            for (level, a) in mg.coarse.iter().enumerate() {
                let mesh = &meshes[level + 1];
                let direct = Stiffness::assemble(mesh);
                assert_eq!(a.rows(), mesh.n_vertices());
                let interior = |i: usize| !mesh.on_boundary[i];
                // The same pattern: the couplings that vanish (across the diagonals of the
                // right-angled meshes) are left out as K leaves them out.
                let entries = (0..a.rows())
                    .filter(|&i| interior(i))
                    .map(|i| direct.row(i).filter(|&(j, _)| interior(j)).count())
                    .sum::<usize>();
                assert_eq!(a.nnz(), entries, "{diagonal:?} level {level}");
                for i in 0..a.rows() {
                    for j in 0..a.rows() {
                        let expected = if interior(i) && interior(j) {
                            direct.matrix().get(i, j)
                        } else {
                            0.0
                        };
                        let d = (a.get(i, j) - expected).abs();
                        assert!(d < 1e-13, "{diagonal:?} level {level} ({i}, {j}): {d}");
                    }
                }
            }
        }
    }

    /// With a base (the operators with the boundary alone skipped), the truncated coarse operators
    /// of a held set are the base's rows away from it and recomputed rows near it: the same
    /// numbers as computed in full, on nested squares and on the disk's hierarchy (whose coarsest
    /// levels are not nested); with the boundary alone skipped, they are the base's own.
    #[test]
    fn operators_recomputed_near_the_held_set_equal_the_full_ones() {
        let disk = crate::case::Case::read(std::path::Path::new("data/cases/disk_contact.toml")).unwrap();
        let (mesh, coarser) = disk.hierarchy(true, Default::default()).unwrap();
        let meshes: Vec<Mesh> = std::iter::once(mesh).chain(coarser).collect();
        let disk = Levels {
            k: Stiffness::assemble(&meshes[0]),
            mass: crate::assembly::lumped_mass(&meshes[0]),
            prolongations: meshes
                .windows(2)
                .map(|w| Prolongation::new(&w[0], &w[1]))
                .collect(),
            meshes,
        };
        for levels in [square(32, Diagonal::Right), square(32, Diagonal::Crossed), disk] {
            let mesh = &levels.meshes[0];
            let boundary = mesh.on_boundary.clone();
            let system = InteriorSystem::numbering(&boundary);
            let scattered: Vec<bool> = noise(system.n(), 4).iter().map(|&v| v > 0.3).collect();
            let (full, based) = (levels.hierarchy(), levels.hierarchy().with_base(boundary.clone()));
            for held in [vec![false; system.n()], held_disk(mesh, &system), scattered] {
                let skip = system.skipped(&held);
                let (a, b) = (
                    full.preconditioner(skip.clone()).unwrap(),
                    based.preconditioner(skip.clone()).unwrap(),
                );
                assert!(a.coarse.len() >= 2);
                let mut recomputed = 0;
                for (a, b) in a.coarse.iter().zip(&b.coarse) {
                    assert_eq!((&a.row_ptr, &a.col, &a.val), (&b.row_ptr, &b.col, &b.val));
                    recomputed += matches!(b, Cow::Owned(_)) as usize;
                }
                let nothing_held = held.iter().all(|&h| !h);
                assert_eq!(recomputed == 0, nothing_held, "{recomputed} levels recomputed");
                let mut levels = (a.levels.iter()).zip(&b.levels);
                assert!(levels.all(|(a, b)| a.skip == b.skip));
            }
        }
    }

    /// Below a held disk of radius 0.3 on the square, the coarse rows computed again are the held
    /// ones (empty rows) and a band around the disk's edge: far fewer than all.
    #[test]
    fn only_rows_near_the_held_set_are_computed_again() {
        let levels = square(64, Diagonal::Right);
        let boundary = levels.meshes[0].on_boundary.clone();
        let h = levels.hierarchy().with_base(boundary.clone());
        let skip = skip_boundary_and_disk(&levels);
        h.preconditioner(skip.clone()).unwrap();
        let (b1, skip1) = &h.base.as_ref().unwrap().1.get().unwrap()[0];
        let p = levels.prolongations[0].matrix();
        let alive: Vec<bool> = skip.iter().map(|&s| !s).collect();
        let held: Vec<bool> = skip.iter().zip(&boundary).map(|(s, b)| s != b).collect();
        let dirty = dirty_rows(
            levels.k.matrix(),
            p,
            &p.transpose(),
            &held,
            &kept(p, &alive),
            skip1,
        );
        let (count, rows) = (dirty.iter().filter(|&&d| d).count(), b1.rows());
        // The disk covers 28 % of the square; its edge's band a few coarse rows more.
        assert!(count < rows / 2, "{count} of {rows} rows computed again");
    }

    /// The energy-norm contraction of the stationary iteration x ← x + B(b − K x), measured
    /// from a random error after `cycles` cycles (the asymptotic rate).
    fn contraction(mg: &mut Multigrid, cycles: usize) -> f64 {
        let n = mg.n();
        let mut e: Vec<f64> = noise(n, 7);
        for (i, e) in e.iter_mut().enumerate() {
            if mg.held(i) {
                *e = 0.0;
            }
        }
        let energy = |mg: &Multigrid, e: &[f64]| {
            let mut ke = vec![0.0; n];
            mg.apply(e, &mut ke);
            dot(e, &ke).sqrt()
        };
        let (mut ke, mut z) = (vec![0.0; n], vec![0.0; n]);
        let mut rate = 0.0;
        for _ in 0..cycles {
            let before = energy(mg, &e);
            mg.apply(&e, &mut ke);
            let r: Vec<f64> = ke.iter().map(|v| -v).collect();
            mg.precondition(&r, &mut z);
            for (e, z) in e.iter_mut().zip(&z) {
                *e += z;
            }
            rate = energy(mg, &e) / before;
        }
        rate
    }

    /// On the unit square (n = 32, 64, 128 cells down to 4): the asymptotic energy-norm
    /// contraction of the stationary V-cycle iteration is ≤ 0.2 with two Gauss–Seidel sweeps on
    /// each side, V(2,2), and ≤ 0.4 with one, V(1,1) (the default: it makes CG faster, see the
    /// module's documentation); CG preconditioned by V(1,1) reduces the residual by ≤ 0.2 per
    /// iteration; none of them grows with 1/h.
    #[test]
    fn v_cycle_convergence_factors_on_the_square() {
        for diagonal in [Diagonal::Right, Diagonal::Crossed] {
            let mut rates: Vec<[f64; 3]> = Vec::new();
            for n in [32, 64, 128] {
                let levels = square(n, diagonal);
                let (meshes, k, h) = (&levels.meshes, &levels.k, levels.hierarchy());
                let mut mg = h.preconditioner(meshes[0].on_boundary.clone()).unwrap();
                assert_eq!(mg.sweeps, 1);
                let v11 = contraction(&mut mg, 12);
                mg.sweeps = 2;
                let v22 = contraction(&mut mg, 12);
                mg.sweeps = 1;
                let b = noise(k.n(), 5);
                let mut x = vec![0.0; k.n()];
                let iterations = mg.solve(b, &mut x, 1e-10, 100).unwrap();
                let cg = 1e-10_f64.powf(1.0 / iterations as f64);
                rates.push([v22, v11, cg]);
            }
            let worst = |k: usize| rates.iter().map(|r| r[k]).fold(0.0, f64::max);
            assert!(
                worst(0) <= 0.2 && worst(1) <= 0.4 && worst(2) <= 0.2,
                "{diagonal:?}: {rates:?}"
            );
            for k in 0..3 {
                assert!(
                    rates[2][k] <= rates[0][k] + 0.03,
                    "{diagonal:?} grows with 1/h: {rates:?}"
                );
            }
        }
    }

    /// A held disk of radius 0.3 about (0.45, 0.52) on the unknowns of `mesh`.
    fn held_disk(mesh: &Mesh, system: &InteriorSystem) -> Vec<bool> {
        (system.vertices.iter())
            .map(|&a| {
                let p = mesh.points[a];
                (p[0] - 0.45).hypot(p[1] - 0.52) < 0.3
            })
            .collect()
    }

    /// The finest level's boundary and [`held_disk`], skipped.
    fn skip_boundary_and_disk(levels: &Levels) -> Vec<bool> {
        let mesh = &levels.meshes[0];
        let system = InteriorSystem::numbering(&mesh.on_boundary);
        system.skipped(&held_disk(mesh, &system))
    }

    /// The V-cycle is symmetric positive definite, with one block per level and with two (the
    /// hybrid smoother of the large levels).
    #[test]
    fn the_v_cycle_is_symmetric() {
        let levels = square(32, Diagonal::Left);
        let (k, skip) = (&levels.k, skip_boundary_and_disk(&levels));
        for block_rows in [usize::MAX, 64] {
            let h = levels.hierarchy().with_block_rows(block_rows);
            let mut mg = h.preconditioner(skip.clone()).unwrap();
            let n = k.n();
            let (mut u, mut v) = (noise(n, 1), noise(n, 2));
            for i in 0..n {
                if skip[i] {
                    u[i] = 0.0;
                    v[i] = 0.0;
                }
            }
            let (mut bu, mut bv) = (vec![0.0; n], vec![0.0; n]);
            mg.precondition(&u, &mut bu);
            mg.precondition(&v, &mut bv);
            let (a, b) = (dot(&v, &bu), dot(&u, &bv));
            assert!((a - b).abs() < 1e-12 * a.abs().max(b.abs()), "{a} vs {b}");
            assert!(dot(&u, &bu) > 0.0 && dot(&v, &bv) > 0.0);
        }
    }

    /// Two blocks per level (from 64 rows) split the levels of the square in halves coupled along
    /// one line of the mesh; swept on one thread or on two, CG computes the same numbers.
    #[test]
    fn two_blocks_on_one_thread_or_two_give_the_same_numbers() {
        let levels = square(64, Diagonal::Right);
        let (k, skip) = (&levels.k, skip_boundary_and_disk(&levels));
        let h = levels.hierarchy().with_block_rows(64);
        let free = AtomicBool::new(true);
        let mut results = Vec::new();
        for second_core in [None, Some(&free)] {
            let mut mg = h.preconditioner(skip.clone()).unwrap();
            let blocks = &mg.levels[0].blocks;
            assert_eq!(blocks.mid, k.n() / 2);
            // Rows numbered by rows of the mesh: the rows of the two mesh lines next to the cut.
            assert!(
                (65..=2 * 65).contains(&blocks.interface.len()),
                "{}",
                blocks.interface.len()
            );
            mg.second_core = second_core;
            let mut x = vec![0.0; k.n()];
            let iterations = mg.solve(noise(k.n(), 3), &mut x, 1e-12, 100).unwrap();
            results.push((iterations, x));
        }
        assert_eq!(results[0], results[1]);
    }

    /// One free fine vertex amid held ones, the midpoint of a coarse edge: both coarse hat
    /// functions of the edge truncate to half its fine hat function. Keeping them both would make
    /// the coarse matrix singular; the rule keeps neither, and CG solves the 1 × 1 system.
    #[test]
    fn a_lone_free_midpoint_keeps_no_coarse_unknown() {
        let levels = square(8, Diagonal::Right);
        let (meshes, k, h) = (&levels.meshes, &levels.k, levels.hierarchy());
        let midpoint = (meshes[0].points.iter())
            .position(|&p| p == [0.375, 0.5])
            .unwrap();
        let skip: Vec<bool> = (0..k.n()).map(|i| i != midpoint).collect();
        let alive: Vec<bool> = skip.iter().map(|&h| !h).collect();
        let p = levels.prolongations[0].matrix();
        assert_eq!(p.row(midpoint).1, &[0.5, 0.5], "the midpoint of a coarse edge");
        let mut mg = h.preconditioner(skip).unwrap();
        let b = vec![1.0; k.n()];
        let mut x = vec![0.0; k.n()];
        assert_eq!(mg.solve(b, &mut x, 1e-12, 10), Ok(1));
        assert!((x[midpoint] - 1.0 / k.diagonal(midpoint)).abs() < 1e-15);
        assert!(kept(p, &alive).iter().all(|&k| !k));
    }

    /// CG returns x = 0 at once for b = 0 (whatever the start), and does not stop on a NaN.
    #[test]
    fn cg_on_a_zero_or_nan_right_hand_side() {
        let levels = square(8, Diagonal::Right);
        let (meshes, k, h) = (&levels.meshes, &levels.k, levels.hierarchy());
        let mut mg = h.preconditioner(meshes[0].on_boundary.clone()).unwrap();
        let mut x = noise(k.n(), 1);
        assert_eq!(mg.solve(vec![0.0; k.n()], &mut x, 1e-13, 10), Ok(0));
        assert!(x.iter().all(|&x| x == 0.0));
        let mut b = vec![1.0; k.n()];
        let inside = meshes[0].on_boundary.iter().position(|&e| !e).unwrap();
        b[inside] = f64::NAN;
        assert!(mg.solve(b, &mut x, 1e-13, 10).is_err());
    }

    #[test]
    fn truncated_cg_reaches_the_cholesky_solution_in_few_iterations() {
        let mut iterations = Vec::new();
        for n in [32, 64, 128, 256] {
            let levels = square(n, Diagonal::Right);
            let (meshes, k, h) = (&levels.meshes, &levels.k, levels.hierarchy());
            let system = InteriorSystem::new(k, &meshes[0].on_boundary);
            let held = held_disk(&meshes[0], &system);
            let b: Vec<f64> = noise(system.n(), 3).iter().map(|v| 1.0 + v).collect();
            let mut factor = system.factorization();
            // Also a scattered held set, with free vertices amid held ones: the truncated coarse
            // basis functions of two coarse vertices can reduce to one fine hat function there.
            let scattered = noise(system.n(), 4).iter().map(|&v| v > -0.6).collect();
            for held in [vec![false; system.n()], held, scattered] {
                factor.factorize(&held).unwrap();
                let mut direct = b.clone();
                factor.solve(&mut direct);
                // One block per level, and two from 256 rows on.
                for h in [h.clone(), h.clone().with_block_rows(256)] {
                    let mut mg = h.preconditioner(system.skipped(&held)).unwrap();
                    let mut x = vec![0.0; k.n()];
                    iterations.push(mg.solve(system.extended(&b), &mut x, 1e-12, 100).unwrap());
                    let x = system.gather(&x);
                    let scale = direct.iter().fold(0.0_f64, |m, v| m.max(v.abs()));
                    let error = x
                        .iter()
                        .zip(&direct)
                        .fold(0.0_f64, |m, (a, b)| m.max((a - b).abs()));
                    assert!(error <= 1e-10 * scale, "n = {n}: {error} / {scale}");
                    assert!(x.iter().zip(&held).all(|(x, &h)| !h || *x == 0.0));
                }
            }
        }
        assert!(iterations.iter().all(|&i| i <= 15), "{iterations:?}");
    }
}
