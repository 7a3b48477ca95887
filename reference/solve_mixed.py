"""Second, independent reference: the mixed problem in (u1, u2, lambda), each P1, with lambda a
Lagrange multiplier paired with the lumped (vertex-rule) L2 product, solved by a primal-dual
active-set loop on the assembled saddle-point system (dolfinx 0.5, PETSc LU with MUMPS):

    mu1 (grad u1, grad v1) - (lambda, v1)_h = (f1, v1)
    mu2 (grad u2, grad v2) + (lambda, v2)_h = (f2, v2)
    on the active set A:  (u1 - u2)(a) = 0;   off it:  lambda_a = 0,

A = {a : lambda_a - c_a (u1 - u2)(a) > 0}, c_a = mu* K_aa / m_a, repeated until A is unchanged.
With (lambda, phi_a)_h = lambda_a m_a, the first equation is (4.5): lambda comes out of the solve,
not from a residual, and neither the Rust code's v/w split nor SNES-VI is involved. (SNES-VI does
not converge on this system: see ../shared/NOTES.md.)

Usage: /usr/bin/python3 reference/solve_mixed.py RUST_RESULT.h5 -o MIXED.h5
"""
import os
import sys
import time

import numpy as np
import ufl
from dolfinx import fem
from dolfinx import mesh as dmesh
from mpi4py import MPI
from petsc4py import PETSc

import dolfinx.fem.petsc  # noqa: F401  (registers fem.petsc)

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import expr  # noqa: E402
from solve_reference import command_line, make_mesh, match_points, read_rust, write_fields  # noqa: E402


def solve(points, cells, case, max_it=200):
    """u1, u2, lambda and the contact set at the input vertices, and the active-set iterations."""
    domain = make_mesh(points, cells)
    P1 = ufl.FiniteElement("Lagrange", ufl.triangle, 1)
    W = fem.FunctionSpace(domain, ufl.MixedElement([P1, P1, P1]))
    subs = [W.sub(i).collapse() for i in range(3)]
    maps = [np.asarray(m) for _, m in subs]
    V = subs[0][0]
    coords = V.tabulate_dof_coordinates()
    mu1, mu2 = float(case["mu1"]), float(case["mu2"])
    q = int(case.get("quadrature", {}).get("degree", 4))
    f1 = expr.to_ufl(expr.parse(case["f1"]), domain)
    f2 = expr.to_ufl(expr.parse(case["f2"]), domain)
    (u1, u2, lam), (v1, v2, m) = ufl.TrialFunctions(W), ufl.TestFunctions(W)
    dx = ufl.dx(domain=domain)
    dxq = ufl.dx(domain=domain, metadata={"quadrature_degree": q})
    dxv = ufl.dx(domain=domain, metadata={"quadrature_rule": "vertex", "quadrature_degree": 1})
    g = ufl.grad
    zero = fem.Constant(domain, PETSc.ScalarType(0.0))  # keeps the lambda-lambda diagonal in the pattern
    a = fem.form(
        mu1 * ufl.inner(g(u1), g(v1)) * dx - lam * v1 * dxv
        + mu2 * ufl.inner(g(u2), g(v2)) * dx + lam * v2 * dxv
        + (u1 - u2) * m * dxv + zero * lam * m * dxv
    )
    L = fem.form(f1 * v1 * dxq + f2 * v2 * dxq)

    # Dirichlet data: u1 = g_h, u2 = 0, lambda = 0 on the boundary.
    domain.topology.create_connectivity(1, 2)
    facets = dmesh.exterior_facet_indices(domain.topology)
    bdofs = [fem.locate_dofs_topological((W.sub(i), subs[i][0]), 1, facets) for i in range(3)]
    boundary = np.zeros(len(coords), bool)
    boundary[bdofs[0][1]] = True
    gh = fem.Function(subs[0][0])
    gh.x.array[:] = np.where(boundary, expr.to_numpy(expr.parse(case["g"]), coords[:, 0], coords[:, 1]), 0.0)
    zeros = [fem.Function(subs[i][0]) for i in (1, 2)]
    bcs = [fem.dirichletbc(gh, bdofs[0], W.sub(0))] + [
        fem.dirichletbc(z, bdofs[i], W.sub(i)) for i, z in zip((1, 2), zeros)
    ]
    A = fem.petsc.assemble_matrix(a, bcs=bcs)
    A.assemble()
    b = fem.petsc.assemble_vector(L)
    fem.petsc.apply_lifting(b, [a], bcs=[bcs])
    b.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
    fem.petsc.set_bc(b, bcs)

    # c_a = mu* K_aa / m_a for the active-set rule (as in the Rust code; any c > 0 converges).
    u, v = ufl.TrialFunction(V), ufl.TestFunction(V)
    K = fem.petsc.assemble_matrix(fem.form(ufl.inner(g(u), g(v)) * dx))
    K.assemble()
    mass = fem.petsc.assemble_vector(fem.form(v * dx)).array.copy()
    c = mu1 * mu2 / (mu1 + mu2) * K.getDiagonal().array / mass

    interior = ~boundary
    active = np.zeros(len(coords), bool)
    ksp = PETSc.KSP().create(MPI.COMM_SELF)
    ksp.setType("preonly")
    ksp.getPC().setType("lu")
    ksp.getPC().setFactorSolverType("mumps")
    x, rhs = b.duplicate(), b.duplicate()
    for it in range(1, max_it + 1):
        # Off the active set the multiplier row becomes lambda_a = 0.
        B = A.copy()
        off = maps[2][interior & ~active].astype(np.int32)
        b.copy(rhs)
        x.set(0.0)
        B.zeroRows(off, diag=1.0, x=x, b=rhs)
        ksp.setOperators(B)
        ksp.solve(rhs, x)
        B.destroy()
        u1h, u2h, lh = (x.array[mp].copy() for mp in maps)
        gap = u1h - u2h
        new = interior & (lh - c * gap > 0.0)
        if np.array_equal(new, active):
            ksp.destroy()
            dof = match_points(points, coords)
            return {"u1": u1h[dof], "u2": u2h[dof], "lambda": np.where(boundary, 0.0, lh)[dof],
                    "contact": active[dof], "iterations": it}
        active = new
    raise RuntimeError("the mixed active-set loop did not converge in %d iterations" % max_it)


def solve_file(rust_path, out_path):
    """Solves the problem of a Rust result file; writes its mesh fields in the same layout."""
    data = read_rust(rust_path)
    t = time.perf_counter()
    res = solve(data["points"], data["cells"], data["case"])
    seconds = time.perf_counter() - t
    fields = {"u1": res["u1"], "u2": res["u2"], "gap": res["u1"] - res["u2"], "lambda": res["lambda"],
              "contact": res["contact"].astype(float)}
    write_fields(out_path, data, fields, {
        "program": "reference: mixed (u1, u2, lambda), primal-dual active sets, dolfinx + MUMPS",
        "iterations": res["iterations"]})
    return {"iterations": res["iterations"], "seconds": seconds}


if __name__ == "__main__":
    command_line(__doc__, solve_file, lambda s: "mixed reference: %d active-set iterations, %.3f s"
                 % (s["iterations"], s["seconds"]))
