"""Formats the lines printed by `cargo bench --bench phases` (stdin) as the `make bench` tables and
checks the targets of the multilevel solver (issue #14):
- at 1024^2 cells the multigrid contact solve <= 0.5 x one Cholesky Poisson solve on the same mesh;
- at 4096^2 cells (16.8M vertices) the peak memory of the whole run <= 400 bytes per vertex, and its
  contact solve <= 20 x the 1024^2 one;
- CG iterations per level printed (flat from level to level);
and of the solver layer (issue #25):
- at 4096^2 the contact solve on all threads >= 1.7 x faster than on one;
- the contact solve against one multigrid Poisson solve of the same code on the same mesh (how many
  Poisson solves the contact problem costs).

and the targets of whole runs (issue #26), `membrane-contact solve --n N [options]` timed as a
process (`whole SPEC ...` lines: the CLI's summary, /usr/bin/time's wall and peak, the result's
bytes):
- at 1024^2 the whole `solve` of the default case <= 3 x its contact solve (`--estimate`: <= 4 x,
  and the estimate phase <= 1 x the contact solve, issue #27);
- at 4096^2 the whole `solve` <= 3 x its contact solve and its peak <= 400 bytes per vertex;
- the result <= 200 bytes per vertex, written in <= 0.5 x the contact solve.

Each size is run several times; timings on a shared machine vary by tens of per cent from run to
run, so the tables show the fastest run of each (its phases) and the median, and ratios of both.
The whole runs also show the CPU seconds the kernel spent for the process (/usr/bin/time's %S),
most of it zeroing and mapping memory the run touches for the first time: on a virtual machine
whose host takes freed memory back, that costs far more than on bare metal (docs/performance.md,
"Measuring").

Usage (from the repository root): ... | /usr/bin/python3 -m reference.bench_table
"""
import re
import statistics
import sys

KINDS = ("poisson", "contact", "contact-mg", "poisson-mg", "contact-mg-1")


def parse(line):
    words = line.split()
    return words[0], words[1], dict(w.split("=", 1) for w in words[2:])


def label(mesh):
    """`1024` → 1024², `disk-6` → disk, refined 6 times."""
    return mesh + "²" if mesh.isdigit() else "disk, refined %s times" % mesh.split("-")[1]


def order(mesh):
    return (not mesh.isdigit(), int(mesh.split("-")[-1]))


def fastest(rows, key):
    return min(rows, key=lambda r: float(r[key]))


def median(rows, key):
    return statistics.median(float(r[key]) for r in rows)


def per_vertex(row):
    return float(row["peak_mb"]) * 2**20 / float(row["vertices"])


PHASES = re.compile(r"seconds\s+mesh ([\d.]+), assembly ([\d.]+), contact solve ([\d.]+) .*?postprocess ([\d.]+)"
                    r"(?:, estimate ([\d.]+))?, write ([\d.]+)")


def parse_whole(line):
    """A `whole SPEC ...` line: the phases of the CLI's summary and the process's figures."""
    spec = line.split()[1]
    m = PHASES.search(line)
    if not m:
        raise SystemExit("bench_table: no phases in: " + line.strip()[:200])
    row = dict(zip(("mesh", "assembly", "contact", "postprocess", "estimate", "write"),
                   (float(v) if v else 0.0 for v in m.groups())))
    row["vertices"] = int(re.search(r"mesh\s+(\d+) vertices", line).group(1))
    for key in ("wall", "sys", "peak_kb", "bytes"):
        row[key] = float(re.search(key + r"=([\d.]+)", line).group(1))
    row["ratio"] = row["wall"] / row["contact"]
    return spec, row


def whole_table(whole):
    """The whole-run rows and their targets."""
    print("\nWhole runs, `membrane-contact solve --n N` as a process (seconds; the fastest run, median of the "
          "ratio in brackets; kernel CPU: the seconds the kernel spent for the process, on all threads):\n")
    cols = ("run", "vertices", "runs", "mesh", "assembly", "contact solve", "postprocess", "estimate", "write",
            "whole process", "kernel CPU", "whole / contact solve", "write / contact solve", "peak MB",
            "peak bytes/vertex",
            "output bytes/vertex")
    print("| " + " | ".join(cols) + " |")
    print("|" + "---|" * len(cols))
    verdicts = []
    verdict = lambda ok: "met" if ok else "NOT MET"
    for spec, rows in whole.items():
        r = min(rows, key=lambda r: r["wall"])
        ratio = statistics.median(x["ratio"] for x in rows)
        peak = max(x["peak_kb"] * 1024 / x["vertices"] for x in rows)
        out = r["bytes"] / r["vertices"]
        n, options = spec.split(":")[0], " ".join(spec.split(":")[1:]).replace(",", " ")
        print("| %s | %d | %d | %.3f | %.3f | %.3f | %.3f | %s | %.3f | %.2f (median %.2f) | %.2f | **%.2f** (%.2f) | %.2f "
              "| %.0f | %.0f | %.0f |" % (
                  ("%s² %s" % (n, options)).strip(), r["vertices"], len(rows), r["mesh"], r["assembly"], r["contact"], r["postprocess"],
                  "%.3f" % r["estimate"] if "estimate" in options else "—", r["write"], r["wall"],
                  statistics.median(x["wall"] for x in rows), r["sys"], r["ratio"], ratio, r["write"] / r["contact"],
                  r["peak_kb"] / 1024, peak, out))
        limit = 4 if "estimate" in options else 3
        line = "- %s: whole / contact solve %.2f (median %.2f; target <= %d): %s" % (
            ("%s² %s" % (n, options)).strip(), r["ratio"], ratio, limit, verdict(r["ratio"] <= limit))
        if "estimate" in options:
            e = r["estimate"] / r["contact"]
            line += "; estimate / contact solve %.2f (target <= 1): %s" % (e, verdict(e <= 1))
        if n == "4096":
            line += "; peak %.0f bytes per vertex (target <= 400): %s" % (peak, verdict(peak <= 400))
        if not options:
            line += "; output %.0f bytes per vertex (target <= 200): %s, written in %.2f x the contact solve " \
                    "(target <= 0.5): %s" % (out, verdict(out <= 200), r["write"] / r["contact"],
                                             verdict(r["write"] <= 0.5 * r["contact"]))
        verdicts.append(line)
    print("\nTargets of whole runs:")
    print("\n".join(verdicts))


def main():
    runs, whole = {}, {}
    for line in sys.stdin:
        if line.startswith(tuple(k + " " for k in KINDS)):
            kind, n, values = parse(line)
            runs.setdefault(n, {}).setdefault(kind, []).append(values)
        elif line.startswith("whole "):
            spec, row = parse_whole(line)
            whole.setdefault(spec, []).append(row)
    meshes = sorted(runs, key=order)

    print("Multigrid contact solve (`[solver] linear = \"multigrid\"`, the default):\n")
    cols = ("mesh", "vertices", "runs", "mesh", "assembly", "coarse levels", "transfers", "coarse operators",
            "CG", "postprocess", "write", "contact solve", "active-set iterations", "CG iterations v; steps",
            "CG iterations per coarser level (most)", "peak MB", "bytes/vertex")
    print("| " + " | ".join(cols) + " |")
    print("|" + "---|" * len(cols))
    for n in meshes:
        cs = runs[n].get("contact-mg")
        if not cs:
            continue
        c = fastest(cs, "contact_solve")
        peak = max(cs, key=per_vertex)
        print("| %s | %s | %d | %s | %s | %s | %s | %s | %s | %s | %s | %s (median %.3f) | %s + %s local (coarser: %s) "
              "| %s; %s | %s | %s | %.0f |" % (
                  label(n), c["vertices"], len(cs), c["mesh"], c["assembly"], c["coarse"], c["symbolic"],
                  c["numeric"], c["solve"], c["postprocess"], c["write"], c["contact_solve"],
                  median(cs, "contact_solve"), c["iterations"], c["local_iterations"], c["coarse_iterations"],
                  c["cg_v"], c["cg"], c["coarse_cg_max"], peak["peak_mb"], per_vertex(peak)))

    print("\nAgainst one Cholesky Poisson solve (symbolic + numeric + solve, one thread) on the same mesh:\n")
    cols = ("mesh", "Poisson, Cholesky", "contact, direct", "contact, multigrid", "multigrid / Poisson",
            "median ratio", "direct / Poisson", "peak MB Poisson / direct / multigrid")
    print("| " + " | ".join(cols) + " |")
    print("|" + "---|" * len(cols))
    ratios = {}
    for n in meshes:
        ps, ds, ms = (runs[n].get(k) for k in KINDS[:3])
        if not ps or not ms:
            continue
        p, m = fastest(ps, "total"), fastest(ms, "contact_solve")
        ratio = float(m["contact_solve"]) / float(p["total"])
        ratios[n] = ratio
        d = fastest(ds, "contact_solve") if ds else None
        print("| %s | %s (median %.3f) | %s | %s (median %.3f) | **%.2f** | %.2f | %s | %s / %s / %s |" % (
            label(n), p["total"], median(ps, "total"), d["contact_solve"] if d else "—", m["contact_solve"],
            median(ms, "contact_solve"), ratio, median(ms, "contact_solve") / median(ps, "total"),
            "%.2f" % (float(d["contact_solve"]) / float(p["total"])) if d else "—", p["peak_mb"],
            max(r["peak_mb"] for r in ds) if ds else "—", max(r["peak_mb"] for r in ms)))

    speedups = threads_table(runs, meshes)
    print("\nseconds; fastest run of each (median in brackets). The contact solve is wall clock: the v "
          "solve beside the coarser levels of nested iteration, then the active-set steps for w, every "
          "kernel on all threads.\n")
    print("Targets:")
    verdict = lambda ok: "met" if ok else "NOT MET"
    if "1024" in ratios:
        print("- 1024²: multigrid contact solve / Poisson Cholesky = %.2f (target <= 0.5, stretch 0.25): %s"
              % (ratios["1024"], verdict(ratios["1024"] <= 0.5)))
    big, small = runs.get("4096", {}).get("contact-mg"), runs.get("1024", {}).get("contact-mg")
    if big:
        worst = max(per_vertex(r) for r in big)
        print("- 4096²: peak memory %.0f bytes per vertex (target <= 400, stretch 250): %s"
              % (worst, verdict(worst <= 400)))
        if small:
            growth = float(fastest(big, "contact_solve")["contact_solve"]) / float(
                fastest(small, "contact_solve")["contact_solve"])
            print("- 4096²: contact solve %.1f x the 1024² one (target <= 20; 16 = linear): %s"
                  % (growth, verdict(growth <= 20)))
    if "4096" in speedups:
        print("- 4096²: contact solve on %s threads %.2f x faster than on one (target >= 1.7): %s"
              % (speedups["4096"][0], speedups["4096"][1], verdict(speedups["4096"][1] >= 1.7)))

    if whole:
        whole_table(whole)


def threads_table(runs, meshes):
    """The contact solve on all threads against one thread and against one multigrid Poisson solve;
    returns the speed-ups by mesh (threads, fastest ratio)."""
    print("\nThe multigrid contact solve on all threads, on one, and against one multigrid Poisson solve "
          "(CG + V-cycles from zero to 1e-12, transfers and set-up included) on the same mesh:\n")
    cols = ("mesh", "threads", "contact", "contact, 1 thread", "speed-up (median)", "Poisson, multigrid",
            "contact / Poisson (median)")
    print("| " + " | ".join(cols) + " |")
    print("|" + "---|" * len(cols))
    speedups = {}
    for n in meshes:
        ms, ones, pmg = (runs[n].get(k) for k in ("contact-mg", "contact-mg-1", "poisson-mg"))
        if not ms or not (ones or pmg):
            continue
        m = fastest(ms, "contact_solve")
        cells = [label(n), m.get("threads", "?"), m["contact_solve"]]
        if ones:
            o = fastest(ones, "contact_solve")
            speedup = float(o["contact_solve"]) / float(m["contact_solve"])
            speedups[n] = (m.get("threads", "?"), speedup)
            cells += [o["contact_solve"], "%.2f (%.2f)" % (speedup, median(ones, "contact_solve") /
                                                           median(ms, "contact_solve"))]
        else:
            cells += ["—", "—"]
        if pmg:
            p = fastest(pmg, "total")
            cells += [p["total"], "%.2f (%.2f)" % (float(m["contact_solve"]) / float(p["total"]),
                                                   median(ms, "contact_solve") / median(pmg, "total"))]
        else:
            cells += ["—", "—"]
        print("| " + " | ".join(cells) + " |")
    return speedups


if __name__ == "__main__":
    main()
