"""`make bench-reference`: solve time and iterations of the dolfinx + SNES-VI reference beside the
Rust solver's, on the same meshes, with the ratio, for two problems: the default case (two
membranes) and the ball obstacle problem (data/cases/ball.toml, the benchmark of SNES-VI), each on
N x N cells. The reference runs from a cold start (zero raised to the bound: w = 0, u = max(0,
psi_h) inside, as SNES-VI projects a zero iterate) and with nested iteration (8^2, 16^2, ... N^2, each level started from the
previous solution, interpolated: PETSc's grid sequencing); its time is SNES plus the final
polish solve, without mesh set-up, form compilation and assembly of the bounds.

Target: Rust >= 30x faster than the best reference run at 512^2.

Usage (from the repository root):
    /usr/bin/python3 -m reference.bench_reference --bin target/release/membrane-contact \
        [--sizes 128 256 512] [--ball-sizes 256 512]
"""
import argparse
import os
import subprocess
import tempfile
import time

import numpy as np
from matplotlib.tri import LinearTriInterpolator, Triangulation

from . import common
from .solve_reference import solver

BALL = os.path.join(common.ROOT, "data", "cases", "ball.toml")


def rust(binary, case, n, out):
    """Solves the case (None: the built-in default) on n x n cells into the result directory `out`."""
    t = time.perf_counter()
    subprocess.run([binary, "solve", *([case] if case else []), "--n", str(n), "-o", out], check=True,
                   capture_output=True)
    wall = time.perf_counter() - t
    a = common.read_result(out)["attrs"]
    return {"solve": float(a["seconds_contact_solve"]), "wall": wall, "iterations": int(a["iterations"])}


def reference(path, guess_from=None):
    """The reference's solve of the problem of a Rust result, from a cold start or from the
    solution `guess_from` of a coarser level: its seconds, SNES iterations and solution."""
    data = common.read_result(path)
    r = solver(data["points"], data["cells"], data["case"])
    guess = None
    if guess_from is not None:
        coords = r.V.tabulate_dof_coordinates()
        tri = Triangulation(guess_from["points"][:, 0], guess_from["points"][:, 1], guess_from["cells"])
        guess = [np.asarray(LinearTriInterpolator(tri, c)(coords[:, 0], coords[:, 1]).filled(0.0))
                 for c in guess_from["components"]]
    t = time.perf_counter()
    res = r.solve(guess)
    seconds = time.perf_counter() - t
    dof = r.vertex_dof
    return seconds, res["snes_iterations"], {"points": data["points"], "cells": data["cells"],
                                            "components": [c[dof] for c in res["components"]]}


def rows(binary, case, sizes, tmp):
    """The table rows of one case, as they are measured: Rust, the reference cold and nested, at
    each of `sizes`."""
    nested_total, previous, n = 0.0, None, 8
    while n <= max(sizes):
        path = os.path.join(tmp, "rust-%s-%d" % (os.path.basename(case or "default"), n))
        rs = rust(binary, case, n, path)
        seconds, its, previous = reference(path, previous)
        nested_total += seconds
        if n in sizes:
            cold_seconds, cold_its, _ = reference(path)
            best = min(cold_seconds, nested_total)
            yield n, rs["solve"], rs["iterations"], cold_seconds, cold_its, nested_total, its, best / rs["solve"]
        n *= 2


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--bin", required=True)
    ap.add_argument("--sizes", type=int, nargs="*", default=[128, 256, 512], help="of the default case")
    ap.add_argument("--ball-sizes", type=int, nargs="*", default=[256, 512], help="of the ball problem")
    args = ap.parse_args()
    binary = os.path.abspath(args.bin)
    tmp = tempfile.mkdtemp()
    for title, case, sizes in (("The default case (two membranes)", None, args.sizes),
                               ("The ball obstacle problem (data/cases/ball.toml)", BALL, args.ball_sizes)):
        if not sizes:
            continue
        print("\n%s\n" % title)
        print("| cells | Rust contact solve (s) | Rust it. | reference cold (s) | SNES it. | reference nested, "
              "all levels (s) | SNES it. (finest) | best reference / Rust |")
        print("|---|---|---|---|---|---|---|---|")
        for row in rows(binary, case, sizes, tmp):
            print("| %d² | %.3f | %d | %.2f | %d | %.2f | %d | **%.0f×** |" % row, flush=True)
    print("\nTarget: Rust >= 30x faster than the best reference run at 512².")


if __name__ == "__main__":
    main()
