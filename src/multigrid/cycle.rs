//! The V-cycle of one held set (see the module [`crate::multigrid`]): smoothing on each level,
//! the residual restricted by Pᵀ, the coarser level's correction interpolated by P, the coarsest
//! level solved by Cholesky; and CG preconditioned by it.

use super::smoother::{postsmooth, presmooth, Level};
use crate::cg::{conjugate_gradients, Free, NotConverged, Preconditioner, Tolerance};
use crate::linear::{Cholesky, NotPositiveDefinite, Unknown};
use crate::mesh::Prolongation;
use crate::parallel::{self, PIECE};
use crate::sparse::Csr;

/// The operators of the V-cycle: its levels, the interpolations P_l from level l + 1 onto level l
/// (with their transposes), and the masses of level 0 (which weigh CG's residual).
pub(super) struct Operators<'h> {
    pub(super) levels: Vec<Level<'h>>,
    pub(super) p: &'h [Prolongation],
    pub(super) mass: &'h [f64],
    /// Gauss–Seidel sweeps before and after the coarse correction.
    pub(super) sweeps: usize,
}

/// The vectors of one level below level 0 (whose iterate and right-hand side are CG's): the
/// iterate, the right-hand side, the residual, and the values the backward sweep reads across its
/// blocks.
#[derive(Default)]
struct Work {
    x: Vec<f64>,
    b: Vec<f64>,
    r: Vec<f64>,
    ghost: Vec<f64>,
}

/// The V-cycle for one held set, and CG preconditioned by it.
pub struct Multigrid<'h> {
    operators: Operators<'h>,
    work: Vec<Work>,
    coarsest: Coarsest,
}

/// The V-cycle as CG's preconditioner: the operators, and the vectors it works in.
struct Cycle<'a, 'h> {
    operators: &'a Operators<'h>,
    work: &'a mut [Work],
    coarsest: &'a mut Coarsest,
}

impl<'h> Multigrid<'h> {
    /// The V-cycle on `operators`, with the coarsest level's factorization.
    pub(super) fn new(operators: Operators<'h>) -> Result<Self, NotPositiveDefinite> {
        let last = operators.levels.last().expect("a level");
        let coarsest = Coarsest::new(&last.a, &last.skip)?;
        let work = (operators.levels.iter().enumerate())
            .map(|(l, level)| {
                let n = level.skip.len();
                let m = if l == 0 { 0 } else { n };
                Work {
                    x: vec![0.0; m],
                    b: vec![0.0; m],
                    r: vec![0.0; n],
                    ghost: Vec::new(),
                }
            })
            .collect();
        Ok(Multigrid {
            operators,
            work,
            coarsest,
        })
    }

    /// The number of vertices of level 0 (skipped ones included).
    pub fn n(&self) -> usize {
        self.operators.levels[0].skip.len()
    }

    /// K_FF of level 0, as CG sees it.
    fn free(&self) -> Free<'_> {
        let level = &self.operators.levels[0];
        Free {
            matrix: &level.a,
            skip: &level.skip,
            mass: self.operators.mass,
        }
    }

    /// Whether vertex i of level 0 is skipped (on the boundary or held).
    #[cfg(test)]
    pub(super) fn held(&self, i: usize) -> bool {
        self.operators.levels[0].skip[i]
    }

    /// Sets the Gauss–Seidel sweeps before and after the coarse correction.
    #[cfg(test)]
    pub(super) fn set_sweeps(&mut self, sweeps: usize) {
        self.operators.sweeps = sweeps;
    }

    /// The levels.
    #[cfg(test)]
    pub(super) fn levels(&self) -> &[Level<'h>] {
        &self.operators.levels
    }

    /// The blocks of level 0's smoother.
    #[cfg(test)]
    pub(super) fn fine_blocks(&self) -> &super::smoother::Blocks {
        &self.operators.levels[0].blocks
    }

    /// y = K_FF x on the free unknowns, 0 on the held ones.
    #[cfg(test)]
    pub(super) fn apply(&self, x: &[f64], y: &mut [f64]) {
        let level = &self.operators.levels[0];
        for (i, y) in y.iter_mut().enumerate() {
            *y = if level.skip[i] { 0.0 } else { level.a.row_dot(i, x) };
        }
    }

    /// z = B r: one V-cycle from zero for the right-hand side r (read on the free unknowns);
    /// z is 0 on the held ones. Returns r·z.
    #[cfg(test)]
    pub(super) fn precondition(&mut self, r: &[f64], z: &mut [f64]) -> f64 {
        let mut cycle = Cycle {
            operators: &self.operators,
            work: &mut self.work,
            coarsest: &mut self.coarsest,
        };
        cycle.cycle::<false>(0, r, z, &mut [])
    }

    /// max_a |r_a|/m_a over the free unknowns: r as a load density.
    pub fn density(&self, r: &[f64]) -> f64 {
        self.free().density(r)
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
        let tolerance = Tolerance {
            density,
            backward: None,
        };
        self.solve_to(b, x, tolerance, max_iterations)
    }

    /// Solves K_FF x = b (b taken) by CG preconditioned by the V-cycle, from the guess `x`, to
    /// `tolerance` (see [`conjugate_gradients`]). Returns the iterations.
    pub fn solve_to(
        &mut self,
        b: Vec<f64>,
        x: &mut [f64],
        tolerance: Tolerance,
        max_iterations: usize,
    ) -> Result<usize, NotConverged> {
        let level = &self.operators.levels[0];
        let free = Free {
            matrix: &level.a,
            skip: &level.skip,
            mass: self.operators.mass,
        };
        let mut cycle = Cycle {
            operators: &self.operators,
            work: &mut self.work,
            coarsest: &mut self.coarsest,
        };
        conjugate_gradients(&free, &mut cycle, b, x, tolerance, max_iterations)
    }
}

impl Preconditioner for Cycle<'_, '_> {
    fn precondition(&mut self, r: &[f64], z: &mut [f64], kz: &mut [f64]) -> f64 {
        self.cycle::<true>(0, r, z, kz)
    }
}

impl Cycle<'_, '_> {
    /// The V-cycle on level l from x = 0 for the right-hand side b: x = B_l b, and with `AX`
    /// also ax = A_l x, from the last smoothing sweep. Returns b·x.
    fn cycle<const AX: bool>(&mut self, l: usize, b: &[f64], x: &mut [f64], ax: &mut [f64]) -> f64 {
        let ops = self.operators;
        let level = &ops.levels[l];
        if l == ops.levels.len() - 1 {
            self.coarsest.solve(b, x);
            if AX {
                // A x = b on the live unknowns (the coarsest solve is exact).
                for ((ax, &b), &skip) in ax.iter_mut().zip(b).zip(&level.skip) {
                    *ax = if skip { 0.0 } else { b };
                }
            }
            return b.iter().zip(&*x).map(|(b, x)| b * x).sum();
        }
        presmooth(level, b, x, &mut self.work[l].r, ops.sweeps);
        let (mut bc, mut xc) = {
            let (fine, coarse) = self.work.split_at_mut(l + 1);
            restrict(ops.p[l].transposed(), &fine[l].r, &mut coarse[0].b);
            (std::mem::take(&mut coarse[0].b), std::mem::take(&mut coarse[0].x))
        };
        self.cycle::<false>(l + 1, &bc, &mut xc, &mut []);
        prolong(ops.p[l].matrix(), &level.skip, &xc, x);
        let bx = postsmooth::<AX>(level, b, x, ax, &mut self.work[l].ghost, ops.sweeps);
        let coarse = &mut self.work[l + 1];
        std::mem::swap(&mut coarse.b, &mut bc);
        std::mem::swap(&mut coarse.x, &mut xc);
        bx
    }
}

/// b_c = Pᵀ r (r is 0 where skipped), by the rows of Pᵀ (`pt`), in parallel.
fn restrict(pt: &Csr, r: &[f64], bc: &mut [f64]) {
    parallel::map_mut(bc, PIECE, |base, bc| {
        for (k, bc) in bc.iter_mut().enumerate() {
            *bc = pt.row_dot(base + k, r);
        }
    });
}

/// x += P x_c on the unknowns not skipped, in parallel.
fn prolong(p: &Csr, skip: &[bool], xc: &[f64], x: &mut [f64]) {
    parallel::map_mut(x, PIECE, |base, x| {
        for (k, x) in x.iter_mut().enumerate() {
            if !skip[base + k] {
                *x += p.row_dot(base + k, xc);
            }
        }
    });
}

/// The coarsest level's Cholesky factorization, on its live unknowns.
pub(super) struct Coarsest {
    /// The live unknowns.
    live: Vec<usize>,
    cholesky: Option<Cholesky>,
    buffer: Vec<f64>,
}

impl Coarsest {
    pub(super) fn new(a: &Csr, skip: &[bool]) -> Result<Self, NotPositiveDefinite> {
        let live: Vec<usize> = (0..a.rows()).filter(|&i| !skip[i]).collect();
        let mut index = vec![Unknown::HELD; a.rows()];
        for (k, &i) in live.iter().enumerate() {
            index[i] = Unknown::new(k);
        }
        // The lower triangle by columns is the upper triangle by rows (a is symmetric).
        let (mut col_ptr, mut row_idx, mut val) = (vec![0], Vec::new(), Vec::new());
        for &i in &live {
            let (cols, vals) = a.row(i);
            for (&j, &v) in cols.iter().zip(vals) {
                let j = j as usize;
                if let Some(k) = index[j].index().filter(|_| j >= i) {
                    row_idx.push(k);
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
