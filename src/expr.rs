//! The case-file expression language: data f1, f2, g and exact solutions as functions of (x, y).
//!
//! Grammar (documented for users in `data/cases/README.md`; `reference/expr.py` mirrors it, and
//! `tests/expressions.rs` checks both against random expressions evaluated independently):
//!
//! ```text
//! expr  := or
//! or    := and ("||" and)*          -- boolean
//! and   := cmp ("&&" cmp)*          -- boolean
//! cmp   := sum [("<"|"<="|">"|">=") sum]
//! sum   := prod (("+"|"-") prod)*
//! prod  := unary (("*"|"/") unary)*
//! unary := ("-"|"+") unary | power
//! power := atom ["^" unary]         -- right-associative, -x^2 = -(x^2)
//! atom  := number | x | y | pi | e | name | function "(" args ")" | "(" expr ")"
//! ```
//!
//! Every level may hold a condition (a comparison, or conditions joined by && and ||), but a
//! condition is allowed only as the first argument of `if`, as an operand of && and ||, and in
//! parentheses around those: `if((x < 0.5 || y < 0.5) && x > 0.2, 1, 0)`.
//!
//! Functions: sqrt, exp, log (natural), sin, cos, tan, atan, tanh, abs, sign, floor (one
//! argument), min, max, atan2(y, x) (two), and the piecewise form `if(condition, a, b)`. A `name`
//! is one of the case's named values ([`Names`], the `[let]` table). All arithmetic is in f64:
//! `1/2` is 0.5.
//!
//! The language is this small on purpose: the Python reference must evaluate it identically (as UFL
//! at quadrature points and as NumPy at vertices), which rules out general-purpose evaluators whose
//! semantics differ (integer division, base-10 `log`, implicit variable ordering).

use std::fmt;
use std::ops::Range;

mod derivative;
mod vector;
use vector::Function;

/// A parse or type error, with the byte offset where it was found.
#[derive(Debug, Clone, PartialEq)]
pub struct ExprError {
    /// The character where it was found.
    pub position: usize,
    /// What is wrong.
    pub message: String,
}

impl fmt::Display for ExprError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{} (at character {})", self.message, self.position + 1)
    }
}

impl std::error::Error for ExprError {}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
enum Unary {
    Neg,
    Sqrt,
    Exp,
    Log,
    Sin,
    Cos,
    Tan,
    Atan,
    Tanh,
    Abs,
    Sign,
    Floor,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
enum Binary {
    Add,
    Sub,
    Mul,
    Div,
    Pow,
    Min,
    Max,
    Atan2,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
enum Compare {
    Lt,
    Le,
    Gt,
    Ge,
}

/// A numeric expression tree.
#[derive(Debug, Clone, PartialEq)]
enum Num {
    Const(f64),
    X,
    Y,
    Unary(Unary, Box<Num>),
    Binary(Binary, Box<Num>, Box<Num>),
    If(Box<Cond>, Box<Num>, Box<Num>),
}

/// A boolean expression tree (only inside `if`).
#[derive(Debug, Clone, PartialEq)]
enum Cond {
    Compare(Compare, Num, Num),
    And(Box<Cond>, Box<Cond>),
    Or(Box<Cond>, Box<Cond>),
}

/// A parsed expression of (x, y), compiled to a [`Program`] for fast evaluation.
#[derive(Debug, Clone, PartialEq)]
pub struct Expr {
    program: Program,
}

/// Expressions compiled together to one list of distinct steps, each step an operation on the
/// values of earlier ones (value numbering): a subexpression they share — sin(πx) in u and in
/// ∂u/∂x, (x − 1/2)² in each term of a load — is computed once per point. Each expression's
/// values are those it has alone, bit for bit: the same operations on the same operands.
#[derive(Debug, Clone, PartialEq)]
pub struct Program {
    steps: Vec<Step>,
    /// The step of each expression's value.
    outputs: Vec<u32>,
    /// Per step, whether it is computed with another: sin(a) and cos(a) of one operand share
    /// their argument reduction where the scalar functions are used (the values are those of each
    /// alone, bit for bit).
    fused: Vec<Fused>,
    /// The steps that branch ([`Step::branches`]), in order.
    branching: Vec<Step>,
}

/// A step's part in a pair computed together.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Fused {
    Alone,
    /// The first of sin(a), cos(a): it computes the later one, the step given, too.
    First(u32),
    /// The later one, already computed.
    Done,
}

/// One step of a [`Program`], on the values of earlier steps (conditions are 1.0 / 0.0).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
enum Step {
    /// A constant, by its bits (so that steps can be compared and hashed).
    Const(u64),
    X,
    Y,
    Unary(Unary, u32),
    Binary(Binary, u32, u32),
    /// a^k for a constant integer exponent k.
    PowI(i32, u32),
    Compare(Compare, u32, u32),
    And(u32, u32),
    Or(u32, u32),
    /// c, a, b → a where c ≠ 0, else b (both branches are evaluated: floats do not trap, and the
    /// program stays straight-line, so that it runs over blocks of points).
    Select(u32, u32, u32),
}

/// Longest accepted expression, in tokens, and the deepest nesting of parentheses, signs and
/// function calls.
const MAX_TOKENS: usize = 10_000;
const MAX_NESTING: usize = 32;
/// Points per block of [`Program::eval_many`].
pub const BLOCK: usize = 64;
/// Steps of a program evaluated at one point with room on the call stack.
const SMALL: usize = 256;

impl Step {
    /// The same operation on the operands `id(i)`.
    fn map(self, mut id: impl FnMut(u32) -> u32) -> Step {
        match self {
            Step::Const(_) | Step::X | Step::Y => self,
            Step::Unary(f, a) => Step::Unary(f, id(a)),
            Step::Binary(f, a, b) => Step::Binary(f, id(a), id(b)),
            Step::PowI(k, a) => Step::PowI(k, id(a)),
            Step::Compare(f, a, b) => Step::Compare(f, id(a), id(b)),
            Step::And(a, b) => Step::And(id(a), id(b)),
            Step::Or(a, b) => Step::Or(id(a), id(b)),
            Step::Select(s, a, b) => Step::Select(id(s), id(a), id(b)),
        }
    }

    /// Whether the step branches: its value, or its derivative, can jump where its operands'
    /// do not (a comparison, `sign`, `floor`; `abs`, `min`, `max`).
    fn branches(&self) -> bool {
        match self {
            Step::Compare(..) => true,
            Step::Unary(f, _) => matches!(f, Unary::Sign | Unary::Floor | Unary::Abs),
            Step::Binary(f, _, _) => matches!(f, Binary::Min | Binary::Max),
            _ => false,
        }
    }
}

fn truth(b: bool) -> f64 {
    f64::from(u8::from(b))
}

impl Expr {
    /// Parses `source`; the error names the offending token and its position.
    pub fn parse(source: &str) -> Result<Self, ExprError> {
        Self::parse_with(source, &Names::default())
    }

    /// Parses `source`, which may use `names` (substituted here, so evaluation costs the same).
    pub fn parse_with(source: &str, names: &Names) -> Result<Self, ExprError> {
        let root = parse_tree(source, names, &[])?;
        let mut c = Compiler::default();
        let output = c.num(&root);
        Ok(Expr {
            program: Program::of(c.steps, vec![output]),
        })
    }

    /// The value at the point (x, y).
    pub fn eval(&self, x: f64, y: f64) -> f64 {
        let mut out = [0.0];
        self.program.eval_many(&[[x, y]], &mut [&mut out[..]]);
        out[0]
    }

    /// The values at `points`, into `out` (see [`Program::eval_many`]).
    pub fn eval_many(&self, points: &[[f64; 2]], out: &mut [f64]) {
        self.program.eval_many(points, &mut [out]);
    }

    /// The values at `points`, by blocks in parallel (as [`Expr::eval_many`], bit for bit).
    pub fn values_at(&self, points: &[[f64; 2]]) -> Vec<f64> {
        let size = crate::parallel::PIECE;
        if points.len() <= size {
            let mut values = vec![0.0; points.len()];
            self.eval_many(points, &mut values);
            return values;
        }
        crate::parallel::collect_by_blocks(points.len(), size, |range, values| {
            values.resize(range.len(), 0.0);
            self.eval_many(&points[range], values);
        })
    }

    /// The value, if the expression does not read x or y.
    pub fn constant(&self) -> Option<f64> {
        let reads_xy = (self.program.steps.iter()).any(|s| matches!(s, Step::X | Step::Y));
        (!reads_xy).then(|| self.eval(0.0, 0.0))
    }
}

impl Program {
    /// The expressions `exprs` compiled together, their shared steps once.
    pub fn new(exprs: &[&Expr]) -> Program {
        let mut c = Compiler::default();
        let outputs = (exprs.iter())
            .map(|e| {
                let p = &e.program;
                let mut at = Vec::with_capacity(p.steps.len());
                for step in &p.steps {
                    let step = step.map(|i| at[i as usize]);
                    at.push(c.add(step));
                }
                at[p.outputs[0] as usize]
            })
            .collect();
        Program::of(c.steps, outputs)
    }

    /// The program of `steps` with these `outputs`, each sin(a) paired with a cos(a).
    fn of(steps: Vec<Step>, outputs: Vec<u32>) -> Program {
        let mut fused = vec![Fused::Alone; steps.len()];
        let mut first = std::collections::HashMap::new();
        for (k, step) in steps.iter().enumerate() {
            if let Step::Unary(f @ (Unary::Sin | Unary::Cos), a) = *step {
                match first.get(&a) {
                    Some(&(i, g)) if g != f => (fused[i], fused[k]) = (Fused::First(k as u32), Fused::Done),
                    _ => _ = first.insert(a, (k, f)),
                }
            }
        }
        let branching = steps.iter().copied().filter(Step::branches).collect();
        Program {
            steps,
            outputs,
            fused,
            branching,
        }
    }

    /// The values of the expressions at `points`, into `out` (one slice per expression, as
    /// long as `points`): the steps run once per block of [`BLOCK`] points, each over the whole
    /// block.
    pub fn eval_many(&self, points: &[[f64; 2]], out: &mut [&mut [f64]]) {
        if points.len() == 1 && self.steps.len() <= SMALL {
            let mut values = [[0.0; 1]; SMALL];
            self.run(points, &mut values);
            self.copy_out(&values, out, 0..1);
            return;
        }
        if self.steps.len() > SMALL {
            return self.eval_with(points, out, &mut Vec::new());
        }
        // The steps' values of a small program in room the thread keeps: a caller that evaluates
        // a few points at a time (a cell's rule) neither allocates nor clears it each time.
        thread_local! {
            static ROOM: std::cell::RefCell<Vec<[f64; BLOCK]>> = const { std::cell::RefCell::new(Vec::new()) };
        }
        ROOM.with_borrow_mut(|values| self.eval_with(points, out, values));
    }

    /// As [`Program::eval_many`], the steps' values in `values` (room kept by a caller that
    /// evaluates many batches).
    pub(crate) fn eval_with(
        &self,
        points: &[[f64; 2]],
        out: &mut [&mut [f64]],
        values: &mut Vec<[f64; BLOCK]>,
    ) {
        self.by_blocks(points, out, values, |_, _| {});
    }

    /// The steps run on each block of [`BLOCK`] points, the outputs copied out, then `each` with
    /// the steps' values and the block's number of points.
    fn by_blocks(
        &self,
        points: &[[f64; 2]],
        out: &mut [&mut [f64]],
        values: &mut Vec<[f64; BLOCK]>,
        mut each: impl FnMut(&[[f64; BLOCK]], usize),
    ) {
        // Grown, never shrunk: room kept for a larger program is not cleared again.
        if values.len() < self.steps.len() {
            values.resize(self.steps.len(), [0.0; BLOCK]);
        }
        for (k, points) in points.chunks(BLOCK).enumerate() {
            self.run(points, values);
            self.copy_out(values, out, k * BLOCK..k * BLOCK + points.len());
            each(values, points.len());
        }
    }

    /// As [`Program::eval_with`], and in `margins`, point after point, the margin of each step
    /// that branches (in the steps' order): a − b of a comparison a ⋚ b (of `if`, `and`, `or`) and
    /// of `min(a, b)`, `max(a, b)`; x of `sign(x)` and `abs(x)`; x − round(x) of `floor(x)`. The
    /// expressions are smooth between points whose margins have the same signs; where a margin
    /// changes sign, a value or a derivative may jump between them.
    pub(crate) fn eval_with_margins(
        &self,
        points: &[[f64; 2]],
        out: &mut [&mut [f64]],
        values: &mut Vec<[f64; BLOCK]>,
        margins: &mut Vec<f64>,
    ) {
        let j = self.branching.len();
        margins.clear();
        self.by_blocks(points, out, values, |values, n| {
            let base = margins.len();
            margins.resize(base + n * j, 0.0);
            for (at, step) in self.branching.iter().enumerate() {
                let v = |s: u32| &values[s as usize][..n];
                let slots = margins[base + at..].iter_mut().step_by(j);
                match *step {
                    Step::Compare(_, a, b) | Step::Binary(_, a, b) => slots
                        .zip(v(a).iter().zip(v(b)))
                        .for_each(|(m, (a, b))| *m = a - b),
                    Step::Unary(Unary::Floor, a) => slots.zip(v(a)).for_each(|(m, a)| *m = a - a.round()),
                    Step::Unary(_, a) => slots.zip(v(a)).for_each(|(m, a)| *m = *a),
                    _ => unreachable!("only the steps that branch"),
                }
            }
        });
    }

    /// The number of steps that branch (the margins of each point).
    pub(crate) fn branches(&self) -> usize {
        self.branching.len()
    }

    /// The outputs' values of a block into `out[..][range]`.
    fn copy_out<const B: usize>(&self, values: &[[f64; B]], out: &mut [&mut [f64]], range: Range<usize>) {
        for (out, &o) in out.iter_mut().zip(&self.outputs) {
            out[range.clone()].copy_from_slice(&values[o as usize][..range.len()]);
        }
    }

    /// Runs the steps on up to B points at once, each step's values into its slot of `values`:
    /// compiled for AVX2 too, and run so where the processor has it (the same values: the
    /// operations are IEEE's, on more lanes at a time).
    fn run<const B: usize>(&self, points: &[[f64; 2]], values: &mut [[f64; B]]) {
        #[cfg(target_arch = "x86_64")]
        if std::arch::is_x86_feature_detected!("avx2") {
            // SAFETY: the processor has AVX2.
            return unsafe { self.run_avx2(points, values) };
        }
        self.steps_on(points, values)
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    unsafe fn run_avx2<const B: usize>(&self, points: &[[f64; 2]], values: &mut [[f64; B]]) {
        self.steps_on(points, values)
    }

    #[inline(always)]
    fn steps_on<const B: usize>(&self, points: &[[f64; 2]], values: &mut [[f64; B]]) {
        let m = points.len();
        for (k, step) in self.steps.iter().enumerate() {
            match self.fused[k] {
                Fused::Alone => {}
                Fused::First(j) => {
                    self.sin_cos(k, j as usize, m, values);
                    continue;
                }
                Fused::Done => continue,
            }
            let (before, slot) = values.split_at_mut(k);
            let (s, at) = (&mut slot[0][..m], |i: u32| &before[i as usize][..m]);
            match *step {
                Step::Const(c) => s.fill(f64::from_bits(c)),
                Step::X | Step::Y => {
                    let k = usize::from(matches!(step, Step::Y));
                    s.iter_mut().zip(points).for_each(|(s, p)| *s = p[k]);
                }
                Step::Unary(f, a) => {
                    let a = at(a);
                    match f {
                        Unary::Neg => map1(s, a, |a| -a),
                        Unary::Sqrt => map1(s, a, f64::sqrt),
                        Unary::Exp => vector::apply(Function::Exp, a, s),
                        Unary::Log => vector::apply(Function::Log, a, s),
                        Unary::Sin => vector::apply(Function::Sin, a, s),
                        Unary::Cos => vector::apply(Function::Cos, a, s),
                        Unary::Tan => map1(s, a, f64::tan),
                        Unary::Atan => map1(s, a, f64::atan),
                        Unary::Tanh => map1(s, a, f64::tanh),
                        Unary::Abs => map1(s, a, f64::abs),
                        Unary::Sign => map1(s, a, sign),
                        Unary::Floor => map1(s, a, f64::floor),
                    }
                }
                Step::PowI(2, a) => map1(s, at(a), |a| a * a),
                Step::PowI(k, a) => map1(s, at(a), |a| a.powi(k)),
                Step::Binary(f, a, b) => {
                    let (a, b) = (at(a), at(b));
                    match f {
                        Binary::Add => map2(s, a, b, |a, b| a + b),
                        Binary::Sub => map2(s, a, b, |a, b| a - b),
                        Binary::Mul => map2(s, a, b, |a, b| a * b),
                        Binary::Div => map2(s, a, b, |a, b| a / b),
                        Binary::Pow => vector::pow(a, b, s),
                        Binary::Min => map2(s, a, b, min),
                        Binary::Max => map2(s, a, b, max),
                        // In (−π, π] as documented: C's atan2(−0, x < 0) is −π (y + 0 is +0 at ±0).
                        Binary::Atan2 => map2(s, a, b, |y, x| (y + 0.0).atan2(x)),
                    }
                }
                Step::Compare(f, a, b) => map2(s, at(a), at(b), |a, b| truth(compare(f, a, b))),
                Step::And(a, b) => map2(s, at(a), at(b), |a, b| truth(a != 0.0 && b != 0.0)),
                Step::Or(a, b) => map2(s, at(a), at(b), |a, b| truth(a != 0.0 || b != 0.0)),
                Step::Select(c, a, b) => {
                    let (c, a, b) = (at(c), at(a), at(b));
                    for i in 0..m {
                        s[i] = if c[i] != 0.0 { a[i] } else { b[i] };
                    }
                }
            }
        }
    }
}

impl Program {
    /// Steps k < j, sin(a) and cos(a) in either order, on the first m points: in one pass by the
    /// scalar functions, each by libmvec where it is used.
    fn sin_cos<const B: usize>(&self, k: usize, j: usize, m: usize, values: &mut [[f64; B]]) {
        let Step::Unary(f, a) = self.steps[k] else {
            unreachable!("a fused step is sin or cos")
        };
        let (head, rest) = values.split_at_mut(j);
        let (operands, first) = head.split_at_mut(k);
        let (a, first, later) = (&operands[a as usize][..m], &mut first[0][..m], &mut rest[0][..m]);
        let (sin, cos) = if f == Unary::Sin {
            (first, later)
        } else {
            (later, first)
        };
        if vector::vectorised() {
            vector::apply(Function::Sin, a, sin);
            vector::apply(Function::Cos, a, cos);
            return;
        }
        for i in 0..m {
            (sin[i], cos[i]) = a[i].sin_cos();
        }
    }
}

/// Compiles trees to the steps of a [`Program`], each distinct step once.
#[derive(Default)]
struct Compiler {
    steps: Vec<Step>,
    index: std::collections::HashMap<Step, u32>,
}

impl Compiler {
    /// The number of `step`, added if new.
    fn add(&mut self, step: Step) -> u32 {
        *self.index.entry(step).or_insert_with(|| {
            self.steps.push(step);
            (self.steps.len() - 1) as u32
        })
    }

    fn num(&mut self, n: &Num) -> u32 {
        let step = match n {
            Num::Const(c) => Step::Const(c.to_bits()),
            Num::X => Step::X,
            Num::Y => Step::Y,
            Num::Unary(op, a) => Step::Unary(*op, self.num(a)),
            Num::Binary(Binary::Pow, a, b) if matches!(**b, Num::Const(k) if k.fract() == 0.0 && k.abs() <= 64.0) =>
            {
                let Num::Const(k) = **b else { unreachable!() };
                Step::PowI(k as i32, self.num(a))
            }
            Num::Binary(op, a, b) => Step::Binary(*op, self.num(a), self.num(b)),
            Num::If(c, a, b) => Step::Select(self.cond(c), self.num(a), self.num(b)),
        };
        self.add(step)
    }

    fn cond(&mut self, c: &Cond) -> u32 {
        let step = match c {
            Cond::Compare(op, a, b) => Step::Compare(*op, self.num(a), self.num(b)),
            Cond::And(a, b) => Step::And(self.cond(a), self.cond(b)),
            Cond::Or(a, b) => Step::Or(self.cond(a), self.cond(b)),
        };
        self.add(step)
    }
}

/// s ← f(a) elementwise.
#[inline]
fn map1(s: &mut [f64], a: &[f64], f: impl Fn(f64) -> f64) {
    s.iter_mut().zip(a).for_each(|(s, a)| *s = f(*a));
}

/// s ← f(a, b) elementwise.
#[inline]
fn map2(s: &mut [f64], a: &[f64], b: &[f64], f: impl Fn(f64, f64) -> f64) {
    (s.iter_mut().zip(a).zip(b)).for_each(|((s, a), b)| *s = f(*a, *b));
}

/// −1, 0 or 1 by the sign of a (+0 at ±0, NaN stays NaN), as NumPy's `sign`; `f64::signum`
/// gives ±1 at ±0.
fn sign(a: f64) -> f64 {
    if a > 0.0 {
        1.0
    } else if a < 0.0 {
        -1.0
    } else if a == 0.0 {
        0.0
    } else {
        a
    }
}

/// The smaller of a and b, ignoring a NaN, and −0 of ±0 (IEEE 754-2019 minimumNumber):
/// `f64::min` leaves the zero open, and gives +0 one by one but −0 when vectorised.
fn min(a: f64, b: f64) -> f64 {
    // `|` and `&`, not `||` and `&&`: a select without branches, which vectorises.
    if (a < b) | b.is_nan() | ((a == b) & a.is_sign_negative()) {
        a
    } else {
        b
    }
}

/// The larger of a and b, ignoring a NaN, and +0 of ±0 (IEEE 754-2019 maximumNumber).
fn max(a: f64, b: f64) -> f64 {
    if (a > b) | b.is_nan() | ((a == b) & a.is_sign_positive()) {
        a
    } else {
        b
    }
}

#[inline]
fn compare(op: Compare, a: f64, b: f64) -> bool {
    match op {
        Compare::Lt => a < b,
        Compare::Le => a <= b,
        Compare::Gt => a > b,
        Compare::Ge => a >= b,
    }
}

#[derive(Debug, Clone, PartialEq)]
enum Token {
    Number(f64),
    Name(String),
    Op(&'static str),
}

impl fmt::Display for Token {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Token::Number(v) => write!(f, "number {v}"),
            Token::Name(s) => write!(f, "name '{s}'"),
            Token::Op(s) => write!(f, "'{s}'"),
        }
    }
}

const OPERATORS: [&str; 15] = [
    "<=", ">=", "&&", "||", "<", ">", "+", "-", "*", "/", "^", "(", ")", ",", "!",
];

fn lex(s: &str) -> Result<Vec<(usize, Token)>, ExprError> {
    let bytes = s.as_bytes();
    let mut out = Vec::new();
    let mut i = 0;
    while i < bytes.len() {
        let c = bytes[i];
        if c.is_ascii_whitespace() {
            i += 1;
        } else if c.is_ascii_digit() || c == b'.' {
            let start = i;
            while i < bytes.len() && (bytes[i].is_ascii_digit() || bytes[i] == b'.') {
                i += 1;
            }
            if i < bytes.len() && (bytes[i] == b'e' || bytes[i] == b'E') {
                let mut j = i + 1;
                if j < bytes.len() && (bytes[j] == b'+' || bytes[j] == b'-') {
                    j += 1;
                }
                if j < bytes.len() && bytes[j].is_ascii_digit() {
                    i = j;
                    while i < bytes.len() && bytes[i].is_ascii_digit() {
                        i += 1;
                    }
                }
            }
            let text = &s[start..i];
            let v: f64 = text.parse().map_err(|_| ExprError {
                position: start,
                message: format!("malformed number '{text}'"),
            })?;
            if v.is_infinite() {
                return Err(ExprError {
                    position: start,
                    message: format!("the number '{text}' is beyond the largest double, about 1.8e308"),
                });
            }
            out.push((start, Token::Number(v)));
        } else if c.is_ascii_alphabetic() || c == b'_' {
            let start = i;
            while i < bytes.len() && (bytes[i].is_ascii_alphanumeric() || bytes[i] == b'_') {
                i += 1;
            }
            out.push((start, Token::Name(s[start..i].to_string())));
        } else if let Some(op) = OPERATORS.iter().find(|op| s[i..].starts_with(**op)) {
            if *op == "!" {
                return Err(ExprError {
                    position: i,
                    message: "'!' is not part of the language".into(),
                });
            }
            out.push((i, Token::Op(op)));
            i += op.len();
        } else {
            let ch = s[i..].chars().next().unwrap_or('?');
            return Err(ExprError {
                position: i,
                message: format!("unexpected character '{}'", visible(ch)),
            });
        }
    }
    Ok(out)
}

/// What a parser level returns: a number, or a condition (allowed only as the first argument of
/// `if`, as an operand of `&&` and `||`, and in parentheses around those).
enum Node {
    Num(Num),
    Cond(Cond),
}

/// A character as a message shows it: escaped where it would not be seen (a control character, a
/// space other than ' ', a format character of no width; a line break would also end the
/// message's one line).
pub(crate) fn visible(c: char) -> String {
    let no_width = matches!(c, '\u{ad}' | '\u{200b}'..='\u{200f}' | '\u{202a}'..='\u{202e}' | '\u{2060}'..='\u{2064}' | '\u{feff}');
    match c.is_control() || (c.is_whitespace() && c != ' ') || no_width {
        true => c.escape_debug().to_string(),
        false => c.to_string(),
    }
}

/// The functions of the language and their number of arguments.
const FUNCTIONS: [(&str, usize); 15] = [
    ("sqrt", 1),
    ("exp", 1),
    ("log", 1),
    ("sin", 1),
    ("cos", 1),
    ("tan", 1),
    ("atan", 1),
    ("tanh", 1),
    ("abs", 1),
    ("sign", 1),
    ("floor", 1),
    ("min", 2),
    ("max", 2),
    ("atan2", 2),
    ("if", 3),
];

/// The names every expression knows.
const BUILTIN_NAMES: [&str; 4] = ["x", "y", "pi", "e"];

/// Most nodes an expression may have once names are substituted (a guard against `a = x + x`,
/// `b = a + a`, … doubling), and the deepest tree (the compiler recurses over it).
const MAX_NODES: usize = 100_000;
const MAX_TREE_DEPTH: usize = MAX_TOKENS;

/// Named values (the `[let]` table of a case), substituted into expressions at parse time so
/// that evaluation is as fast as if they had been written out.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Names {
    /// Name, tree and node count, in order of definition.
    defs: Vec<(String, Num, usize)>,
}

impl Names {
    /// Defines `key` as `source`, which may use the names defined before it; `later` are the
    /// names still to be defined (a reference to one of them is an error: a name may use only
    /// earlier ones, which also rules out cycles).
    pub fn define(&mut self, key: &str, source: &str, later: &[&str]) -> Result<(), ExprError> {
        let problem = if !is_name(key) {
            Some("is not a name (letters, digits and '_', not starting with a digit)")
        } else if BUILTIN_NAMES.contains(&key) {
            Some("would shadow a built-in name (x, y, pi, e)")
        } else if FUNCTIONS.iter().any(|(f, _)| *f == key) {
            Some("would shadow a function of the language")
        } else if self.get(key).is_some() {
            Some("is defined twice")
        } else {
            None
        };
        if let Some(problem) = problem {
            return Err(ExprError {
                position: 0,
                message: format!("the name '{key}' {problem}"),
            });
        }
        let mut later_and_self = later.to_vec();
        later_and_self.push(key);
        let tree = parse_tree(source, self, &later_and_self)?;
        let nodes = count_nodes(&tree);
        self.defs.push((key.to_string(), tree, nodes));
        Ok(())
    }

    fn get(&self, name: &str) -> Option<&(String, Num, usize)> {
        self.defs.iter().find(|d| d.0 == name)
    }
}

fn is_name(s: &str) -> bool {
    let mut chars = s.chars();
    chars.next().is_some_and(|c| c.is_ascii_alphabetic() || c == '_')
        && chars.all(|c| c.is_ascii_alphanumeric() || c == '_')
}

fn count_nodes(n: &Num) -> usize {
    1 + match n {
        Num::Const(_) | Num::X | Num::Y => 0,
        Num::Unary(_, a) => count_nodes(a),
        Num::Binary(_, a, b) => count_nodes(a) + count_nodes(b),
        Num::If(c, a, b) => count_cond(c) + count_nodes(a) + count_nodes(b),
    }
}

fn count_cond(c: &Cond) -> usize {
    match c {
        Cond::Compare(_, a, b) => 1 + count_nodes(a) + count_nodes(b),
        Cond::And(a, b) | Cond::Or(a, b) => 1 + count_cond(a) + count_cond(b),
    }
}

fn tree_depth(n: &Num) -> usize {
    1 + match n {
        Num::Const(_) | Num::X | Num::Y => 0,
        Num::Unary(_, a) => tree_depth(a),
        Num::Binary(_, a, b) => tree_depth(a).max(tree_depth(b)),
        Num::If(c, a, b) => cond_depth(c).max(tree_depth(a)).max(tree_depth(b)),
    }
}

fn cond_depth(c: &Cond) -> usize {
    1 + match c {
        Cond::Compare(_, a, b) => tree_depth(a).max(tree_depth(b)),
        Cond::And(a, b) | Cond::Or(a, b) => cond_depth(a).max(cond_depth(b)),
    }
}

/// Parses `source` to a number tree, substituting `names`; `later` are names not defined yet.
fn parse_tree(source: &str, names: &Names, later: &[&str]) -> Result<Num, ExprError> {
    let tokens = lex(source)?;
    if tokens.len() > MAX_TOKENS {
        return Err(ExprError {
            position: 0,
            message: format!(
                "expression too long ({} tokens, at most {MAX_TOKENS})",
                tokens.len()
            ),
        });
    }
    let mut p = Parser {
        tokens,
        pos: 0,
        end: source.len(),
        depth: 0,
        names,
        later,
        nodes: 0,
    };
    let root = p.or()?;
    if p.pos < p.tokens.len() {
        let (at, ref t) = p.tokens[p.pos];
        return Err(p.error_at(at, &format!("unexpected {t}")));
    }
    let Node::Num(root) = root else {
        return Err(p.error_at(0, "a condition is allowed only as the first argument of if(…)"));
    };
    if tree_depth(&root) > MAX_TREE_DEPTH {
        return Err(p.error_at(0, "expression nested too deeply (with the names substituted)"));
    }
    Ok(root)
}

struct Parser<'a> {
    tokens: Vec<(usize, Token)>,
    pos: usize,
    end: usize,
    /// Nesting depth (bounded, so that no input can exhaust the call stack).
    depth: usize,
    names: &'a Names,
    later: &'a [&'a str],
    /// Nodes brought in by substituted names so far.
    nodes: usize,
}

impl Parser<'_> {
    fn error_at(&self, position: usize, message: &str) -> ExprError {
        ExprError {
            position,
            message: message.to_string(),
        }
    }

    fn here(&self) -> usize {
        self.tokens.get(self.pos).map_or(self.end, |t| t.0)
    }

    fn peek_op(&self, op: &str) -> bool {
        matches!(self.tokens.get(self.pos), Some((_, Token::Op(o))) if *o == op)
    }

    /// Consumes the first of `ops` that comes next.
    fn take_op<T: Copy>(&mut self, ops: &[(&str, T)]) -> Option<T> {
        let found = ops.iter().find(|(op, _)| self.peek_op(op))?;
        self.pos += 1;
        Some(found.1)
    }

    fn expect_op(&mut self, op: &str) -> Result<(), ExprError> {
        if self.peek_op(op) {
            self.pos += 1;
            Ok(())
        } else {
            let found = match self.tokens.get(self.pos) {
                Some((_, t)) => t.to_string(),
                None => "end of expression".to_string(),
            };
            Err(self.error_at(self.here(), &format!("expected '{op}', found {found}")))
        }
    }

    fn num(&self, node: Node, at: usize) -> Result<Num, ExprError> {
        match node {
            Node::Num(n) => Ok(n),
            Node::Cond(_) => Err(self.error_at(at, "a condition is used where a number is expected")),
        }
    }

    fn cond(&self, node: Node, at: usize) -> Result<Cond, ExprError> {
        match node {
            Node::Cond(c) => Ok(c),
            Node::Num(_) => Err(self.error_at(at, "a number is used where a condition (a < b) is expected")),
        }
    }

    /// A level that parses a number, as a number tree (with its position).
    fn num_of(&mut self, level: fn(&mut Self) -> Result<Node, ExprError>) -> Result<Num, ExprError> {
        let at = self.here();
        let node = level(self)?;
        self.num(node, at)
    }

    /// `level (op level)*` for && and ||: conditions joined left to right.
    fn conditions(
        &mut self,
        op: &str,
        level: fn(&mut Self) -> Result<Node, ExprError>,
    ) -> Result<Node, ExprError> {
        let at = self.here();
        let mut left = level(self)?;
        while self.peek_op(op) {
            self.pos += 1;
            let at_r = self.here();
            let right = level(self)?;
            let (l, r) = (Box::new(self.cond(left, at)?), Box::new(self.cond(right, at_r)?));
            left = Node::Cond(if op == "&&" {
                Cond::And(l, r)
            } else {
                Cond::Or(l, r)
            });
        }
        Ok(left)
    }

    fn or(&mut self) -> Result<Node, ExprError> {
        self.conditions("||", Self::and)
    }

    fn and(&mut self) -> Result<Node, ExprError> {
        self.conditions("&&", Self::compare)
    }

    fn compare(&mut self) -> Result<Node, ExprError> {
        let at = self.here();
        let left = self.sum()?;
        let ops = [
            ("<", Compare::Lt),
            ("<=", Compare::Le),
            (">", Compare::Gt),
            (">=", Compare::Ge),
        ];
        let Some(op) = self.take_op(&ops) else {
            return Ok(left);
        };
        let left = self.num(left, at)?;
        let right = self.num_of(Self::sum)?;
        Ok(Node::Cond(Cond::Compare(op, left, right)))
    }

    /// `level (op level)*` for + - and * /: numbers joined left to right.
    fn arithmetic(
        &mut self,
        ops: &[(&str, Binary)],
        level: fn(&mut Self) -> Result<Node, ExprError>,
    ) -> Result<Node, ExprError> {
        let at = self.here();
        let mut left = level(self)?;
        while let Some(op) = self.take_op(ops) {
            let l = self.num(left, at)?;
            let r = self.num_of(level)?;
            left = Node::Num(Num::Binary(op, Box::new(l), Box::new(r)));
        }
        Ok(left)
    }

    fn sum(&mut self) -> Result<Node, ExprError> {
        self.arithmetic(&[("+", Binary::Add), ("-", Binary::Sub)], Self::product)
    }

    fn product(&mut self) -> Result<Node, ExprError> {
        self.arithmetic(&[("*", Binary::Mul), ("/", Binary::Div)], Self::unary)
    }

    fn unary(&mut self) -> Result<Node, ExprError> {
        self.depth += 1;
        if self.depth > MAX_NESTING {
            return Err(self.error_at(self.here(), "expression nested too deeply"));
        }
        let result = match self.take_op(&[("-", true), ("+", false)]) {
            Some(negate) => {
                let a = self.num_of(Self::unary)?;
                Ok(Node::Num(if negate {
                    Num::Unary(Unary::Neg, Box::new(a))
                } else {
                    a
                }))
            }
            None => self.power(),
        };
        self.depth -= 1;
        result
    }

    fn power(&mut self) -> Result<Node, ExprError> {
        let at = self.here();
        let base = self.atom()?;
        if !self.peek_op("^") {
            return Ok(base);
        }
        self.pos += 1;
        let base = self.num(base, at)?;
        let exponent = self.num_of(Self::unary)?;
        Ok(Node::Num(Num::Binary(
            Binary::Pow,
            Box::new(base),
            Box::new(exponent),
        )))
    }

    fn atom(&mut self) -> Result<Node, ExprError> {
        let at = self.here();
        let Some((_, token)) = self.tokens.get(self.pos).cloned() else {
            return Err(self.error_at(at, "unexpected end of expression"));
        };
        self.pos += 1;
        match token {
            Token::Number(v) => Ok(Node::Num(Num::Const(v))),
            Token::Op("(") => {
                let inner = self.or()?;
                self.expect_op(")")?;
                Ok(inner)
            }
            Token::Name(name) if self.peek_op("(") => {
                self.pos += 1;
                let mut args = vec![(self.here(), self.or()?)];
                while self.peek_op(",") {
                    self.pos += 1;
                    args.push((self.here(), self.or()?));
                }
                self.expect_op(")")?;
                self.call(&name, at, args)
            }
            Token::Name(name) => self.name(&name, at).map(Node::Num),
            t => Err(self.error_at(at, &format!("unexpected {t}"))),
        }
    }

    /// A name outside a call: x, y, pi, e or a named value.
    fn name(&mut self, name: &str, at: usize) -> Result<Num, ExprError> {
        match name {
            "x" => return Ok(Num::X),
            "y" => return Ok(Num::Y),
            "pi" => return Ok(Num::Const(std::f64::consts::PI)),
            "e" => return Ok(Num::Const(std::f64::consts::E)),
            _ => {}
        }
        if let Some((_, tree, nodes)) = self.names.get(name) {
            self.nodes += nodes;
            if self.nodes > MAX_NODES {
                return Err(self.error_at(
                    at,
                    &format!("expression too large with the names substituted (over {MAX_NODES} nodes)"),
                ));
            }
            return Ok(tree.clone());
        }
        let message = if self.later.last() == Some(&name) {
            format!("'{name}' refers to itself")
        } else if self.later.contains(&name) {
            format!("'{name}' is defined later: a name may use only the names defined before it")
        } else if FUNCTIONS.iter().any(|(f, _)| *f == name) {
            format!("'{name}' is a function: write {name}(…)")
        } else {
            let known: Vec<&str> = BUILTIN_NAMES
                .into_iter()
                .chain(self.names.defs.iter().map(|d| d.0.as_str()))
                .collect();
            format!("unknown name '{name}' (known: {})", known.join(", "))
        };
        Err(self.error_at(at, &message))
    }

    fn call(&mut self, name: &str, at: usize, args: Vec<(usize, Node)>) -> Result<Node, ExprError> {
        let Some(&(_, arity)) = FUNCTIONS.iter().find(|(f, _)| *f == name) else {
            let known: Vec<&str> = FUNCTIONS.iter().map(|(f, _)| *f).collect();
            return Err(self.error_at(
                at,
                &format!("unknown function '{name}' (known: {})", known.join(", ")),
            ));
        };
        if args.len() != arity {
            return Err(self.error_at(
                at,
                &format!("{name}(…) takes {arity} argument(s), found {}", args.len()),
            ));
        }
        let mut args = args.into_iter();
        if name == "if" {
            let (ac, c) = args.next().unwrap();
            let c = self.cond(c, ac)?;
            let (aa, a) = args.next().unwrap();
            let (ab, b) = args.next().unwrap();
            let (a, b) = (self.num(a, aa)?, self.num(b, ab)?);
            return Ok(Node::Num(Num::If(Box::new(c), Box::new(a), Box::new(b))));
        }
        let mut nums = Vec::with_capacity(arity);
        for (a, n) in args {
            nums.push(Box::new(self.num(n, a)?));
        }
        let second = if arity == 2 { nums.pop() } else { None };
        let first = nums.pop().expect("one argument at least");
        Ok(Node::Num(match second {
            Some(b) => Num::Binary(binary_function(name), first, b),
            None => Num::Unary(unary_function(name), first),
        }))
    }
}

/// The operation of a two-argument function of [`FUNCTIONS`].
fn binary_function(name: &str) -> Binary {
    match name {
        "min" => Binary::Min,
        "max" => Binary::Max,
        _ => Binary::Atan2,
    }
}

/// The unary operation of a one-argument function of [`FUNCTIONS`].
fn unary_function(name: &str) -> Unary {
    match name {
        "sqrt" => Unary::Sqrt,
        "exp" => Unary::Exp,
        "log" => Unary::Log,
        "sin" => Unary::Sin,
        "cos" => Unary::Cos,
        "tan" => Unary::Tan,
        "atan" => Unary::Atan,
        "tanh" => Unary::Tanh,
        "abs" => Unary::Abs,
        "sign" => Unary::Sign,
        _ => Unary::Floor,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ev(s: &str, x: f64, y: f64) -> f64 {
        Expr::parse(s).unwrap().eval(x, y)
    }

    #[test]
    fn arithmetic_and_precedence() {
        assert_eq!(ev("1/2", 0.0, 0.0), 0.5);
        assert_eq!(ev("-x^2", 3.0, 0.0), -9.0);
        assert_eq!(ev("2^3^2", 0.0, 0.0), 512.0);
        assert_eq!(ev("2^-1", 0.0, 0.0), 0.5);
        assert_eq!(ev("1 + 2*3 - 4/2", 0.0, 0.0), 5.0);
        assert_eq!(ev("(1+2)*3", 0.0, 0.0), 9.0);
        assert_eq!(ev("1.5e2 + 2E-1", 0.0, 0.0), 150.2);
        assert!((ev("sin(pi/2) + cos(0) + exp(0) + log(exp(2))", 0.0, 0.0) - 5.0).abs() < 1e-15);
        assert_eq!(ev("min(x, y) + max(x, y) + abs(-3) + sqrt(16)", 1.0, 2.0), 10.0);
        assert_eq!(ev("atan2(y, x)", -1.0, 0.0), std::f64::consts::PI);
        assert_eq!(ev("atan2(y, x)", 0.0, -2.0), -std::f64::consts::FRAC_PI_2);
        // (−π, π]: the polar angle of a point on the negative x-axis is π, also where −y is −0.
        assert_eq!(ev("atan2(-y, x)", -1.0, 0.0), std::f64::consts::PI);
        assert_eq!(ev("atan2(-0, -1)", 0.0, 0.0), std::f64::consts::PI);
    }

    #[test]
    fn piecewise() {
        let e = Expr::parse("if(x < 0.5 && y >= 0 || x > 2, 1, -1)").unwrap();
        assert_eq!(e.eval(0.2, 0.0), 1.0);
        assert_eq!(e.eval(0.2, -1.0), -1.0);
        assert_eq!(e.eval(3.0, -1.0), 1.0);
        assert_eq!(e.eval(1.0, 1.0), -1.0);
    }

    #[test]
    fn errors_name_the_problem() {
        let refused = |source: &str, message: &str| {
            let e = Expr::parse(source).unwrap_err();
            assert!(e.message.contains(message), "{source:?}: {e}");
        };
        let e = Expr::parse("x + foo").unwrap_err();
        assert!(e.message.contains("unknown name 'foo'"), "{e}");
        assert_eq!(e.position, 4);
        refused("bar(x)", "unknown function 'bar'");
        refused("(x + 1", "expected ')'");
        refused("x +", "end of expression");
        refused("x < 1", "condition");
        refused("if(x, 1, 2)", "condition");
        refused("min(x)", "2 argument");
        refused("x $ 2", "unexpected character '$'");
        // Invisible characters are shown escaped (a vertical tab printed as is, a NUL as a NUL).
        refused("x +\u{b} 1", "unexpected character '\\u{b}'");
        refused("x\u{a0}+ 1", "'\\u{a0}'");
        // A literal beyond the doubles was read as inf, refused later at a point of the mesh.
        refused("1e400 * x", "'1e400' is beyond the largest double");
        refused("x\u{200b}+ 1", "'\\u{200b}'");
        refused("sin x", "'sin' is a function: write sin(…)");
        assert!(Expr::parse("").is_err());
        refused("1..2", "malformed number");
    }

    #[test]
    fn hostile_inputs_are_refused_not_crashed() {
        let deep = format!("{}x{}", "(".repeat(100_000), ")".repeat(100_000));
        assert!(Expr::parse(&deep).unwrap_err().message.contains("too long"));
        let nested = format!("{}x{}", "(".repeat(40), ")".repeat(40));
        assert!(Expr::parse(&nested)
            .unwrap_err()
            .message
            .contains("nested too deeply"));
        assert!(Expr::parse(&"-".repeat(5000))
            .unwrap_err()
            .message
            .contains("nested too deeply"));
        let long_sum = vec!["x"; 4000].join(" + ");
        assert_eq!(Expr::parse(&long_sum).unwrap().eval(1.0, 0.0), 4000.0);
        let nested_ifs = (0..10).fold("y".to_string(), |e, k| format!("if(x > {k}, {e}, {k})"));
        assert_eq!(Expr::parse(&nested_ifs).unwrap().eval(20.0, 7.0), 7.0);
        assert_eq!(Expr::parse(&nested_ifs).unwrap().eval(4.5, 7.0), 9.0);
    }

    #[test]
    fn expressions_compiled_together_share_steps_and_keep_their_values() {
        let parse = |s: &str| Expr::parse(s).unwrap();
        let exprs = [
            parse("0.5*sin(pi*x)*sin(pi*y) + max((x-0.5)^2 + (y-0.5)^2 - 0.0625, 0)^2"),
            parse("0.5*pi*cos(pi*x)*sin(pi*y) + 4*max((x-0.5)^2 + (y-0.5)^2 - 0.0625, 0)*(x-0.5)"),
            // The first but for one constant, and a condition.
            parse("0.25*sin(pi*x)*sin(pi*y) + if(x < 0.5 && y > 0.25, 1, 2)"),
            // cos before sin, computed together even in an expression alone.
            parse("cos(2*x) - sin(2*x)*y"),
        ];
        let program = Program::new(&exprs.each_ref());
        // sin and cos of πx, of 2x: each pair in one pass.
        let pairs = program.fused.iter().filter(|f| **f == Fused::Done).count();
        assert_eq!(pairs, 2, "{:?}", program.fused);
        let alone: usize = exprs.iter().map(|e| e.program.steps.len()).sum();
        assert!(
            3 * program.steps.len() < 2 * alone,
            "{} of {alone} steps",
            program.steps.len()
        );
        let points: Vec<[f64; 2]> = (0..100)
            .map(|k| [k as f64 / 97.0, (k * k % 89) as f64 / 83.0])
            .collect();
        let mut values = [[0.0; 100]; 4];
        program.eval_many(&points, &mut values.each_mut().map(|v| &mut v[..]));
        for (e, values) in exprs.iter().zip(&values) {
            for (p, v) in points.iter().zip(values) {
                assert_eq!(v.to_bits(), e.eval(p[0], p[1]).to_bits(), "at {p:?}");
            }
        }
        // Against the standard library's sin and cos (libmvec's differ by a few units in the last
        // place where it is used).
        for (p, v) in points.iter().zip(&values[3]) {
            let [x, y] = *p;
            let exact = (2.0 * x).cos() - (2.0 * x).sin() * y;
            assert!(
                (v - exact).abs() <= 1e-15 * (1.0 + y.abs()),
                "at {p:?}: {v} against {exact}"
            );
        }
    }

    #[test]
    fn blocks_of_points_agree_with_single_points() {
        let e = Expr::parse(
            "if(x < 0.3 && y >= 0.2 || x > 0.9, atan2(y, x)^2, -min(x^3, y) / 2) + sqrt(abs(x - y))",
        )
        .unwrap();
        // 100 points: three full blocks and a partial one.
        let points: Vec<[f64; 2]> = (0..100)
            .map(|k| [k as f64 / 99.0, ((7 * k) % 100) as f64 / 99.0])
            .collect();
        let mut many = vec![0.0; points.len()];
        e.eval_many(&points, &mut many);
        for (p, v) in points.iter().zip(&many) {
            assert_eq!(v.to_bits(), e.eval(p[0], p[1]).to_bits(), "at {p:?}");
        }
        let x = 0.1_f64;
        let y = 0.5_f64;
        assert_eq!(e.eval(x, y), y.atan2(x).powi(2) + (x - y).abs().sqrt());
    }

    #[test]
    fn new_functions_and_e() {
        assert_eq!(ev("e", 0.0, 0.0), std::f64::consts::E);
        assert_eq!(
            ev("tan(x) + atan(y) + tanh(x*y)", 0.5, 2.0),
            0.5f64.tan() + 2f64.atan() + 1f64.tanh()
        );
        assert_eq!(
            ev("sign(x) + 10*sign(y) + 100*sign(x - 1)", -3.0, 0.0),
            -1.0 + 0.0 - 100.0
        );
        assert!(ev("sign(log(x))", -1.0, 0.0).is_nan());
        assert_eq!(ev("floor(x) + floor(y)", -0.5, 2.0), -1.0 + 2.0);
    }

    #[test]
    fn signed_zeros() {
        let bits = |s: &str| ev(s, 0.0, -0.0).to_bits();
        assert_eq!([bits("min(x, y)"), bits("min(y, x)")], [(-0.0f64).to_bits(); 2]);
        assert_eq!(
            [bits("max(x, y)"), bits("max(y, x)"), bits("sign(y)")],
            [0.0f64.to_bits(); 3]
        );
    }

    #[test]
    fn conditions_in_parentheses() {
        let e = Expr::parse("if((x<0.5 || y<0.5) && x>0.2, 1, 0)").unwrap();
        assert_eq!(
            [e.eval(0.3, 0.9), e.eval(0.1, 0.1), e.eval(0.7, 0.7)],
            [1.0, 0.0, 0.0]
        );
        assert_eq!(ev("if(((x > 0)), 1, 2)", 1.0, 0.0), 1.0);
        for bad in [
            "(x < 1) + 2",
            "-(x < 1)",
            "sin((x < 1))",
            "(x < 1)^2",
            "(x < 1)",
            "2^(x<1)",
        ] {
            let e = Expr::parse(bad).unwrap_err();
            assert!(e.message.contains("condition"), "{bad}: {e}");
        }
    }

    /// Names in order; the errors of `define`.
    fn names(entries: &[(&str, &str)]) -> Result<Names, ExprError> {
        let keys: Vec<&str> = entries.iter().map(|e| e.0).collect();
        let mut names = Names::default();
        for (i, (key, source)) in entries.iter().enumerate() {
            names.define(key, source, &keys[i + 1..])?;
        }
        Ok(names)
    }

    #[test]
    fn named_values_are_substituted() {
        let n = names(&[
            ("r", "sqrt((x-0.5)^2 + (y-0.5)^2)"),
            ("C", "sqrt(2)/(sqrt(2)-1)"),
            ("u", "C*r^2"),
        ])
        .unwrap();
        let e = Expr::parse_with("u + r", &n).unwrap();
        let c = 2f64.sqrt() / (2f64.sqrt() - 1.0);
        assert_eq!(e.eval(0.5, 1.5), c + 1.0);
        assert_eq!(
            e,
            Expr::parse("(sqrt(2)/(sqrt(2)-1))*sqrt((x-0.5)^2 + (y-0.5)^2)^2 + sqrt((x-0.5)^2 + (y-0.5)^2)")
                .unwrap()
        );
        assert!(Expr::parse("u").unwrap_err().message.contains("unknown name 'u'"));
    }

    #[test]
    fn named_value_errors() {
        let message = |entries: &[(&str, &str)]| names(entries).unwrap_err().message;
        assert!(message(&[("a", "b + 1"), ("b", "x")]).contains("'b' is defined later"));
        assert!(message(&[("a", "b"), ("b", "a")]).contains("'b' is defined later"));
        assert!(message(&[("a", "a + 1")]).contains("'a' refers to itself"));
        assert!(message(&[("a", "z")]).contains("unknown name 'z' (known: x, y, pi, e)"));
        for builtin in ["x", "y", "pi", "e"] {
            assert!(message(&[(builtin, "1")]).contains(&format!("'{builtin}' would shadow a built-in")));
        }
        assert!(message(&[("sin", "1")]).contains("'sin' would shadow a function"));
        assert!(message(&[("2a", "1")]).contains("not a name"));
        assert!(message(&[("a", "1"), ("a", "2")]).contains("twice"));
        let doubling: Vec<(String, String)> = (1..40)
            .map(|k| (format!("a{k}"), format!("a{} + a{}", k - 1, k - 1)))
            .collect();
        let mut entries = vec![("a0", "x")];
        entries.extend(doubling.iter().map(|(k, s)| (k.as_str(), s.as_str())));
        assert!(message(&entries).contains("too large"));
    }

    #[test]
    fn constants_are_recognised() {
        assert_eq!(
            Expr::parse("2*pi").unwrap().constant(),
            Some(2.0 * std::f64::consts::PI)
        );
        assert_eq!(Expr::parse("x").unwrap().constant(), None);
    }
}
