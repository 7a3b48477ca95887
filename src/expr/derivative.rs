//! Derivatives of an expression by forward differentiation of its steps: each step's derivative
//! is a few more steps on the values and derivatives of its operands (the chain rule), compiled
//! with the expression itself, so that a subexpression they share — sin(πx) in ψ and cos(πx) in
//! ∂ψ/∂x — is computed once per point. Exact up to round-off, unlike a difference quotient; where
//! the expression branches (`if`, `abs`, `min`, `max`, `sign`, `floor`) the derivative is that of
//! the branch taken: a kink or a jump contributes no Dirac mass.

use super::{Binary, Compare, Compiler, Expr, Program, Step, Unary};

/// A derivative: the step of its value, or `None` where it is structurally zero (so that no step
/// is spent on 0 · a, and no NaN of `log(a)` for a ≤ 0 is multiplied by zero).
type D = Option<u32>;

impl Expr {
    /// ψ, ∂ψ/∂x, ∂ψ/∂y, ∂²ψ/∂x² and ∂²ψ/∂y² of this expression ψ, compiled together (the
    /// outputs in that order).
    pub fn with_derivatives(&self) -> Program {
        let (mut c, value) = self.compiler();
        let second = |c: &mut Compiler, var: Step| {
            let first = differentiate(c, var, value);
            let second = first.and_then(|d| differentiate(c, var, d));
            (c.zero_or(first), second)
        };
        let (dx, dxx) = second(&mut c, Step::X);
        let (dy, dyy) = second(&mut c, Step::Y);
        let (dxx, dyy) = (c.zero_or(dxx), c.zero_or(dyy));
        Program::of(c.steps, vec![value, dx, dy, dxx, dyy])
    }

    /// ∂ψ/∂x and ∂ψ/∂y of this expression ψ, each an expression of its own.
    pub fn gradient(&self) -> [Expr; 2] {
        [Step::X, Step::Y].map(|var| {
            let (mut c, value) = self.compiler();
            let d = differentiate(&mut c, var, value);
            let d = c.zero_or(d);
            Expr {
                program: c.program_of(d),
            }
        })
    }

    /// A compiler holding this expression's steps, and the step of its value.
    fn compiler(&self) -> (Compiler, u32) {
        let mut c = Compiler::default();
        let at: Vec<u32> = self.program.steps.iter().fold(Vec::new(), |mut at, step| {
            at.push(c.add(step.map(|i| at[i as usize])));
            at
        });
        (c, at[self.program.outputs[0] as usize])
    }
}

/// The derivative along `var` (x or y) of the step `target`: the steps it depends on are
/// differentiated in order (operands come before the steps that use them), the others not.
fn differentiate(c: &mut Compiler, var: Step, target: u32) -> D {
    let n = target as usize + 1;
    let needed = c.cone(target);
    let mut d: Vec<D> = vec![None; n];
    for k in (0..n).filter(|&k| needed[k]) {
        let step = c.steps[k];
        let dk = match step {
            Step::X | Step::Y => (step == var).then(|| c.constant(1.0)),
            Step::Const(_) | Step::Compare(..) | Step::And(..) | Step::Or(..) => None,
            Step::Unary(f, a) => d[a as usize].and_then(|da| c.unary(f, k as u32, a, da)),
            Step::PowI(0, _) => None,
            Step::PowI(n, a) => d[a as usize].map(|da| {
                // (aⁿ)' = n aⁿ⁻¹ a'.
                let power = match n - 1 {
                    0 => None,
                    1 => Some(a),
                    m => Some(c.add(Step::PowI(m, a))),
                };
                let factor = c.times(power, n as f64);
                c.mul(factor, da)
            }),
            Step::Binary(f, a, b) => c.binary(f, k as u32, (a, d[a as usize]), (b, d[b as usize])),
            Step::Select(s, a, b) => c.select(s, d[a as usize], d[b as usize]),
        };
        d[k] = dk;
    }
    d[target as usize]
}

impl Compiler {
    /// Whether each step up to `target` is one `target` depends on (itself included).
    fn cone(&self, target: u32) -> Vec<bool> {
        let n = target as usize + 1;
        let mut needed = vec![false; n];
        needed[target as usize] = true;
        for k in (0..n).rev() {
            if needed[k] {
                self.steps[k].map(|i| {
                    needed[i as usize] = true;
                    i
                });
            }
        }
        needed
    }

    /// The program of the one output `output`, with only the steps it depends on.
    fn program_of(&self, output: u32) -> Program {
        let needed = self.cone(output);
        let mut kept = Compiler::default();
        let mut at = vec![0; needed.len()];
        for (k, _) in needed.iter().enumerate().filter(|(_, &n)| n) {
            at[k] = kept.add(self.steps[k].map(|i| at[i as usize]));
        }
        Program::of(kept.steps, vec![at[output as usize]])
    }

    fn constant(&mut self, v: f64) -> u32 {
        self.add(Step::Const(v.to_bits()))
    }

    /// The step of `d`, 0 for a structural zero.
    fn zero_or(&mut self, d: D) -> u32 {
        d.unwrap_or_else(|| self.constant(0.0))
    }

    fn mul(&mut self, a: u32, b: u32) -> u32 {
        let one = Step::Const(1f64.to_bits());
        match (self.steps[a as usize], self.steps[b as usize]) {
            (s, _) if s == one => b,
            (_, s) if s == one => a,
            _ => self.add(Step::Binary(Binary::Mul, a, b)),
        }
    }

    /// v · a, a = 1 for `None`.
    fn times(&mut self, a: Option<u32>, v: f64) -> u32 {
        let v = self.constant(v);
        a.map_or(v, |a| self.mul(v, a))
    }

    fn div(&mut self, a: u32, b: u32) -> u32 {
        self.add(Step::Binary(Binary::Div, a, b))
    }

    fn neg(&mut self, a: u32) -> u32 {
        self.add(Step::Unary(Unary::Neg, a))
    }

    fn sum(&mut self, a: D, b: D) -> D {
        match (a, b) {
            (Some(a), Some(b)) => Some(self.add(Step::Binary(Binary::Add, a, b))),
            (a, b) => a.or(b),
        }
    }

    fn difference(&mut self, a: D, b: D) -> D {
        match (a, b) {
            (Some(a), Some(b)) => Some(self.add(Step::Binary(Binary::Sub, a, b))),
            (a, None) => a,
            (None, Some(b)) => Some(self.neg(b)),
        }
    }

    /// (f(a))' = f'(a) a' for the step k = f(a), a' = `da`.
    fn unary(&mut self, f: Unary, k: u32, a: u32, da: u32) -> D {
        let one = self.constant(1.0);
        let derivative = match f {
            Unary::Neg => return Some(self.neg(da)),
            Unary::Sign | Unary::Floor => return None,
            // (√a)' = a' / (2√a), (log a)' = a'/a.
            Unary::Sqrt => {
                let two = self.times(Some(k), 2.0);
                return Some(self.div(da, two));
            }
            Unary::Log => return Some(self.div(da, a)),
            Unary::Exp => k,
            Unary::Sin => self.add(Step::Unary(Unary::Cos, a)),
            Unary::Cos => {
                let sin = self.add(Step::Unary(Unary::Sin, a));
                self.neg(sin)
            }
            // tan' = 1 + tan², tanh' = 1 − tanh², atan'(a) = 1/(1 + a²).
            Unary::Tan | Unary::Tanh => {
                let square = self.add(Step::PowI(2, k));
                let op = if f == Unary::Tan { Binary::Add } else { Binary::Sub };
                self.add(Step::Binary(op, one, square))
            }
            Unary::Atan => {
                let square = self.add(Step::PowI(2, a));
                let denominator = self.add(Step::Binary(Binary::Add, one, square));
                return Some(self.div(da, denominator));
            }
            Unary::Abs => self.add(Step::Unary(Unary::Sign, a)),
        };
        Some(self.mul(derivative, da))
    }

    /// The derivative of the step k = f(a, b), a' = `da`, b' = `db`.
    fn binary(&mut self, f: Binary, k: u32, (a, da): (u32, D), (b, db): (u32, D)) -> D {
        match f {
            Binary::Add => self.sum(da, db),
            Binary::Sub => self.difference(da, db),
            // (ab)' = a'b + ab'.
            Binary::Mul => {
                let left = da.map(|da| self.mul(da, b));
                let right = db.map(|db| self.mul(a, db));
                self.sum(left, right)
            }
            // (a/b)' = (a' − (a/b) b') / b.
            Binary::Div => {
                let right = db.map(|db| self.mul(k, db));
                let numerator = self.difference(da, right)?;
                Some(self.div(numerator, b))
            }
            Binary::Pow => self.power(k, (a, da), (b, db)),
            // min and max take one operand: its derivative. The one taken is the one the value
            // equals (k ≤ a and k ≥ a), which follows the value's own rule where the other is NaN.
            Binary::Min | Binary::Max => {
                let below = self.add(Step::Compare(Compare::Le, k, a));
                let above = self.add(Step::Compare(Compare::Ge, k, a));
                let first = self.add(Step::And(below, above));
                self.select(first, da, db)
            }
            // atan2(a, b)' = (b a' − a b') / (a² + b²).
            Binary::Atan2 => {
                let left = da.map(|da| self.mul(b, da));
                let right = db.map(|db| self.mul(a, db));
                let numerator = self.difference(left, right)?;
                let (a2, b2) = (self.add(Step::PowI(2, a)), self.add(Step::PowI(2, b)));
                let denominator = self.add(Step::Binary(Binary::Add, a2, b2));
                Some(self.div(numerator, denominator))
            }
        }
    }

    /// (a^b)' for the step k = a^b: b a^(b−1) a' + a^b log(a) b', each part only where its
    /// factor a' or b' is not zero (so that a constant exponent needs no log of a base ≤ 0).
    fn power(&mut self, k: u32, (a, da): (u32, D), (b, db): (u32, D)) -> D {
        let by_base = da.map(|da| {
            let one = self.constant(1.0);
            let exponent = self.add(Step::Binary(Binary::Sub, b, one));
            let power = self.add(Step::Binary(Binary::Pow, a, exponent));
            let factor = self.mul(b, power);
            self.mul(factor, da)
        });
        let by_exponent = db.map(|db| {
            let log = self.add(Step::Unary(Unary::Log, a));
            let factor = self.mul(k, log);
            self.mul(factor, db)
        });
        self.sum(by_base, by_exponent)
    }

    /// The derivative of select(s, a, b): that of the branch taken.
    fn select(&mut self, s: u32, da: D, db: D) -> D {
        if da.is_none() && db.is_none() {
            return None;
        }
        let (da, db) = (self.zero_or(da), self.zero_or(db));
        Some(self.add(Step::Select(s, da, db)))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// ψ, ∂ψ/∂x, ∂ψ/∂y, Δψ of `source` at (x, y).
    fn derivatives(source: &str, x: f64, y: f64) -> [f64; 4] {
        let program = Expr::parse(source).unwrap().with_derivatives();
        let mut out = [[0.0]; 5];
        let [a, b, c, d, e] = &mut out;
        program.eval_many(&[[x, y]], &mut [a, b, c, d, e]);
        let [[v], [dx], [dy], [dxx], [dyy]] = out;
        [v, dx, dy, dxx + dyy]
    }

    fn close(a: [f64; 4], b: [f64; 4], source: &str) {
        for (k, (a, b)) in a.iter().zip(b).enumerate() {
            assert!(
                (a - b).abs() <= 1e-12 * (1.0 + b.abs()),
                "{source}, output {k}: {a} vs {b}"
            );
        }
    }

    /// Each function of the language against its derivatives by hand (SymPy's `diff` gives the
    /// same expressions), at a point where none branches.
    #[test]
    fn every_function_has_its_derivatives() {
        let (x, y) = (0.3, 0.7);
        let cases: [(&str, [f64; 4]); 14] = [
            ("sin(pi*x)*sin(pi*y)", {
                let p = std::f64::consts::PI;
                let (sx, cx, sy, cy) = ((p * x).sin(), (p * x).cos(), (p * y).sin(), (p * y).cos());
                [sx * sy, p * cx * sy, p * sx * cy, -2.0 * p * p * sx * sy]
            }),
            (
                "x^3*y^2",
                [
                    x.powi(3) * y * y,
                    3.0 * x * x * y * y,
                    2.0 * x.powi(3) * y,
                    6.0 * x * y * y + 2.0 * x.powi(3),
                ],
            ),
            ("x/y", [x / y, 1.0 / y, -x / (y * y), 2.0 * x / y.powi(3)]),
            ("sqrt(x + y)", {
                let s = (x + y).sqrt();
                [s, 0.5 / s, 0.5 / s, 2.0 * (-0.25) / (s * s * s)]
            }),
            ("exp(x*y)", {
                let e = (x * y).exp();
                [e, y * e, x * e, (x * x + y * y) * e]
            }),
            ("log(x + 2*y)", {
                let s = x + 2.0 * y;
                [s.ln(), 1.0 / s, 2.0 / s, -5.0 / (s * s)]
            }),
            ("cos(x - y)", {
                let (s, c) = (x - y).sin_cos();
                [c, -s, s, -2.0 * c]
            }),
            ("tan(x)", {
                let t = x.tan();
                [t, 1.0 + t * t, 0.0, 2.0 * t * (1.0 + t * t)]
            }),
            (
                "atan(y)",
                [
                    y.atan(),
                    0.0,
                    1.0 / (1.0 + y * y),
                    -2.0 * y / (1.0 + y * y).powi(2),
                ],
            ),
            ("tanh(2*x)", {
                let t = (2.0 * x).tanh();
                [t, 2.0 * (1.0 - t * t), 0.0, -8.0 * t * (1.0 - t * t)]
            }),
            ("x^y", {
                let (p, l) = (x.powf(y), x.ln());
                [
                    p,
                    y * x.powf(y - 1.0),
                    p * l,
                    y * (y - 1.0) * x.powf(y - 2.0) + p * l * l,
                ]
            }),
            (
                "(-x)^2.0 + x^0.5",
                [
                    x * x + x.sqrt(),
                    2.0 * x + 0.5 / x.sqrt(),
                    0.0,
                    2.0 - 0.25 * x.powf(-1.5),
                ],
            ),
            ("atan2(y, x)", {
                let r2 = x * x + y * y;
                [y.atan2(x), -y / r2, x / r2, 0.0]
            }),
            ("abs(x - y) + min(x, y)^2 + max(x, 2*y) + sign(x) + floor(y)", {
                let v = (x - y).abs() + x * x + 2.0 * y + 1.0 + 0.0;
                [v, -1.0 + 2.0 * x, 1.0 + 2.0, 2.0]
            }),
        ];
        for (source, expected) in cases {
            close(derivatives(source, x, y), expected, source);
        }
    }

    /// The gradient as expressions of their own: the same values as `with_derivatives`', and only
    /// the steps each needs (∂/∂x of sin(πx) sin(πy) takes cos(πx), not sin(πx)).
    #[test]
    fn the_gradient_is_two_expressions_of_their_own() {
        let source = "sin(pi*x)*sin(pi*y) + x^3*y";
        let [dx, dy] = Expr::parse(source).unwrap().gradient();
        let (x, y) = (0.3, 0.7);
        let d = derivatives(source, x, y);
        assert_eq!([dx.eval(x, y), dy.eval(x, y)], [d[1], d[2]]);
        let sines = |e: &Expr| {
            let steps = e.program.steps.iter();
            steps
                .filter(|s| matches!(s, Step::Unary(Unary::Sin | Unary::Cos, _)))
                .count()
        };
        assert_eq!((sines(&dx), sines(&dy)), (2, 2));
    }

    /// An `if` differentiates branch by branch; a constant has no derivative steps.
    #[test]
    fn a_branch_has_the_derivatives_of_the_branch_taken() {
        let source = "if(x < 0.5 && y > 0, x^2, 3*y)";
        close(derivatives(source, 0.2, 0.4), [0.04, 0.4, 0.0, 2.0], source);
        close(derivatives(source, 0.7, 0.4), [1.2, 0.0, 3.0, 0.0], source);
        close(derivatives("2.5", 0.1, 0.2), [2.5, 0.0, 0.0, 0.0], "2.5");
    }

    /// A shared subexpression costs one step: sin(πx) sin(πy) and its derivatives take the steps
    /// of πx, πy, their sines and cosines, and a few products.
    #[test]
    fn the_derivatives_share_the_steps_of_the_expression() {
        let program = Expr::parse("sin(pi*x)*sin(pi*y)").unwrap().with_derivatives();
        let sines = (program.steps.iter())
            .filter(|s| matches!(s, Step::Unary(Unary::Sin | Unary::Cos, _)))
            .count();
        assert_eq!(sines, 4, "{:?}", program.steps);
    }
}
