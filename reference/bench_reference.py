"""`make bench-reference`: solve time and iterations of the dolfinx + SNES-VI reference beside the
Rust solver's, on the same meshes (the default case on N x N cells), with the ratio. The reference
runs from a cold start (w = g_h, no contact) and with nested iteration (8^2, 16^2, ... N^2, each level
started from the previous solution, interpolated); its time is SNES plus the final polish solve,
without mesh set-up, form compilation and assembly of the bounds.

Target: Rust >= 30x faster than the best reference run at 512^2.

Usage (from the repository root):
    /usr/bin/python3 -m reference.bench_reference --bin target/release/membrane-contact [--sizes 128 256 512]
"""
import argparse
import os
import subprocess
import sys
import tempfile
import time

import numpy as np
from matplotlib.tri import LinearTriInterpolator, Triangulation

from . import common
from .solve_reference import Reference


def rust(binary, n, out):
    """Solves the default case on n x n cells into the result directory `out`."""
    t = time.perf_counter()
    subprocess.run([binary, "solve", "--n", str(n), "-o", out], check=True, capture_output=True)
    wall = time.perf_counter() - t
    a = common.read_result(out)["attrs"]
    return {"solve": float(a["seconds_contact_solve"]), "wall": wall, "iterations": int(a["iterations"])}


def reference(path, guess_from=None):
    data = common.read_result(path)
    r = Reference(data["points"], data["cells"], data["case"])
    guess = None
    if guess_from is not None:
        coords = r.V.tabulate_dof_coordinates()
        tri = Triangulation(guess_from["points"][:, 0], guess_from["points"][:, 1], guess_from["cells"])
        guess = [np.asarray(LinearTriInterpolator(tri, guess_from[k])(coords[:, 0], coords[:, 1]).filled(0.0))
                 for k in ("w", "s")]
    t = time.perf_counter()
    res = r.solve(guess)
    seconds = time.perf_counter() - t
    dof = r.vertex_dof
    return seconds, res["snes_iterations"], {"points": data["points"], "cells": data["cells"],
                                            "w": res["w"][dof], "s": res["s"][dof]}


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--bin", required=True)
    ap.add_argument("--sizes", type=int, nargs="*", default=[128, 256, 512])
    args = ap.parse_args()
    binary = os.path.abspath(args.bin)
    tmp = tempfile.mkdtemp()
    rows = []
    nested_total, previous, n = 0.0, None, 8
    while n <= max(args.sizes):
        path = os.path.join(tmp, "rust-%d" % n)
        rs = rust(binary, n, path)
        seconds, its, previous = reference(path, previous)
        nested_total += seconds
        if n in args.sizes:
            cold_seconds, cold_its, _ = reference(path)
            best = min(cold_seconds, nested_total)
            rows.append((n, rs["solve"], rs["iterations"], cold_seconds, cold_its, nested_total, its,
                         best / rs["solve"]))
            print("n=%d done" % n, file=sys.stderr, flush=True)
        n *= 2
    print("| cells | Rust contact solve (s) | Rust it. | reference cold (s) | SNES it. | reference nested, "
          "all levels (s) | SNES it. (finest) | best reference / Rust |")
    print("|---|---|---|---|---|---|---|---|")
    for row in rows:
        print("| %d² | %.3f | %d | %.2f | %d | %.2f | %d | **%.0f×** |" % row)
    print("\nTarget: Rust >= 30x faster than the best reference run at 512².")


if __name__ == "__main__":
    main()
