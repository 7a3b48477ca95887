"""What every part of the reference shares: result files, vertex matching, lumped masses, case data.

A Rust result is the directory written by `membrane-contact solve ... -o DIR`: DIR/solution.h5
(read here), DIR/solution.xdmf and DIR/dual.xdmf (read by ParaView in paraview_check). The
reference's own files (reference-N.h5, mixed-N.h5) hold /mesh/{geometry, topology} and vertex
fields under /mesh in the Rust vertex order, the case text and a summary as attributes of `/`.
"""
import os
import tomllib

import h5py
import numpy as np

from . import expr, problems

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
FLUX_FIELDS = ("t%s_x", "t%s_y", "div_t%s")  # of each flux (problems.Problem.fluxes: suffix 1, 2 or none)


def read_result(path):
    """Everything of a Rust result directory (or its solution.h5) that the reference uses:
    mesh and vertex fields, the dual submesh S_h with its cell fields (when written), the case and
    the attributes."""
    h5 = os.path.join(path, "solution.h5") if os.path.isdir(path) else path
    with h5py.File(h5, "r") as f:
        mesh = f["mesh"]
        out = {
            "path": path,
            "points": mesh["geometry"][...],
            "cells": mesh["topology"][...].astype(np.int64),
            "attrs": {k: f.attrs[k] for k in f.attrs},
        }
        case = tomllib.loads(str(out["attrs"]["case_text"]))
        problem = problems.of(case)
        exact = tuple(k + "_exact" for k in problem.displacements + ("lambda",))
        out.update({k: mesh[k][...] for k in problem.fields + exact if k in mesh})
        if "dual" in f:  # written by `solve --dual` or `--flux`
            dual = f["dual"]
            out.update({
                "dual_points": dual["geometry"][...],
                "dual_cells": dual["topology"][...].astype(np.int64),
                "dual_owner": dual["vertex"][...].astype(np.int64),
                "dual_lambda": dual["lambda"][...],
            })
            out.update({k % s: dual[k % s][...] for s, *_ in problem.fluxes for k in FLUX_FIELDS if k % s in dual})
    out["case_text"] = str(out["attrs"]["case_text"])
    from . import groups

    groups.use(path, case, str(out["attrs"]["case_origin"]))
    # Expressions parsed once, with the names of the case's [let] table substituted.
    out["case"] = expr.parse_case(case)
    out["problem"] = problem
    return out


def errors_of(attrs, problem):
    """{key: value} of the error norms held by the attributes of a Rust result or a reference file
    (the keys of `problem` that are present)."""
    return {k: float(attrs["error_" + k]) for k in problem.error_keys if "error_" + k in attrs}


def write_reference(path, result, fields, attrs):
    """Writes vertex fields on the mesh of a Rust result through a temporary file renamed at the end."""
    tmp = path + ".tmp"
    with h5py.File(tmp, "w") as f:
        f["mesh/geometry"] = result["points"]
        f["mesh/topology"] = result["cells"]
        for k, v in fields.items():
            f["mesh/" + k] = v
        f.attrs["case_text"] = result["case_text"]
        for k, v in attrs.items():
            f.attrs[k] = v
    os.replace(tmp, path)


def read_reference(path):
    """A file written by `write_reference`: {"points", "cells", "attrs", field: values}."""
    with h5py.File(path, "r") as f:
        out = {k: f["mesh/" + k][...] for k in f["mesh"]}
        out["points"], out["cells"] = out.pop("geometry"), out.pop("topology")
        out["attrs"] = {k: f.attrs[k] for k in f.attrs}
    return out


def match_points(a, b):
    """perm with b[perm[i]] == a[i] (to round-off): rows of a found among rows of b (x, y only)."""
    scale = max(np.abs(a).max(), np.abs(b).max(), 1.0)
    ka = np.round(a[:, :2] / scale, 9)
    kb = np.round(b[:, :2] / scale, 9)
    lookup = {tuple(r): i for i, r in enumerate(kb)}
    try:
        return np.array([lookup[tuple(r)] for r in ka])
    except KeyError as e:
        raise RuntimeError("point %s not found in the other mesh" % (e,)) from None


def areas(points, cells):
    """Areas of triangles."""
    p = points[cells]
    return 0.5 * np.abs((p[:, 1, 0] - p[:, 0, 0]) * (p[:, 2, 1] - p[:, 0, 1])
                        - (p[:, 1, 1] - p[:, 0, 1]) * (p[:, 2, 0] - p[:, 0, 0]))


def lumped_mass(points, cells):
    """m_a = int phi_a = |D_a| at every vertex."""
    m = np.zeros(len(points))
    np.add.at(m, cells.ravel(), np.repeat(areas(points, cells) / 3.0, 3))
    return m


def quadrature_degree(case):
    """The degree of the load rule (case key quadrature.degree, default 4 as in the Rust code)."""
    return int(case.get("quadrature", {}).get("degree", 4))


def at_points(source, points):
    """A case expression (string, number or parsed tree) at points (N x >= 2), as a NumPy array."""
    return expr.to_numpy(expr.parse(source), points[:, 0], points[:, 1])


def as_ufl(source, domain):
    """A case expression (string, number or parsed tree) as UFL of the spatial coordinate of
    `domain`; never UFL's Zero. UFL turns a zero number into Zero and simplifies what it touches
    (`0`, `0*x`, `x*0 + y*0`, `0^2`, `sqrt(0)`: Zero, or a plain Python 0.0 for a function of a
    constant), and Zero * v is Zero again, without the test function v: the load form
    `f * v * dx` of a zero f has no argument, dolfinx compiles it as a rank-0 form without a
    function space, and `assemble_vector` fails on it (IndexError in function_spaces[0]). A zero
    is therefore a `fem.Constant` of value 0, which UFL does not simplify away (the load
    assembles to exact zeros). A nonzero constant stays a UFL literal, as before."""
    import ufl
    from dolfinx import fem
    from petsc4py import PETSc

    value = ufl.as_ufl(expr.to_ufl(expr.parse(source), domain))
    if isinstance(value, ufl.constantvalue.Zero):
        return fem.Constant(domain, PETSc.ScalarType(0.0))
    return value


def shipped_cases(only_validation=False):
    """The case files of data/cases/ (those with a [validation] table if asked)."""
    import glob

    paths = sorted(glob.glob(os.path.join(ROOT, "data", "cases", "*.toml")))
    return [p for p in paths if not only_validation or "validation" in load_case(p)]


def load_case(path):
    with open(path, "rb") as f:
        return tomllib.load(f)


def make_mesh(points, cells):
    """A dolfinx mesh of P1 triangles (serial) from vertex coordinates and cells."""
    import ufl
    from dolfinx import mesh as dmesh
    from mpi4py import MPI

    element = ufl.Mesh(ufl.VectorElement("Lagrange", ufl.triangle, 1))
    return dmesh.create_mesh(MPI.COMM_SELF, cells.astype(np.int64), points[:, :2].copy(), element)


def lu_solver(A=None, ksp=None):
    """A PETSc KSP (new, or `ksp`) that solves by LU with MUMPS (serial)."""
    from mpi4py import MPI
    from petsc4py import PETSc

    ksp = ksp or PETSc.KSP().create(MPI.COMM_SELF)
    ksp.setType("preonly")
    ksp.getPC().setType("lu")
    ksp.getPC().setFactorSolverType("mumps")
    if A is not None:
        ksp.setOperators(A)
    return ksp


def dirichlet(W, spaces, values):
    """Boundary conditions on the space W whose collapsed subspaces are `spaces` (or on W alone,
    spaces = [W], a space without subspaces): component i = the P1 interpolant of the case
    expression values[i] on the boundary. Returns the bcs, the mask of boundary dofs (dofs of
    spaces[0]) and the first component's boundary data as a function of spaces[0] (0 inside)."""
    from dolfinx import fem
    from dolfinx import mesh as dmesh

    domain = W.mesh
    domain.topology.create_connectivity(1, 2)
    facets = dmesh.exterior_facet_indices(domain.topology)
    whole = spaces == [W]
    subs = [W] if whole else [W.sub(i) for i in range(len(spaces))]
    bcs, boundary, first = [], None, None
    for sub, V, value in zip(subs, spaces, values):
        dofs = fem.locate_dofs_topological(V if whole else (sub, V), 1, facets)
        own = dofs if whole else dofs[1]  # the dofs of the collapsed space V
        coords = V.tabulate_dof_coordinates()
        data = fem.Function(V)
        data.x.array[own] = at_points(value, coords[own])
        bcs.append(fem.dirichletbc(data, dofs) if whole else fem.dirichletbc(data, dofs, sub))
        if first is None:
            boundary = np.zeros(len(coords), bool)
            boundary[own] = True
            first = data
    return bcs, boundary, first


def dolfinx_version():
    import dolfinx

    return dolfinx.__version__
