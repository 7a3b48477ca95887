"""Formats the lines printed by `cargo bench --bench phases` (stdin) as the `make bench` table:
phases of the contact solve beside one Poisson factorization + solve on the same mesh, the ratio
(target <= 3 at 1024^2 cells) and peak memory (target <= 3 GB).

Each size is run several times, alternating the two; timings on a shared machine vary by tens of
per cent from run to run, so the table shows the fastest run of each (its phases) and the median,
and the ratio of both.

Usage (from the repository root): ... | /usr/bin/python3 -m reference.bench_table
"""
import statistics
import sys


def parse(line):
    words = line.split()
    return words[0], words[1], dict(w.split("=", 1) for w in words[2:])


def label(mesh):
    """`1024` → 1024², `disk-6` → disk, refined 6 times."""
    return mesh + "²" if mesh.isdigit() else "disk, refined %s times" % mesh.split("-")[1]


def order(mesh):
    return (not mesh.isdigit(), int(mesh.split("-")[-1]))


def main():
    runs = {}
    for line in sys.stdin:
        if line.startswith(("poisson ", "contact ")):
            kind, n, values = parse(line)
            runs.setdefault(n, {}).setdefault(kind, []).append(values)
    cols = ("mesh", "vertices", "runs", "mesh", "assembly", "coarse", "symbolic", "numeric", "solve",
            "postprocess", "write", "contact solve", "iterations", "Poisson", "ratio", "median ratio", "peak MB",
            "Poisson MB")
    print("| " + " | ".join(cols) + " |")
    print("|" + "---|" * len(cols))
    for n in sorted(runs, key=order):
        cs, ps = runs[n].get("contact"), runs[n].get("poisson")
        if not cs or not ps:
            continue
        c = min(cs, key=lambda r: float(r["contact_solve"]))
        p = min(ps, key=lambda r: float(r["total"]))
        c_med = statistics.median(float(r["contact_solve"]) for r in cs)
        p_med = statistics.median(float(r["total"]) for r in ps)
        print("| %s | %s | %d | %s | %s | %s | %s | %s | %s | %s | %s | %s (median %.3f) | %s + %s local (coarse %s) "
              "| %s (median %.3f) | **%.2f** | %.2f | %s | %s |" % (
                  label(n), c["vertices"], len(cs), c["mesh"], c["assembly"], c["coarse"], c["symbolic"], c["numeric"],
                  c["solve"], c["postprocess"], c["write"], c["contact_solve"], c_med, c["iterations"],
                  c["local_iterations"], c["coarse_iterations"], p["total"], p_med,
                  float(c["contact_solve"]) / float(p["total"]), c_med / p_med, max(r["peak_mb"] for r in cs), p["peak_mb"]))
    print("\nseconds; fastest run of each (median in brackets); ratio = contact solve / Poisson (symbolic + "
          "numeric + solve, one thread). The contact solve is wall clock: symbolic analysis, the v solve, "
          "the coarse levels of nested iteration and the active-set iterations for w on two threads. "
          "Targets at 1024²: ratio <= 3, peak <= 3000 MB.")


if __name__ == "__main__":
    main()
