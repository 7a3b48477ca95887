"""Checks every case with an exact solution with SymPy, reading the expressions with SymPy's OWN
parser (sympy.parsing.sympy_parser.parse_expr), not the project's parser (reference/expr.py).

Translation of the case language (data/cases/README.md) into SymPy's input, textual and minimal:
  `a ^ b`      -> `a ** b`   (both right-associative, both bind tighter than unary minus)
  `if(c, a, b)` -> `ite(c, a, b)`, ite = Piecewise((a, c), (b, True))   (`if` is a Python keyword)
  `min`, `max`, `abs`, `sign` -> Min, Max, Abs, sign;  `log` is natural in both;  `x`, `y` real
  symbols; numbers become exact rationals (the `rationalize` transformation), `pi` and `e` are
  SymPy's pi and E; the names of the [let] table are SymPy expressions read in file order.
`&&` and `||` are not translated (Python's `&` binds tighter than comparisons), nor is `floor`
(it switches at every integer, which the regions below cannot follow): a case using them is
reported as not checkable.

The statements depend on the case's problem (reference/problems.py): for the membranes, the gap
is u1 - u2 and the boundary values u1 = g, u2 = g2 (default 0); for the obstacle problem the gap
is u - psi and the boundary value u = g. The domain is split into regions where no Max, Min, Abs,
sign or Piecewise switches (sign patterns of their switching functions at sample points); in each
region every switch is replaced by its branch, and there
  - the PDEs  f1 + mu1 lap u1 + lambda = 0,  f2 + mu2 lap u2 - lambda = 0 (obstacle problem:
    f + mu lap u + lambda = 0), the given gradients and the complementarity gap lambda = 0 are
    checked symbolically (simplify), else at the region's sample points (|residual| <= 1e-9);
  - gap >= 0 and lambda >= 0 at the region's sample points (>= -1e-9);
across every switching curve u1, u2 (or u) and their given gradients are continuous: they differ
by at most 1e-5 between the points of each pair 2e-7 apart on either side (the PDEs hold in H^1
only so; for a free boundary it checks the constants of the matching conditions);
and the boundary values and g - g2 >= 0 (g - psi >= 0) on EVERY piece of the boundary: each edge
of a polygon (holes included) or of a mesh file's triangulation, each circle of a disk or annulus
(symbolically along the piece, else at 201 points of it, ends included). Sample points: random
points of the domain, plus pairs 1e-7 on either side of every switching curve (found by
bisection between random points).

Usage (from the repository root):
    /usr/bin/python3 -m reference.exact_cases [CASE.toml ...]   (default: data/cases/*.toml)
"""
import functools
import os
import re
import signal
import sys

import numpy as np
import sympy as sp
from matplotlib.path import Path
from sympy.parsing.sympy_parser import parse_expr, rationalize, standard_transformations

from . import common, problems

X, Y = sp.symbols("x y", real=True)
T = sp.symbols("t", nonnegative=True)
NAMES = {"x": X, "y": Y, "ite": lambda c, a, b: sp.Piecewise((a, c), (b, True)), "min": sp.Min, "max": sp.Max,
         "abs": sp.Abs, "sqrt": sp.sqrt, "exp": sp.exp, "log": sp.log, "sin": sp.sin, "cos": sp.cos,
         "atan2": sp.atan2, "pi": sp.pi, "e": sp.E, "tan": sp.tan, "atan": sp.atan, "tanh": sp.tanh,
         "sign": sp.sign}
TOL = 1e-9
JUMP_TOL = 1e-5  # the largest change of u and grad u across a switching curve (points 2e-7 apart)
SIMPLIFY_SECONDS = 20


def to_sympy(source, names=None):
    """A case expression (string or number) read by SymPy's parser after the translation above;
    `names` are the [let] names read so far."""
    text = repr(source) if isinstance(source, (int, float)) else source
    if "&&" in text or "||" in text or re.search(r"\bfloor\s*\(", text):
        raise ValueError("'&&', '||' and floor are not translated for SymPy: %r" % text)
    text = re.sub(r"\bif\s*\(", "ite(", text.replace("^", "**"))
    return parse_expr(text, local_dict={**NAMES, **(names or {})},
                      transformations=standard_transformations + (rationalize,))


class Domain:
    """The case's domain: a bounding box, a test for points inside, and the boundary pieces, each
    a curve p(t), t in [0, 1], given numerically (`at`) and symbolically (`subs`, x and y in T)."""

    def __init__(self, case, path):
        m = case["mesh"]
        self.pieces = []
        if m["kind"] == "disk":
            c, radii = m.get("centre", [0.0, 0.0]), [m["radius"]] + ([m["inner_radius"]] if "inner_radius" in m else [])
            for r in radii:
                self.circle(c, r)
            self.lo, self.hi = np.subtract(c, m["radius"]), np.add(c, m["radius"])
            r2 = [r * r for r in radii]
            self.inside = lambda p: ((p - c) ** 2).sum(1) < r2[0] if len(r2) == 1 else (
                (((p - c) ** 2).sum(1) < r2[0]) & (((p - c) ** 2).sum(1) > r2[1]))
            return
        rings = self.rings(m, path)
        for ring in rings:
            for k in range(len(ring)):
                self.edge(ring[k], ring[(k + 1) % len(ring)])
        paths = [Path(r) for r in rings]
        self.lo, self.hi = rings[0].min(axis=0), rings[0].max(axis=0)
        self.inside = lambda p: paths[0].contains_points(p) & ~np.any([q.contains_points(p) for q in paths[1:]]
                                                                      + [np.zeros(len(p), bool)], axis=0)

    @staticmethod
    def rings(m, path):
        """The boundary polygons, the outer one first."""
        if m["kind"] == "rectangle":
            (x0, y0), (x1, y1) = m.get("corners", [[0, 0], [1, 1]])
            return [np.array([[x0, y0], [x1, y0], [x1, y1], [x0, y1]], float)]
        if m["kind"] == "lshape":  # (-1, 1)^2 minus [0, 1] x [-1, 0]
            return [np.array([[-1, -1], [0, -1], [0, 0], [1, 0], [1, 1], [-1, 1]], float)]
        if m["kind"] == "polygon":
            return [np.array(r, float) for r in [m["boundary"]] + m.get("holes", [])]
        if m["kind"] == "file":
            return mesh_rings(os.path.join(os.path.dirname(os.path.abspath(path)), m["path"]))
        raise ValueError("no boundary for mesh kind %r" % m["kind"])

    def edge(self, p, q):
        on = {X: sp.nsimplify(p[0]) + T * sp.nsimplify(q[0] - p[0]), Y: sp.nsimplify(p[1]) + T * sp.nsimplify(q[1] - p[1])}
        self.pieces.append(("edge (%g, %g)-(%g, %g)" % (*p, *q), lambda t: p + t * (q - p), on))

    def circle(self, c, r):
        cx, cy, rr = (sp.nsimplify(v) for v in (c[0], c[1], r))
        on = {X: cx + rr * sp.cos(2 * sp.pi * T), Y: cy + rr * sp.sin(2 * sp.pi * T)}
        at = lambda t: np.column_stack([c[0] + r * np.cos(2 * np.pi * t[:, 0]), c[1] + r * np.sin(2 * np.pi * t[:, 0])])  # noqa: E731
        self.pieces.append(("circle about (%g, %g) of radius %g" % (c[0], c[1], r), at, on))


def mesh_rings(path):
    """The boundary loops of a triangle mesh file (read by meshio), the one of largest area first."""
    import meshio
    mesh = meshio.read(path)
    tri = np.concatenate([c.data for c in mesh.cells if c.type == "triangle"])
    edges = np.sort(np.concatenate([tri[:, [0, 1]], tri[:, [1, 2]], tri[:, [2, 0]]]), axis=1)
    unique, count = np.unique(edges, axis=0, return_counts=True)
    nxt = {}
    for a, b in unique[count == 1]:
        nxt.setdefault(a, []).append(b)
        nxt.setdefault(b, []).append(a)
    rings, seen = [], set()
    for start in nxt:
        if start in seen:
            continue
        ring, prev, cur = [start], None, start
        seen.add(start)
        while True:
            step = [v for v in nxt[cur] if v != prev][0]
            if step == start:
                break
            ring.append(step)
            seen.add(step)
            prev, cur = cur, step
        rings.append(mesh.points[ring, :2])
    area = lambda r: abs(np.dot(r[:, 0], np.roll(r[:, 1], -1)) - np.dot(r[:, 1], np.roll(r[:, 0], -1)))  # noqa: E731
    return sorted(rings, key=area, reverse=True)


def switches(exprs):
    """The switching functions s (branch changes where s = 0) of Max, Min, Abs, sign and
    Piecewise."""
    found = []
    for e in exprs:
        for node in sp.preorder_traversal(e):
            if isinstance(node, (sp.Max, sp.Min)) and len(node.args) == 2:
                found.append(node.args[0] - node.args[1])
            elif isinstance(node, (sp.Abs, sp.sign)):
                found.append(node.args[0])
            elif isinstance(node, sp.Piecewise):
                found += [c.lhs - c.rhs for _, c in node.args if isinstance(c, sp.core.relational.Relational)]
    unique = []
    for s in found:
        if not any(sp.expand(s - u) == 0 or sp.expand(s + u) == 0 for u in unique):
            unique.append(s)
    return unique


def numeric(e):
    """e as a NumPy function of points (the branches of a Piecewise that are not taken may be NaN).
    Max and Min are rewritten with Abs (SymPy prints them as NumPy's amax of a tuple, which does
    not work elementwise on arrays)."""
    pair = lambda s: lambda *a: functools.reduce(lambda p, q: (p + q + s * sp.Abs(p - q)) / 2, a)  # noqa: E731
    e = e.replace(sp.Max, pair(1)).replace(sp.Min, pair(-1)) if isinstance(e, sp.Basic) else e
    fn = sp.lambdify((X, Y), e, modules="numpy")

    def at(p):
        with np.errstate(invalid="ignore", divide="ignore"):
            return np.broadcast_to(np.asarray(fn(p[:, 0], p[:, 1]), float), (len(p),))
    return at


def samples(domain, funcs, rng, count=400):
    """Random points of the domain and points 1e-7 on either side of each switching curve."""
    p, pairs = straddles(domain, funcs, rng, count)
    q = np.concatenate([p] + [x for pair in pairs for x in pair])
    return q[domain.inside(q)]


def straddles(domain, funcs, rng, count=400):
    """`count` random points of the domain, and [(a, b)]: for each switching function, points
    a, b 1e-7 on either side of its curve (found by bisection between random points)."""
    p = rng.uniform(domain.lo, domain.hi, (4 * count, 2))
    p = p[domain.inside(p)][:count]
    pairs = []
    for f in funcs:
        v = f(p)
        a, b = p[:count // 2], p[count // 2: 2 * (count // 2)]
        cut = np.sign(v[:count // 2]) * np.sign(v[count // 2: 2 * (count // 2)]) < 0
        a, b = a[cut], b[cut]
        for _ in range(60):  # bisection towards f = 0
            m = 0.5 * (a + b)
            same = np.sign(f(m)) == np.sign(f(a))
            a, b = np.where(same[:, None], m, a), np.where(same[:, None], b, m)
        d = (b - a) / np.maximum(np.linalg.norm(b - a, axis=1), 1e-300)[:, None]
        pairs.append((a - 1e-7 * d, b + 1e-7 * d))
    return p, pairs


def resolve(e, point):
    """e with every Max, Min, Abs, sign and Piecewise replaced by its branch at `point`."""
    at = {X: point[0], Y: point[1]}

    def branch(node):
        if isinstance(node, sp.Max):
            return node.args[0] if (node.args[0] - node.args[1]).evalf(subs=at) > 0 else node.args[1]
        if isinstance(node, sp.Min):
            return node.args[0] if (node.args[0] - node.args[1]).evalf(subs=at) < 0 else node.args[1]
        if isinstance(node, sp.Abs):
            return node.args[0] if node.args[0].evalf(subs=at) >= 0 else -node.args[0]
        if isinstance(node, sp.sign):
            return sp.sign(node.args[0].evalf(subs=at))
        for value, cond in node.args:  # Piecewise
            if cond == sp.true or bool(cond.subs(at)):
                return value
        raise ValueError("no branch of %s at %s" % (node, point))

    return e.replace(lambda n: isinstance(n, (sp.Max, sp.Min, sp.Abs, sp.sign, sp.Piecewise)), branch)


class Timeout(Exception):
    pass


def is_zero(e):
    """True when SymPy simplifies e to 0 (within SIMPLIFY_SECONDS), else False."""
    def alarm(signum, frame):
        raise Timeout()

    old = signal.signal(signal.SIGALRM, alarm)
    signal.alarm(SIMPLIFY_SECONDS)
    try:
        return sp.simplify(e) == 0
    except Timeout:
        return False
    finally:
        signal.alarm(0)
        signal.signal(signal.SIGALRM, old)


def zero_check(name, e, pts, failures, how):
    """e = 0 symbolically, else at the points; records the way it was shown in `how`."""
    if is_zero(e):
        how["symbolic"] += 1
        return
    how["numeric"] += 1
    v = numeric(e)(pts)
    bad = ~(np.abs(v) <= TOL)
    if bad.any():
        failures.append("%s = %.3e at (%.6g, %.6g)" % (name, v[bad][0], *pts[bad][0]))


def read(case, problem):
    """The case's data and exact solution as SymPy expressions, and the problem's gap (u1 - u2 or
    u - psi), boundary values ({displacement: its value}) and the least boundary value of the
    first displacement (g >= g2 or g >= psi)."""
    names = {}
    for k, v in case.get("let", {}).items():
        names[k] = to_sympy(v, names)
    ex = case["exact"]
    e = {k: to_sympy(ex[k], names) for k in problem.displacements + ("lambda",)}
    e.update({k: to_sympy(case[k] if k in case else problem.defaults[k], names) for k in problem.expressions})
    for name in problem.displacements:
        if ex.get("grad_" + name):
            e["grad_" + name] = [to_sympy(c, names) for c in ex["grad_" + name]]
    if problem is problems.MEMBRANES:
        e["gap"], e["floor"], values = e["u1"] - e["u2"], e["g2"], {"u1": "g", "u2": "g2"}
    else:
        e["gap"], e["floor"], values = e["u"] - e["psi"], e["psi"], {"u": "g"}
    e.update({"%s - %s" % (u, g): e[u] - e[g] for u, g in values.items()})
    return e, ["%s - %s" % kv for kv in values.items()]


def region_identities(e, mu, problem):
    """{name: expression that must vanish} in a region (e already resolved there): each
    membrane's PDE (+ lambda on the upper one, - lambda on the lower), the complementarity and
    the gradients."""
    lap = lambda u: sp.diff(u, X, 2) + sp.diff(u, Y, 2)  # noqa: E731
    out = {"gap lambda": e["gap"] * e["lambda"]}
    for i, (u, f, m, t) in enumerate(zip(problem.displacements, problem.loads, mu, problem.tensions)):
        sign = 1 if i == 0 else -1
        out["%s + %s lap %s %s lambda" % (f, t, u, "+-"[i > 0])] = e[f] + m * lap(e[u]) + sign * e["lambda"]
    for name in problem.displacements:
        for k, var in enumerate((X, Y)):
            if "grad_" + name in e:
                out["grad_%s[%d] - d%s/d%s" % (name, k, name, var)] = e["grad_" + name][k] - sp.diff(e[name], var)
    return out


def regions(exprs, pts, funcs):
    """[(resolved exprs, the points of the region)] for the sign patterns of the switches at pts."""
    exprs = dict(exprs)
    signs = np.stack([np.sign(f(pts)) for f in funcs], axis=1) if funcs else np.zeros((len(pts), 0))
    patterns, which = np.unique(signs, axis=0, return_inverse=True)
    out = []
    for k in range(len(patterns)):
        sel = pts[which.ravel() == k]
        resolved = {n: [resolve(c, sel[0]) for c in v] if isinstance(v, list) else resolve(v, sel[0])
                    for n, v in exprs.items()}
        out.append((resolved, sel))
    return out


def check_interior(e, mu, problem, domain, funcs, rng, failures, how):
    """The PDEs, gradients, complementarity and sign conditions in every region."""
    pts = samples(domain, funcs, rng)
    for r, sel in regions(e, pts, funcs):
        for name, res in region_identities(r, mu, problem).items():
            zero_check(name, res, sel, failures, how)
        for name, v in (("gap", r["gap"]), ("lambda", r["lambda"])):
            val = numeric(v)(sel)
            if (val < -TOL).any():
                failures.append("%s = %.3e < 0 at (%.6g, %.6g)" % (name, val.min(), *sel[np.argmin(val)]))
    return len(pts)


def check_continuity(e, problem, domain, funcs, rng, failures):
    """The displacements and their given gradients change by at most JUMP_TOL across every
    switching curve."""
    _, pairs = straddles(domain, funcs, rng)
    fields = [(u, e[u]) for u in problem.displacements]
    fields += [("grad_%s[%d]" % (u, k), c) for u in problem.displacements for k, c in enumerate(e.get("grad_" + u, []))]
    for name, v in fields:
        fn = numeric(v)
        for a, b in pairs:
            inside = domain.inside(a) & domain.inside(b)
            a, b = a[inside], b[inside]
            jump = np.abs(fn(a) - fn(b))
            if (jump > JUMP_TOL).any():
                k = np.argmax(jump)
                failures.append("%s jumps by %.3e across a switching curve at (%.6g, %.6g)" % (name, jump[k], *a[k]))


def check_boundary(e, boundary, domain, funcs, failures, how):
    """The boundary values (the `boundary` keys of e vanish) and g >= g2 (g >= psi) on every
    piece of the boundary."""
    t = np.linspace(0.0, 1.0, 201)[:, None]
    floor = "g - floor"
    for edge, at, on_edge in domain.pieces:
        pts = at(t)
        for r, sel in regions({**{k: e[k] for k in boundary}, floor: e["g"] - e["floor"]}, pts, funcs):
            for name in boundary:
                if is_zero(r[name].subs(on_edge)):
                    how["symbolic"] += 1
                else:
                    zero_check("%s on the %s" % (name, edge), r[name], sel, failures, how)
            g = numeric(r[floor])(sel)
            if (g < -TOL).any():
                failures.append("g is %.3e below its floor (g2 or psi) on the %s" % (g.min(), edge))


def check(path):
    """The failures of one case (an empty list when its exact solution checks out) and how the
    identities were shown ({"symbolic": count, "numeric": count})."""
    case = common.load_case(path)
    problem = problems.of(case)
    e, boundary = read(case, problem)
    mu = tuple(sp.nsimplify(case[k]) for k in problem.tensions)
    everything = [v for k in e for v in (e[k] if isinstance(e[k], list) else [e[k]])]
    funcs = [numeric(s) for s in switches(everything)]
    domain = Domain(case, path)
    failures, how = [], {"symbolic": 0, "numeric": 0}
    count = check_interior(e, mu, problem, domain, funcs, np.random.default_rng(1), failures, how)
    check_continuity(e, problem, domain, funcs, np.random.default_rng(2), failures)
    check_boundary(e, boundary, domain, funcs, failures, how)
    how["points"] = count
    return failures, how


def main(paths):
    paths = paths or common.shipped_cases()
    ok = True
    for path in paths:
        if "exact" not in common.load_case(path):
            continue
        try:
            failures, how = check(path)
        except ValueError as err:
            failures, how = ["not checkable: %s" % err], None
        ok &= not failures
        shown = "" if how is None else " (%d identities symbolically, %d at %d sample points)" % (
            how["symbolic"], how["numeric"], how["points"])
        print("%-40s %s%s" % (os.path.relpath(path, common.ROOT), "FAIL" if failures else "exact solution checked",
                              shown))
        for line in failures[:10]:
            print("    " + line)
    return ok


if __name__ == "__main__":
    sys.exit(0 if main(sys.argv[1:]) else 1)
