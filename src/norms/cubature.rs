//! Adaptive cubature of nonnegative densities over the cells of a mesh, for the error norms.
//!
//! On every cell two rules of different degree give Q_hi and Q_lo; Q_hi is kept, and its error
//! is estimated by |Q_hi − Q_lo| where the exact fields are smooth on the cell. Where they branch
//! (`if`, `min`, `max`, `abs`, …: `Program::eval_with_margins` says at which points, the cell's
//! corners included), a value or a derivative may jump inside the cell and both rules may miss it:
//! the estimate is then at least the cell's area times the range of the density over its points,
//! and once the cell is cut, the difference between its value and its quarters' (the error of the
//! coarser, which the finer about halves across a jump and divides by more across a kink).
//!
//! The cells whose estimate exceeds an even share of half the tolerance ([`RTOL`] of the integral)
//! stay open; the open cells above an even share are cut into four at their edges' midpoints and
//! each quarter is integrated the same way, round after round, until the summed estimate is within
//! the tolerance or a budget of points is spent. So the rule is cheap where the exact solution is
//! smooth on the cell, and refined along the curves where it jumps or bends and where the two
//! rules see a layer differently. A jump that crosses one edge of a cell twice between its points
//! and corners is not seen.
//!
//! A density may know that it is a constant on a cell ([`Density::constant`]): that cell's
//! integral is then exact, with no rule. The norms use it for λ − λ_h on the cells of S_h where λ
//! takes one constant branch on their triangle ([`constant_on`]): λ = 0 away from the contact set.

use crate::assembly::Quadrature;
use crate::expr::{Expr, Program, BLOCK};
use crate::mesh::dual::{barycentre, midpoint};

use crate::parallel::{self, PIECE};

/// Relative tolerance on each integral (a squared norm) for the cells' estimates and their sum.
pub const RTOL: f64 = 1e-6;

/// A quarter whose estimated errors are at most this fraction of its values is closed: all such
/// quarters add at most [`RTOL`] / 4 of the integral, the cells closed at the start at most a half.
const CLOSE: f64 = RTOL / 4.0;

/// Rounds of cutting at most: a jump along a curve halves its cells' error per round.
const MAX_ROUNDS: usize = 24;

/// Points the rounds may spend at least, whatever the mesh's size; beyond it, an eighth of what the
/// first pass over the cells spent (a jump then leaves an estimate above the tolerance, stated).
const MIN_BUDGET: usize = 1 << 20;

/// Cells (or quarters) whose points are evaluated together.
const CELLS_PER_BLOCK: usize = 16;

/// A density of M nonnegative components on the cells of a mesh.
pub trait Density<const M: usize>: Sync {
    /// What the density needs of one cell (e.g. its discrete fields), made once per cell visit.
    type Local;
    /// The expressions evaluated at the points (the exact solution), in the order `at` reads them.
    fn fields(&self) -> Vec<&Expr>;
    /// The cell's data.
    fn local(&self, cell: usize) -> Self::Local;
    /// The components at the point `k` (at `x` in the cell), `values[f][k]` field f's value there.
    fn at(&self, local: &Self::Local, x: [f64; 2], values: &[Vec<f64>], k: usize) -> [f64; M];
    /// The density on the cell, where it is known to be a constant there (no rule then).
    fn constant(&self, _cell: usize) -> Option<[f64; M]> {
        None
    }
}

/// The pair of rules on each cell: the value is the higher degree's.
#[derive(Debug, Clone, Copy)]
pub struct Rules {
    /// The rule whose disagreement estimates the error.
    pub lo: Quadrature,
    /// The rule whose value is kept.
    pub hi: Quadrature,
}

/// ∫ of each component over the mesh, with the estimated error of each.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Integral<const M: usize> {
    /// The integrals.
    pub value: [f64; M],
    /// Their estimated errors (summed over the final pieces).
    pub error: [f64; M],
}

/// ∫ over the cells 0..n (`corners` of each) of `density`, adaptively by `rules`.
pub fn integrate<const M: usize, D: Density<M>>(
    n: usize,
    corners: impl Fn(usize) -> [[f64; 2]; 3] + Sync,
    density: &D,
    rules: Rules,
) -> Integral<M> {
    let piece = |cell| Piece {
        cell,
        corners: corners(cell),
    };
    // Every cell's estimate, kept as its errors alone until the tolerance is known.
    let first = parallel::map_with(
        n,
        PIECE,
        || Evaluator::new(density, rules),
        |ev, range| {
            let constant: Vec<Option<[f64; M]>> = range.clone().map(|c| density.constant(c)).collect();
            let rest: Vec<Piece> = (range.clone().zip(&constant))
                .filter(|(_, d)| d.is_none())
                .map(|(c, _)| piece(c))
                .collect();
            let mut estimated = ev.estimates(&rest).into_iter();
            let mut whole = Integral::zero();
            let errors: Vec<[f32; M]> = (range.zip(constant))
                .map(|(c, d)| {
                    let (value, error) = match d {
                        // A constant's integral is exact.
                        Some(d) => {
                            let area = piece(c).area();
                            (d.map(|d| d * area), [0.0; M])
                        }
                        None => {
                            let e = estimated.next().expect("an estimate for each cell not constant");
                            (e.value, e.error)
                        }
                    };
                    whole.add(&value, &error);
                    error.map(|e| e as f32)
                })
                .collect();
            (whole, errors)
        },
    );
    let whole = first.iter().fold(Integral::zero(), |s, (w, _)| s.plus(w));
    let tol = whole.value.map(|v| RTOL * v);
    // The cells above an even share of half the tolerance stay open; the others add at most half.
    let fair = 0.5 / n.max(1) as f64;
    let mut closed = Integral {
        value: whole.value,
        error: [0.0; M],
    };
    let mut open = Vec::new();
    for (c, e) in first.iter().flat_map(|(_, e)| e).enumerate() {
        let e = e.map(f64::from);
        if share(&e, &tol) > fair {
            open.push(piece(c));
        } else {
            (0..M).for_each(|m| closed.error[m] += e[m]);
        }
    }
    let ev = Evaluator::new(density, rules);
    let open = ev.all(&open);
    for (m, v) in closed.value.iter_mut().enumerate() {
        *v -= open.iter().map(|e| e.value[m]).sum::<f64>();
    }
    let budget = MIN_BUDGET.max(n * ev.points_per_piece() / 8);
    refine(open, closed, ev, budget)
}

/// The largest of the errors `e` relative to the tolerances `tol`.
fn share<const M: usize>(e: &[f64; M], tol: &[f64; M]) -> f64 {
    (0..M)
        .map(|m| if e[m] > 0.0 { e[m] / tol[m] } else { 0.0 })
        .fold(0.0, f64::max)
}

/// The rounds of cutting of the open cells (see the module's description), by `ev`'s rules.
fn refine<const M: usize, D: Density<M>>(
    mut open: Vec<Estimate<M>>,
    mut closed: Integral<M>,
    ev: Evaluator<'_, M, D>,
    mut budget: usize,
) -> Integral<M> {
    let cost = 4 * ev.points_per_piece();
    for _ in 0..MAX_ROUNDS {
        let total = sum(&closed, &open);
        let tol = total.value.map(|v| RTOL * v);
        let done = (0..M).all(|m| total.error[m] <= tol[m]) || budget < cost || open.is_empty();
        if done || crate::progress::cancelled() {
            break;
        }
        // The pieces above an even share of half the tolerance, the largest first if the budget
        // does not reach them all.
        let fair = 0.5 / open.len() as f64;
        let shares: Vec<f64> = open.iter().map(|e| share(&e.error, &tol)).collect();
        let mut chosen: Vec<usize> = (0..open.len()).filter(|&i| shares[i] > fair).collect();
        let fits = budget / cost;
        if chosen.len() > fits {
            chosen.select_nth_unstable_by(fits, |&a, &b| shares[b].total_cmp(&shares[a]).then(a.cmp(&b)));
            chosen.truncate(fits);
        }
        let mut is_cut = vec![false; open.len()];
        chosen.iter().for_each(|&i| is_cut[i] = true);
        let (mut cut, mut keep) = (Vec::new(), Vec::new());
        for (e, c) in open.into_iter().zip(is_cut) {
            if c {
                cut.push(e)
            } else {
                keep.push(e)
            }
        }
        open = keep;
        budget -= cut.len() * cost;
        let quarters: Vec<Piece> = cut.iter().flat_map(|e| e.piece.quarters()).collect();
        let mut quarters = ev.all(&quarters);
        for (parent, quarters) in cut.iter().zip(quarters.chunks_mut(4)) {
            across_branch(parent, quarters);
            for e in quarters.iter() {
                if (0..M).all(|m| e.error[m] <= CLOSE * e.value[m]) {
                    closed.add(&e.value, &e.error);
                } else {
                    open.push(*e);
                }
            }
        }
    }
    sum(&closed, &open)
}

/// The quarters of `parent` with their errors estimated: a branch makes both rules unreliable,
/// so across one that their points see, the difference between the parent's value and its
/// quarters' (the error of the coarser, which the finer about halves) is shared among the
/// quarters it crosses (all four if it crossed the parent's points and slipped between theirs),
/// at least their rules' own difference. A quarter whose corners alone see a jump keeps its
/// bound (the rules' points, the parent's and the quarters', may all miss the clipped corner).
fn across_branch<const M: usize>(parent: &Estimate<M>, quarters: &mut [Estimate<M>]) {
    if parent.kind != Kind::Straddle {
        return;
    }
    let sum: [f64; M] = std::array::from_fn(|m| quarters.iter().map(|q| q.value[m]).sum());
    let crossed = quarters.iter().filter(|q| q.kind == Kind::Straddle).count();
    let all = crossed == 0 && quarters.iter().all(|q| q.kind == Kind::Smooth);
    let targets = if all { 4 } else { crossed };
    for q in quarters.iter_mut().filter(|q| q.kind == Kind::Straddle || all) {
        q.error = std::array::from_fn(|m| q.rules[m].max((parent.value[m] - sum[m]).abs() / targets as f64));
    }
}

/// `closed` plus the values and errors of `open`, added in order.
fn sum<const M: usize>(closed: &Integral<M>, open: &[Estimate<M>]) -> Integral<M> {
    let mut total = *closed;
    for e in open {
        total.add(&e.value, &e.error);
    }
    total
}

impl<const M: usize> Integral<M> {
    fn zero() -> Self {
        Integral {
            value: [0.0; M],
            error: [0.0; M],
        }
    }

    fn add(&mut self, value: &[f64; M], error: &[f64; M]) {
        for m in 0..M {
            self.value[m] += value[m];
            self.error[m] += error[m];
        }
    }

    fn plus(&self, other: &Integral<M>) -> Self {
        Integral {
            value: std::array::from_fn(|m| self.value[m] + other.value[m]),
            error: std::array::from_fn(|m| self.error[m] + other.error[m]),
        }
    }
}

/// A triangle inside the mesh cell `cell` (the cell itself, or a quarter of a quarter …).
#[derive(Debug, Clone, Copy)]
struct Piece {
    cell: usize,
    corners: [[f64; 2]; 3],
}

impl Piece {
    fn area(&self) -> f64 {
        let [p, q, r] = self.corners;
        0.5 * crate::mesh::orient(p, q, r).abs()
    }

    /// The four triangles cut by the edges' midpoints, oriented as this one.
    fn quarters(&self) -> [Piece; 4] {
        let [p, q, r] = self.corners;
        let (pq, qr, rp) = (midpoint(p, q), midpoint(q, r), midpoint(r, p));
        [[p, pq, rp], [pq, q, qr], [rp, qr, r], [qr, rp, pq]].map(|corners| Piece {
            cell: self.cell,
            corners,
        })
    }
}

/// A piece's Q_hi and |Q_hi − Q_lo| per component.
#[derive(Debug, Clone, Copy)]
struct Estimate<const M: usize> {
    piece: Piece,
    value: [f64; M],
    /// The estimate of the value's error.
    error: [f64; M],
    /// |Q_hi − Q_lo|.
    rules: [f64; M],
    /// Where the piece lies from the branches of the fields.
    kind: Kind,
}

/// The value of `e` on each cell 0..n (`corners` of each) where it is a constant as far as its
/// values show: the same at the points of [`CONSTANT_TEST`], the corners, the edges' midpoints
/// and the centroid, with the same sign of every branch's margin there (as `Kind::Smooth`: the
/// expression does not branch between them, and takes one constant branch, as λ = max(…, 0)
/// away from the contact set).
pub fn constant_on(n: usize, corners: impl Fn(usize) -> [[f64; 2]; 3] + Sync, e: &Expr) -> Vec<Option<f64>> {
    let program = Program::new(&[e]);
    let j = program.branches();
    let rule = CONSTANT_TEST.rule();
    let per_cell = rule.len() + 7;
    let pieces = parallel::map(n, PIECE, |range| {
        let (mut xs, mut values, mut scratch, mut margins) = (Vec::new(), Vec::new(), Vec::new(), Vec::new());
        let mut out = Vec::with_capacity(range.len());
        for cells in range.collect::<Vec<_>>().chunks(CELLS_PER_BLOCK) {
            xs.clear();
            for &c in cells {
                let [p, q, r] = corners(c);
                let at = |l: [f64; 3]| std::array::from_fn(|d| l[0] * p[d] + l[1] * q[d] + l[2] * r[d]);
                xs.extend(rule.iter().map(|&[xi, eta, _]| at([1.0 - xi - eta, xi, eta])));
                xs.extend([
                    p,
                    q,
                    r,
                    midpoint(p, q),
                    midpoint(q, r),
                    midpoint(r, p),
                    barycentre([p, q, r]),
                ]);
            }
            values.resize(xs.len(), 0.0);
            program.eval_with_margins(&xs, &mut [&mut values[..]], &mut scratch, &mut margins);
            out.extend((0..cells.len()).map(|k| {
                let points = k * per_cell..(k + 1) * per_cell;
                let v = values[points.start];
                let same = values[points.clone()].iter().all(|w| w.to_bits() == v.to_bits());
                let one_side = (0..j).all(|b| {
                    let side = |k: usize| margins[k * j + b] < 0.0;
                    points.clone().all(|k| side(k) == side(points.start))
                });
                (same && one_side && v.is_finite()).then_some(v)
            }));
        }
        out
    });
    pieces.concat()
}

/// The rule whose points [`constant_on`] tests (with the corners, midpoints and centroid): as fine
/// as the rules on T_h of the norms.
const CONSTANT_TEST: Quadrature = Quadrature { degree: 6 };

/// A piece's place with respect to the branches of the fields (where a value or a derivative may
/// jump), from the signs of their margins (`Program::eval_with_margins`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Kind {
    /// No branch between its points and corners: the rules' difference estimates the error.
    Smooth,
    /// A branch between a corner and the rules' points, which are all on one side: it clips a
    /// corner that the rules do not see.
    Corner,
    /// A branch between the rules' points.
    Straddle,
}

/// Room for evaluating the fields at the two rules' points (and the corners) of a block of pieces.
struct Evaluator<'a, const M: usize, D: Density<M>> {
    density: &'a D,
    program: Program,
    rules: [&'static [[f64; 3]]; 2],
    /// The steps where the fields branch: their margins are computed, at the corners too.
    branches: usize,
    xs: Vec<[f64; 2]>,
    /// The weight × |J| of each point (zero at the corners).
    weights: Vec<f64>,
    values: Vec<Vec<f64>>,
    margins: Vec<f64>,
    scratch: Vec<[f64; BLOCK]>,
}

impl<const M: usize, D: Density<M>> Clone for Evaluator<'_, M, D> {
    fn clone(&self) -> Self {
        Evaluator {
            program: self.program.clone(),
            values: vec![Vec::new(); self.values.len()],
            xs: Vec::new(),
            weights: Vec::new(),
            margins: Vec::new(),
            scratch: Vec::new(),
            ..*self
        }
    }
}

impl<'a, const M: usize, D: Density<M>> Evaluator<'a, M, D> {
    fn new(density: &'a D, rules: Rules) -> Self {
        let fields = density.fields();
        let program = Program::new(&fields);
        Evaluator {
            density,
            branches: program.branches(),
            program,
            rules: [rules.lo.rule(), rules.hi.rule()],
            xs: Vec::new(),
            weights: Vec::new(),
            values: vec![Vec::new(); fields.len()],
            margins: Vec::new(),
            scratch: Vec::new(),
        }
    }

    /// The points evaluated per piece: both rules', and the three corners where the fields branch.
    fn points_per_piece(&self) -> usize {
        self.rules[0].len() + self.rules[1].len() + if self.branches > 0 { 3 } else { 0 }
    }

    /// The estimates of `pieces`, in their order, in parallel (each thread with room of its own).
    fn all(&self, pieces: &[Piece]) -> Vec<Estimate<M>> {
        let parts = parallel::map_with(
            pieces.len(),
            PIECE,
            || self.clone(),
            |ev, r| ev.estimates(&pieces[r]),
        );
        parts.into_iter().flatten().collect()
    }

    /// The estimates of `pieces`, in their order.
    fn estimates(&mut self, pieces: &[Piece]) -> Vec<Estimate<M>> {
        let mut out = Vec::with_capacity(pieces.len());
        for block in pieces.chunks(CELLS_PER_BLOCK) {
            self.evaluate(block);
            let np = self.points_per_piece();
            out.extend(
                block
                    .iter()
                    .enumerate()
                    .map(|(k, piece)| self.estimate(piece, k * np)),
            );
        }
        out
    }

    /// The fields at both rules' points, and the corners where they branch, of every piece of
    /// `block`.
    fn evaluate(&mut self, block: &[Piece]) {
        self.xs.clear();
        self.weights.clear();
        for piece in block {
            let [p, q, r] = piece.corners;
            let jac = crate::mesh::orient(p, q, r).abs();
            for &[xi, eta, w] in self.rules.iter().flat_map(|rule| rule.iter()) {
                let l = [1.0 - xi - eta, xi, eta];
                self.xs
                    .push(std::array::from_fn(|d| l[0] * p[d] + l[1] * q[d] + l[2] * r[d]));
                self.weights.push(w * jac);
            }
            if self.branches > 0 {
                self.xs.extend(piece.corners);
                self.weights.extend([0.0; 3]);
            }
        }
        let n = self.xs.len();
        for v in &mut self.values {
            v.resize(n, 0.0);
        }
        let mut out: Vec<&mut [f64]> = self.values.iter_mut().map(|v| &mut v[..n]).collect();
        if self.branches > 0 {
            (self.program).eval_with_margins(&self.xs, &mut out, &mut self.scratch, &mut self.margins);
        } else {
            self.program.eval_with(&self.xs, &mut out, &mut self.scratch);
        }
    }

    /// Q_lo and Q_hi of the piece whose points start at `first`, and the estimate of Q_hi's error:
    /// |Q_hi − Q_lo| away from the branches; where one crosses, at least the piece's area times the
    /// range of the density over its points and corners.
    fn estimate(&self, piece: &Piece, first: usize) -> Estimate<M> {
        let local = self.density.local(piece.cell);
        let density = |k: usize| self.density.at(&local, self.xs[k], &self.values, k);
        let (lo_points, rule_points) = (self.rules[0].len(), self.rules[0].len() + self.rules[1].len());
        let sum = |points: std::ops::Range<usize>| {
            let mut q = [0.0; M];
            for k in points {
                let d = density(k);
                for m in 0..M {
                    q[m] += self.weights[k] * d[m];
                }
            }
            q
        };
        let [lo, hi] = [
            sum(first..first + lo_points),
            sum(first + lo_points..first + rule_points),
        ];
        let rules: [f64; M] = std::array::from_fn(|m| (hi[m] - lo[m]).abs());
        let points = first..first + self.points_per_piece();
        let kind = self.kind(first, rule_points);
        let mut error = rules;
        if kind != Kind::Smooth {
            let (mut low, mut high) = ([f64::INFINITY; M], [f64::NEG_INFINITY; M]);
            for d in points.map(density) {
                for m in 0..M {
                    // A corner may be a singular point of the fields (a corner of ω): not a jump.
                    if d[m].is_finite() {
                        (low[m], high[m]) = (low[m].min(d[m]), high[m].max(d[m]));
                    }
                }
            }
            error = std::array::from_fn(|m| rules[m].max(piece.area() * (high[m] - low[m])));
        }
        Estimate {
            piece: *piece,
            value: hi,
            error,
            rules,
            kind,
        }
    }

    /// Where the piece whose points start at `first` (its rules' `rule_points`, then its corners)
    /// lies from the branches, by the signs of their margins.
    fn kind(&self, first: usize, rule_points: usize) -> Kind {
        let j = self.branches;
        let sides = |points: std::ops::Range<usize>, step: usize| {
            let mut sides = points.map(|k| self.margins[k * j + step] < 0.0);
            let one = sides.next();
            sides.any(|s| Some(s) != one)
        };
        let end = first + self.points_per_piece();
        if (0..j).any(|step| sides(first..first + rule_points, step)) {
            Kind::Straddle
        } else if (0..j).any(|step| sides(first..end, step)) {
            Kind::Corner
        } else {
            Kind::Smooth
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// (f − c)² on the triangles of a unit square cut by its diagonal.
    struct Square {
        f: Expr,
    }

    impl Density<1> for Square {
        type Local = ();
        fn fields(&self) -> Vec<&Expr> {
            vec![&self.f]
        }
        fn local(&self, _: usize) {}
        fn at(&self, _: &(), _: [f64; 2], values: &[Vec<f64>], k: usize) -> [f64; 1] {
            [values[0][k] * values[0][k]]
        }
    }

    const CELLS: [[[f64; 2]; 3]; 2] = [
        [[0.0, 0.0], [1.0, 0.0], [1.0, 1.0]],
        [[0.0, 0.0], [1.0, 1.0], [0.0, 1.0]],
    ];

    fn square(source: &str, rules: Rules) -> Integral<1> {
        integrate(
            2,
            |t| CELLS[t],
            &Square {
                f: Expr::parse(source).unwrap(),
            },
            rules,
        )
    }

    /// ∫ f² over the two triangles by one rule.
    fn fixed_rule(source: &str, rule: Quadrature) -> f64 {
        let f = Expr::parse(source).unwrap();
        let mut sum = 0.0;
        rule.visit(
            |t| CELLS[t],
            0..2,
            [&f],
            |_, points, [f]| {
                sum += points.iter().zip(f).map(|(p, f)| p.weight * f * f).sum::<f64>();
            },
        );
        sum
    }

    const PAIR: Rules = Rules {
        lo: Quadrature { degree: 4 },
        hi: Quadrature { degree: 5 },
    };

    #[test]
    fn a_polynomial_the_rules_integrate_exactly() {
        // ∫ (x y)² over the unit square = 1/9, exact for degree 4 and 5: nothing is cut.
        let i = square("x*y", PAIR);
        assert!((i.value[0] - 1.0 / 9.0).abs() < 1e-15, "{:?}", i);
        assert!(i.error[0] < 1e-15);
    }

    #[test]
    fn a_jump_along_a_circle() {
        // ∫ χ_{r < 0.3}² = π 0.09 / 4 (a quarter disk), which no fixed rule integrates.
        let exact = std::f64::consts::PI * 0.09 / 4.0;
        let fixed = fixed_rule("if(x^2 + y^2 < 0.09, 1, 0)", PAIR.hi);
        assert!((fixed - exact).abs() > 1e-2 * exact, "{fixed}");
        let i = square("if(x^2 + y^2 < 0.09, 1, 0)", PAIR);
        let error = (i.value[0] - exact).abs();
        // The estimate bounds the error (pieces whose corners alone see the circle count their
        // area), and the value is far more accurate than that bound.
        assert!(
            error <= i.error[0] && i.error[0] <= 1e-3 * exact,
            "{error:e} {i:?}"
        );
        assert!(error <= 2.0 * RTOL * exact, "{error:e} {i:?}");
    }

    #[test]
    fn a_smooth_density_is_cut_where_the_rules_disagree() {
        // ∫ sin(8x)² cos(8y)² over the unit square, in closed form.
        let s = (16.0f64).sin() / 32.0;
        let exact = (0.5 - s) * (0.5 + s);
        let i = square("sin(8*x)*cos(8*y)", PAIR);
        let error = (i.value[0] - exact).abs();
        assert!(
            error <= i.error[0] && i.error[0] <= 2.0 * RTOL * exact,
            "{error:e} {i:?}"
        );
    }

    #[test]
    fn constants_are_found_where_a_branch_is_constant_and_only_there() {
        let mesh = crate::mesh::Mesh::rectangle([0.0, 0.0], [1.0, 1.0], 16, 16, crate::mesh::Diagonal::Right)
            .unwrap();
        let r2 = |p: [f64; 2]| (p[0] - 0.5).powi(2) + (p[1] - 0.5).powi(2);
        let of = |source: &str| {
            constant_on(
                mesh.n_triangles(),
                |t| mesh.corners(t),
                &Expr::parse(source).unwrap(),
            )
        };
        let quadratic = of("40*max(0.0625 - (x-0.5)^2 - (y-0.5)^2, 0)");
        let step = of("if((x-0.5)^2 + (y-0.5)^2 < 0.0625, 10, 0)");
        let (mut zero, mut ten) = (0, 0);
        for t in 0..mesh.n_triangles() {
            let r = mesh.corners(t).map(r2);
            let inside = r.iter().all(|&r| r < 0.0625);
            // A triangle whose corners are outside may still be crossed, one whose corner is on the
            // circle only touch it: only the others are sure.
            let crossed = r.iter().any(|&r| r < 0.0625) && r.iter().any(|&r| r > 0.0625);
            match (inside, crossed) {
                (true, _) => {
                    assert_eq!(quadratic[t], None, "{t}: λ is not a constant inside");
                    assert_eq!(step[t], Some(10.0), "{t}");
                    ten += 1;
                }
                (_, true) => assert!(quadratic[t].is_none() && step[t].is_none(), "{t}: crossed"),
                _ => zero += usize::from(quadratic[t] == Some(0.0) && step[t] == Some(0.0)),
            }
        }
        // The disk covers about 0.2 of the square's 512 triangles.
        assert!(ten > 50 && zero > 350, "{ten} inside, {zero} outside");
        assert!(of("x*y").iter().all(Option::is_none), "no polynomial is constant");
    }
}
