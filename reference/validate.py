"""`make validate`: every case marked for validation is solved by the Rust code and by two dolfinx
references on the same meshes -- SNES-VI in (w, u2) (solve_reference.py) and a primal-dual
active-set loop on the mixed (u1, u2, lambda) system (solve_mixed.py); fields are compared vertex
by vertex and, for cases with an exact solution, error norms and their experimental orders of
convergence (EOC) side by side.

Fails (exit 1) when fields differ by more than --tol (relative, max norm), contact sets differ,
the two codes' EOCs differ by more than 0.02, the Rust H1 EOC on a convex domain misses the
paper's rate 1 (Theorem 9) by more than 0.1, the H-1 EOC of the action falls below 1 - 0.1
(Theorem 21), the flux reconstruction (4.13) misses the local conservation of Lemma 17, an exact
case fails its SymPy check, or ParaView cannot read a result in double precision. Writes OUT/report.md with plots.
"""
import argparse
import glob
import math
import os
import subprocess
import sys
import time
import tomllib

import h5py
import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)
sys.path.insert(0, HERE)
import compare  # noqa: E402
import exact_cases  # noqa: E402
import solve_mixed  # noqa: E402
import solve_reference  # noqa: E402

# (key, label, the paper's rate on convex domains: Thm 9 for H1 (exact), Thm 21 for H-1 (at least))
NORMS = (("h1_u1", "|u1-u1h|_H1", 1.0), ("h1_u2", "|u2-u2h|_H1", 1.0), ("l2_u1", "||u1-u1h||_L2", None),
         ("l2_u2", "||u2-u2h||_L2", None), ("l2_lambda", "||lam-lamh||_L2", None),
         ("hm1_lambda", "||lam-lamh||_H-1", 1.0))
AT_LEAST = {"hm1_lambda"}
EOC_AGREEMENT = 0.02
THEORY_MARGIN = 0.1
NEGLIGIBLE = 1e-10
FLUX_CONSERVATION = 1e-13  # relative defect of Lemma 17's local conservation, a round-off identity


def eocs(h, e):
    return [math.log(e[i - 1] / e[i]) / math.log(h[i - 1] / h[i]) if e[i] > NEGLIGIBLE and e[i - 1] > NEGLIGIBLE
            else float("nan") for i in range(1, len(e))]


def run_case(path, binary, out, tol, failures):
    case = tomllib.load(open(path, "rb"))
    name = os.path.splitext(os.path.basename(path))[0]
    workdir = os.path.join(out, name)
    os.makedirs(workdir, exist_ok=True)
    levels = []
    for n in case["validation"]["sizes"]:
        rust = os.path.join(workdir, "rust-%d.h5" % n)
        ref = os.path.join(workdir, "reference-%d.h5" % n)
        t = time.perf_counter()
        proc = subprocess.run([binary, "solve", path, "--n", str(n), "--hminus1", "--flux", "-o", rust],
                              capture_output=True, text=True)
        rust_seconds = time.perf_counter() - t
        if proc.returncode != 0:
            failures.append("%s n=%d: Rust solver failed: %s" % (name, n, proc.stderr.strip()))
            return None
        summary = solve_reference.solve_file(rust, ref)
        diffs, mismatch = compare.compare(rust, ref)
        mixed_path = os.path.join(workdir, "mixed-%d.h5" % n)
        mixed = solve_mixed.solve_file(rust, mixed_path)
        mixed_diffs, mixed_mismatch = compare.compare(rust, mixed_path)
        with h5py.File(rust, "r") as f:
            attrs = {k: f.attrs[k] for k in f.attrs}
        level = {"n": n, "h": float(attrs["h"]), "vertices": int(attrs["vertices"]), "diffs": diffs,
                 "mismatch": mismatch, "rust_iterations": int(attrs["iterations"]), "rust_seconds": rust_seconds,
                 "snes_iterations": summary["snes_iterations"], "ref_seconds": summary["seconds"],
                 "mixed_diffs": mixed_diffs, "mixed_mismatch": mixed_mismatch, "mixed_iterations": mixed["iterations"],
                 "rust": {k: float(attrs["error_" + k]) for k, _, _ in NORMS if "error_" + k in attrs},
                 "ref": {k: float(summary[k]) for k, _, _ in NORMS if k in summary}, "file": rust}
        for field, (mx, _) in diffs.items():
            if not mx <= tol:
                failures.append("%s n=%d: %s differs by %.2e (relative max) > %.0e" % (name, n, field, mx, tol))
        if mismatch:
            failures.append("%s n=%d: contact sets differ at %d vertices" % (name, n, mismatch))
        for i in (1, 2):
            defect = float(attrs["flux_conservation_%d" % i])
            if not defect <= FLUX_CONSERVATION:
                failures.append("%s n=%d: the flux t%dh is not conservative on the dual cells (defect %.1e)"
                                % (name, n, i, defect))
        for field, (mx, _) in mixed_diffs.items():
            if not mx <= tol:
                failures.append("%s n=%d: %s differs from the mixed reference by %.2e > %.0e" % (name, n, field, mx, tol))
        if mixed_mismatch:
            failures.append("%s n=%d: contact sets of Rust and the mixed reference differ at %d vertices"
                            % (name, n, mixed_mismatch))
        levels.append(level)
    convex = case["mesh"]["kind"] == "rectangle"
    rates = {}
    if "exact" in case:
        h = [lv["h"] for lv in levels]
        for key, label, theory in NORMS:
            if key not in levels[0]["rust"]:
                continue
            er = eocs(h, [lv["rust"][key] for lv in levels])
            ef = eocs(h, [lv["ref"][key] for lv in levels])
            rates[key] = (er, ef)
            for i, (a, b) in enumerate(zip(er, ef)):
                if not (math.isnan(a) and math.isnan(b)) and not abs(a - b) <= EOC_AGREEMENT:
                    failures.append("%s: EOC of %s differ between codes at level %d: %.3f vs %.3f" % (name, label, i + 1, a, b))
            if convex and theory is not None and er and not math.isnan(er[-1]):
                low = er[-1] < theory - THEORY_MARGIN
                if low or (key not in AT_LEAST and er[-1] > theory + THEORY_MARGIN):
                    failures.append("%s: Rust EOC of %s is %.3f, the paper's rate is %s%.1f"
                                    % (name, label, er[-1], ">= " if key in AT_LEAST else "", theory))
    return {"name": name, "title": case.get("title", ""), "path": path, "levels": levels, "rates": rates,
            "convex": convex, "exact": "exact" in case}


def mesh_files(binary, out, tol, failures):
    """Meshes written by meshio and by dolfinx (XDMF + HDF5), read by the Rust solver: a jittered
    (unstructured) square mesh, the default case's data, compared with the reference."""
    import meshio
    import dolfinx.io
    from mpi4py import MPI

    workdir = os.path.join(out, "mesh_files")
    os.makedirs(workdir, exist_ok=True)
    base = open(os.path.join(ROOT, "data", "cases", "default.toml")).read()
    data = base[: base.index("[mesh]")]
    m = dolfinx.mesh.create_unit_square(MPI.COMM_SELF, 20, 20, cell_type=dolfinx.mesh.CellType.triangle)
    x = m.geometry.x
    inside = (x[:, 0] > 1e-9) & (x[:, 0] < 1 - 1e-9) & (x[:, 1] > 1e-9) & (x[:, 1] < 1 - 1e-9)
    x[inside, :2] += np.random.default_rng(3).uniform(-0.015, 0.015, (inside.sum(), 2))
    cells = m.geometry.dofmap.array.reshape(-1, 3)
    lines = ["| writer | vertices | max Δu1 | max Δu2 | max Δgap | max Δλ | contact mismatches |", "|---|---|---|---|---|---|---|"]
    for writer in ("meshio", "dolfinx"):
        mesh_path = os.path.join(workdir, writer + "_mesh.xdmf")
        if writer == "meshio":
            meshio.write(mesh_path, meshio.Mesh(x.copy(), [("triangle", cells.copy())]))
        else:
            with dolfinx.io.XDMFFile(MPI.COMM_SELF, mesh_path, "w") as f:
                f.write_mesh(m)
        case_path = os.path.join(workdir, writer + ".toml")
        with open(case_path, "w") as f:
            f.write(data + '[mesh]\nkind = "file"\npath = "%s"\n' % os.path.basename(mesh_path))
        rust, ref = os.path.join(workdir, writer + "-rust.h5"), os.path.join(workdir, writer + "-reference.h5")
        proc = subprocess.run([binary, "solve", case_path, "-o", rust], capture_output=True, text=True)
        if proc.returncode != 0:
            failures.append("mesh file from %s: Rust solver failed: %s" % (writer, proc.stderr.strip()))
            continue
        solve_reference.solve_file(rust, ref)
        diffs, mismatch = compare.compare(rust, ref)
        with h5py.File(rust, "r") as f:
            nv = int(f.attrs["vertices"])
        if nv != len(x):
            failures.append("mesh file from %s: %d vertices read, %d written" % (writer, nv, len(x)))
        for field, (mx, _) in diffs.items():
            if not mx <= tol:
                failures.append("mesh file from %s: %s differs by %.2e" % (writer, field, mx))
        if mismatch:
            failures.append("mesh file from %s: contact sets differ at %d vertices" % (writer, mismatch))
        lines.append("| %s | %d | %s | %s | %s | %s | %d |" % (writer, nv, *(fmt(diffs[k][0]) for k in compare.FIELDS), mismatch))
    return ["### Meshes read from files (meshio and dolfinx XDMF, jittered 20 × 20 square, default case data)", ""] + lines + [""]


def fmt(v):
    return "—" if v is None or (isinstance(v, float) and math.isnan(v)) else "%.3e" % v


def tables(result):
    """Markdown tables of one case: field agreement, then errors and EOCs."""
    lines = ["### %s — %s" % (result["name"], result["title"]), "",
             "| n | vertices | max Δu1 | max Δu2 | max Δgap | max Δλ | contact mismatches | Rust it. | SNES it. "
             "| mixed: max Δu | mixed: max Δλ | mixed: mismatches | mixed it. |",
             "|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for lv in result["levels"]:
        d, md = lv["diffs"], lv["mixed_diffs"]
        lines.append("| %d | %d | %s | %s | %s | %s | %d | %d | %d | %s | %s | %d | %d |" % (
            lv["n"], lv["vertices"], fmt(d["u1"][0]), fmt(d["u2"][0]), fmt(d["gap"][0]), fmt(d["lambda"][0]),
            lv["mismatch"], lv["rust_iterations"], lv["snes_iterations"],
            fmt(max(md[k][0] for k in ("u1", "u2", "gap"))), fmt(md["lambda"][0]), lv["mixed_mismatch"],
            lv["mixed_iterations"]))
    lines.append("")
    if result["rates"]:
        head = "| n | h |" + "".join(" %s Rust | EOC | reference | EOC |" % label for key, label, _ in NORMS
                                     if key in result["rates"])
        lines += [head, "|" + "---|" * (2 + 4 * len(result["rates"]))]
        for i, lv in enumerate(result["levels"]):
            row = "| %d | %.4f |" % (lv["n"], lv["h"])
            for key, _, _ in NORMS:
                if key in result["rates"]:
                    er, ef = result["rates"][key]
                    row += " %s | %s | %s | %s |" % (
                        fmt(lv["rust"][key]), "%.3f" % er[i - 1] if i and not math.isnan(er[i - 1]) else "—",
                        fmt(lv["ref"][key]), "%.3f" % ef[i - 1] if i and not math.isnan(ef[i - 1]) else "—")
            lines.append(row)
        lines.append("")
    return lines


def plots(result, out):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import matplotlib.tri as mtri

    images = []
    name = result["name"]
    if result["rates"]:
        fig, ax = plt.subplots(figsize=(6, 4.5))
        h = np.array([lv["h"] for lv in result["levels"]])
        for key, label, _ in NORMS:
            if key not in result["rates"]:
                continue
            e = np.array([lv["rust"][key] for lv in result["levels"]])
            if (e <= NEGLIGIBLE).all():
                continue
            line, = ax.loglog(h, e, "o-", label=label + " (Rust)")
            ax.loglog(h, [lv["ref"][key] for lv in result["levels"]], "x--", color=line.get_color(),
                      label=label + " (reference)")
        for slope, style in ((1, ":"), (2, "-.")):
            ax.loglog(h, 0.5 * (h / h[0]) ** slope * ax.get_ylim()[1], "k" + style, lw=0.8, label="slope %d" % slope)
        ax.set_xlabel("h")
        ax.set_ylabel("error")
        ax.set_title(name)
        ax.legend(fontsize=7)
        fig.tight_layout()
        images.append(name + "-convergence.png")
        fig.savefig(os.path.join(out, images[-1]), dpi=110)
        plt.close(fig)
    with h5py.File(result["levels"][-1]["file"], "r") as f:
        p, c = f["mesh/geometry"][...], f["mesh/topology"][...]
        tri = mtri.Triangulation(p[:, 0], p[:, 1], c)
        fig, axes = plt.subplots(1, 4, figsize=(16, 3.6))
        for ax, field in zip(axes, ("u1", "u2", "gap", "lambda")):
            im = ax.tripcolor(tri, f["mesh/" + field][...], shading="gouraud")
            ax.set_aspect("equal")
            ax.set_title(field)
            fig.colorbar(im, ax=ax, shrink=0.8)
        fig.suptitle("%s, n = %d (Rust)" % (name, result["levels"][-1]["n"]))
        fig.tight_layout()
        images.append(name + "-fields.png")
        fig.savefig(os.path.join(out, images[-1]), dpi=90)
        plt.close(fig)
    return images


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--bin", required=True)
    ap.add_argument("--out", default="validation")
    ap.add_argument("--tol", type=float, default=1e-8)
    ap.add_argument("cases", nargs="*")
    args = ap.parse_args()
    binary = os.path.abspath(args.bin)
    os.makedirs(args.out, exist_ok=True)
    paths = args.cases or sorted(glob.glob(os.path.join(ROOT, "data", "cases", "*.toml")))
    paths = [p for p in paths if "validation" in tomllib.load(open(p, "rb"))]
    failures = []
    start = time.perf_counter()
    print("SymPy check of the exact solutions:")
    if not exact_cases.main(paths):
        failures.append("an exact-solution case fails its SymPy check")
    report = ["# Validation report", "",
              "Rust solver against the dolfinx %s + PETSc SNES-VI reference (`reference/solve_reference.py`) "
              "on the same meshes; field differences are relative to the field's max norm (tolerance %.0e). "
              "EOCs must agree within %.2f; on convex domains the Rust H1 EOC must be within %.1f of 1 (Thm 9) "
              "and the H-1 EOC of the action at least 1 - %.1f (Thm 21; computed as the dual norm over P1 on "
              "the dual submesh S_h)."
              % (solve_reference.dolfinx_version(), args.tol, EOC_AGREEMENT, THEORY_MARGIN, THEORY_MARGIN), ""]
    for path in paths:
        result = run_case(path, binary, args.out, args.tol, failures)
        if result is None:
            continue
        lines = tables(result)
        print("\n" + "\n".join(lines))
        report += lines
        report += ["![%s](%s)" % (img, img) for img in plots(result, args.out)] + [""]
        finest = os.path.splitext(result["levels"][-1]["file"])[0] + ".xdmf"
        pv = subprocess.run([sys.executable, os.path.join(HERE, "paraview_check.py"), finest],
                            capture_output=True, text=True)
        print(pv.stdout.strip())
        report += ["ParaView: `%s`" % pv.stdout.strip(), ""]
        if pv.returncode != 0:
            failures.append("ParaView check failed for %s: %s" % (finest, (pv.stdout + pv.stderr).strip()[-500:]))
    lines = mesh_files(binary, args.out, args.tol, failures)
    print("\n" + "\n".join(lines))
    report += lines
    report += ["## Verdict", ""] + (["- " + f for f in failures] if failures else ["All checks passed."])
    report.append("\n(%.1f s)" % (time.perf_counter() - start))
    with open(os.path.join(args.out, "report.md"), "w") as f:
        f.write("\n".join(report) + "\n")
    print("\nreport: %s" % os.path.join(args.out, "report.md"))
    if failures:
        print("VALIDATION FAILED:")
        for line in failures:
            print("  " + line)
        print("validate: %d passed, %d failed" % (0, len(failures)))
        sys.exit(1)
    print("validate: all %d cases passed" % len(paths))


if __name__ == "__main__":
    main()
