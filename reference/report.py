"""The tables and plots of the validation report (validate.py)."""
import math
import os

import numpy as np

from . import common, flux_checks

# (key, label, the paper's rate on convex domains: Thm 9 for H1 (exact), Thm 21 for H-1 (at least))
NORMS = (("h1_u1", "|u1-u1h|_H1", 1.0), ("h1_u2", "|u2-u2h|_H1", 1.0), ("h1_u", "|u-uh|_H1", 1.0),
         ("l2_u1", "||u1-u1h||_L2", None), ("l2_u2", "||u2-u2h||_L2", None), ("l2_u", "||u-uh||_L2", None),
         ("energy", "energy norm", None),
         ("l2_lambda", "||lam-lamh||_L2", None), ("hminus1_lambda", "||lam-lamh||_H-1", 1.0))
NEGLIGIBLE = 1e-10


def eocs(h, e):
    return [math.log(e[i - 1] / e[i]) / math.log(h[i - 1] / h[i]) if e[i] > NEGLIGIBLE and e[i - 1] > NEGLIGIBLE
            else float("nan") for i in range(1, len(e))]


def fmt(v):
    return "—" if v is None or (isinstance(v, float) and math.isnan(v)) else "%.3e" % v


def eoc(rates, i):
    return "%.3f" % rates[i - 1] if i and not math.isnan(rates[i - 1]) else "—"


def header(tol, eoc_agreement, theory_margin):
    return ["# Validation report", "",
            "Rust solver against the dolfinx %s + PETSc SNES-VI reference (`reference/solve_reference.py`) "
            "and the mixed (u1, u2, λ) reference (`reference/solve_mixed.py`) on the same meshes; field "
            "differences are relative to the field's max norm (tolerance %.0e). Error norm values must agree "
            "within twice the same norm of the two codes' field difference plus 1e-9 (relative); EOCs within "
            "%.2f; on convex domains the Rust H1 EOC must be within %.1f of 1 (Thm 9) and the H-1 EOC of the "
            "action at least 1 - %.1f (Thm 21; computed as the dual norm over P1 on the dual submesh S_h). "
            "The written fluxes are checked by `reference/flux_checks.py`."
            % (common.dolfinx_version(), tol, eoc_agreement, theory_margin, theory_margin), ""]


def field_table(result):
    problem = result["levels"][0]["problem"]
    names = {"lambda": "λ", "lambda2": "λ2"}
    compared = " | ".join("max Δ%s" % names.get(k, k) for k in problem.compared)
    lines = ["| level | vertices | %s | contact mismatches | Rust it. | SNES it. | mixed: max Δu | mixed: max Δ%s "
             "| mixed: mismatches | mixed it. |" % (compared, ", Δ".join(names[k] for k in problem.actions)),
             "|---" * (10 + len(problem.compared) - 1) + "|"]
    for lv in result["levels"]:
        d, md = lv["diffs"], lv["mixed_diffs"]
        lines.append("| %s | %d | %s | %d | %d | %d | %s | %s | %d | %d |" % (
            lv["n"], lv["vertices"], " | ".join(fmt(d[k][0]) for k in problem.compared),
            lv["mismatch"], lv["rust_iterations"], lv["snes_iterations"],
            fmt(max(md[k][0] for k in problem.displacements + ("gap",))),
            fmt(max(md[k][0] for k in problem.actions)), lv["mixed_mismatch"], lv["mixed_iterations"]))
    return lines + [""]


def error_table(result):
    """Errors of both codes, EOCs, and the relative difference of the values with its tolerance."""
    keys = [(k, label) for k, label, _ in NORMS if k in result["rates"]]
    lines = ["| level | h |" + "".join(" %s Rust | EOC | reference | EOC | value Δ (tol) |" % label for _, label in keys),
             "|" + "---|" * (2 + 5 * len(keys))]
    for i, lv in enumerate(result["levels"]):
        row = "| %s | %.4f |" % (lv["n"], lv["h"])
        for key, _ in keys:
            er, ef = result["rates"][key]
            rel, tol = lv["norm_checks"].get(key, (float("nan"), float("nan")))
            row += " %s | %s | %s | %s | %.1e (%.1e) |" % (fmt(lv["rust"].get(key)), eoc(er, i), fmt(lv["ref"][key]),
                                                           eoc(ef, i), rel, tol)
        lines.append(row)
    return lines + [""]


def flux_table(result):
    """The checks of the written fluxes per level (t1h, t2h; th above an obstacle)."""
    names = list(result["levels"][0]["flux"])
    rates = {s: result["rates"].get(flux_checks.named("flux", s)) for s in names}
    has_error = any(rates.values())
    lines = ["| level |" + "".join(" normal jump t%sh |" % s for s in names)
             + "".join(" conservation t%sh |" % s for s in names)
             + ("".join(" ‖t%sh+μ%s∇u%s‖ | EOC |" % (s, s, s) for s in names) if has_error else ""),
             "|---" * (1 + (4 if has_error else 2) * len(names)) + "|"]
    for i, lv in enumerate(result["levels"]):
        f = lv["flux"]
        row = "| %s |" % lv["n"] + "".join(" %s |" % fmt(f[s]["jump"]) for s in names) \
            + "".join(" %s |" % fmt(f[s]["conservation"][0]) for s in names)
        if has_error:
            row += "".join(" %s | %s |" % (fmt(f[s].get("error")), eoc(rates[s][0], i) if rates[s] else "—")
                           for s in names)
        lines.append(row)
    return lines + [""]


def tables(result):
    """Markdown tables of one case: field agreement, errors and EOCs, flux checks."""
    lines = ["### %s — %s" % (result["name"], result["title"]), ""] + field_table(result)
    if any(k in result["rates"] for k, _, _ in NORMS):
        lines += error_table(result)
    return lines + (flux_table(result) if result["levels"][0]["flux"] else [])


def convergence_plot(result, out):
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6, 4.5))
    h = np.array([lv["h"] for lv in result["levels"]])
    for key, label, _ in NORMS:
        e = np.array([lv["rust"].get(key, np.nan) for lv in result["levels"]])
        if key not in result["rates"] or not (e > NEGLIGIBLE).any():
            continue
        line, = ax.loglog(h, e, "o-", label=label + " (Rust)")
        ax.loglog(h, [lv["ref"][key] for lv in result["levels"]], "x--", color=line.get_color(),
                  label=label + " (reference)")
    for slope, style in ((1, ":"), (2, "-.")):
        ax.loglog(h, 0.5 * (h / h[0]) ** slope * ax.get_ylim()[1], "k" + style, lw=0.8, label="slope %d" % slope)
    ax.set_xlabel("h")
    ax.set_ylabel("error")
    ax.set_title(result["name"])
    ax.legend(fontsize=7)
    return save(fig, out, result["name"] + "-convergence.png", 110)


def fields_plot(result, out):
    import matplotlib.pyplot as plt
    import matplotlib.tri as mtri

    finest = common.read_result(result["levels"][-1]["dir"])
    tri = mtri.Triangulation(finest["points"][:, 0], finest["points"][:, 1], finest["cells"])
    shown = finest["problem"].displacements + ("gap", "lambda")
    fig, axes = plt.subplots(1, len(shown), figsize=(4 * len(shown), 3.6))
    for ax, field in zip(axes, shown):
        im = ax.tripcolor(tri, finest[field], shading="gouraud")
        ax.set_aspect("equal")
        ax.set_title(field)
        fig.colorbar(im, ax=ax, shrink=0.8)
    fig.suptitle("%s, level %s (Rust)" % (result["name"], result["levels"][-1]["n"]))
    return save(fig, out, result["name"] + "-fields.png", 90)


def save(fig, out, name, dpi):
    """Writes the figure to OUT/NAME and closes it; returns NAME."""
    import matplotlib.pyplot as plt

    fig.tight_layout()
    fig.savefig(os.path.join(out, name), dpi=dpi)
    plt.close(fig)
    return name


def plots(result, out):
    import matplotlib

    matplotlib.use("Agg")
    return ([convergence_plot(result, out)] if result["rates"] else []) + [fields_plot(result, out)]


def write(out, lines, failures, seconds):
    lines = lines + ["## Verdict", ""] + (["- " + f for f in failures] if failures else ["All checks passed."])
    lines.append("\n(%.1f s)" % seconds)
    path = os.path.join(out, "report.md")
    with open(path, "w") as f:
        f.write("\n".join(lines) + "\n")
    print("\nreport: %s" % path)
