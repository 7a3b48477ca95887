//! The case-file expression language: data f1, f2, g and exact solutions as functions of (x, y).
//!
//! Grammar (documented for users in `data/cases/README.md`; `reference/expr.py` mirrors it):
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
//! atom  := number | x | y | pi | name "(" args ")" | "(" expr ")"
//! ```
//!
//! Functions: sqrt, exp, log (natural), sin, cos, abs (one argument), min, max, atan2(y, x) (two),
//! and the piecewise form `if(condition, a, b)`. All arithmetic is in f64: `1/2` is 0.5.
//!
//! The language is this small on purpose: the Python reference must evaluate it identically (as UFL
//! at quadrature points and as NumPy at vertices), which rules out general-purpose evaluators whose
//! semantics differ (integer division, base-10 `log`, implicit variable ordering).

use std::fmt;

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

#[derive(Debug, Clone, Copy, PartialEq)]
enum Unary {
    Neg,
    Sqrt,
    Exp,
    Log,
    Sin,
    Cos,
    Abs,
}

#[derive(Debug, Clone, Copy, PartialEq)]
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

#[derive(Debug, Clone, Copy, PartialEq)]
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

/// A parsed expression of (x, y), compiled to a stack program for fast evaluation.
#[derive(Debug, Clone, PartialEq)]
pub struct Expr {
    code: Vec<Op>,
    /// The deepest stack the program needs.
    depth: usize,
}

/// One instruction of the stack program (conditions are 1.0 / 0.0 on the stack).
#[derive(Debug, Clone, Copy, PartialEq)]
enum Op {
    Const(f64),
    X,
    Y,
    Unary(Unary),
    Binary(Binary),
    /// a^k for a constant integer exponent k.
    PowI(i32),
    Compare(Compare),
    And,
    Or,
    /// c, a, b → a where c ≠ 0, else b (both branches are evaluated: floats do not trap, and the
    /// program stays straight-line, so that it runs over blocks of points).
    Select,
}

/// Longest accepted expression, in tokens, and the deepest nesting of the stack program.
const MAX_TOKENS: usize = 10_000;
const STACK: usize = 64;
/// Points per block of [`Expr::eval_many`].
pub const BLOCK: usize = 32;

/// The stack slots sp − 1 (mutable) and sp.
fn two<const B: usize>(stack: &mut [[f64; B]], sp: usize) -> (&mut [f64; B], &[f64; B]) {
    let (lo, hi) = stack.split_at_mut(sp);
    (&mut lo[sp - 1], &hi[0])
}

fn truth(b: bool) -> f64 {
    f64::from(u8::from(b))
}

impl Expr {
    /// Parses `source`; the error names the offending token and its position.
    pub fn parse(source: &str) -> Result<Self, ExprError> {
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
        };
        let root = match p.or()? {
            Node::Num(n) => n,
            Node::Cond(_) => {
                return Err(p.error_at(0, "a condition is allowed only as the first argument of if(…)"))
            }
        };
        if p.pos < p.tokens.len() {
            let (at, ref t) = p.tokens[p.pos];
            return Err(p.error_at(at, &format!("unexpected {t}")));
        }
        let mut c = Compiler::default();
        c.num(&root);
        if c.max_depth > STACK {
            return Err(p.error_at(0, "expression nested too deeply"));
        }
        Ok(Expr {
            code: c.code,
            depth: c.max_depth,
        })
    }

    /// The value at the point (x, y).
    pub fn eval(&self, x: f64, y: f64) -> f64 {
        let mut out = [0.0];
        self.run(&[[x, y]], &mut out, &mut [[0.0; 1]; STACK]);
        out[0]
    }

    /// The values at `points`, into `out`: the program runs once per block of [`BLOCK`] points,
    /// each instruction over the whole block.
    pub fn eval_many(&self, points: &[[f64; 2]], out: &mut [f64]) {
        let mut stack = vec![[0.0; BLOCK]; self.depth.max(1)];
        for (points, out) in points.chunks(BLOCK).zip(out.chunks_mut(BLOCK)) {
            self.run(points, out, &mut stack);
        }
    }

    /// Runs the program on up to B points at once.
    fn run<const B: usize>(&self, points: &[[f64; 2]], out: &mut [f64], stack: &mut [[f64; B]]) {
        let m = points.len();
        let mut sp = 0;
        for op in &self.code {
            match *op {
                Op::Const(c) => {
                    stack[sp][..m].fill(c);
                    sp += 1;
                }
                Op::X | Op::Y => {
                    let k = usize::from(matches!(op, Op::Y));
                    for (s, p) in stack[sp].iter_mut().zip(points) {
                        *s = p[k];
                    }
                    sp += 1;
                }
                Op::Unary(f) => {
                    let a = &mut stack[sp - 1][..m];
                    match f {
                        Unary::Neg => map1(a, |a| -a),
                        Unary::Sqrt => map1(a, f64::sqrt),
                        Unary::Exp => map1(a, f64::exp),
                        Unary::Log => map1(a, f64::ln),
                        Unary::Sin => map1(a, f64::sin),
                        Unary::Cos => map1(a, f64::cos),
                        Unary::Abs => map1(a, f64::abs),
                    }
                }
                Op::PowI(2) => map1(&mut stack[sp - 1][..m], |a| a * a),
                Op::PowI(k) => map1(&mut stack[sp - 1][..m], |a| a.powi(k)),
                Op::Binary(f) => {
                    sp -= 1;
                    let (a, b) = two(stack, sp);
                    let (a, b) = (&mut a[..m], &b[..m]);
                    match f {
                        Binary::Add => map2(a, b, |a, b| a + b),
                        Binary::Sub => map2(a, b, |a, b| a - b),
                        Binary::Mul => map2(a, b, |a, b| a * b),
                        Binary::Div => map2(a, b, |a, b| a / b),
                        Binary::Pow => map2(a, b, f64::powf),
                        Binary::Min => map2(a, b, f64::min),
                        Binary::Max => map2(a, b, f64::max),
                        Binary::Atan2 => map2(a, b, f64::atan2),
                    }
                }
                Op::Compare(f) => {
                    sp -= 1;
                    let (a, b) = two(stack, sp);
                    (a[..m].iter_mut().zip(&b[..m])).for_each(|(a, b)| *a = truth(compare(f, *a, *b)));
                }
                Op::And | Op::Or => {
                    sp -= 1;
                    let and = matches!(op, Op::And);
                    let (a, b) = two(stack, sp);
                    a[..m].iter_mut().zip(&b[..m]).for_each(|(a, b)| {
                        *a = truth(if and {
                            *a != 0.0 && *b != 0.0
                        } else {
                            *a != 0.0 || *b != 0.0
                        })
                    });
                }
                Op::Select => {
                    sp -= 2;
                    let (c, rest) = stack[sp - 1..].split_at_mut(1);
                    let (a, b) = rest.split_at(1);
                    for i in 0..m {
                        c[0][i] = if c[0][i] != 0.0 { a[0][i] } else { b[0][i] };
                    }
                }
            }
        }
        out.copy_from_slice(&stack[0][..m]);
    }

    /// The value, if the expression does not read x or y.
    pub fn constant(&self) -> Option<f64> {
        let reads_xy = self.code.iter().any(|op| matches!(op, Op::X | Op::Y));
        (!reads_xy).then(|| self.eval(0.0, 0.0))
    }
}

/// Compiles the tree to postfix code, tracking the stack depth.
#[derive(Default)]
struct Compiler {
    code: Vec<Op>,
    depth: usize,
    max_depth: usize,
}

impl Compiler {
    fn push(&mut self, op: Op, change: isize) {
        self.code.push(op);
        self.depth = self.depth.saturating_add_signed(change);
        self.max_depth = self.max_depth.max(self.depth);
    }

    fn num(&mut self, n: &Num) {
        match n {
            Num::Const(c) => self.push(Op::Const(*c), 1),
            Num::X => self.push(Op::X, 1),
            Num::Y => self.push(Op::Y, 1),
            Num::Unary(op, a) => {
                self.num(a);
                self.push(Op::Unary(*op), 0);
            }
            Num::Binary(Binary::Pow, a, b) if matches!(**b, Num::Const(k) if k.fract() == 0.0 && k.abs() <= 64.0) =>
            {
                let Num::Const(k) = **b else { unreachable!() };
                self.num(a);
                self.push(Op::PowI(k as i32), 0);
            }
            Num::Binary(op, a, b) => {
                self.num(a);
                self.num(b);
                self.push(Op::Binary(*op), -1);
            }
            Num::If(c, a, b) => {
                self.cond(c);
                self.num(a);
                self.num(b);
                self.push(Op::Select, -2);
            }
        }
    }

    fn cond(&mut self, c: &Cond) {
        match c {
            Cond::Compare(op, a, b) => {
                self.num(a);
                self.num(b);
                self.push(Op::Compare(*op), -1);
            }
            Cond::And(a, b) | Cond::Or(a, b) => {
                self.cond(a);
                self.cond(b);
                self.push(
                    if matches!(c, Cond::And(..)) {
                        Op::And
                    } else {
                        Op::Or
                    },
                    -1,
                );
            }
        }
    }
}

/// a ← f(a) elementwise.
#[inline]
fn map1(a: &mut [f64], f: impl Fn(f64) -> f64) {
    a.iter_mut().for_each(|a| *a = f(*a));
}

/// a ← f(a, b) elementwise.
#[inline]
fn map2(a: &mut [f64], b: &[f64], f: impl Fn(f64, f64) -> f64) {
    a.iter_mut().zip(b).for_each(|(a, b)| *a = f(*a, *b));
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
                message: format!("unexpected character '{ch}'"),
            });
        }
    }
    Ok(out)
}

enum Node {
    Num(Num),
    Cond(Cond),
}

struct Parser {
    tokens: Vec<(usize, Token)>,
    pos: usize,
    end: usize,
    /// Nesting depth (bounded, so that no input can exhaust the call stack).
    depth: usize,
}

impl Parser {
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

    fn num(&mut self, node: Node, at: usize) -> Result<Num, ExprError> {
        match node {
            Node::Num(n) => Ok(n),
            Node::Cond(_) => Err(self.error_at(at, "a condition is used where a number is expected")),
        }
    }

    fn cond(&mut self, node: Node, at: usize) -> Result<Cond, ExprError> {
        match node {
            Node::Cond(c) => Ok(c),
            Node::Num(_) => Err(self.error_at(at, "a number is used where a condition (a < b) is expected")),
        }
    }

    fn or(&mut self) -> Result<Node, ExprError> {
        let at = self.here();
        let mut left = self.and()?;
        while self.peek_op("||") {
            self.pos += 1;
            let at_r = self.here();
            let right = self.and()?;
            let l = self.cond(left, at)?;
            let r = self.cond(right, at_r)?;
            left = Node::Cond(Cond::Or(Box::new(l), Box::new(r)));
        }
        Ok(left)
    }

    fn and(&mut self) -> Result<Node, ExprError> {
        let at = self.here();
        let mut left = self.compare()?;
        while self.peek_op("&&") {
            self.pos += 1;
            let at_r = self.here();
            let right = self.compare()?;
            let l = self.cond(left, at)?;
            let r = self.cond(right, at_r)?;
            left = Node::Cond(Cond::And(Box::new(l), Box::new(r)));
        }
        Ok(left)
    }

    fn compare(&mut self) -> Result<Node, ExprError> {
        let left = self.sum()?;
        let op = match self.tokens.get(self.pos) {
            Some((_, Token::Op("<"))) => Compare::Lt,
            Some((_, Token::Op("<="))) => Compare::Le,
            Some((_, Token::Op(">"))) => Compare::Gt,
            Some((_, Token::Op(">="))) => Compare::Ge,
            _ => return Ok(Node::Num(left)),
        };
        self.pos += 1;
        let right = self.sum()?;
        Ok(Node::Cond(Cond::Compare(op, left, right)))
    }

    fn sum(&mut self) -> Result<Num, ExprError> {
        let mut left = self.product()?;
        loop {
            let op = if self.peek_op("+") {
                Binary::Add
            } else if self.peek_op("-") {
                Binary::Sub
            } else {
                return Ok(left);
            };
            self.pos += 1;
            let right = self.product()?;
            left = Num::Binary(op, Box::new(left), Box::new(right));
        }
    }

    fn product(&mut self) -> Result<Num, ExprError> {
        let mut left = self.unary()?;
        loop {
            let op = if self.peek_op("*") {
                Binary::Mul
            } else if self.peek_op("/") {
                Binary::Div
            } else {
                return Ok(left);
            };
            self.pos += 1;
            let right = self.unary()?;
            left = Num::Binary(op, Box::new(left), Box::new(right));
        }
    }

    fn unary(&mut self) -> Result<Num, ExprError> {
        self.depth += 1;
        if self.depth > STACK / 2 {
            return Err(self.error_at(self.here(), "expression nested too deeply"));
        }
        let result = self.unary_inner();
        self.depth -= 1;
        result
    }

    fn unary_inner(&mut self) -> Result<Num, ExprError> {
        if self.peek_op("-") {
            self.pos += 1;
            return Ok(Num::Unary(Unary::Neg, Box::new(self.unary()?)));
        }
        if self.peek_op("+") {
            self.pos += 1;
            return self.unary();
        }
        self.power()
    }

    fn power(&mut self) -> Result<Num, ExprError> {
        let base = self.atom()?;
        if self.peek_op("^") {
            self.pos += 1;
            let exponent = self.unary()?;
            return Ok(Num::Binary(Binary::Pow, Box::new(base), Box::new(exponent)));
        }
        Ok(base)
    }

    fn atom(&mut self) -> Result<Num, ExprError> {
        let at = self.here();
        let Some((_, token)) = self.tokens.get(self.pos).cloned() else {
            return Err(self.error_at(at, "unexpected end of expression"));
        };
        self.pos += 1;
        match token {
            Token::Number(v) => Ok(Num::Const(v)),
            Token::Op("(") => {
                let inner = self.or()?;
                self.expect_op(")")?;
                self.num(inner, at)
            }
            Token::Name(name) => {
                if !self.peek_op("(") {
                    return match name.as_str() {
                        "x" => Ok(Num::X),
                        "y" => Ok(Num::Y),
                        "pi" => Ok(Num::Const(std::f64::consts::PI)),
                        _ => Err(self.error_at(at, &format!("unknown name '{name}' (known: x, y, pi)"))),
                    };
                }
                self.pos += 1;
                let mut args = vec![(self.here(), self.or()?)];
                while self.peek_op(",") {
                    self.pos += 1;
                    args.push((self.here(), self.or()?));
                }
                self.expect_op(")")?;
                self.call(&name, at, args)
            }
            t => Err(self.error_at(at, &format!("unexpected {t}"))),
        }
    }

    fn call(&mut self, name: &str, at: usize, args: Vec<(usize, Node)>) -> Result<Num, ExprError> {
        let arity = match name {
            "sqrt" | "exp" | "log" | "sin" | "cos" | "abs" => 1,
            "min" | "max" | "atan2" => 2,
            "if" => 3,
            _ => {
                return Err(self.error_at(
                    at,
                    &format!(
                    "unknown function '{name}' (known: sqrt, exp, log, sin, cos, abs, min, max, atan2, if)"
                ),
                ))
            }
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
            let a = self.num(a, aa)?;
            let (ab, b) = args.next().unwrap();
            let b = self.num(b, ab)?;
            return Ok(Num::If(Box::new(c), Box::new(a), Box::new(b)));
        }
        let mut nums = Vec::with_capacity(arity);
        for (a, n) in args {
            nums.push(self.num(n, a)?);
        }
        let mut nums = nums.into_iter();
        let first = Box::new(nums.next().unwrap());
        Ok(match name {
            "min" => Num::Binary(Binary::Min, first, Box::new(nums.next().unwrap())),
            "max" => Num::Binary(Binary::Max, first, Box::new(nums.next().unwrap())),
            "atan2" => Num::Binary(Binary::Atan2, first, Box::new(nums.next().unwrap())),
            "sqrt" => Num::Unary(Unary::Sqrt, first),
            "exp" => Num::Unary(Unary::Exp, first),
            "log" => Num::Unary(Unary::Log, first),
            "sin" => Num::Unary(Unary::Sin, first),
            "cos" => Num::Unary(Unary::Cos, first),
            _ => Num::Unary(Unary::Abs, first),
        })
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
        let e = Expr::parse("x + foo").unwrap_err();
        assert!(e.message.contains("unknown name 'foo'"), "{e}");
        assert_eq!(e.position, 4);
        assert!(Expr::parse("bar(x)")
            .unwrap_err()
            .message
            .contains("unknown function 'bar'"));
        assert!(Expr::parse("(x + 1")
            .unwrap_err()
            .message
            .contains("expected ')'"));
        assert!(Expr::parse("x +")
            .unwrap_err()
            .message
            .contains("end of expression"));
        assert!(Expr::parse("x < 1").unwrap_err().message.contains("condition"));
        assert!(Expr::parse("if(x, 1, 2)")
            .unwrap_err()
            .message
            .contains("condition"));
        assert!(Expr::parse("min(x)").unwrap_err().message.contains("2 argument"));
        assert!(Expr::parse("x $ 2")
            .unwrap_err()
            .message
            .contains("unexpected character '$'"));
        assert!(Expr::parse("").is_err());
        assert!(Expr::parse("1..2")
            .unwrap_err()
            .message
            .contains("malformed number"));
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
    fn constants_are_recognised() {
        assert_eq!(
            Expr::parse("2*pi").unwrap().constant(),
            Some(2.0 * std::f64::consts::PI)
        );
        assert_eq!(Expr::parse("x").unwrap().constant(), None);
    }
}
