"""membrane_contact: the unilateral contact between two elastic membranes (and the classical
obstacle problem) by P1 finite elements, with numpy arrays in and out.

The solver is the Rust library of the `membrane-contact` command line, called in process: the
arrays of a `Result` are the very values the command line writes to `solution.h5`.

    import membrane_contact as mc
    r = mc.solve("data/cases/default.toml", estimate=True)
    r.u1, r.lambda_, r.contact, r.eta, r.summary()

A case is a path, a TOML string or a dict of the case file's keys (docs: data/cases/README.md);
a mesh is a meshio.Mesh, a (points, triangles) pair or a dolfinx mesh. Errors are `InputError`
(a ValueError), `SolverError` (a RuntimeError) and `OutputError` (an OSError), with the command
line's one-line messages. Ctrl-C stops a run.
"""

import json
import numbers
import os
import tempfile

import numpy as np

from . import _core
from ._core import InputError, OutputError, SolverError

__all__ = [
    "solve",
    "study",
    "adapt",
    "read",
    "Result",
    "InputError",
    "SolverError",
    "OutputError",
    "default_case",
]

__version__ = _core.version


def default_case():
    """The built-in default case, as the text of a case file."""
    return _core.default_case()


def _case(case):
    """((kind, value), origin) of a case: None (the default case), a path, TOML text or a dict."""
    if case is None:
        return ("default", ""), "built-in default case"
    if isinstance(case, dict):
        return ("text", _core.dict_to_toml(case)), "case dict"
    if isinstance(case, os.PathLike):
        path = os.fspath(case)
        return ("path", os.fsdecode(path)), path
    if isinstance(case, bytes):
        case = case.decode()
    if isinstance(case, str):
        # One line without "=" is a path (no case fits in it); anything else is TOML.
        if "\n" not in case and "=" not in case:
            return ("path", case), case
        return ("text", case), "case text"
    raise InputError(
        f"case: need a path, a TOML string or a dict, got {type(case).__name__}"
    )


def _mesh(mesh):
    """(points float64 (N, 2), triangles int64 (M, 3), groups) of a mesh, or (None, None, None);
    groups: the physical groups of a meshio mesh read from a Gmsh file (`_groups`), or None."""
    if mesh is None:
        return None, None, None
    groups = None
    if hasattr(mesh, "cells_dict") and hasattr(mesh, "points"):  # meshio.Mesh
        kinds = ", ".join(sorted(mesh.cells_dict)) or "none"
        if "triangle" not in mesh.cells_dict:
            raise InputError(f"mesh: a meshio mesh needs 'triangle' cells (it has {kinds})")
        # Cells of lower dimension (Gmsh's lines and points of its physical groups) are not part
        # of the domain; any other kind of cell is, and the domain would lose it.
        others = sorted(set(mesh.cells_dict) - {"triangle", "line", "vertex"})
        if others:
            raise InputError(
                f"mesh: a meshio mesh of linear triangles only is solved on; it has {kinds}: "
                f"{', '.join(others)} cells are not supported (split quadrilaterals into triangles, "
                "and use linear triangles, not curved ones)"
            )
        groups = _groups(mesh)
        points, triangles, used = _used_points(np.asarray(mesh.points), np.asarray(mesh.cells_dict["triangle"]))
        if groups is not None:
            groups = _renumbered_lines(groups, used)
    elif hasattr(mesh, "geometry") and hasattr(mesh, "topology"):  # a dolfinx mesh
        _linear_triangles(mesh)
        points = mesh.geometry.x
        dofmap = mesh.geometry.dofmap
        # dolfinx 0.5–0.6: an adjacency list; later versions: an array.
        cells = dofmap.array if hasattr(dofmap, "array") else dofmap
        triangles = np.asarray(cells).reshape(-1, 3)
    elif isinstance(mesh, (tuple, list)) and any(hasattr(m, "geometry") for m in mesh):
        raise InputError(
            "mesh: a dolfinx mesh is given alone (it carries no groups); for data per group write it "
            "with its meshtags by dolfinx.io.XDMFFile (write_mesh, write_meshtags) and give the file"
        )
    elif isinstance(mesh, (tuple, list)) and len(mesh) == 2:
        points, triangles = mesh
    else:
        raise InputError(
            "mesh: need a meshio.Mesh, a (points, triangles) pair or a dolfinx mesh, "
            f"got {type(mesh).__name__}"
        )
    points = np.asarray(points)
    triangles = np.asarray(triangles)
    if points.ndim != 2 or points.shape[1] not in (2, 3):
        raise InputError(f"mesh: points need shape (N, 2) or (N, 3), got {points.shape}")
    if np.iscomplexobj(points):
        raise InputError(f"mesh: points need real coordinates, got dtype {points.dtype}")
    if not np.issubdtype(points.dtype, np.number):
        raise InputError(f"mesh: points need numbers, got dtype {points.dtype}")
    if points.shape[1] == 3 and len(points):
        # a plane z = constant, up to round-off (as the mesh files' readers take it)
        z, xy = points[:, 2].astype(np.float64), points[:, :2].astype(np.float64)
        tolerance = 1e-12 * np.ptp(xy, axis=0).max() + 4 * np.finfo(np.float64).eps * abs(z[0])
        off = ~(np.abs(z - z[0]) <= tolerance)  # NaN is no plane either
        if np.any(off):
            i = int(np.argmax(off))
            raise InputError(f"mesh: point {i} has z = {z[i]}, the first z = {z[0]}: the mesh must lie in a plane z = constant")
    points = points[:, :2]
    if triangles.ndim != 2 or triangles.shape[1] != 3:
        raise InputError(f"mesh: triangles need shape (M, 3), got {triangles.shape}")
    if not np.issubdtype(triangles.dtype, np.integer):
        raise InputError(f"mesh: triangles need integer vertex numbers, got dtype {triangles.dtype}")
    too_large = triangles > np.iinfo(np.int64).max if triangles.dtype.kind == "u" else None
    if too_large is not None and too_large.any():
        t = int(np.argmax(too_large.any(axis=1)))
        v = int(triangles[t][too_large[t]][0])
        raise InputError(f"mesh: triangle {t} refers to vertex {v}, which does not exist")
    points = np.ascontiguousarray(points, dtype=np.float64)
    triangles = np.ascontiguousarray(triangles, dtype=np.int64)
    return points, triangles, groups


def _groups(mesh):
    """The physical groups of a meshio mesh read from a Gmsh file, as the core takes them: the
    names [(dimension, tag, name)] of `field_data`, the `gmsh:physical` tag of each triangle (0 for
    none), the line cells and their tags; None for a mesh without `gmsh:physical`."""
    tags = mesh.cell_data_dict.get("gmsh:physical") if mesh.cell_data else None
    if not tags or "triangle" not in tags:
        return None
    lines = np.asarray(mesh.cells_dict.get("line", np.zeros((0, 2))), dtype=np.int64).reshape(-1, 2)
    line_tags = np.asarray(tags.get("line", np.zeros(len(lines))), dtype=np.int64)
    if len(line_tags) != len(lines) or (lines.size and (lines.min() < 0 or lines.max() >= len(mesh.points))):
        raise InputError("mesh: the meshio mesh's line cells or their gmsh:physical tags do not fit its points")
    names = [(int(v[1]), int(v[0]), str(k)) for k, v in (mesh.field_data or {}).items() if len(v) >= 2]
    return names, np.asarray(tags["triangle"], dtype=np.int64), lines, line_tags


def _renumbered_lines(groups, used):
    """`groups` as lists, its lines in the numbering of the points the triangles use (`used`, from
    `_used_points`: None where it kept every point); lines on other points are not on the mesh and
    are dropped."""
    names, triangle_tags, lines, line_tags = groups
    if used is not None and lines.size:
        at = np.searchsorted(used, lines).clip(max=len(used) - 1)
        keep = (used[at] == lines).all(axis=1)
        lines, line_tags = at[keep], line_tags[keep]
    return names, triangle_tags.tolist(), lines.tolist(), line_tags.tolist()


def _linear_triangles(mesh):
    """Raises InputError unless the dolfinx mesh is of linear (straight) triangles."""
    cell = getattr(mesh.topology, "cell_type", None)
    name = getattr(cell, "name", str(cell))
    if name != "triangle":
        raise InputError(f"mesh: a dolfinx mesh of triangles is solved on; this one has {name} cells")
    element = getattr(mesh, "ufl_domain", lambda: None)()
    degree = element.ufl_coordinate_element().degree() if element is not None else 1
    if degree != 1:
        raise InputError(
            f"mesh: a dolfinx mesh of linear triangles is solved on; this one's geometry has degree "
            f"{degree} (curved triangles)"
        )


def _used_points(points, triangles):
    """The points the triangles use, in their order, the triangles renumbered and the old number
    of each point kept (None where every point is kept): a file read by meshio keeps every node (a
    Gmsh geometry point that no triangle uses, say)."""
    in_range = triangles.size and triangles.min() >= 0 and triangles.max() < len(points)
    if not in_range or np.issubdtype(triangles.dtype, np.floating):
        return points, triangles, None  # checked and refused below
    used = np.unique(triangles)
    if len(used) == len(points):
        return points, triangles, None
    return points[used], np.searchsorted(used, triangles), used


def _count(name, value, least=0):
    """`value` if it is None or a whole number ≥ `least` (as the command line's options take),
    else an InputError naming the argument."""
    if value is None:
        return None
    whole = isinstance(value, numbers.Integral) and not isinstance(value, bool)
    if not whole or value < least or value >= 2**64:
        raise InputError(f"{name} = {value!r}: need a whole number ≥ {least}")
    return int(value)


def _counts(name, values):
    """A list of `_count`s, or None."""
    return None if values is None else [_count(name, v) for v in values]


def _read_only(array):
    """`array` on an immutable buffer: read-only for good (an array that owns its data, or a view
    of one, could be made writable again)."""
    return np.frombuffer(array.tobytes(), dtype=array.dtype).reshape(array.shape)


class _ReadOnlyDict(dict):
    """A dict that cannot be changed; it copies, pickles and serializes as a plain dict."""

    def _refuse(self, *args, **kwargs):
        raise TypeError("a Result's mappings are read-only (copy one with dict() to change it)")

    __setitem__ = __delitem__ = __ior__ = _refuse
    clear = pop = popitem = setdefault = update = _refuse

    def __reduce__(self):
        return dict, (dict(self),)


class Result:
    """A solved case: the mesh, the fields and the summary's figures.

    Arrays: `points` (N, 2), `triangles` (M, 3), and per vertex `u1`, `u2`, `gap` (u1 − u2),
    `lambda_` (λ_h; the file's `lambda`), `lambda2` (λ_h from membrane 2), `contact` (bool); above
    an obstacle `u`, `psi`, `gap`, `lambda_`, `contact`; with an exact solution `u1_exact`, …;
    with `estimate=True` per triangle `estimator` and its terms; on a mesh with physical groups (a
    Gmsh file) per triangle `group`, the index of its surface in the JSON list `surface_groups`.
    `fields` maps the file's names to the arrays, `places` to "vertices" or "cells". With `dual`
    or `flux`, the dual submesh S_h as dual.xdmf holds it: `dual_points` (P, 2),
    `dual_triangles` (6M, 3) and `dual_fields`, name → one value per cell (`lambda`, λ_h constant
    on each D_a; `vertex`, the a of D_a; with `flux` the fluxes t_ih of (4.13): `t1_x`, `t1_y`,
    `div_t1`, …); without them None, None and {}. The arrays and the mappings are read-only: they
    are what `write` writes (copy one to change it). A result pickles (and deep-copies) whole, as
    the files `write` writes.

    Figures: every attribute of `solution.h5` (`iterations`, `check_*`, `error_*`, `effectivity`,
    …) is in `attributes`, and an attribute of the result where no field has its name: `estimator`,
    `estimator_boundary`, `estimator_contact` and `estimator_data` are fields per triangle (the
    totals are `attributes["estimator"]`, …; `eta` is η).
    """

    def __init__(self, parts):
        self._parts = parts
        self.points = _read_only(parts.points())
        self.triangles = _read_only(parts.triangles())
        self.fields = {}
        self.places = {}
        for name, place, values in parts.fields():
            if name == "contact":
                values = values != 0.0
            self.fields[name] = _read_only(values)
            self.places[name] = place
        # S_h, with `dual` or `flux`: the grid and cell fields of dual.xdmf
        self.dual_points = self.dual_triangles = None
        self.dual_fields = {}
        dual = parts.dual()
        if dual is not None:
            points, triangles, fields = dual
            self.dual_points, self.dual_triangles = _read_only(points), _read_only(triangles)
            self.dual_fields = {name: _read_only(values) for name, values in fields}
        self.attributes = _ReadOnlyDict(parts.attributes())
        self.fields = _ReadOnlyDict(self.fields)
        self.places = _ReadOnlyDict(self.places)
        self.dual_fields = _ReadOnlyDict(self.dual_fields)

    @property
    def lambda_(self):
        """λ_h at the vertices (the field `lambda`)."""
        return self.fields["lambda"]

    @property
    def eta(self):
        """η, the guaranteed bound of the energy error (None without `estimate=True`)."""
        value = self.attributes.get("estimator")
        return value if isinstance(value, float) else None

    @property
    def problem(self):
        """"membranes" or "obstacle"."""
        return self.attributes.get("problem")

    def __getattr__(self, name):
        if name.startswith("_"):
            raise AttributeError(name)
        fields = self.__dict__.get("fields", {})
        if name in fields:
            return fields[name]
        attributes = self.__dict__.get("attributes", {})
        if name in attributes:
            return attributes[name]
        raise AttributeError(f"this result has no field or figure '{name}'")

    def __dir__(self):
        return sorted(set(super().__dir__()) | set(self.fields) | set(self.attributes))

    def summary(self):
        """The summary the command line prints (its write time 0); of a result read back (`read`),
        the one its run stored (but for the times, in `attributes`), and a line saying so."""
        return self.__dict__.get("_summary") or self._parts.summary()

    def __reduce__(self):
        # Pickled (and deep-copied) as the files of its result directory, read back whole.
        with tempfile.TemporaryDirectory() as d:
            out = os.path.join(d, "result")
            self.write(out)
            files = {}
            for name in sorted(os.listdir(out)):
                with open(os.path.join(out, name), "rb") as f:
                    files[name] = f.read()
        return _unpickled, (files, self.summary())

    def write(self, directory):
        """Writes the whole result directory `directory` as the command line does: solution.h5,
        solution.xdmf (and dual.xdmf with `dual` or `flux`), put in place whole; an earlier result
        there is replaced, anything else is left alone with an OutputError."""
        self._parts.write(os.fspath(directory))

    def __repr__(self):
        return (
            f"<membrane_contact.Result: {self.problem}, {len(self.points)} vertices, "
            f"{len(self.triangles)} triangles, fields {', '.join(self.fields)}>"
        )


def solve(
    case=None,
    mesh=None,
    *,
    estimate=False,
    flux=False,
    dual=False,
    hminus1=False,
    linear=None,
    refine=None,
    n=None,
    start=None,
    verbose=False,
    threads=None,
):
    """Solves a case (the built-in default case without one) and returns its `Result`.

    case: a path (str or os.PathLike; a str of one line without "=" is always a path), a TOML string
        or a dict of the case file's keys.
    mesh: a meshio.Mesh (its "triangle" cells; read from a Gmsh file, its physical groups too:
    gmsh:physical and field_data), a (points, triangles) pair (points (N, 2), or
    (N, 3) in a plane z = constant; triangles (M, 3) of any integer type) or a dolfinx mesh; it replaces the
    mesh the case's [mesh] names (the table may then be left out, or hold `refine` alone), is
    refined as the table's `refine` says (refine= overrides it), keeps its vertex numbering (but
    for the points of a meshio.Mesh that no triangle uses, dropped) and the order of its triangles
    (each turned counter-clockwise: a clockwise [0, 4, 1] comes back as [0, 1, 4]), and is checked
    as a mesh file is. estimate, flux, dual, hminus1: as the command line's --estimate, --flux, --dual,
    --hminus1. linear: "multigrid" or "direct". refine: uniform refinements (K). n: cells per side
    of a built-in mesh. start: "nested" (the default) or "cold". verbose: the solver's details in
    `summary()`. threads: the threads to compute on (default: RAYON_NUM_THREADS, else one per
    core); the results are the same bit for bit on any number. The summary's peak memory is the
    process's (the whole Python session's) so far.
    """
    (source, origin), (points, triangles, groups) = _case(case), _mesh(mesh)
    parts = _core.solve(
        source,
        origin,
        points,
        triangles,
        groups,
        estimate=estimate,
        flux=flux,
        dual=dual,
        hminus1=hminus1,
        linear=linear,
        refine=_count("refine", refine),
        n=_count("n", n),
        start=start,
        verbose=verbose,
        threads=_count("threads", threads, least=1),
    )
    return Result(parts)


def _row(level):
    """A flat dict of a study level: the errors' norms beside the other columns."""
    row = {k: v for k, v in level.items() if k != "errors"}
    for k, v in (level.get("errors") or {}).items():
        if k != "rigid":
            row[k] = v
    return row


def study(
    case=None,
    mesh=None,
    *,
    levels=None,
    refine=None,
    cold=False,
    grading=None,
    hminus1_max=512,
    linear=None,
    threads=None,
):
    """A convergence study, as `membrane-contact study` computes it (nothing is written).

    levels: cells per side of a built-in mesh on each level; refine: refinements of the case's
    (or the given) mesh on each level; neither: the case's [validation] levels, else 8, 16, 32, 64
    or 0, 1, 2, 3. Each level starts from the one before (nested iteration). threads: as in
    `solve`.

    Returns (table, results): one dict per level (cells or refine, h, vertices, the error norms,
    estimator, effectivity, bound (whether η is a guaranteed bound on the level), iterations,
    cold_iterations, seconds, the norms' estimated quadrature
    error and the exact solution's mismatches; with several gradings also `variant`), and the
    `Result` of each level, in the same order.
    """
    (source, origin), (points, triangles, groups) = _case(case), _mesh(mesh)
    series = _core.study(
        source,
        origin,
        points,
        triangles,
        groups,
        levels=_counts("levels", levels),
        refine=_counts("refine", refine),
        cold=cold,
        grading=None if grading is None else [float(g) for g in grading],
        hminus1_max=_count("hminus1_max", hminus1_max),
        linear=linear,
        threads=_count("threads", threads, least=1),
    )
    table, results = [], []
    for label, levels_json, parts in series:
        for level, p in zip(json.loads(levels_json), parts):
            row = _row(level)
            if label:
                row["variant"] = label
            table.append(row)
            results.append(Result(p))
    return table, results


def adapt(
    case=None,
    mesh=None,
    *,
    n=None,
    refine=None,
    theta=None,
    target=None,
    max_vertices=None,
    steps=None,
    dual=False,
    threads=None,
):
    """Adaptive refinement, as `membrane-contact adapt` computes it (nothing is written): solve,
    estimate, refine the triangles with the largest indicators (Dörfler's θ), solve again, … until
    η ≤ target, the vertex budget or the step count (each default: the case's [adapt]). n: cells
    per side of a built-in initial mesh; refine: uniform refinements of the initial mesh (K), any
    kind. dual: each step's `Result` holds S_h (`dual_points`, …), as `adapt --dual` writes it.
    threads: as in `solve`.

    Returns (table, results): one dict per step (vertices, triangles, marked (None on the last
    step), estimator, bound, error, effectivity, round_off (u_h exact to round-off: no
    effectivity), mismatch, iterations, seconds; bound: whether η is a guaranteed bound at
    that step — False where the case's rule does not resolve the loads or the boundary data admit
    no solution, as the step's summary() says; mismatch: where the case's exact solution misses
    its boundary data on ∂ω_h most, a dict {relative, at, at_vertex}, else None; unsolved: what
    the exact solution misses of its equations, in words, where its errors are not this case's,
    else None; stopped: on the
    last step, why the loop stopped — the target, the step count or the vertex budget, as
    `adapt.md` says —, None on the others) and the `Result` of each step.
    """
    (source, origin), (points, triangles, groups) = _case(case), _mesh(mesh)
    steps_json, parts, stopped = _core.adapt(
        source,
        origin,
        points,
        triangles,
        groups,
        n=_count("n", n),
        refine=_count("refine", refine),
        theta=theta,
        target=target,
        max_vertices=_count("max_vertices", max_vertices),
        steps=_count("steps", steps),
        dual=dual,
        threads=_count("threads", threads, least=1),
    )
    table = json.loads(steps_json)
    for row in table:
        row["stopped"] = None
    table[-1]["stopped"] = stopped
    return table, [Result(p) for p in parts]


def read(directory):
    """The `Result` of a result directory written by `Result.write` or the command line; an
    InputError for a path that is not one, an OutputError for files that cannot be read."""
    return Result(_core.read(os.fspath(directory)))


def _unpickled(files, summary):
    """The `Result` pickled as the `files` of its result directory, with its `summary`."""
    with tempfile.TemporaryDirectory() as d:
        out = os.path.join(d, "result")
        os.mkdir(out)
        for name, data in files.items():
            with open(os.path.join(out, name), "wb") as f:
                f.write(data)
        result = read(out)
    result._summary = summary
    return result
