//! Integrals of error integrands, cell by cell, with the rule chosen per cell: two rules of
//! neighbouring degrees on each cell, their difference |high − low| the cell's error indicator
//! and the higher one's value kept. In each piece of [`parallel::PIECE`] cells, the part with the
//! largest indicator is split in four (and its quarters ranked like the rest) as long as the
//! indicators add up to more than the piece's share (by area) of [`TOLERANCE`] × the integral.
//! Smooth integrands pass with a handful of points per cell; the cells cut by a layer, a kink, a
//! jump or at a singularity are refined, as deep as the error there needs, with the budget that
//! the smooth cells of the piece leave unused.
//!
//! The integral is estimated first on every seventh cell (and the whole pass done again
//! with the true value if that estimate was more than twice too large). The fields are evaluated
//! for a block of parts at a time ([`Expr::eval_many`]), the pieces in parallel and their sums
//! added in their order: the result does not depend on the thread count.

use crate::assembly::Quadrature;
use crate::expr::Expr;
use crate::mesh::orient;
use crate::parallel::{self, PIECE};
use std::collections::BinaryHeap;

/// The relative accuracy asked of each integral: Σ over the parts of |high − low| is at most
/// about this share of the integral (|high − low| bounds the lower rule's error; the value kept
/// is the higher rule's).
pub const TOLERANCE: f64 = 1e-7;

/// Splits of a part at most (a part of 4⁻¹² of its cell); past them the higher rule is kept.
const MAX_SPLITS: u32 = 12;

/// Splits of a piece at most: this many per cell of it, and at least [`SPLITS_AT_LEAST`]. Where
/// the integrand jumps along a curve (λ at the free boundary) no split meets the budget, and the
/// splits stop here, the higher rule kept (a piece's work is then at most about 17 times its
/// unsplit work).
const SPLITS_PER_CELL: usize = 4;
/// Splits of a piece at least (the few cells of a coarse mesh may need many to follow a layer).
const SPLITS_AT_LEAST: usize = 4096;

/// The integral is estimated on every SAMPLE-th cell first (a prime, so that it does not follow
/// the rows of a structured mesh).
const SAMPLE: usize = 7;

/// Cells whose points are evaluated together.
const BLOCK: usize = 16;

/// The degrees of the two rules of an integral.
#[derive(Debug, Clone, Copy)]
pub struct Rules {
    /// The rule that tells whether `high` is accurate on a cell.
    pub low: usize,
    /// The rule whose value is kept.
    pub high: usize,
}

/// ∫ over the union of `n` cells of an integrand depending on E exact fields: the cell c has the
/// corners `corners(c)`, and `integrand(c)` gives the integrand on it as a function of the
/// barycentric coordinates in c and of the fields' values there.
pub struct Integral<'a, const E: usize, C, I> {
    /// The number of cells.
    pub n: usize,
    /// The corners of a cell, counter-clockwise.
    pub corners: C,
    /// The exact fields the integrand reads.
    pub fields: [&'a Expr; E],
    /// The integrand on a cell.
    pub integrand: I,
    /// The rules.
    pub rules: Rules,
}

/// A triangle inside a cell: its corners and their barycentric coordinates in the cell, and how
/// many splits made it.
#[derive(Debug, Clone, Copy)]
struct Part {
    cell: usize,
    x: [[f64; 2]; 3],
    b: [[f64; 3]; 3],
    depth: u32,
}

impl Part {
    /// The four triangles of a split at the edge midpoints.
    fn split(&self) -> [Part; 4] {
        let mid = |i: usize, j: usize| {
            let x = [0, 1].map(|k| 0.5 * (self.x[i][k] + self.x[j][k]));
            let b = [0, 1, 2].map(|k| 0.5 * (self.b[i][k] + self.b[j][k]));
            (x, b)
        };
        let corner = |i: usize| (self.x[i], self.b[i]);
        let (m01, m12, m20) = (mid(0, 1), mid(1, 2), mid(2, 0));
        [
            [corner(0), m01, m20],
            [m01, corner(1), m12],
            [m20, m12, corner(2)],
            [m01, m12, m20],
        ]
        .map(|c| Part {
            cell: self.cell,
            x: c.map(|(x, _)| x),
            b: c.map(|(_, b)| b),
            depth: self.depth + 1,
        })
    }
}

/// A part with its higher rule's value and its indicator, ranked by the indicator.
#[derive(Debug, Clone, Copy)]
struct Ranked {
    gap: f64,
    high: f64,
    part: Part,
}

impl PartialEq for Ranked {
    fn eq(&self, other: &Self) -> bool {
        self.gap.total_cmp(&other.gap).is_eq()
    }
}

impl Eq for Ranked {}

impl PartialOrd for Ranked {
    fn partial_cmp(&self, other: &Self) -> Option<std::cmp::Ordering> {
        Some(self.cmp(other))
    }
}

impl Ord for Ranked {
    fn cmp(&self, other: &Self) -> std::cmp::Ordering {
        self.gap.total_cmp(&other.gap)
    }
}

impl<const E: usize, C, I, P> Integral<'_, E, C, I>
where
    C: Fn(usize) -> [[f64; 2]; 3] + Sync,
    I: Fn(usize) -> P + Sync,
    P: Fn([f64; 3], [f64; E]) -> f64,
{
    /// The integral, to [`TOLERANCE`] relative.
    pub fn value(&self) -> f64 {
        let area = parallel::sum(self.n, PIECE, |cells| {
            cells.map(|c| area(&(self.corners)(c))).sum()
        });
        if area <= 0.0 {
            return 0.0;
        }
        let stride = if self.n >= 64 * SAMPLE { SAMPLE } else { 1 };
        let sampled = parallel::sum(self.n.div_ceil(stride), PIECE, |k| {
            self.once(k.map(|k| k * stride))
        });
        let estimate = (stride as f64 * sampled).abs();
        let total = self.refined(TOLERANCE * estimate / area);
        if estimate > 2.0 * total.abs() {
            return self.refined(TOLERANCE * total.abs() / area);
        }
        total
    }

    /// The sum over all cells, the indicators of each piece brought to `per_area` × its area.
    fn refined(&self, per_area: f64) -> f64 {
        parallel::sum(self.n, PIECE, |cells| self.piece(cells, per_area))
    }

    /// The sum over one piece of cells: the part with the largest indicator split while the
    /// indicators add up to more than `per_area` × the piece's area.
    fn piece(&self, cells: std::ops::Range<usize>, per_area: f64) -> f64 {
        let parts: Vec<Part> = cells.map(|c| self.whole(c)).collect();
        let budget = per_area * parts.iter().map(|p| area(&p.x)).sum::<f64>();
        let mut queue = BinaryHeap::with_capacity(parts.len());
        let mut open = 0.0;
        for block in parts.chunks(BLOCK) {
            open += self.rank(block, &mut queue);
        }
        let (mut kept, mut splits) = (0.0, (SPLITS_PER_CELL * parts.len()).max(SPLITS_AT_LEAST));
        // NaN stops the splitting (and is reported by the caller).
        while open > budget && splits > 0 {
            splits -= 1;
            match queue.peek() {
                // The running sum is rounded: the largest indicator bounds what is left.
                Some(worst) if worst.gap * queue.len() as f64 > budget => {}
                _ => break,
            }
            let worst = queue.pop().expect("a part");
            open -= worst.gap;
            if worst.part.depth == MAX_SPLITS {
                kept += worst.high;
            } else {
                open += self.rank(&worst.part.split(), &mut queue);
            }
        }
        kept + queue.iter().map(|r| r.high).sum::<f64>()
    }

    /// The higher rule's sum over the `cells`, unrefined.
    fn once(&self, cells: impl Iterator<Item = usize>) -> f64 {
        let parts: Vec<Part> = cells.map(|c| self.whole(c)).collect();
        parts
            .chunks(BLOCK)
            .flat_map(|block| self.both(block))
            .map(|(high, _)| high)
            .sum()
    }

    /// Cell c as a part.
    fn whole(&self, c: usize) -> Part {
        Part {
            cell: c,
            x: (self.corners)(c),
            b: [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
            depth: 0,
        }
    }

    /// Evaluates the `parts` and ranks them into `queue`; returns the sum of their indicators.
    fn rank(&self, parts: &[Part], queue: &mut BinaryHeap<Ranked>) -> f64 {
        let mut gaps = 0.0;
        for (part, (high, low)) in parts.iter().zip(self.both(parts)) {
            let gap = (high - low).abs();
            gaps += gap;
            queue.push(Ranked {
                gap,
                high,
                part: *part,
            });
        }
        gaps
    }

    /// (high rule, low rule) on each part.
    fn both(&self, parts: &[Part]) -> Vec<(f64, f64)> {
        let rules = [self.rules.high, self.rules.low].map(|d| Quadrature { degree: d }.rule());
        let per_part = rules[0].len() + rules[1].len();
        let mut xs = Vec::with_capacity(parts.len() * per_part);
        let mut at = Vec::with_capacity(parts.len() * per_part);
        for p in parts {
            let jac = orient(p.x[0], p.x[1], p.x[2]);
            for &[xi, eta, w] in rules.iter().copied().flatten() {
                let l = [1.0 - xi - eta, xi, eta];
                let point = |v: &[[f64; 2]; 3], k: usize| (0..3).map(|j| l[j] * v[j][k]).sum::<f64>();
                xs.push([point(&p.x, 0), point(&p.x, 1)]);
                let b = [0, 1, 2].map(|k| (0..3).map(|j| l[j] * p.b[j][k]).sum::<f64>());
                at.push((b, w * jac));
            }
        }
        let values: [Vec<f64>; E] = self.fields.map(|f| {
            let mut v = vec![0.0; xs.len()];
            f.eval_many(&xs, &mut v);
            v
        });
        let mut q = 0;
        let mut out = Vec::with_capacity(parts.len());
        for p in parts {
            let g = (self.integrand)(p.cell);
            let mut rule_sum = |len: usize| {
                let mut s = 0.0;
                for _ in 0..len {
                    s += at[q].1 * g(at[q].0, std::array::from_fn(|e| values[e][q]));
                    q += 1;
                }
                s
            };
            let high = rule_sum(rules[0].len());
            out.push((high, rule_sum(rules[1].len())));
        }
        out
    }
}

/// The area of a counter-clockwise triangle.
fn area(x: &[[f64; 2]; 3]) -> f64 {
    0.5 * orient(x[0], x[1], x[2])
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::assembly::gradients;
    use crate::mesh::{Diagonal, DualMesh, Edges, Mesh};

    fn square(n: usize) -> Mesh {
        Mesh::rectangle([0.0, 0.0], [1.0, 1.0], n, n, Diagonal::Right).unwrap()
    }

    /// ∫_K f by the degree-20 rule on each of the 4^k triangles of K split k times, f given the
    /// point: no cell of it is chosen by the code under test.
    fn fine(k: [[f64; 2]; 3], splits: u32, f: &impl Fn([f64; 2]) -> f64) -> f64 {
        if splits > 0 {
            let m = |i: usize, j: usize| [0.5 * (k[i][0] + k[j][0]), 0.5 * (k[i][1] + k[j][1])];
            let (a, b, c) = (m(0, 1), m(1, 2), m(2, 0));
            return [[k[0], a, c], [a, k[1], b], [c, b, k[2]], [a, b, c]]
                .iter()
                .map(|t| fine(*t, splits - 1, f))
                .sum();
        }
        let jac = orient(k[0], k[1], k[2]);
        let at = |l: [f64; 3], i: usize| l[0] * k[0][i] + l[1] * k[1][i] + l[2] * k[2][i];
        (Quadrature { degree: 20 }.rule().iter())
            .map(|&[xi, eta, w]| {
                let l = [1.0 - xi - eta, xi, eta];
                w * jac * f([at(l, 0), at(l, 1)])
            })
            .sum()
    }

    /// The P1 interpolant of `u` on `mesh` at the point x of triangle t.
    fn interpolant(mesh: &Mesh, u: &Expr, t: usize, x: [f64; 2]) -> f64 {
        let [p, q, r] = mesh.corners(t);
        let (b1, b2) = (
            orient(p, x, r) / orient(p, q, r),
            orient(p, q, x) / orient(p, q, r),
        );
        let v = mesh.corners(t).map(|c| u.eval(c[0], c[1]));
        (1.0 - b1 - b2) * v[0] + b1 * v[1] + b2 * v[2]
    }

    /// ‖u − I_h u‖²_L² adaptively and by the fine rule (4³ pieces per triangle).
    fn l2_interpolation_error(mesh: &Mesh, u: &Expr) -> (f64, f64) {
        let adaptive = Integral {
            n: mesh.n_triangles(),
            corners: |t| mesh.corners(t),
            fields: [u],
            integrand: |t| {
                let v = mesh.corners(t).map(|c| u.eval(c[0], c[1]));
                move |b: [f64; 3], [u]: [f64; 1]| (u - b[0] * v[0] - b[1] * v[1] - b[2] * v[2]).powi(2)
            },
            rules: Rules { low: 5, high: 6 },
        }
        .value();
        let reference = (0..mesh.n_triangles())
            .map(|t| {
                fine(mesh.corners(t), 3, &|x| {
                    (u.eval(x[0], x[1]) - interpolant(mesh, u, t, x)).powi(2)
                })
            })
            .sum();
        (adaptive, reference)
    }

    /// |u − I_h u|²_H¹ adaptively and by the fine rule.
    fn h1_interpolation_error(mesh: &Mesh, u: &Expr, grad: [&Expr; 2]) -> (f64, f64) {
        let slope = |t: usize| {
            let g = gradients(mesh.corners(t));
            let v = mesh.corners(t).map(|c| u.eval(c[0], c[1]));
            [0, 1].map(|k| (0..3).map(|i| g[i][k] * v[i]).sum::<f64>())
        };
        let adaptive = Integral {
            n: mesh.n_triangles(),
            corners: |t| mesh.corners(t),
            fields: grad,
            integrand: |t| {
                let s = slope(t);
                move |_: [f64; 3], [gx, gy]: [f64; 2]| (gx - s[0]).powi(2) + (gy - s[1]).powi(2)
            },
            rules: Rules { low: 4, high: 5 },
        }
        .value();
        let reference = (0..mesh.n_triangles())
            .map(|t| {
                let s = slope(t);
                fine(mesh.corners(t), 3, &|x| {
                    (grad[0].eval(x[0], x[1]) - s[0]).powi(2) + (grad[1].eval(x[0], x[1]) - s[1]).powi(2)
                })
            })
            .sum();
        (adaptive, reference)
    }

    /// Within ten times the indicators' budget: a kink between a rule's points escapes them.
    fn close(what: &str, (value, reference): (f64, f64)) {
        let relative = (value - reference).abs() / reference;
        assert!(
            relative <= 10.0 * TOLERANCE,
            "{what}: {value:e} against {reference:e}: {relative:.1e}"
        );
    }

    #[test]
    fn smooth_and_layered_errors_are_integrated_as_by_a_much_finer_rule() {
        let e = |s: &str| Expr::parse(s).unwrap();
        for n in [8, 16] {
            let mesh = square(n);
            let smooth = e("exp(x)*sin(3*y)");
            close("smooth L2", l2_interpolation_error(&mesh, &smooth));
            let grad = [e("exp(x)*sin(3*y)"), e("3*exp(x)*cos(3*y)")];
            close(
                "smooth H1",
                h1_interpolation_error(&mesh, &smooth, [&grad[0], &grad[1]]),
            );
            // A layer of width 1/50, thinner than the cells, across the mesh's diagonals.
            let layer = e("tanh((x + 0.3*y - 0.61)/0.02)");
            close("layer L2", l2_interpolation_error(&mesh, &layer));
            let sech2 = "(1 - tanh((x + 0.3*y - 0.61)/0.02)^2)";
            let grad = [e(&format!("50*{sech2}")), e(&format!("15*{sech2}"))];
            close(
                "layer H1",
                h1_interpolation_error(&mesh, &layer, [&grad[0], &grad[1]]),
            );
        }
    }

    #[test]
    fn a_kink_and_a_jump_of_the_gradient_are_integrated_to_the_closed_forms() {
        let mesh = square(16);
        let e = |s: &str| Expr::parse(s).unwrap();
        // u = max(x − 0.37, 0) y, ∇u = (H(x − 0.37) y, max(x − 0.37, 0)): u² has a jump of its second
        // derivative, |∇u|² a jump; ∫u² = 0.63³/9 and ∫|∇u|² = 0.63/3 + 0.63³/3 on the unit square.
        let cube = 0.63f64.powi(3);
        let integral = |fields: [&Expr; 2], rules| {
            Integral {
                n: mesh.n_triangles(),
                corners: |t| mesh.corners(t),
                fields,
                integrand: |_| |_: [f64; 3], [a, b]: [f64; 2]| a * a + b * b,
                rules,
            }
            .value()
        };
        let (zero, u) = (e("0"), e("max(x - 0.37, 0)*y"));
        close(
            "kink",
            (integral([&u, &zero], Rules { low: 5, high: 6 }), cube / 9.0),
        );
        let grad = [e("if(x > 0.37, y, 0)"), e("max(x - 0.37, 0)")];
        // A jump of the integrand is seen only where a rule's points straddle it: a sliver between
        // the points and an edge stays unseen, so it is integrated to 5e-4 (1e-3 without splits).
        let jump = integral([&grad[0], &grad[1]], Rules { low: 4, high: 5 });
        let exact = 0.63 / 3.0 + cube / 3.0;
        assert!(
            (jump - exact).abs() <= 5e-4 * exact,
            "gradient jump: {jump:e} against {exact:e}"
        );
        // λ = 40 max(1/16 − r², 0) on the cells of S_h: ∫λ² = 1600 π/(3 · 16³).
        let edges = Edges::new(&mesh);
        let dual = DualMesh::new(&mesh, &edges);
        let lambda = e("40*max(0.0625 - (x-0.5)^2 - (y-0.5)^2, 0)");
        let on_dual = Integral {
            n: dual.n_cells(),
            corners: |s| dual.corners(s),
            fields: [&lambda],
            integrand: |_| |_: [f64; 3], [l]: [f64; 1]| l * l,
            rules: Rules { low: 4, high: 5 },
        };
        close(
            "λ",
            (on_dual.value(), 1600.0 * std::f64::consts::PI / (3.0 * 4096.0)),
        );
    }

    #[test]
    fn the_integral_does_not_depend_on_the_thread_count() {
        let mesh = square(64);
        let u = Expr::parse("tanh((x - 0.4)/0.01)*y").unwrap();
        let value = |threads| {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap();
            pool.install(|| l2_interpolation_error(&mesh, &u).0)
        };
        let one = value(1);
        assert_eq!(value(3).to_bits(), one.to_bits());
    }
}
