"""Field-by-field comparison of a Rust result with a reference file, matched by vertex coordinates:
max-norm and L2 differences of the fields of the case's problem (reference/problems.py) -- u1,
u2, gap, lambda (membrane 1's action) and lambda2 (membrane 2's); or u, gap, lambda for the
obstacle problem -- relative to the size of the displacements (for u1, u2, u, gap) or of the
action (for lambda, lambda2: their max, or the max of the loads at the vertices when there is no
contact), so that a field that vanishes is compared at its natural scale.

Usage (from the repository root):
    /usr/bin/python3 -m reference.compare RESULT_DIR REFERENCE.h5 [--tol 1e-8]
"""
import argparse
import sys

import numpy as np

from . import common


def compare(rust, ref):
    """{field: (relative max difference, relative L2 difference)} and the contact mismatch count,
    for a Rust result (common.read_result) and a reference (common.read_reference)."""
    pa, problem = rust["points"], rust["problem"]
    perm = common.match_points(pa, ref["points"])
    m = common.lumped_mass(pa, rust["cells"])
    fields = {k: (rust[k], ref[k][perm]) for k in problem.compared}
    loads = [np.abs(common.at_points(rust["case"][f], pa)).max() for f in problem.loads]
    u_scale = max(np.abs(v).max() for k in problem.displacements for v in fields[k])
    lam_scale = max(*(np.abs(v).max() for k in problem.actions for v in fields[k]), *loads)
    out = {}
    for k, (x, y) in fields.items():
        size = max(lam_scale if k in problem.actions else u_scale, 1e-300)
        out[k] = (np.abs(x - y).max() / size, np.sqrt(np.sum(m * (x - y) ** 2) / np.sum(m)) / size)
    mismatch = int(np.sum(rust["contact"] != ref["contact"][perm]))
    return out, mismatch


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("rust", help="a result directory of membrane-contact solve")
    ap.add_argument("reference", help="a file of reference.solve_reference or reference.solve_mixed")
    ap.add_argument("--tol", type=float, default=1e-8)
    args = ap.parse_args()
    diffs, mismatch = compare(common.read_result(args.rust), common.read_reference(args.reference))
    ok = mismatch == 0
    for k, (mx, l2) in diffs.items():
        good = mx <= args.tol
        ok &= good
        print("%-7s max %.2e  L2 %.2e  %s" % (k, mx, l2, "ok" if good else "FAIL"))
    print("contact sets differ at %d vertices" % mismatch)
    sys.exit(0 if ok else 1)


if __name__ == "__main__":
    main()
