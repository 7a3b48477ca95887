"""The case-file expression language (src/expr.rs), evaluated identically in Python.

The same grammar as the Rust parser (see data/cases/README.md): numbers, x, y, pi, e, named values
(the case's [let] table), + - * / ^, parentheses, sqrt, exp, log, sin, cos, tan, atan, tanh, abs,
sign, floor, min, max, atan2, if(cond, a, b) with cond built from < <= > >= && || (and
parentheses). A condition is allowed only as the first argument of if, as an operand of && and ||,
and in parentheses around those. `parse` returns a tree; `to_numpy` and `to_ufl` turn it into a
NumPy value at points or a UFL expression of the spatial coordinate. `parse_case` parses every
expression of a case with its [let] names. (The SymPy check of exact solutions does not use this
parser: exact_cases.py reads the expressions with SymPy's own.) tests/expressions.rs checks this
parser and the Rust one against random expressions evaluated from their syntax trees
(reference/random_expressions.py).
"""
import math
import re

from . import problems

_TOKEN = re.compile(
    r"[ \t\n\r\f]*(?:(?P<num>(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?)|(?P<name>[A-Za-z_][A-Za-z_0-9]*)"
    r"|(?P<op><=|>=|&&|\|\||[<>+\-*/^(),]))",
    re.ASCII,
)
# ASCII whitespace only, as Rust's u8::is_ascii_whitespace (not \v, nor Unicode spaces).
_SPACE = " \t\n\r\f"
UNARY = ("sqrt", "exp", "log", "sin", "cos", "tan", "atan", "tanh", "abs", "sign", "floor")
BINARY = ("min", "max", "atan2")
ARITY = dict([(f, 1) for f in UNARY] + [(f, 2) for f in BINARY] + [("if", 3)])
CONSTANTS = {"pi": math.pi, "e": math.e}
BUILTIN_NAMES = ("x", "y", "pi", "e")
CONDITIONS = ("cmp", "and", "or")
# The limits of src/expr.rs: tokens, nesting of the unary level, stack slots of the evaluator,
# nodes after substituting names.
MAX_TOKENS = 10_000
MAX_NESTING = 32
STACK = 64
MAX_NODES = 100_000


class ExprError(ValueError):
    pass


def _lex(s):
    out, i = [], 0
    while i < len(s):
        if s[i] in _SPACE:
            i += 1
            continue
        m = _TOKEN.match(s, i)
        if not m or m.end() == i:
            raise ExprError("unexpected character %r at %d" % (s[i], i + 1))
        kind = m.lastgroup
        text = m.group(kind)
        out.append((kind, float(text) if kind == "num" else text))
        i = m.end()
    if len(out) > MAX_TOKENS:
        raise ExprError("expression too long (%d tokens, at most %d)" % (len(out), MAX_TOKENS))
    return out


def _num(tree):
    if tree[0] in CONDITIONS:
        raise ExprError("a condition is used where a number is expected")
    return tree


def _cond(tree):
    if tree[0] not in CONDITIONS:
        raise ExprError("a number is used where a condition (a < b) is expected")
    return tree


def _size(tree):
    return 1 + sum(_size(t) for t in tree[1:] if isinstance(t, tuple))


class _Parser:
    def __init__(self, tokens, names, later):
        self.t, self.p, self.depth, self.nodes = tokens, 0, 0, 0
        self.names, self.later = names, later

    def peek(self, op):
        return self.p < len(self.t) and self.t[self.p] == ("op", op)

    def take(self, op):
        if not self.peek(op):
            raise ExprError("expected %r" % op)
        self.p += 1

    def joined(self, op, kind, level):
        left = level()
        while self.peek(op):
            self.p += 1
            left = (kind, _cond(left), _cond(level()))
        return left

    def or_(self):
        return self.joined("||", "or", self.and_)

    def and_(self):
        return self.joined("&&", "and", self.cmp)

    def cmp(self):
        left = self.sum()
        for op in ("<=", ">=", "<", ">"):
            if self.peek(op):
                self.p += 1
                return ("cmp", op, _num(left), _num(self.sum()))
        return left

    def arithmetic(self, ops, level):
        left = level()
        while any(self.peek(op) for op in ops):
            op = self.t[self.p][1]
            self.p += 1
            left = (op, _num(left), _num(level()))
        return left

    def sum(self):
        return self.arithmetic("+-", self.prod)

    def prod(self):
        return self.arithmetic("*/", self.unary)

    def unary(self):
        self.depth += 1
        if self.depth > MAX_NESTING:
            raise ExprError("expression nested too deeply")
        if self.peek("-") or self.peek("+"):
            negate = self.peek("-")
            self.p += 1
            a = _num(self.unary())
            out = ("neg", a) if negate else a
        else:
            out = self.power()
        self.depth -= 1
        return out

    def power(self):
        base = self.atom()
        if self.peek("^"):
            self.p += 1
            return ("^", _num(base), _num(self.unary()))
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
            return self.call(v) if self.peek("(") else self.name(v)
        raise ExprError("unexpected %r" % (v,))

    def name(self, v):
        if v in ("x", "y"):
            return (v,)
        if v in CONSTANTS:
            return ("const", CONSTANTS[v])
        if v in self.names:
            tree = self.names[v]
            self.nodes += _size(tree)
            if self.nodes > MAX_NODES:
                raise ExprError("expression too large with the names substituted")
            return tree
        if v in self.later:
            raise ExprError("%r is defined later (or is the name being defined): a name may use only "
                            "the names defined before it" % v)
        raise ExprError("unknown name %r" % v)

    def call(self, v):
        self.p += 1
        args = [self.or_()]
        while self.peek(","):
            self.p += 1
            args.append(self.or_())
        self.take(")")
        if len(args) != ARITY.get(v, -1):
            raise ExprError("bad call %s(...) with %d argument(s)" % (v, len(args)))
        if v == "if":
            return ("call", v, _cond(args[0]), _num(args[1]), _num(args[2]))
        return ("call", v, *map(_num, args))


def _parse_tree(source, names, later):
    """The tree of `source`, with `names` ({name: tree}) substituted; `later` are names not
    defined yet."""
    p = _Parser(_lex(source), names, later)
    tree = p.or_()
    if p.p != len(p.t):
        raise ExprError("unexpected %r" % (p.t[p.p][1],))
    if tree[0] in CONDITIONS:
        raise ExprError("a condition is allowed only as the first argument of if(...)")
    return tree


def _stack(tree):
    """The stack the Rust evaluator needs for `tree` (src/expr.rs compiles to a stack program and
    refuses more than STACK slots): each operand is pushed after those before it."""
    k = tree[0]
    if k in ("const", "x", "y"):
        return 1
    if k == "neg":
        return _stack(tree[1])
    exponent = tree[2] if k == "^" else None
    if exponent and exponent[0] == "const" and exponent[1] % 1 == 0 and abs(exponent[1]) <= 64:
        return _stack(tree[1])  # a^k for an integer constant k: one instruction on a
    operands = [t for t in tree[1:] if isinstance(t, tuple)]
    return max(_stack(t) + i for i, t in enumerate(operands))


def parse(source, names=None):
    """Parses an expression (a number is accepted as is, a tree is returned as is); `names` maps
    named values to their trees (see `parse_names`)."""
    if isinstance(source, tuple):
        return source
    if isinstance(source, dict):  # a table per physical group (reference/groups.py)
        return ("table", {k: parse(v, names) for k, v in source.items()})
    if isinstance(source, (int, float)):
        return ("const", float(source))
    tree = _parse_tree(source, names or {}, ())
    if _stack(tree) > STACK:
        raise ExprError("expression nested too deeply")
    return tree


def parse_names(table):
    """{name: tree} of a [let] table, in its order: each name may use only the names above it."""
    names, keys = {}, list(table)
    for i, (key, source) in enumerate(table.items()):
        problem = ("is not a name" if not re.fullmatch(r"[A-Za-z_][A-Za-z_0-9]*", key)
                   else "would shadow a built-in name" if key in BUILTIN_NAMES
                   else "would shadow a function" if key in ARITY else None)
        try:
            if problem:
                raise ExprError("the name %r %s" % (key, problem))
            if isinstance(source, bool) or not isinstance(source, (str, int, float)):
                raise ExprError("need an expression (a string or a number)")
            names[key] = parse(source) if not isinstance(source, str) else _parse_tree(source, names, keys[i:])
        except ExprError as e:
            raise ExprError("key 'let.%s': %s" % (key, e)) from None
    return names


def parse_case(case):
    """The case (a dict from TOML) with every expression parsed to a tree, the [let] names
    substituted, so that `to_numpy`, `to_ufl` and the helpers of common.py take them as they are.
    The expression keys are those of the case's problem (reference/problems.py); an optional one
    that is absent gets its default (g2 = 0)."""
    problem = problems.of(case)
    names = parse_names(case.get("let", {}))
    out = dict(case)
    for k in problem.expressions:
        out[k] = parse(case[k] if k in case else problem.defaults[k], names)
    if "exact" in case:
        ex = out["exact"] = dict(case["exact"])
        for k in problem.exact_keys:
            if k in ex:
                ex[k] = [parse(c, names) for c in ex[k]] if k.startswith("grad") else parse(ex[k], names)
    return out


def _build(tree, x, y, lib):
    b = lambda t: _build(t, x, y, lib)  # noqa: E731
    k = tree[0]
    if k == "table":
        return lib["table"](tree[1], b)
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


def _minimum_number(np, smaller):
    """min (smaller=True) or max of two arrays as src/expr.rs: a NaN is ignored, and of +0 and -0
    min takes -0, max +0 (np.fmin and np.fmax return their second argument on a tie)."""

    def f(a, b):
        a, b = np.broadcast_arrays(a, b)
        first = (a < b if smaller else a > b) | np.isnan(b) | ((a == b) & (np.signbit(a) == smaller))
        return np.where(first, a, b)

    return f


def _groups():
    from . import groups

    if groups.CURRENT is None:
        raise RuntimeError("a table per physical group, but no mesh file with groups was read")
    return groups.CURRENT


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
        "tan": np.tan,
        "atan": np.arctan,
        "tanh": np.tanh,
        "abs": np.abs,
        "sign": np.sign,
        "floor": np.floor,
        "min": _minimum_number(np, True),
        "max": _minimum_number(np, False),
        "atan2": lambda y, x: np.arctan2(y + 0.0, x),  # in (-pi, pi]: y = -0 is taken as +0
        "if": np.where,
        "table": lambda entries, b: _groups().numpy(entries, x, y, b),
    }
    with np.errstate(all="ignore"):
        return np.asarray(_build(tree, np.asarray(x, float), np.asarray(y, float), lib), float)


def _ufl_floor(a):
    """floor(a) in UFL. UFL 2022.2 has no floor, but FFCx turns a plain MathFunction into a call
    of the C function of its name. Two things a plain MathFunction lacks are added: UFL rebuilds
    an operator as `type(o)(*operands)`, which MathFunction(name, argument) does not take, so its
    rebuild keeps the name (UFL's own functions, its subclasses, are rebuilt as before); and the
    derivative rules call `derivative()` of a function they have no rule for (the SNES Jacobian
    differentiates the loads too), which is 0 for floor."""
    import ufl
    from ufl.core.operator import Operator
    from ufl.mathfunctions import MathFunction

    def rebuild(self, *operands):
        if type(self) is MathFunction:
            return MathFunction(self._name, *operands)
        return Operator._ufl_expr_reconstruct_(self, *operands)

    def derivative(self):
        if self._name != "floor":
            raise ExprError("no derivative of %s" % self._name)
        return ufl.as_ufl(0.0)

    MathFunction._ufl_expr_reconstruct_ = rebuild
    MathFunction.derivative = derivative
    return MathFunction("floor", a)


def to_ufl(tree, mesh):
    """The expression as UFL of the spatial coordinate of `mesh`. sign is UFL's (0 at 0, as NumPy;
    it differs from NumPy only at NaN, where UFL gives 1); min and max are C's fmin and fmax
    (which of +0 and -0 they return is left open: it matters only for 1/min(x, -x) at x = 0)."""
    import ufl

    X = ufl.SpatialCoordinate(mesh)
    lib = {
        "table": lambda entries, b: _groups().ufl(entries, mesh, b),
        "const": lambda v: ufl.as_ufl(v),
        "cmp": lambda op, a, c: {"<": ufl.lt, "<=": ufl.le, ">": ufl.gt, ">=": ufl.ge}[op](a, c),
        "and": ufl.And,
        "or": ufl.Or,
        "sqrt": ufl.sqrt,
        "exp": ufl.exp,
        "log": ufl.ln,
        "sin": ufl.sin,
        "cos": ufl.cos,
        "tan": ufl.tan,
        "atan": ufl.atan,
        "tanh": ufl.tanh,
        "abs": abs,
        "sign": ufl.sign,
        "floor": _ufl_floor,
        "min": ufl.min_value,
        "max": ufl.max_value,
        "atan2": ufl.atan_2,
        "if": ufl.conditional,
    }
    return _build(tree, X[0], X[1], lib)


def to_numpy_gradient(tree, x, y):
    """(value, d/dx, d/dy) of the expression at points (x, y), by forward-mode differentiation of
    the tree: exact (up to round-off) wherever the expression is differentiable. The value is that
    of `to_numpy`; min, max and if take the derivative of the branch they select; sign and floor
    have derivative 0; a^c with a constant c is c a^(c-1) a' (0 where a' = 0)."""
    import numpy as np

    x, y = np.broadcast_arrays(np.asarray(x, float), np.asarray(y, float))
    zero, one = np.zeros(x.shape), np.ones(x.shape)

    def cond(t):
        k = t[0]
        if k == "cmp":
            a, c = b(t[2])[0], b(t[3])[0]
            return {"<": a < c, "<=": a <= c, ">": a > c, ">=": a >= c}[t[1]]
        if k in ("and", "or"):
            return (np.logical_and if k == "and" else np.logical_or)(cond(t[1]), cond(t[2]))
        raise ExprError("not a condition: %r" % (t,))

    def b(t):
        k = t[0]
        if k == "const":
            return np.full(x.shape, t[1]), zero, zero
        if k == "x":
            return x, one, zero
        if k == "y":
            return y, zero, one
        if k == "neg":
            v, dx, dy = b(t[1])
            return -v, -dx, -dy
        if k in ("+", "-", "*", "/", "^"):
            (a, ax, ay), (c, cx, cy) = b(t[1]), b(t[2])
            if k == "+":
                return a + c, ax + cx, ay + cy
            if k == "-":
                return a - c, ax - cx, ay - cy
            if k == "*":
                return a * c, ax * c + a * cx, ay * c + a * cy
            if k == "/":
                return a / c, (ax * c - a * cx) / c ** 2, (ay * c - a * cy) / c ** 2
            v = a ** c
            if t[2][0] == "const":
                d = c * a ** (c - 1.0)
                return v, np.where(ax == 0, 0.0, d * ax), np.where(ay == 0, 0.0, d * ay)
            return v, v * (cx * np.log(a) + c * ax / a), v * (cy * np.log(a) + c * ay / a)
        if k == "call":
            name = t[1]
            if name == "if":
                c = cond(t[2])
                (a, ax, ay), (e, ex, ey) = b(t[3]), b(t[4])
                return np.where(c, a, e), np.where(c, ax, ex), np.where(c, ay, ey)
            args = [b(s) for s in t[2:]]
            if name in ("min", "max"):
                (a, ax, ay), (c, cx, cy) = args
                smaller = name == "min"  # the selection of _minimum_number
                first = (a < c if smaller else a > c) | np.isnan(c) | ((a == c) & (np.signbit(a) == smaller))
                return np.where(first, a, c), np.where(first, ax, cx), np.where(first, ay, cy)
            if name == "atan2":
                (p, px, py), (q, qx, qy) = args
                r2 = p * p + q * q
                return np.arctan2(p + 0.0, q), (q * px - p * qx) / r2, (q * py - p * qy) / r2
            (a, ax, ay), = args
            v, d = {
                "sqrt": lambda: (np.sqrt(a), 0.5 / np.sqrt(a)),
                "exp": lambda: (np.exp(a), np.exp(a)),
                "log": lambda: (np.log(a), 1.0 / a),
                "sin": lambda: (np.sin(a), np.cos(a)),
                "cos": lambda: (np.cos(a), -np.sin(a)),
                "tan": lambda: (np.tan(a), 1.0 + np.tan(a) ** 2),
                "atan": lambda: (np.arctan(a), 1.0 / (1.0 + a * a)),
                "tanh": lambda: (np.tanh(a), 1.0 - np.tanh(a) ** 2),
                "abs": lambda: (np.abs(a), np.sign(a)),
                "sign": lambda: (np.sign(a), zero),
                "floor": lambda: (np.floor(a), zero),
            }[name]()
            return v, d * ax, d * ay
        raise ExprError("bad tree %r" % (t,))

    with np.errstate(all="ignore"):
        return b(tree)
