"""Checks every case with an exact solution symbolically (SymPy): the loads are f1 = -mu1 lap u1 -
lambda and f2 = -mu2 lap u2 + lambda, the gradients are those of u1 and u2, u1 - u2 >= 0,
lambda >= 0, (u1 - u2) lambda = 0, u1 = g and u2 = 0 on the boundary.

Derivatives are taken by SymPy on the case's own expressions (piecewise parts included) and
compared at random points of each region, away from the kinks where they are not defined.

Usage: /usr/bin/python3 reference/exact_cases.py [CASE.toml ...]   (default: data/cases/*.toml)
"""
import glob
import os
import sys
import tomllib

import numpy as np
import sympy as sp

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import expr  # noqa: E402

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def sample(case, rng, count):
    """Random points of the domain and of its boundary."""
    m = case["mesh"]
    if m["kind"] == "rectangle":
        (x0, y0), (x1, y1) = m.get("corners", [[0, 0], [1, 1]])
        p = rng.uniform([x0, y0], [x1, y1], (count, 2))
        t = rng.uniform(0, 1, count)
        side = rng.integers(0, 4, count)
        bx = np.select([side == 0, side == 1, side == 2], [x0 + t * (x1 - x0), x1, x0 + t * (x1 - x0)], x0)
        by = np.select([side == 0, side == 1, side == 2], [y0, y0 + t * (y1 - y0), y1], y0 + t * (y1 - y0))
        return p, np.c_[bx, by]
    if m["kind"] == "lshape":
        p = rng.uniform(-1, 1, (3 * count, 2))
        p = p[~((p[:, 0] > 0) & (p[:, 1] < 0))][:count]
        t = rng.uniform(-1, 1, count)
        b = np.c_[t, np.ones(count)]
        return p, b
    raise ValueError("no sampler for mesh kind %r" % m["kind"])


def check(path, count=400, tol=1e-9):
    case = tomllib.load(open(path, "rb"))
    ex = case["exact"]
    sym = lambda e: expr.to_sympy(expr.parse(e))[0]  # noqa: E731
    x, y = sp.symbols("x y", real=True)
    u1, u2, lam = sym(ex["u1"]), sym(ex["u2"]), sym(ex["lambda"])
    f1, f2, g = sym(case["f1"]), sym(case["f2"]), sym(case["g"])
    mu1, mu2 = sp.nsimplify(case["mu1"]), sp.nsimplify(case["mu2"])
    lap = lambda u: sp.diff(u, x, 2) + sp.diff(u, y, 2)  # noqa: E731
    residuals = {
        "f1 + mu1 lap u1 + lambda": f1 + mu1 * lap(u1) + lam,
        "f2 + mu2 lap u2 - lambda": f2 + mu2 * lap(u2) - lam,
    }
    for name in ("u1", "u2"):
        grad = ex.get("grad_" + name)
        if grad:
            u = u1 if name == "u1" else u2
            residuals["d%s/dx" % name] = sym(grad[0]) - sp.diff(u, x)
            residuals["d%s/dy" % name] = sym(grad[1]) - sp.diff(u, y)
    rng = np.random.default_rng(1)
    p, b = sample(case, rng, count)
    failures = []
    mods = [{"Heaviside": lambda s: np.heaviside(s, 0.5), "DiracDelta": lambda s: 0.0 * s}, "numpy"]
    for name, r in residuals.items():
        fn = sp.lambdify((x, y), r.rewrite(sp.Piecewise), modules=mods)
        v = np.broadcast_to(np.asarray(fn(p[:, 0], p[:, 1]), float), (len(p),))
        bad = np.abs(v) > tol
        if bad.any():
            failures.append("%s = %.3e at %s" % (name, v[bad][0], p[bad][0]))
    num = lambda e, q: np.broadcast_to(  # noqa: E731
        np.asarray(sp.lambdify((x, y), e.rewrite(sp.Piecewise), modules=mods)(q[:, 0], q[:, 1]), float), (len(q),)
    )
    gap, lv = num(u1 - u2, p), num(lam, p)
    if (gap < -tol).any():
        failures.append("u1 - u2 < 0 at %s" % p[gap < -tol][0])
    if (lv < -tol).any():
        failures.append("lambda < 0 at %s" % p[lv < -tol][0])
    if (np.abs(gap * lv) > tol).any():
        failures.append("(u1 - u2) lambda != 0 at %s" % p[np.abs(gap * lv) > tol][0])
    if (np.abs(num(u1 - g, b)) > tol).any() or (np.abs(num(u2, b)) > tol).any():
        failures.append("boundary conditions u1 = g, u2 = 0 fail")
    if (num(g, b) < 0).any():
        failures.append("g < 0 on the boundary")
    return failures


def main(paths):
    paths = paths or sorted(glob.glob(os.path.join(ROOT, "data", "cases", "*.toml")))
    ok = True
    for path in paths:
        with open(path, "rb") as f:
            if "exact" not in tomllib.load(f):
                continue
        failures = check(path)
        ok &= not failures
        print("%-40s %s" % (os.path.relpath(path, ROOT), "exact solution checked" if not failures else "FAIL"))
        for line in failures:
            print("    " + line)
    return ok


if __name__ == "__main__":
    sys.exit(0 if main(sys.argv[1:]) else 1)
