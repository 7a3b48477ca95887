"""The case-file expression language (src/expr.rs), evaluated identically in Python.

The same grammar as the Rust parser (see data/cases/README.md): numbers, x, y, pi, + - * / ^,
parentheses, sqrt, exp, log, sin, cos, abs, min, max, atan2, if(cond, a, b) with cond built from
< <= > >= && ||. `parse` returns a tree; `to_numpy` and `to_ufl` turn it into a NumPy value at
points or a UFL expression of the spatial coordinate. (The SymPy check of exact solutions does not
use this parser: exact_cases.py reads the expressions with SymPy's own.)
"""
import math
import re

_TOKEN = re.compile(
    r"\s*(?:(?P<num>(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?)|(?P<name>[A-Za-z_][A-Za-z_0-9]*)"
    r"|(?P<op><=|>=|&&|\|\||[<>+\-*/^(),]))"
)
UNARY = {"sqrt", "exp", "log", "sin", "cos", "abs"}
BINARY = {"min", "max", "atan2"}


class ExprError(ValueError):
    pass


def _lex(s):
    out, i = [], 0
    while i < len(s):
        if s[i].isspace():
            i += 1
            continue
        m = _TOKEN.match(s, i)
        if not m or m.end() == i:
            raise ExprError("unexpected character %r at %d" % (s[i], i + 1))
        kind = m.lastgroup
        text = m.group(kind)
        out.append((kind, float(text) if kind == "num" else text))
        i = m.end()
    return out


class _Parser:
    def __init__(self, tokens):
        self.t, self.p = tokens, 0

    def peek(self, op):
        return self.p < len(self.t) and self.t[self.p] == ("op", op)

    def take(self, op):
        if not self.peek(op):
            raise ExprError("expected %r" % op)
        self.p += 1

    def or_(self):
        left = self.and_()
        while self.peek("||"):
            self.p += 1
            left = ("or", left, self.and_())
        return left

    def and_(self):
        left = self.cmp()
        while self.peek("&&"):
            self.p += 1
            left = ("and", left, self.cmp())
        return left

    def cmp(self):
        left = self.sum()
        for op in ("<=", ">=", "<", ">"):
            if self.peek(op):
                self.p += 1
                return ("cmp", op, left, self.sum())
        return left

    def sum(self):
        left = self.prod()
        while self.peek("+") or self.peek("-"):
            op = self.t[self.p][1]
            self.p += 1
            left = (op, left, self.prod())
        return left

    def prod(self):
        left = self.unary()
        while self.peek("*") or self.peek("/"):
            op = self.t[self.p][1]
            self.p += 1
            left = (op, left, self.unary())
        return left

    def unary(self):
        if self.peek("-"):
            self.p += 1
            return ("neg", self.unary())
        if self.peek("+"):
            self.p += 1
            return self.unary()
        base = self.atom()
        if self.peek("^"):
            self.p += 1
            return ("^", base, self.unary())
        return base

    def atom(self):
        if self.p >= len(self.t):
            raise ExprError("unexpected end of expression")
        kind, v = self.t[self.p]
        self.p += 1
        if kind == "num":
            return ("const", v)
        if (kind, v) == ("op", "("):
            inner = self.or_()
            self.take(")")
            return inner
        if kind == "name":
            if not self.peek("("):
                if v in ("x", "y"):
                    return (v,)
                if v == "pi":
                    return ("const", math.pi)
                raise ExprError("unknown name %r" % v)
            self.p += 1
            args = [self.or_()]
            while self.peek(","):
                self.p += 1
                args.append(self.or_())
            self.take(")")
            arity = 1 if v in UNARY else 2 if v in BINARY else 3 if v == "if" else None
            if arity is None or len(args) != arity:
                raise ExprError("bad call %s(...)" % v)
            return ("call", v, *args)
        raise ExprError("unexpected %r" % (v,))


def parse(source):
    """Parses an expression (a number is accepted as is)."""
    if isinstance(source, (int, float)):
        return ("const", float(source))
    p = _Parser(_lex(source))
    tree = p.or_()
    if p.p != len(p.t):
        raise ExprError("unexpected %r" % (p.t[p.p][1],))
    return tree


def _build(tree, x, y, lib):
    b = lambda t: _build(t, x, y, lib)  # noqa: E731
    k = tree[0]
    if k == "const":
        return lib["const"](tree[1])
    if k == "x":
        return x
    if k == "y":
        return y
    if k == "neg":
        return -b(tree[1])
    if k in ("+", "-", "*", "/", "^"):
        a, c = b(tree[1]), b(tree[2])
        if k == "+":
            return a + c
        if k == "-":
            return a - c
        if k == "*":
            return a * c
        if k == "/":
            return a / c
        return a**c
    if k == "cmp":
        return lib["cmp"](tree[1], b(tree[2]), b(tree[3]))
    if k in ("and", "or"):
        return lib[k](b(tree[1]), b(tree[2]))
    if k == "call":
        name, args = tree[1], [b(t) for t in tree[2:]]
        return lib[name](*args)
    raise ExprError("bad tree %r" % (tree,))


def to_numpy(tree, x, y):
    """The expression at points (x, y) (NumPy arrays)."""
    import numpy as np

    lib = {
        "const": lambda v: np.full(np.shape(x), v),
        "cmp": lambda op, a, c: {"<": a < c, "<=": a <= c, ">": a > c, ">=": a >= c}[op],
        "and": np.logical_and,
        "or": np.logical_or,
        "sqrt": np.sqrt,
        "exp": np.exp,
        "log": np.log,
        "sin": np.sin,
        "cos": np.cos,
        "abs": np.abs,
        "min": np.fmin,
        "max": np.fmax,
        "atan2": np.arctan2,
        "if": np.where,
    }
    with np.errstate(all="ignore"):
        return np.asarray(_build(tree, np.asarray(x, float), np.asarray(y, float), lib), float)


def to_ufl(tree, mesh):
    """The expression as UFL of the spatial coordinate of `mesh`."""
    import ufl

    X = ufl.SpatialCoordinate(mesh)
    lib = {
        "const": lambda v: ufl.as_ufl(v),
        "cmp": lambda op, a, c: {"<": ufl.lt, "<=": ufl.le, ">": ufl.gt, ">=": ufl.ge}[op](a, c),
        "and": ufl.And,
        "or": ufl.Or,
        "sqrt": ufl.sqrt,
        "exp": ufl.exp,
        "log": ufl.ln,
        "sin": ufl.sin,
        "cos": ufl.cos,
        "abs": abs,
        "min": ufl.min_value,
        "max": ufl.max_value,
        "atan2": ufl.atan_2,
        "if": ufl.conditional,
    }
    return _build(tree, X[0], X[1], lib)
