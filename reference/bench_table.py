"""Formats the lines printed by `cargo bench --bench phases` (stdin) as the `make bench` table:
phases of the contact solve beside one Poisson factorization + solve on the same mesh, the ratio
(target <= 3 at 1024^2 cells) and peak memory (target <= 3 GB)."""
import sys


def parse(line):
    words = line.split()
    return words[0], int(words[1]), dict(w.split("=", 1) for w in words[2:])


def main():
    runs = {}
    for line in sys.stdin:
        if line.startswith(("poisson ", "contact ")):
            kind, n, values = parse(line)
            runs.setdefault(n, {})[kind] = values
    cols = ("cells", "vertices", "mesh", "assembly", "coarse", "symbolic", "numeric", "solve", "postproc",
            "contact solve", "iterations", "Poisson", "ratio", "peak MB", "Poisson MB")
    print("| " + " | ".join(cols) + " |")
    print("|" + "---|" * len(cols))
    for n in sorted(runs):
        c, p = runs[n].get("contact"), runs[n].get("poisson")
        if not c or not p:
            continue
        ratio = float(c["contact_solve"]) / float(p["total"])
        print("| %d² | %s | %s | %s | %s | %s | %s | %s | %s | %s | %s (coarse %s) | %s | **%.2f** | %s | %s |" % (
            n, c["vertices"], c["mesh"], c["assembly"], c["coarse"], c["symbolic"], c["numeric"], c["solve"],
            c["postprocess"], c["contact_solve"], c["iterations"], c["coarse_iterations"], p["total"], ratio,
            c["peak_mb"], p["peak_mb"]))
    print("\nseconds; ratio = contact solve (coarse levels + symbolic + numeric + solves) / Poisson "
          "(symbolic + numeric + solve). Targets at 1024²: ratio <= 3, peak <= 3000 MB.")


if __name__ == "__main__":
    main()
