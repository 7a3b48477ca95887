"""Independent reference: the same discrete problem (3.4) solved with dolfinx 0.5 and PETSc SNES-VI.

Reads a result file of the Rust solver (its mesh and its case text), assembles with UFL using the
same quadrature rule for the loads, and solves with bound constraints in the variables
(w = u1 - u2 >= 0, s = u2) -- not the Rust code's v/w split:

    w-row:  mu1 (grad(w + s), grad phi) - (f1, phi)                      = lambda_a m_a  (>= 0)
    s-row:  mu1 (grad(w + s), grad psi) + mu2 (grad s, grad psi) - (f1 + f2, psi) = 0

with `vinewtonrsls` and LU. lambda_a is the w-row residual divided by m_a = int phi_a (4.5).
PETSc's bound test has a fixed 1e-8 tolerance, so the active set SNES reports is finished by a
linear solve with that set held ("polish"), which restores exact complementarity (4.8).

Usage: /usr/bin/python3 reference/solve_reference.py RUST_RESULT.h5 -o REFERENCE.h5
"""
import argparse
import logging
import os
import sys
import time
import tomllib

import h5py
import numpy as np
import ufl
from dolfinx import fem
from dolfinx import mesh as dmesh
from mpi4py import MPI
from petsc4py import PETSc

import dolfinx.fem.petsc  # noqa: F401  (registers fem.petsc)

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import expr  # noqa: E402

ERROR_DEGREE = 10  # the Rust code's error rule (src/norms.rs)
logging.disable(logging.INFO)  # the JIT compiler logs every build at INFO


def match_points(a, b):
    """perm with b[perm[i]] == a[i] (to round-off): rows of a found among rows of b."""
    scale = max(np.abs(a).max(), np.abs(b).max(), 1.0)
    ka = np.round(a[:, :2] / scale, 9)
    kb = np.round(b[:, :2] / scale, 9)
    lookup = {tuple(r): i for i, r in enumerate(kb)}
    try:
        return np.array([lookup[tuple(r)] for r in ka])
    except KeyError as e:
        raise RuntimeError("point %s not found in the other mesh" % (e,)) from None


def read_rust(path):
    with h5py.File(path, "r") as f:
        out = {
            "points": f["mesh/geometry"][...],
            "cells": f["mesh/topology"][...],
            "dual_points": f["dual/geometry"][...],
            "dual_cells": f["dual/topology"][...],
            "dual_owner": f["dual/vertex"][...].astype(np.int64),
            "case": tomllib.loads(f.attrs["case_text"]),
            "case_text": f.attrs["case_text"],
        }
        for name in ("u1", "u2", "gap", "lambda", "contact"):
            out[name] = f["mesh/" + name][...]
    return out


def make_mesh(points, cells):
    element = ufl.Mesh(ufl.VectorElement("Lagrange", ufl.triangle, 1))
    return dmesh.create_mesh(MPI.COMM_SELF, cells.astype(np.int64), points[:, :2].copy(), element)


class Reference:
    """The (w, s) formulation on one mesh."""

    def __init__(self, points, cells, case):
        self.case = case
        self.domain = make_mesh(points, cells)
        P1 = ufl.FiniteElement("Lagrange", ufl.triangle, 1)
        self.W = fem.FunctionSpace(self.domain, ufl.MixedElement([P1, P1]))
        self.Vw, self.map_w = self.W.sub(0).collapse()
        self.Vs, self.map_s = self.W.sub(1).collapse()
        self.map_w, self.map_s = np.asarray(self.map_w), np.asarray(self.map_s)
        coords = self.Vw.tabulate_dof_coordinates()
        # dof of V_w at each input vertex (input order)
        self.vertex_dof = match_points(points, coords)
        mu1, mu2 = float(case["mu1"]), float(case["mu2"])
        q = int(case.get("quadrature", {}).get("degree", 4))
        f1 = expr.to_ufl(expr.parse(case["f1"]), self.domain)
        f2 = expr.to_ufl(expr.parse(case["f2"]), self.domain)
        self.U = fem.Function(self.W)
        w, s = ufl.split(self.U)
        phi, psi = ufl.TestFunctions(self.W)
        u1, u2 = w + s, s
        dx = ufl.dx(domain=self.domain)
        dxq = ufl.dx(domain=self.domain, metadata={"quadrature_degree": q})
        g = ufl.grad
        F = (
            mu1 * ufl.inner(g(u1), g(phi)) * dx
            - f1 * phi * dxq
            + (mu1 * ufl.inner(g(u1), g(psi)) + mu2 * ufl.inner(g(u2), g(psi))) * dx
            - (f1 + f2) * psi * dxq
        )
        self.F = fem.form(F)
        self.J = fem.form(ufl.derivative(F, self.U))
        # m_a = int phi_a
        v = ufl.TestFunction(self.Vw)
        self.mass = fem.petsc.assemble_vector(fem.form(v * dx)).array.copy()
        # Dirichlet data: w = g_h, s = 0 on the boundary.
        self.domain.topology.create_connectivity(1, 2)
        facets = dmesh.exterior_facet_indices(self.domain.topology)
        self.bdofs_w = fem.locate_dofs_topological((self.W.sub(0), self.Vw), 1, facets)
        self.bdofs_s = fem.locate_dofs_topological((self.W.sub(1), self.Vs), 1, facets)
        self.boundary = np.zeros(len(coords), bool)
        self.boundary[self.bdofs_w[1]] = True
        gvals = expr.to_numpy(expr.parse(case["g"]), coords[:, 0], coords[:, 1])
        self.g = fem.Function(self.Vw)
        self.g.x.array[:] = np.where(self.boundary, gvals, 0.0)
        zero = fem.Function(self.Vs)
        self.bcs = [
            fem.dirichletbc(self.g, self.bdofs_w, self.W.sub(0)),
            fem.dirichletbc(zero, self.bdofs_s, self.W.sub(1)),
        ]

    def residual(self, x):
        """F(x) without boundary conditions (the w-rows give lambda_a m_a)."""
        x.copy(self.U.vector)
        self.U.x.scatter_forward()
        b = fem.petsc.assemble_vector(self.F)
        b.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
        return b.array.copy()

    def solve(self, guess=None, max_it=200):
        """SNES-VI solve; guess = (w, s) arrays on the V_w / V_s dofs, else w = g_h, s = 0."""
        F, J, bcs = self.F, self.J, self.bcs
        b = fem.petsc.create_vector(F)
        A = fem.petsc.create_matrix(J)

        def fcb(snes, x, out):
            x.copy(self.U.vector)
            self.U.x.scatter_forward()
            with out.localForm() as loc:
                loc.set(0.0)
            fem.petsc.assemble_vector(out, F)
            fem.petsc.apply_lifting(out, [J], bcs=[bcs], x0=[x], scale=-1.0)
            out.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
            fem.petsc.set_bc(out, bcs, x, -1.0)

        def jcb(snes, x, mat, pmat):
            mat.zeroEntries()
            fem.petsc.assemble_matrix(mat, J, bcs=bcs)
            mat.assemble()

        x = self.U.vector.copy()
        xa = x.array
        if guess is None:
            xa[self.map_w] = self.g.x.array
            xa[self.map_s] = 0.0
        else:
            xa[self.map_w] = np.maximum(guess[0], 0.0)
            xa[self.map_s] = guess[1]
        fem.petsc.set_bc(x, bcs)
        lb, ub = x.duplicate(), x.duplicate()
        lb.array[:] = PETSc.NINFINITY
        lb.array[self.map_w] = 0.0
        ub.array[:] = PETSc.INFINITY

        snes = PETSc.SNES().create(MPI.COMM_SELF)
        snes.setFunction(fcb, b)
        snes.setJacobian(jcb, A)
        snes.setType("vinewtonrsls")
        snes.setVariableBounds(lb, ub)
        snes.setTolerances(atol=1e-11, rtol=1e-13, stol=0.0, max_it=max_it)
        ksp = snes.getKSP()
        ksp.setType("preonly")
        pc = ksp.getPC()
        pc.setType("lu")
        pc.setFactorSolverType("mumps")
        t = time.perf_counter()
        snes.solve(None, x)
        seconds = time.perf_counter() - t
        reason, its = snes.getConvergedReason(), snes.getIterationNumber()
        if reason <= 0:
            raise RuntimeError("SNES-VI did not converge (reason %d after %d iterations)" % (reason, its))
        w = x.array[self.map_w].copy()
        s = x.array[self.map_s].copy()
        polish = self.polish(w, s)
        snes.destroy()
        return {"snes_iterations": its, "snes_seconds": seconds, **polish}

    def polish(self, w, s, rounds=5):
        """Linear solves with the active set held at w = 0, until the set is consistent."""
        scale = max(np.abs(w).max(), 1e-300)
        r = self.residual_for(w, s)
        interior = ~self.boundary
        active = interior & (w <= 1e-7 * scale) & (r > 0.0)
        for k in range(rounds):
            w, s = self.linear_solve(active)
            r = self.residual_for(w, s)
            lam_m = np.where(interior, r, 0.0)
            wrong = (active & (lam_m < 0.0)) | (interior & ~active & (w < 0.0))
            if not wrong.any():
                return {"w": w, "s": s, "active": active, "lambda": lam_m / self.mass, "polish_rounds": k + 1}
            active = interior & ((active & (lam_m > 0.0)) | (~active & (w < 0.0)))
        raise RuntimeError("the polished active set is not consistent after %d rounds" % rounds)

    def residual_for(self, w, s):
        x = self.U.vector.copy()
        x.array[self.map_w] = w
        x.array[self.map_s] = s
        return self.residual(x)[self.map_w]

    def linear_solve(self, active):
        """The affine system F(U) = 0 with w = 0 held on `active` (and the boundary values)."""
        zero = fem.Function(self.Vw)
        dofs = np.flatnonzero(active).astype(np.int32)
        held = fem.dirichletbc(zero, [self.map_w[dofs].astype(np.int32), dofs], self.W.sub(0))
        bcs = self.bcs + [held]
        A = fem.petsc.assemble_matrix(self.J, bcs=bcs)
        A.assemble()
        self.U.x.array[:] = 0.0
        rhs = fem.petsc.assemble_vector(self.F)  # F(0) = -b
        rhs.scale(-1.0)
        fem.petsc.apply_lifting(rhs, [self.J], bcs=[bcs])
        rhs.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
        fem.petsc.set_bc(rhs, bcs)
        ksp = PETSc.KSP().create(MPI.COMM_SELF)
        ksp.setOperators(A)
        ksp.setType("preonly")
        ksp.getPC().setType("lu")
        ksp.getPC().setFactorSolverType("mumps")
        x = rhs.duplicate()
        ksp.solve(rhs, x)
        ksp.destroy()
        return x.array[self.map_w].copy(), x.array[self.map_s].copy()

    def errors(self, w, s, lam_vertices, dual_points, dual_cells, dual_owner, exact):
        """The Rust code's error norms, computed with UFL (same rules)."""
        dxe = ufl.dx(domain=self.domain, metadata={"quadrature_degree": ERROR_DEGREE})
        u1h, u2h = fem.Function(self.Vw), fem.Function(self.Vs)
        u1h.x.array[:] = w + s
        u2h.x.array[:] = s
        out = {}
        scalar = lambda form: float(fem.assemble_scalar(fem.form(form)))  # noqa: E731
        for name, uh in (("u1", u1h), ("u2", u2h)):
            u = expr.to_ufl(expr.parse(exact[name]), self.domain)
            out["l2_" + name] = np.sqrt(scalar((u - uh) ** 2 * dxe))
            grad = exact.get("grad_" + name)
            if grad is not None:
                gu = ufl.as_vector([expr.to_ufl(expr.parse(c), self.domain) for c in grad])
                out["h1_" + name] = np.sqrt(scalar(ufl.inner(gu - ufl.grad(uh), gu - ufl.grad(uh)) * dxe))
        # lambda_h on the dual submesh S_h, as DG0.
        sub = make_mesh(dual_points, dual_cells)
        V0 = fem.FunctionSpace(sub, ("DG", 0))
        lh = fem.Function(V0)
        centroids = dual_points[dual_cells].mean(axis=1)
        sub_x = sub.geometry.x
        sub_cells = sub.geometry.dofmap.array.reshape(-1, 3)
        perm = match_points(sub_x[sub_cells].mean(axis=1), centroids)
        lh.x.array[:] = lam_vertices[dual_owner[perm]]
        lam = expr.to_ufl(expr.parse(exact["lambda"]), sub)
        dxs = ufl.dx(domain=sub, metadata={"quadrature_degree": ERROR_DEGREE})
        out["l2_lambda"] = np.sqrt(scalar((lam - lh) ** 2 * dxs))
        # ||lam - lam_h||_H-1 as the dual norm over P1_0 on S_h: |z|_H1 with -lap z = lam - lam_h.
        V1 = fem.FunctionSpace(sub, ("Lagrange", 1))
        z, v = ufl.TrialFunction(V1), ufl.TestFunction(V1)
        sub.topology.create_connectivity(1, 2)
        dofs = fem.locate_dofs_topological(V1, 1, dmesh.exterior_facet_indices(sub.topology))
        bc = fem.dirichletbc(PETSc.ScalarType(0.0), dofs, V1)
        problem = fem.petsc.LinearProblem(
            ufl.inner(ufl.grad(z), ufl.grad(v)) * ufl.dx(domain=sub),
            (lam - lh) * v * dxs,
            bcs=[bc],
            petsc_options={"ksp_type": "preonly", "pc_type": "lu", "pc_factor_mat_solver_type": "mumps"},
        )
        zh = problem.solve()
        out["hm1_lambda"] = np.sqrt(max(scalar((lam - lh) * zh * dxs), 0.0))
        return out


def solve_file(rust_path, out_path, guess=None):
    """Solves the problem of a Rust result file; writes the same layout; returns a summary."""
    data = read_rust(rust_path)
    case = data["case"]
    ref = Reference(data["points"], data["cells"], case)
    t = time.perf_counter()
    res = ref.solve(guess)
    total = time.perf_counter() - t
    dof = ref.vertex_dof
    w, s = res["w"][dof], res["s"][dof]
    lam = np.where(ref.boundary, 0.0, res["lambda"])[dof]
    fields = {
        "u1": w + s,
        "u2": s,
        "gap": w,
        "lambda": lam,
        "contact": res["active"][dof].astype(float),
    }
    summary = {"snes_iterations": res["snes_iterations"], "seconds": total, "polish_rounds": res["polish_rounds"]}
    if "exact" in case:
        summary.update(
            ref.errors(
                res["w"], res["s"], lam, data["dual_points"], data["dual_cells"], data["dual_owner"], case["exact"]
            )
        )
    write_fields(out_path, data, fields,
                 {"program": "reference: dolfinx %s + PETSc SNES vinewtonrsls" % dolfinx_version(), **summary})
    summary["fields"] = fields
    return summary


def write_fields(out_path, data, fields, attrs):
    """Writes vertex fields on the mesh of a Rust result `data` in its layout, through a temporary
    file renamed at the end."""
    tmp = out_path + ".tmp"
    with h5py.File(tmp, "w") as f:
        f["mesh/geometry"] = data["points"]
        f["mesh/topology"] = data["cells"]
        for k, v in fields.items():
            f["mesh/" + k] = v
        f.attrs["case_text"] = data["case_text"]
        for k, v in attrs.items():
            f.attrs[k] = v
    os.replace(tmp, out_path)


def command_line(doc, solve_file, describe):
    """`SCRIPT RUST_RESULT.h5 -o OUT.h5`: solves the problem of a Rust result file, prints a line."""
    ap = argparse.ArgumentParser(description=doc.split("\n")[0])
    ap.add_argument("rust_result")
    ap.add_argument("-o", "--output", required=True)
    a = ap.parse_args()
    print("%s -> %s" % (describe(solve_file(a.rust_result, a.output)), a.output))


def dolfinx_version():
    import dolfinx

    return dolfinx.__version__


if __name__ == "__main__":
    command_line(__doc__, solve_file, lambda s: "reference: %d SNES iterations, %.3f s, polish rounds %d"
                 % (s["snes_iterations"], s["seconds"], s["polish_rounds"]))
