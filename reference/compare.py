"""Field-by-field comparison of two result files (Rust solver and reference), matched by vertex
coordinates: max-norm and L2 differences of u1, u2, gap and lambda, relative to the size of the
displacements (for u1, u2, gap) or of the action (for lambda: max |lambda|, or max |f1|, |f2| at the
vertices when there is no contact), so that a field that vanishes is compared at its natural scale.

Usage: /usr/bin/python3 reference/compare.py A.h5 B.h5 [--tol 1e-8]
"""
import argparse
import os
import sys

import tomllib

import h5py
import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import expr  # noqa: E402
from solve_reference import match_points  # noqa: E402

FIELDS = ("u1", "u2", "gap", "lambda")


def lumped_mass(points, cells):
    p = points[cells]
    area = 0.5 * np.abs(
        (p[:, 1, 0] - p[:, 0, 0]) * (p[:, 2, 1] - p[:, 0, 1]) - (p[:, 1, 1] - p[:, 0, 1]) * (p[:, 2, 0] - p[:, 0, 0])
    )
    m = np.zeros(len(points))
    np.add.at(m, cells.ravel(), np.repeat(area / 3.0, 3))
    return m


def compare(path_a, path_b):
    """{field: (relative max difference, relative L2 difference)} and the contact mismatch count."""
    with h5py.File(path_a, "r") as a, h5py.File(path_b, "r") as b:
        pa, pb = a["mesh/geometry"][...], b["mesh/geometry"][...]
        perm = match_points(pa, pb)
        m = lumped_mass(pa, a["mesh/topology"][...])
        fields = {k: (a["mesh/" + k][...], b["mesh/" + k][...][perm]) for k in FIELDS}
        case = tomllib.loads(a.attrs["case_text"])
        loads = [np.abs(expr.to_numpy(expr.parse(case[f]), pa[:, 0], pa[:, 1])).max() for f in ("f1", "f2")]
        u_scale = max(np.abs(v).max() for k in ("u1", "u2") for v in fields[k])
        lam_scale = max(np.abs(fields["lambda"][0]).max(), np.abs(fields["lambda"][1]).max(), *loads)
        out = {}
        for k in FIELDS:
            x, y = fields[k]
            size = max(lam_scale if k == "lambda" else u_scale, 1e-300)
            out[k] = (np.abs(x - y).max() / size, np.sqrt(np.sum(m * (x - y) ** 2) / np.sum(m)) / size)
        mismatch = int(np.sum(a["mesh/contact"][...] != b["mesh/contact"][...][perm]))
    return out, mismatch


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("a")
    ap.add_argument("b")
    ap.add_argument("--tol", type=float, default=1e-8)
    args = ap.parse_args()
    diffs, mismatch = compare(args.a, args.b)
    ok = mismatch == 0
    for k, (mx, l2) in diffs.items():
        good = mx <= args.tol
        ok &= good
        print("%-7s max %.2e  L2 %.2e  %s" % (k, mx, l2, "ok" if good else "FAIL"))
    print("contact sets differ at %d vertices" % mismatch)
    sys.exit(0 if ok else 1)


if __name__ == "__main__":
    main()
