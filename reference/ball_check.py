"""The obstacle reference on its own: the ball problem (data/cases/ball.toml) solved by
solve_reference.Obstacle on dolfinx's own meshes of (-2, 2)^2 (create_rectangle, n x n cells),
without the Rust code. Prints the errors against the exact solution and their EOCs, SNES
iterations and seconds per level.

Fails (exit 1) when, on some level, u_h < psi_h at a vertex (the polished solution keeps the bound
exactly), lambda_h < -1e-10 max lambda_h or |lambda_h (u_h - psi_h)| > 1e-10 max lambda_h
max (u_h - psi_h) at a vertex (off the contact set lambda_h is a residual: round-off, ~1e-13 at
64^2, not 0); or when, between the last two
levels, the EOC of |u - u_h|_H1 is off 1 by more than 0.1, that of ||u - u_h||_L2 below 2 - 0.2,
or that of ||lambda - lambda_h||_H-1 (on the dual submesh, as in validate) below 1 - 0.1.

Usage (from the repository root):
    /usr/bin/python3 -m reference.ball_check [--sizes 32 64 128] [--case data/cases/ball.toml]
"""
import argparse
import os
import sys

import numpy as np
from dolfinx import mesh as dmesh
from mpi4py import MPI

from . import common, estimator, expr, norms
from .report import eocs
from .solve_reference import Obstacle

# (error key, its label, the least EOC, the largest EOC)
ROUNDOFF = 1e-10
RATES = (("h1_u", "|u-uh|_H1", 0.9, 1.1), ("l2_u", "||u-uh||_L2", 1.8, None),
         ("hminus1_lambda", "||lam-lamh||_H-1", 0.9, None))


def rectangle(case, n):
    """The vertices and cells of dolfinx's mesh of the case's rectangle, n x n cells."""
    (x0, y0), (x1, y1) = case["mesh"]["corners"]
    m = dmesh.create_rectangle(MPI.COMM_SELF, [np.array([x0, y0]), np.array([x1, y1])], [n, n],
                               cell_type=dmesh.CellType.triangle)
    return m.geometry.x.copy(), m.geometry.dofmap.array.reshape(-1, 3).astype(np.int64)


def level(case, n):
    """Solves one level; its errors, SNES iterations, seconds and the violations of the VI."""
    points, cells = rectangle(case, n)
    ref = Obstacle(points, cells, case)
    res = ref.solve()
    u = res["components"][0]
    lam = np.where(ref.boundary, 0.0, res["lambda"])
    gap = u - ref.lower.x.array
    exact = case["exact"]
    out = {"n": n, "h": 4.0 / n, "snes_iterations": res["snes_iterations"], "seconds": res["snes_seconds"],
           "contact": int(res["active"].sum()), "min_lambda": lam.min(), "min_gap": gap.min(),
           "max_lambda": lam.max(), "max_gap": gap.max(),
           "complementarity": np.abs(lam * gap).max()}
    out["l2_u"], out["h1_u"] = norms.p1_errors(ref.V, u, exact["u"], exact["grad_u"])
    dual_points, dual_cells, owner, _ = estimator.dual_submesh(points, cells)
    dual = norms.DualSubmesh(dual_points, dual_cells)
    out["l2_lambda"], out["hminus1_lambda"] = dual.errors(lam[ref.vertex_dof][owner], exact["lambda"])
    return out


def failures_of(levels):
    """The failed checks of the docstring."""
    out = []
    for lv in levels:
        if (lv["min_gap"] < 0.0 or lv["min_lambda"] < -ROUNDOFF * lv["max_lambda"]
                or lv["complementarity"] > ROUNDOFF * lv["max_lambda"] * lv["max_gap"]):
            out.append("%d²: min lambda %.1e, min gap %.1e, max |lambda gap| %.1e"
                       % (lv["n"], lv["min_lambda"], lv["min_gap"], lv["complementarity"]))
    h = [lv["h"] for lv in levels]
    for key, label, least, most in RATES:
        rate = eocs(h, [lv[key] for lv in levels])[-1]
        if not (rate >= least and (most is None or rate <= most)):
            out.append("EOC of %s is %.3f, outside [%.1f, %s]" % (label, rate, least, most or "inf"))
    return out


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--case", default=os.path.join(common.ROOT, "data", "cases", "ball.toml"))
    ap.add_argument("--sizes", type=int, nargs="+", default=[32, 64, 128])
    args = ap.parse_args()
    case = expr.parse_case(common.load_case(args.case))
    levels = [level(case, n) for n in args.sizes]
    h = [lv["h"] for lv in levels]
    keys = ("h1_u", "l2_u", "l2_lambda", "hminus1_lambda")
    rates = {k: [float("nan")] + eocs(h, [lv[k] for lv in levels]) for k in keys}
    print("| n | vertices in contact | SNES it. | SNES s | " + " | ".join("%s | EOC" % k for k in keys)
          + " | min λ_h | min u_h − ψ_h | max |λ_h (u_h − ψ_h)| |")
    print("|---" * (7 + 2 * len(keys)) + "|")
    for i, lv in enumerate(levels):
        print("| %d² | %d | %d | %.2f | %s | %.2e | %.2e | %.1e |" % (
            lv["n"], lv["contact"], lv["snes_iterations"], lv["seconds"],
            " | ".join("%.3e | %.3f" % (lv[k], rates[k][i]) for k in keys),
            lv["min_lambda"], lv["min_gap"], lv["complementarity"]))
    failures = failures_of(levels)
    for f in failures:
        print("FAIL: " + f)
    sys.exit(1 if failures else 0)


if __name__ == "__main__":
    main()
