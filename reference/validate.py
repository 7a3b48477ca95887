"""`make validate`: every case marked for validation is solved by the Rust code and by two dolfinx
references on the same meshes -- SNES-VI with bounds (solve_reference: in (w, u2) for the
membranes, in u >= psi_h for the obstacle problem) and a primal-dual active-set loop on the mixed
system with lambda a multiplier (solve_mixed); fields are compared vertex by vertex, the written
fluxes are checked, and for cases with an exact solution the error norms' values and
their experimental orders of convergence (EOC) side by side. The fields and norms are those of
the case's problem (reference/problems.py).

Fails (exit 1) when
  - u1, u2, gap, lambda or lambda2 (obstacle problem: u, gap, lambda) differ by more than --tol
    (relative, max norm) from either reference, or contact sets differ;
  - an error norm's VALUE (L2, H1 of u1, u2 or of u, energy, L2 and H-1 of lambda) differs from the
    reference's by more than 2 (d + q) + 1e-9 e (+1e-15), d the same norm of the difference of the
    two codes' discrete fields (|e_Rust - e_ref| <= d if both integrated exactly: the triangle
    inequality) and q what their quadratures may miss: each code's adaptive rule estimates it
    (the Rust code's error_quadrature, relative, src/norms/cubature.rs: conservative; the
    reference's reference/cubature.py, degree 10 on pieces and their quarters); the H-1 norm is
    one degree-10 rule in both (q = 0). The factor 2 is margin, and 1e-9 e covers round-off;
  - the two codes' EOCs differ by more than 0.02, the Rust H1 EOC on a convex domain misses the
    paper's rate 1 (Theorem 9) by more than 0.1, or the H-1 EOC of the action falls below 1 - 0.1
    (Theorem 21);
  - the written flux fields (t1h, t2h of the membranes, th of u above an obstacle) fail a check of
    reference/flux_checks.py: the normal jump on an interior edge of S_h exceeds 1e-12 of the
    flux scale (an identity: round-off only, ~2e-15 measured); the local conservation (Lemma 17)
    with the reference's loads and lambda misses by more than 1e-11 + 2 (max_a |lambda_Rust -
    lambda_ref| |D_a|) of its scale (round-off, plus what the lambda difference between the codes
    accounts for); ||t_ih + mu_i grad u_i||_L2 (||t_h + mu grad u||_L2 above an obstacle)
    decreases at an EOC below 0.9 between successive levels on a convex domain (rate 1
    expected), below 2/3 - 0.1 on the L-shape (u in H^(5/3 - eps) only, Remark 10); the Rust
    code's own conservation defect exceeds 1e-13;
  - an exact case fails its SymPy check (exact_cases), or ParaView cannot read a result in double
    precision (paraview_check);
  - the a posteriori estimator (`solve --estimate`, on the first validation level of every case of
    two membranes with u2 = 0 on the boundary, on the jittered mesh files and on a mesh whose holes
    touch at a vertex) differs from its recomputation by reference/estimator.py
    (--compare: every attribute and cell field, 1e-9 of eta for the flux, oscillation and means,
    1e-7 for the boundary terms and what contains them), or eta < |||u - u_h||| on an exact case;
  - on meshes made by `adapt` (newest-vertex bisection of the L-shape toward its corner, and of
    the disk with new boundary vertices on the circle), a middle and the last step: fields differ
    from the reference by more than --tol, or the estimator from its recomputation;
  - the default linear solver (multigrid) and Cholesky (`--linear direct`), on the last level of
    every case: u1, u2, the gap or lambda differ by more than 1e-10 of their largest value (for
    lambda, a residual, at least max |f1| + |f2| at the vertices), or the contact sets differ.
Writes OUT/report.md with plots.

Usage (from the repository root):
    /usr/bin/python3 -m reference.validate --bin target/release/membrane-contact --out validation
"""
import argparse
import os
import subprocess
import sys
import time

import numpy as np

from . import common, compare, estimator, exact_cases, flux_checks, problems, report, solve_mixed, solve_reference
from .report import NORMS, eocs

AT_LEAST = {"hminus1_lambda"}
EOC_AGREEMENT = 0.02
THEORY_MARGIN = 0.1
NORM_MARGIN, NORM_ROUNDOFF, NORM_FLOOR = 2.0, 1e-9, 1e-15
FLUX_JUMP = 1e-12  # relative normal jump of t_ih on the edges of S_h (an identity)
CONSERVATION_ROUNDOFF = 1e-11  # relative defect of Lemma 17 beyond the lambda difference
RUST_CONSERVATION = 1e-13  # the Rust code's own reported defect (flux_conservation_i, flux_conservation)
FLUX_RATE = {True: 0.9, False: 2.0 / 3.0 - 0.1}  # minimal EOC of the flux error: convex / L-shape


def levels_of(case):
    """The validation levels of a case: [(option, value, label, file tag)] from `[validation] sizes`
    (cells per side, `--n`) or `[validation] refine` (uniform refinements of any mesh, `--refine`)."""
    v = case["validation"]
    if "refine" in v:
        return [("--refine", k, "refine %d" % k, "r%d" % k) for k in v["refine"]]
    return [("--n", n, "%d" % n, "%d" % n) for n in v["sizes"]]


def run_level(path, name, level, binary, workdir, tol, failures, reuse=False, exact=True):
    """Solves one level with the Rust code (unless `reuse` and its result exists), then checks it;
    with an `exact` solution also its ||lam - lamh||_H-1."""
    option, value, label, tag = level
    rust_dir = os.path.join(workdir, "rust-%s" % tag)
    t = time.perf_counter()
    if not (reuse and os.path.isdir(rust_dir)):
        norm = ["--hminus1"] if exact else []
        proc = subprocess.run([binary, "solve", path, option, str(value), *norm, "--flux", "-o", rust_dir],
                              capture_output=True, text=True)
        if proc.returncode != 0:
            failures.append("%s %s: Rust solver failed: %s" % (name, label, proc.stderr.strip()))
            return None
    return check_level("%s %s" % (name, label), (label, tag), rust_dir, workdir, tol, failures,
                       time.perf_counter() - t)


def check_level(label, level, rust_dir, workdir, tol, failures, rust_seconds):
    """Solves the level (its table label and file tag) of a Rust result with both references; checks
    fields, norm values, fluxes."""
    ref_path, mixed_path = (os.path.join(workdir, "%s-%s.h5" % (k, level[1])) for k in ("reference", "mixed"))
    summary = solve_reference.solve_file(rust_dir, ref_path)
    mixed = solve_mixed.solve_file(rust_dir, mixed_path)
    rust, ref = common.read_result(rust_dir), common.read_reference(ref_path)
    diffs, mismatch = compare.compare(rust, ref)
    mixed_diffs, mixed_mismatch = compare.compare(rust, common.read_reference(mixed_path))
    field_failures(label, "", diffs, mismatch, tol, failures)
    field_failures(label, " from the mixed reference", mixed_diffs, mixed_mismatch, tol, failures)
    level = {"n": level[0], "h": float(rust["attrs"]["h"]), "vertices": int(rust["attrs"]["vertices"]),
             "diffs": diffs, "mismatch": mismatch, "rust_iterations": int(rust["attrs"]["iterations"]),
             "rust_seconds": rust_seconds, "snes_iterations": summary["snes_iterations"],
             "ref_seconds": summary["seconds"], "mixed_diffs": mixed_diffs, "mixed_mismatch": mixed_mismatch,
             "mixed_iterations": mixed["iterations"], "rust": common.errors_of(rust["attrs"], rust["problem"]),
             "ref": common.errors_of(ref["attrs"], rust["problem"]), "problem": rust["problem"],
             "flux": flux_checks.check_level(rust, ref), "dir": rust_dir, "norm_checks": {}}
    if "exact" in rust["case"]:
        level["norm_checks"] = norm_value_failures(label, level, ref["attrs"], rust["attrs"], failures)
    flux_failures(label, level["flux"], rust["attrs"], failures)
    return level


def field_failures(label, which, diffs, mismatch, tol, failures):
    for field, (mx, _) in diffs.items():
        if not mx <= tol:
            failures.append("%s: %s differs%s by %.2e (relative max) > %.0e" % (label, field, which, mx, tol))
    if mismatch:
        failures.append("%s: contact sets differ%s at %d vertices" % (label, which, mismatch))


def norm_value_failures(label, level, ref_attrs, rust_attrs, failures):
    """Every error norm's value against the reference's: {key: (relative difference, relative tolerance)}."""
    out = {}
    rust_quadrature = float(rust_attrs.get("error_quadrature", 0.0))
    for key in level["problem"].error_keys:
        if key not in level["ref"]:
            continue
        e_ref, e_rust = level["ref"][key], level["rust"].get(key, float("nan"))
        d = float(ref_attrs["difference_" + key])
        # What each code's quadrature may miss: the reference's estimate, the Rust code's bound (the
        # H-1 norm is one rule of degree 10 in both).
        quadrature = float(ref_attrs.get("quadrature_" + key, 0.0))
        if key != "hminus1_lambda":
            quadrature += rust_quadrature * e_rust
        allowed = NORM_MARGIN * (d + quadrature) + NORM_ROUNDOFF * e_ref + NORM_FLOOR
        size = max(e_ref, NORM_FLOOR)
        out[key] = (abs(e_rust - e_ref) / size, allowed / size)
        if not abs(e_rust - e_ref) <= allowed:
            failures.append("%s: error_%s = %.6e, the reference's %.6e (relative difference %.2e > %.2e, "
                            "field difference %.2e, quadrature %.2e)"
                            % (label, key, e_rust, e_ref, out[key][0], out[key][1], d, quadrature))
    return out


def flux_failures(label, flux, attrs, failures):
    """The checks of flux_checks.check_level per flux (suffix s: t1h, t2h, or th above an obstacle)."""
    for s, f in flux.items():
        if not f["jump"] <= FLUX_JUMP:
            failures.append("%s: t%sh has a normal jump of %.2e (relative) on an edge of S_h > %.0e%s"
                            % (label, s, f["jump"], FLUX_JUMP, " (S_h is not joined across the "
                               "edges of T_h)" if f["jump"] == float("inf") else ""))
        defect, lam_term = f["conservation"]
        allowed = CONSERVATION_ROUNDOFF + 2.0 * lam_term
        if not defect <= allowed:
            failures.append("%s: div t%sh misses the local conservation (Lemma 17) by %.2e (relative) > %.2e"
                            % (label, s, defect, allowed))
        own = float(attrs[flux_checks.named("flux_conservation", s)])
        if not own <= RUST_CONSERVATION:
            failures.append("%s: the Rust code reports a conservation defect of t%sh of %.1e > %.0e"
                            % (label, s, own, RUST_CONSERVATION))


def rate_failures(name, levels, convex, failures):
    """EOCs of both codes, their agreement, the paper's rates; the flux error's rate."""
    h = [lv["h"] for lv in levels]
    rates = {}
    for key, label, theory in NORMS:
        if key not in levels[0]["ref"]:
            continue
        er = eocs(h, [lv["rust"].get(key, float("nan")) for lv in levels])
        ef = eocs(h, [lv["ref"][key] for lv in levels])
        rates[key] = (er, ef)
        for i, (a, b) in enumerate(zip(er, ef)):
            if not (a != a and b != b) and not abs(a - b) <= EOC_AGREEMENT:
                failures.append("%s: EOC of %s differ between codes at level %d: %.3f vs %.3f"
                                % (name, label, i + 1, a, b))
        if convex and theory is not None and er and er[-1] == er[-1]:
            if er[-1] < theory - THEORY_MARGIN or (key not in AT_LEAST and er[-1] > theory + THEORY_MARGIN):
                failures.append("%s: Rust EOC of %s is %.3f, the paper's rate is %s%.1f"
                                % (name, label, er[-1], ">= " if key in AT_LEAST else "", theory))
    for s, f in levels[0]["flux"].items():
        if "error" in f:
            er = eocs(h, [lv["flux"][s]["error"] for lv in levels])
            rates[flux_checks.named("flux", s)] = (er, None)
            for k, a in enumerate(er):
                if not a >= FLUX_RATE[convex]:
                    failures.append("%s: EOC of ||t%sh + mu%s grad u%s||_L2 at level %d is %.3f < %.2f"
                                    % (name, s, s, s, k + 1, a, FLUX_RATE[convex]))
    return rates


def estimator_check(path, label, level, binary, workdir, failures, reuse=False):
    """One more Rust run of `level` with --estimate (unless `reuse` and it exists), compared with
    reference/estimator.py: the row of the report's estimator table, or None."""
    option, value, _, tag = level
    rust_dir = os.path.join(workdir, "estimate-%s" % tag)
    t = time.perf_counter()
    if not (reuse and os.path.isdir(rust_dir)):
        proc = subprocess.run([binary, "solve", path, option, str(value), "--estimate", "--dual", "-o", rust_dir],
                              capture_output=True, text=True)
        if proc.returncode != 0:
            failures.append("%s: Rust solver failed with --estimate: %s" % (label, proc.stderr.strip()))
            return None
    row = estimator_row(label, rust_dir, failures)
    print("estimator of %s: Rust run and comparison %.1f s" % (label, time.perf_counter() - t), flush=True)
    return row


def estimator_row(label, rust_dir, failures):
    """Compares the estimator of a result with --estimate against reference/estimator.py."""
    rows, fails, summary = estimator.compare(rust_dir)
    failures += ["%s: %s" % (label, f) for f in fails]
    return estimator.summary_row(label, rows, summary) if rows else None


ESTIMATOR_HEAD = ["### A posteriori estimator: Rust against `reference/estimator.py --compare`", "",
                  "Max |Rust − reference| relative to η (η² for the contact terms, the value itself for the §8 "
                  "bound and the effectivity); tolerances %.0e (flux, oscillation, means; plus the round-off of "
                  "∫f² − (∫f)²/|κ| for the oscillation), %.0e (contact), %.0e (boundary terms and what contains "
                  "them); last column η/|||u − u_h||| (must be ≥ 1)." % (estimator.FLUX_TOL, estimator.CONTACT_TOL,
                                                                         estimator.BOUNDARY_TOL), "",
                  "| result | " + " | ".join(t for t, _ in estimator.GROUPS) + " | η/E |",
                  "|---" * (len(estimator.GROUPS) + 2) + "|"]


DIRECT_TOL = 1e-10  # multigrid (the default) against Cholesky: max |difference| / max |value|


def direct_agreement(path, label, level, binary, workdir, failures, reuse=False):
    """A level solved again with `--linear direct` (Cholesky): the default's fields (of the level's
    result) agree to DIRECT_TOL relative, the contact sets exactly. The report's row."""
    option, value, _, tag = level
    default_dir, direct_dir = (os.path.join(workdir, "%s-%s" % (k, tag)) for k in ("rust", "direct"))
    if not (reuse and os.path.isdir(direct_dir)):
        proc = subprocess.run([binary, "solve", path, option, str(value), "--linear", "direct", "--dual", "-o", direct_dir],
                              capture_output=True, text=True)
        if proc.returncode != 0:
            failures.append("%s: Rust solver failed with --linear direct: %s" % (label, proc.stderr.strip()))
            return None
    a, b = common.read_result(default_dir), common.read_result(direct_dir)
    solver = str(a["attrs"]["linear_solver"])
    # λ is a residual: where it vanishes its round-off is measured against the loads' size.
    load = np.max(sum(np.abs(common.at_points(a["case"][f], a["points"])) for f in a["problem"].loads))
    rel = {}
    for k in direct_fields(a["problem"]):
        floor = load if k == "lambda" else 1e-300
        rel[k] = float(np.max(np.abs(a[k] - b[k])) / max(np.max(np.abs(b[k])), floor))
    mismatch = int(np.sum(a["contact"] != b["contact"]))
    for k, r in rel.items():
        if not r <= DIRECT_TOL:
            failures.append("%s: %s of the default solver differs from Cholesky's by %.1e relative (> %.0e)"
                            % (label, k, r, DIRECT_TOL))
    if mismatch:
        failures.append("%s: the contact sets of the default solver and Cholesky differ at %d vertices"
                        % (label, mismatch))
    return "| %s | %s | %s | %d |" % (label, solver, ", ".join("%s %.1e" % (k, rel[k]) for k in rel),
                                      mismatch)


DIRECT_HEAD = ["### The default linear solver against Cholesky (`--linear direct`), last level of each case", "",
               "Max |difference| relative to max |value| (for λ at least max |f1| + |f2| at the vertices); tolerance %.0e, "
               "contact sets equal." % DIRECT_TOL, "",
               "| result | default solver | fields | contact mismatches |", "|---|---|---|---|"]


def direct_fields(problem):
    """The fields compared between the default linear solver and Cholesky."""
    return problem.displacements + ("gap", "lambda")


def has_estimator(case):
    """Whether the case has the a posteriori estimator of docs/a-posteriori.md: two membranes with
    u2 = 0 on the boundary (its lifting is of g - g_h alone; the Rust code refuses --estimate
    otherwise, as for the obstacle problem)."""
    from . import groups

    # The reference estimator takes its data as expressions: not yet tables per physical group.
    return problems.of(case) is problems.MEMBRANES and case.get("g2", 0) == 0 and not groups.has_tables(case)


def run_case(path, binary, out, tol, failures, reuse=False):
    case = common.load_case(path)
    name = os.path.splitext(os.path.basename(path))[0]
    workdir = os.path.join(out, name)
    os.makedirs(workdir, exist_ok=True)
    first = levels_of(case)[0]
    estimate = None
    if has_estimator(case):
        estimate = estimator_check(path, "%s %s" % (name, first[2]), first, binary, workdir, failures, reuse)
    levels = []
    for spec in levels_of(case):
        level = run_level(path, name, spec, binary, workdir, tol, failures, reuse, "exact" in case)
        if level is None:
            return None
        levels.append(level)
    last = levels_of(case)[-1]
    direct = direct_agreement(path, "%s %s" % (name, last[2]), last, binary, workdir, failures, reuse)
    mesh = case["mesh"]
    convex = mesh["kind"] == "rectangle" or (mesh["kind"] == "disk" and "inner_radius" not in mesh)
    rates = rate_failures(name, levels, convex, failures) if "exact" in case else {}
    return {"name": name, "title": case.get("title", ""), "path": path, "levels": levels, "rates": rates,
            "convex": convex, "exact": "exact" in case, "estimate": estimate, "direct": direct}


def pinched_mesh_file(workdir):
    """A 16 x 16 square mesh (meshio) with two square holes that touch at one vertex, (7/16, 7/16):
    its patch is two fans, as a Gmsh file can give (the estimator's local problems then have
    ψ(a) once per fan). Its path and vertex count."""
    import meshio
    import numpy as np

    n = 16
    i, j = np.meshgrid(np.arange(n + 1), np.arange(n + 1), indexing="xy")
    points = np.stack([i.ravel() / n, j.ravel() / n, 0.0 * i.ravel()], axis=1)
    v = lambda i, j: j * (n + 1) + i  # noqa: E731
    cells = [t for j in range(n) for i in range(n) if (i, j) not in ((6, 6), (7, 7))
             for t in ([v(i, j), v(i + 1, j), v(i + 1, j + 1)], [v(i, j), v(i + 1, j + 1), v(i, j + 1)])]
    path = os.path.join(workdir, "pinched_mesh.xdmf")
    meshio.write(path, meshio.Mesh(points, [("triangle", np.array(cells))]))
    return path, len(points)


def jittered_mesh_files(workdir):
    """A jittered (unstructured) 20 x 20 square mesh written by meshio and by dolfinx (XDMF + HDF5):
    {writer: mesh path}, and its vertex count."""
    import dolfinx.io
    import meshio
    import numpy as np
    from mpi4py import MPI

    m = dolfinx.mesh.create_unit_square(MPI.COMM_SELF, 20, 20, cell_type=dolfinx.mesh.CellType.triangle)
    x = m.geometry.x
    inside = (x[:, 0] > 1e-9) & (x[:, 0] < 1 - 1e-9) & (x[:, 1] > 1e-9) & (x[:, 1] < 1 - 1e-9)
    x[inside, :2] += np.random.default_rng(3).uniform(-0.015, 0.015, (inside.sum(), 2))
    paths = {w: os.path.join(workdir, w + "_mesh.xdmf") for w in ("meshio", "dolfinx")}
    cells = m.geometry.dofmap.array.reshape(-1, 3)
    meshio.write(paths["meshio"], meshio.Mesh(x.copy(), [("triangle", cells.copy())]))
    with dolfinx.io.XDMFFile(MPI.COMM_SELF, paths["dolfinx"], "w") as f:
        f.write_mesh(m)
    return paths, len(x)


def mesh_files(binary, out, tol, failures):
    """Meshes written by meshio and by dolfinx, read by the Rust solver with the default case's
    data, compared with the reference; and a mesh with a pinched vertex (the default data without
    the exact solution, which does not hold on its holes)."""
    workdir = os.path.join(out, "mesh_files")
    os.makedirs(workdir, exist_ok=True)
    base = open(os.path.join(common.ROOT, "data", "cases", "default.toml")).read()
    data = base[: base.index("[mesh]")]
    lines = ["| writer | vertices | max Δu1 | max Δu2 | max Δgap | max Δλ | max Δλ2 | contact mismatches |",
             "|---|---|---|---|---|---|---|---|"]
    paths, count = jittered_mesh_files(workdir)
    meshes = {writer: (path, count, data) for writer, path in paths.items()}
    meshes["meshio, pinched"] = pinched_mesh_file(workdir) + (base[: base.index("[exact]")],)
    estimates = []
    for writer, (mesh_path, count, case_data) in meshes.items():
        case_path = os.path.join(workdir, writer.replace(", ", "_") + ".toml")
        with open(case_path, "w") as f:
            f.write(case_data + '[mesh]\nkind = "file"\npath = "%s"\n' % os.path.basename(mesh_path))
        stem = os.path.join(workdir, writer.replace(", ", "_"))
        rust_dir, ref_path = stem + "-rust", stem + "-reference.h5"
        proc = subprocess.run([binary, "solve", case_path, "--estimate", "--dual", "-o", rust_dir], capture_output=True, text=True)
        label = "mesh file from %s" % writer
        if proc.returncode != 0:
            failures.append("%s: Rust solver failed: %s" % (label, proc.stderr.strip()))
            continue
        estimates.append(estimator_row(label, rust_dir, failures))
        solve_reference.solve_file(rust_dir, ref_path)
        rust = common.read_result(rust_dir)
        diffs, mismatch = compare.compare(rust, common.read_reference(ref_path))
        nv = int(rust["attrs"]["vertices"])
        if nv != count:
            failures.append("%s: %d vertices read, %d written" % (label, nv, count))
        field_failures(label, "", diffs, mismatch, tol, failures)
        cols = " | ".join(report.fmt(diffs[k][0]) for k in problems.MEMBRANES.compared)
        lines.append("| %s | %d | %s | %d |" % (writer, nv, cols, mismatch))
    return ["### Meshes read from files (meshio and dolfinx XDMF, jittered 20 × 20 square, default case data; "
            "a 16 × 16 square with two holes touching at a vertex)",
            ""] + lines + [""], [e for e in estimates if e]


ADAPTED = [("lshape_corner", ["--n", "8", "--max-vertices", "4000", "--dual"]),
           ("disk_contact", ["--max-vertices", "5000", "--theta", "0.3", "--dual"])]


def adapted_meshes(binary, out, tol, failures):
    """`adapt` on the L-shape (corner singularity) and the disk (curved boundary): the reference
    solves on a middle and the last bisected mesh, fields compared, and recomputes the estimator;
    ParaView opens the steps as one time series."""
    workdir = os.path.join(out, "adapted")
    os.makedirs(workdir, exist_ok=True)
    lines = ["### Adapted meshes (`adapt`: Dörfler marking, newest-vertex bisection)", "",
             "| case | step | vertices | smallest/largest triangle area | max Δu1 | max Δu2 | max Δgap | max Δλ | max Δλ2 | contact mismatches |",
             "|---|---|---|---|---|---|---|---|---|---|"]
    estimates, views = [], []
    for name, options in ADAPTED:
        adapt_dir = os.path.join(workdir, name)
        case_path = os.path.join(common.ROOT, "data", "cases", name + ".toml")
        proc = subprocess.run([binary, "adapt", case_path, "-o", adapt_dir] + options, capture_output=True, text=True)
        if proc.returncode != 0:
            failures.append("adapt %s: Rust failed: %s" % (name, proc.stderr.strip()))
            continue
        steps = sorted(d for d in os.listdir(adapt_dir) if d.startswith("step-"))
        if len(steps) < 4:
            failures.append("adapt %s: only %d steps" % (name, len(steps)))
            continue
        for step in (steps[len(steps) // 2], steps[-1]):
            rust_dir = os.path.join(adapt_dir, step)
            label = "adapted %s %s" % (name, step)
            estimates.append(estimator_row(label, rust_dir, failures))
            ref_path = os.path.join(workdir, "%s-%s-reference.h5" % (name, step))
            solve_reference.solve_file(rust_dir, ref_path)
            rust = common.read_result(rust_dir)
            diffs, mismatch = compare.compare(rust, common.read_reference(ref_path))
            field_failures(label, "", diffs, mismatch, tol, failures)
            areas = np.abs(common.areas(rust["points"], rust["cells"]))
            cols = " | ".join(report.fmt(diffs[k][0]) for k in problems.MEMBRANES.compared)
            lines.append("| %s | %s | %d | %.1e | %s | %d |" % (name, step[5:], int(rust["attrs"]["vertices"]),
                                                                 areas.min() / areas.max(), cols, mismatch))
        views += paraview(adapt_dir, failures)
    return lines + [""] + views, [e for e in estimates if e]


def paraview(result_dir, failures):
    """paraview_check in a separate process (ParaView's Python stays out of this one)."""
    pv = subprocess.run([sys.executable, "-m", "reference.paraview_check", os.path.abspath(result_dir)],
                        capture_output=True, text=True, cwd=common.ROOT)
    print(pv.stdout.strip())
    if pv.returncode != 0:
        failures.append("ParaView check failed for %s: %s" % (result_dir, (pv.stdout + pv.stderr).strip()[-500:]))
    return ["ParaView: `%s`" % pv.stdout.strip(), ""]


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--bin", required=True)
    ap.add_argument("--out", default="validation")
    ap.add_argument("--tol", type=float, default=1e-8)
    ap.add_argument("--reuse", action="store_true",
                    help="check the Rust results already in OUT instead of solving again (to test the checks)")
    ap.add_argument("cases", nargs="*")
    args = ap.parse_args()
    binary = os.path.abspath(args.bin)
    os.makedirs(args.out, exist_ok=True)
    paths = [p for p in (args.cases or common.shipped_cases()) if "validation" in common.load_case(p)]
    failures = []
    start = time.perf_counter()
    print("SymPy check of the exact solutions:")
    if not exact_cases.main(paths):
        failures.append("an exact-solution case fails its SymPy check")
    lines = report.header(args.tol, EOC_AGREEMENT, THEORY_MARGIN)
    estimates, directs = [], []
    for path in paths:
        result = run_case(path, binary, args.out, args.tol, failures, args.reuse)
        if result is None:
            continue
        if result["estimate"]:
            estimates.append(result["estimate"])
        if result["direct"]:
            directs.append(result["direct"])
        tables = report.tables(result)
        print("\n" + "\n".join(tables))
        lines += tables + ["![%s](%s)" % (img, img) for img in report.plots(result, args.out)] + [""]
        lines += paraview(result["levels"][-1]["dir"], failures)
    mesh_lines, mesh_estimates = mesh_files(binary, args.out, args.tol, failures)
    adapted_lines, adapted_estimates = adapted_meshes(binary, args.out, args.tol, failures)
    mesh_lines += adapted_lines + ESTIMATOR_HEAD + estimates + mesh_estimates + adapted_estimates + [""]
    mesh_lines += DIRECT_HEAD + directs + [""]
    print("\n" + "\n".join(mesh_lines))
    report.write(args.out, lines + mesh_lines, failures, time.perf_counter() - start)
    if failures:
        print("VALIDATION FAILED:")
        for line in failures:
            print("  " + line)
        print("validate: %d passed, %d failed" % (0, len(failures)))
        sys.exit(1)
    print("validate: all %d cases passed" % len(paths))


if __name__ == "__main__":
    main()
