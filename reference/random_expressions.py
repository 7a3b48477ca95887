"""Random expressions of the case language with their values, for tests/expressions.rs.

Each expression is built as a syntax tree, written out as case-language text (with random spacing
and redundant parentheses) and evaluated with NumPy DIRECTLY FROM THE TREE: that evaluation is the
oracle the parsers are checked against, and it never reads the text. Some expressions are made to
be rejected (syntax errors, conditions outside if, unknown names, wrong arity, bad [let] names,
nesting beyond the limits) and are marked with why. Before writing, the Python reference's parser
(reference/expr.py, to NumPy) is checked against the oracle on every expression.

Output (JSON): {"points": [[repr of x, repr of y], ...], "cases": [{"lets": [[name, text], ...], "text": ...,
"values": [repr of the value at each point, or null where it is ill-conditioned (see `oracle`),
...] or null, "derivatives": [[∂x, ∂y, ∂²/∂x², ∂²/∂y²] at each point, or null where they are not
well-conditioned (see `derivatives`), ...] or null, "reject": why or null}, ...]}; numbers are `repr` strings so that nan and inf
survive JSON, and so that they are read back exactly (serde_json's default float parsing may be
off by a unit in the last place).

Usage (from the repository root):
    /usr/bin/python3 -m reference.random_expressions --seed 1 --count 10000 --out cases.json
"""
import argparse
import json
import math
import sys

import numpy as np

from . import expr

ONE = ("sqrt", "exp", "log", "sin", "cos", "tan", "atan", "tanh", "abs", "sign", "floor")
TWO = ("min", "max", "atan2")
NUMPY = {"sqrt": np.sqrt, "exp": np.exp, "log": np.log, "sin": np.sin, "cos": np.cos, "tan": np.tan,
         "atan": np.arctan, "tanh": np.tanh, "abs": np.abs, "sign": np.sign, "floor": np.floor,
         "min": lambda a, b: signed_zeros(np.fmin(a, b), a, b, np.logical_or),
         "max": lambda a, b: signed_zeros(np.fmax(a, b), a, b, np.logical_and),
         "atan2": lambda y, x: np.arctan2(y + 0.0, x)}  # in (-pi, pi]: y = -0 is taken as +0
COMPARE = {"<": np.less, "<=": np.less_equal, ">": np.greater, ">=": np.greater_equal}
ARITHMETIC = {"+": np.add, "-": np.subtract, "*": np.multiply, "/": np.divide, "^": np.power}
# Binding strength of each node kind (a child weaker than its slot needs parentheses).
LEVEL = {"or": 0, "and": 1, "cmp": 2, "+": 3, "-": 3, "*": 4, "/": 4, "neg": 5, "pos": 5, "^": 6}
LET_NAMES = ("r", "C", "a1", "_t", "s_2", "rho", "Exp", "xx", "pi2", "e_")
NOT_NAMES = ("z", "X", "Pi", "E", "foo", "ln", "sinh", "pow", "PI", "x1")
RTOL = 1e-12
NOISE = 4e-15
RUNS = 6
SAFETY = 10


def signed_zeros(value, a, b, negative):
    """The documented tie of min and max: of +0 and -0, min is -0 (negative = or: either is -0)
    and max is +0 (negative = and: both are -0)."""
    zeros = (a == 0) & (b == 0)
    return np.where(zeros, np.where(negative(np.signbit(a), np.signbit(b)), -0.0, 0.0), value)


class Gen:
    """Random trees: ("num", text, value), ("x",), ("y",), ("pi",), ("e",), ("name", n),
    ("neg"|"pos", a), (op, a, b) for + - * / ^, ("fn", f, args...), ("if", c, a, b), and the
    conditions ("cmp", op, a, b), ("and", c, d), ("or", c, d)."""

    def __init__(self, rng):
        self.rng = rng

    def pick(self, seq):
        return seq[self.rng.integers(len(seq))]

    def number(self):
        r = self.rng
        v = self.pick([0.5, 1, 2, 3, 0.25, 0.1, 10]) if r.random() < 0.5 else round(r.uniform(0, 5), 3)
        text = self.pick(["%r" % float(v), "%g" % v, "%.3e" % v, "%.2E" % v])
        if v == int(v) and r.random() < 0.5:
            text = self.pick(["%d" % v, "%d." % v])
        if text.startswith("0.") and len(text) > 2 and r.random() < 0.3:
            text = text[1:]
        return ("num", text, float(text))

    def num(self, depth, names):
        r = self.rng
        if depth <= 0 or r.random() < 0.15:
            leaves = [("x",), ("y",), ("x",), ("y",), ("pi",), ("e",)] + [("name", n) for n in names]
            return self.number() if r.random() < 0.35 else self.pick(leaves)
        k = r.random()
        sub = lambda: self.num(depth - 1, names)  # noqa: E731
        if k < 0.35:
            op = self.pick("+-*/")
            return (op, sub(), sub())
        if k < 0.45:
            small = str(r.integers(0, 5))  # a small integer exponent (a^k is a loop of products in Rust)
            exponent = ("num", small, float(small)) if r.random() < 0.3 else (
                self.number() if r.random() < 0.4 else sub())
            return ("^", sub(), exponent)
        if k < 0.55:
            return (self.pick(["neg", "neg", "pos"]), sub())
        if k < 0.75:
            return ("fn", self.pick(ONE), sub())
        if k < 0.85:
            return ("fn", self.pick(TWO), sub(), sub())
        return ("if", self.cond(depth - 1, names), sub(), sub())

    def cond(self, depth, names):
        r = self.rng
        if depth <= 0 or r.random() < 0.5:
            a, b = self.num(depth - 1, names), self.num(depth - 1, names)
            return ("cmp", self.pick(list(COMPARE)), a, b)
        return (self.pick(["and", "or"]), self.cond(depth - 1, names), self.cond(depth - 1, names))


def text(node, rng, need=0):
    """The case-language text of a tree; parentheses where the slot (binding `need`) requires,
    and at random elsewhere."""
    k = node[0]
    level = LEVEL.get(k, 7)
    s = " " if rng.random() < 0.5 else ""
    t = lambda n, need: text(n, rng, need)  # noqa: E731
    if k == "num":
        out = node[1]
    elif k in ("x", "y", "pi", "e"):
        out = k
    elif k == "name":
        out = node[1]
    elif k in ("neg", "pos"):
        out = ("-" if k == "neg" else "+") + s + t(node[1], 5)
    elif k == "^":
        out = t(node[1], 7) + s + "^" + s + t(node[2], 5)
    elif k in ("+", "-", "*", "/"):
        out = t(node[1], level) + s + k + s + t(node[2], level + 1)
    elif k == "cmp":
        out = t(node[2], 3) + s + node[1] + s + t(node[3], 3)
    elif k in ("and", "or"):
        out = t(node[1], level) + s + {"and": "&&", "or": "||"}[k] + s + t(node[2], level + 1)
    else:
        args = node[1:] if k == "if" else node[2:]
        name = "if" if k == "if" else node[1]
        out = name + "(" + ("," + s).join(t(a, 0) for a in args) + ")"
    if level < need or rng.random() < 0.08:
        out = "(" + s + out + s + ")"
    return out


def evaluate(node, x, y, lets, noise=None, flags=None, kinks=None):
    """The oracle: the tree evaluated with NumPy (`lets` maps names to trees). With `noise` (a
    random generator), x and y have rows (runs): row 0 is computed as is, the others with every
    computed number perturbed by a relative NOISE; `flags` (one per point) is then set where a
    discontinuity is within the spread of the runs (see `oracle`), and `kinks` where a jump of a
    derivative is within it or met exactly (`near_kink`)."""
    ev = lambda n: evaluate(n, x, y, lets, noise, flags, kinks)  # noqa: E731
    k = node[0]
    if k == "num":
        return np.full(x.shape, node[2])
    if k in ("x", "y"):
        return x if k == "x" else y
    if k in ("pi", "e"):
        return np.full(x.shape, math.pi if k == "pi" else math.e)
    if k == "name":
        return ev(lets[node[1]])
    args = [ev(a) for a in node[1:] if isinstance(a, tuple)]
    if noise is not None:
        near_discontinuity(k, node, args, flags)
        near_kink(k, node, args, kinks)
    if k == "cmp":
        return COMPARE[node[1]](*args)
    if k in ("and", "or"):
        return (np.logical_and if k == "and" else np.logical_or)(*args)
    if k in ("neg", "pos"):
        value = -args[0] if k == "neg" else args[0]
    elif k in ARITHMETIC:
        value = ARITHMETIC[k](*args)
    elif k == "fn":
        value = NUMPY[node[1]](*args)
    else:
        value = np.where(*args)
    if noise is None:
        return value
    factor = 1 + noise.choice([-1, 1], x.shape) * noise.uniform(NOISE / 4, NOISE, x.shape)
    factor[0] = 1
    return value * factor


def near_discontinuity(k, node, args, flags):
    """flags |= points where the exact run (row 0) is within SAFETY spreads of the runs from a
    jump: a comparison's equality, floor's integers, sign's and sqrt's and log's 0, atan2's
    negative x axis, the integer exponents of a negative base, base 0 and ±1, exponent 0, and
    factors, numerators and denominators at 0."""
    def spread(a):
        return np.abs(a - a[0]).max(axis=0)

    def near(distance, a):
        return np.abs(distance) < SAFETY * spread(a)

    if k == "cmp":
        a, b = args
        flags |= near(a[0] - b[0], a - b)
    elif k == "fn" and node[1] in ("sign", "sqrt", "log"):
        flags |= near(args[0][0], args[0])
    elif k == "fn" and node[1] == "floor":
        flags |= near(args[0][0] - np.round(args[0][0]), args[0])
    elif k == "fn" and node[1] == "atan2":
        flags |= (args[1][0] < 0) & near(args[0][0], args[0])
    elif k == "^":
        base, p = args
        flags |= (base[0] < 0) & near(p[0] - np.round(p[0]), p)
        flags |= near(base[0], base)  # the domain's edge (0^p is 0 or inf, b^p NaN below 0)
        flags |= near(np.abs(base[0]) - 1, base) | near(p[0], p)  # 1^p, b^0 = 1; (±1)^inf = 1
    elif k in ("*", "/"):
        flags |= near(args[0][0], args[0]) | near(args[1][0], args[1])  # 0 * inf, 0 / 0, 1 / ±0


def near_kink(k, node, args, kinks):
    """kinks |= points where a derivative may jump within SAFETY spreads of the runs, or exactly
    there: abs and sign at 0, a tie of min or max, a comparison's equality, floor at an integer, a
    power's base at 0 (and every discontinuity of the value, `near_discontinuity`). At such a point
    the derivative of the branch taken is not the derivative of the function (|y²| at y = 0)."""
    def near(distance, a):
        return np.abs(distance) <= SAFETY * np.abs(a - a[0]).max(axis=0)

    if k == "cmp" or (k == "fn" and node[1] in ("min", "max")):
        a, b = args
        kinks |= near(a[0] - b[0], a - b)
    elif k == "fn" and node[1] in ("abs", "sign", "sqrt", "log"):
        kinks |= near(args[0][0], args[0])
    elif k == "fn" and node[1] == "floor":
        kinks |= near(args[0][0] - np.round(args[0][0]), args[0])
    elif k == "^":
        kinks |= near(args[0][0], args[0])


def oracle(tree, x, y, lets, rng, kinks=None):
    """The values of a tree at the points, None where they are ill-conditioned: where RUNS - 1
    evaluations with every computed number perturbed by a relative NOISE / 4 to NOISE (5 to 20
    units in the last place) move the value by more than RTOL / 10, or put a jump (`near_discontinuity`) within
    reach. There the last bits of the functions (NumPy's vectorised exp, log, ... against the C
    library's that Rust calls) decide the value, which is then no reference. Five perturbed runs:
    perturbations are rounded to whole units in the last place, so that two perturbed terms of a
    cancelling sum can cancel exactly in one run by chance. `kinks`, if given, is set where a
    derivative may jump (`near_kink`)."""
    flags = np.zeros(x.shape, bool)
    kinks = np.zeros(x.shape, bool) if kinks is None else kinks
    runs = [np.broadcast_to(c, (RUNS, len(c))) for c in (x, y)]
    with np.errstate(all="ignore"):
        v = evaluate(tree, *runs, lets, rng, flags, kinks)
    stable = np.logical_and.reduce([close(v[0], w, RTOL / 10) for w in v[1:]]) & ~flags
    return [repr(float(a)) if ok else None for a, ok in zip(v[0], stable)]


def derivatives(case, pts, values, kinks):
    """∂x, ∂y (forward differentiation of the reference parser's tree, expr.to_numpy_gradient) and
    ∂²/∂x², ∂²/∂y² (central differences of those) at each point where they are well-conditioned:
    the value is finite and well-conditioned, no derivative may jump there (`kinks`, from
    `near_kink`), the value is the mean of its neighbours' at ±1e-5 (to 1e-8), the gradient agrees with central differences of the value at two steps, and the
    second differences at two steps agree; None elsewhere (where the differences lose their
    digits). A first derivative is then known to
    about 1e-12, a second to about 1e-6 (the differences' error)."""
    tree = expr.parse(case["text"], expr.parse_names(dict(case["lets"])))
    n = len(pts)
    # The points, then each shifted by ±h along x and along y for h = 1e-5, 1e-4: one evaluation.
    shifts = [(k, h, sign) for k in (0, 1) for h in (1e-5, 1e-4) for sign in (1, -1)]
    at = np.concatenate([pts] + [pts + sign * h * np.eye(2)[k] for k, h, sign in shifts])
    with np.errstate(all="ignore"):
        values_at = expr.to_numpy(tree, at[:, 0], at[:, 1])
        gradients_at = expr.to_numpy_gradient(tree, at[:, 0], at[:, 1])[1:]
        block = lambda f, j: f[n * j:n * (j + 1)]  # noqa: E731
        value, gx, gy = block(values_at, 0), block(gradients_at[0], 0), block(gradients_at[1], 0)

        def along(k, h, f):
            j = 1 + shifts.index((k, h, 1))
            return (block(f, j) - block(f, j + 1)) / (2 * h)

        scale = np.abs(value) + np.abs(gx) + np.abs(gy) + 1.0
        ok = np.isfinite(scale) & np.array([v is not None for v in values]) & ~kinks
        second = []
        for k, g in ((0, gx), (1, gy)):
            # Continuous there (not a branch the points beside it do not take), and the gradient
            # that of the differences.
            j = 1 + shifts.index((k, 1e-5, 1))
            ok &= np.abs(value - (block(values_at, j) + block(values_at, j + 1)) / 2) <= 1e-8 * scale
            ok &= np.abs(along(k, 1e-5, values_at) - g) <= 1e-6 * scale
            ok &= np.abs(along(k, 1e-4, values_at) - g) <= 1e-4 * scale
            fine, coarse = along(k, 1e-5, gradients_at[k]), along(k, 1e-4, gradients_at[k])
            ok &= np.isfinite(fine) & (np.abs(fine - coarse) <= 1e-6 * (scale + np.abs(fine)))
            second.append(fine)
    out = [None] * n
    for i in np.flatnonzero(ok):
        out[i] = [repr(float(v[i])) for v in (gx, gy, second[0], second[1])]
    return out


def valid(gen, rng):
    """A random expression, with [let] names some of the time: (lets, tree)."""
    lets, names = [], []
    if rng.random() < 0.3:
        for _ in range(rng.integers(1, 4)):
            name = gen.pick([n for n in LET_NAMES if n not in names])
            lets.append((name, gen.num(2, names)))
            names.append(name)
    return lets, gen.num(int(rng.integers(1, 6)), names)


def rejected(gen, rng):
    """An expression that must be rejected: (lets as text, text, why)."""
    n = text(gen.num(3, []), rng)
    c = text(gen.cond(2, []), rng)
    unknown = gen.pick(NOT_NAMES)
    one, two = gen.pick(ONE), gen.pick(TWO)
    kinds = {
        "syntax": [n + " " + gen.pick(["+", "-", "*", "/", "^", "<", "&&", "||", ",", "("]), "(" + n, n + ")",
                   n + " " + gen.number()[1], n + " * * 2", "", "  ", "()", "1..2", "1.2.3", "2e+", "x" + " e",
                   n + gen.pick([" $ ", " ! ", " # ", " = ", " % ", " ? "]) + "x", "x\v+ 1", "x +\u00a01",
                   "x + \u0663", "sin(x)\u2009"],
        "condition outside if": [c, "(" + c + ")", "(" + c + ") + " + n, one + "(" + c + ")", "-(" + c + ")",
                                 "if(" + c + ", " + c + ", 1)", two + "(" + c + ", 1)", "(" + c + ")^2",
                                 "2^(" + c + ")", "if(" + n + ", 1, 2)", "if(x && y < 1, 1, 2)",
                                 "if(" + c + " || (x), 1, 2)"],
        "unknown name": [n + " + " + unknown, unknown + "(x)", gen.pick(["x", "y", "pi", "e"]) + "(1)",
                         one + " + 1", two],
        "wrong arity": [one + "(x, " + n + ")", two + "(" + n + ")", two + "(x, y, " + n + ")",
                        "if(" + c + ", 1)", "if(" + c + ", 1, 2, 3)", one + "()"],
        "too deep": ["(" * 32 + "x" + ")" * 32, "-" * 32 + "x", "sin(" * 32 + "x" + ")" * 32],
    }
    lets = {
        "shadowing": [[(gen.pick(["x", "y", "pi", "e", "sin", "if", "floor", "sign"]), "1")], "1"],
        "forward reference": [[("a", "b + 1"), ("b", "x")], "a"],
        "self reference": [[("a", "a + 1")], "a"],
        "cycle": [[("a", "b"), ("b", "a")], "a + b"],
        "unknown name in [let]": [[("a", unknown + " + 1")], "a"],
        "not a name": [[(gen.pick(["2a", "a-b", "a b", ""]), "1")], "1"],
        "named value called": [[("r", "x")], "r(1)"],
        "condition as named value": [[("c", c)], "if(c, 1, 2)"],
        "names too large": [[("a0", "x")] + [("a%d" % k, "a%d + a%d" % (k - 1, k - 1)) for k in range(1, 17)], "a16"],
    }
    if rng.random() < 0.2:
        why = gen.pick(list(lets))
        return [list(kv) for kv in lets[why][0]], lets[why][1], why
    why = gen.pick(list(kinds))
    return [], gen.pick(kinds[why]), why


def points(rng, count=16):
    """Points of a box, with the special values the conditions and functions meet."""
    special = [[0.0, 0.0], [-0.0, 0.0], [0.5, 0.5], [1.0, -1.0], [-0.5, 2.0], [0.25, 0.1]]
    return np.array(special + rng.uniform(-2.0, 2.0, size=(count - len(special), 2)).tolist())


def close(a, b, rtol=RTOL):
    """Elementwise: equal to rtol relative, or both NaN, or the same infinity."""
    a, b = np.asarray(a, float), np.asarray(b, float)
    with np.errstate(invalid="ignore"):
        near = np.abs(a - b) <= rtol * np.maximum(np.abs(a), np.abs(b))
    return near | (a == b) | (np.isnan(a) & np.isnan(b))


def python_check(case, pts):
    """None if reference/expr.py agrees with the oracle on a case, else what differs."""
    try:
        names = expr.parse_names(dict(case["lets"]))
        values = expr.to_numpy(expr.parse(case["text"], names), pts[:, 0], pts[:, 1])
    except expr.ExprError as e:
        return None if case["reject"] else "rejected (%s), expected %s" % (e, case["values"])
    if case["reject"]:
        return "accepted, expected a rejection (%s)" % case["reject"]
    known = [i for i, v in enumerate(case["values"]) if v is not None]
    expected = np.array([float(case["values"][i]) for i in known])
    if close(values[known], expected).all():
        return None
    return "values %s, expected %s" % (values.tolist(), case["values"])


def generate(seed, count):
    """{"points", "cases"} of `count` random expressions."""
    rng = np.random.default_rng(seed)
    gen = Gen(rng)
    pts = points(rng)
    cases = []
    for depth in (31, 32):  # the nesting limit: 31 parentheses are allowed, 32 are not
        cases.append({"lets": [], "text": "(" * depth + "x" + ")" * depth,
                      "reject": None if depth == 31 else "too deep",
                      "values": None if depth == 32 else [repr(float(v)) for v in pts[:, 0]]})
    while len(cases) < count:
        if rng.random() < 0.2:
            lets, source, why = rejected(gen, rng)
            cases.append({"lets": lets, "text": source, "values": None, "reject": why})
            continue
        lets, tree = valid(gen, rng)
        kinks = np.zeros(len(pts), bool)
        case = {"lets": [[k, text(v, rng)] for k, v in lets], "text": text(tree, rng), "reject": None,
                "values": oracle(tree, pts[:, 0], pts[:, 1], dict(lets), rng, kinks)}
        case["derivatives"] = derivatives(case, pts, case["values"], kinks)
        cases.append(case)
    return {"points": [[repr(float(c)) for c in p] for p in pts], "cases": cases}


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--count", type=int, default=10_000)
    ap.add_argument("--out", required=True)
    args = ap.parse_args(argv)
    data = generate(args.seed, args.count)
    pts = np.array(data["points"], float)
    failures = [(c, why) for c in data["cases"] for why in [python_check(c, pts)] if why]
    for case, why in failures[:10]:
        print("reference/expr.py disagrees on %r (lets %r): %s" % (case["text"], case["lets"], why), file=sys.stderr)
    with open(args.out, "w") as f:
        json.dump(data, f)
    rejected_count = sum(1 for c in data["cases"] if c["reject"])
    values = [v for c in data["cases"] if c["values"] for v in c["values"]]
    gradients = [d for c in data["cases"] if c.get("derivatives") for d in c["derivatives"]]
    print("%d expressions (%d to reject), seed %d, %d of %d values and %d derivatives well-conditioned; "
          "reference/expr.py disagrees on %d" % (len(data["cases"]), rejected_count, args.seed,
                                                 sum(v is not None for v in values), len(values),
                                                 sum(d is not None for d in gradients), len(failures)),
          file=sys.stderr)
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
