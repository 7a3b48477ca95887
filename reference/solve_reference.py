"""Independent reference: the discrete problem (3.4) solved with dolfinx 0.5 and PETSc SNES-VI.

Reads a Rust result (its mesh and its case text), assembles with UFL using the same quadrature
rule for the loads, and solves with bound constraints in the variables (w = u1 - u2 >= 0, s = u2)
-- not the Rust code's v/w split -- by `vinewtonrsls` and LU (MUMPS). lambda_a is the w-row
residual divided by m_a = int phi_a (4.5); lambda2_a is computed from membrane 2's equation.
PETSc's bound test has a fixed 1e-8 tolerance, so the active set SNES reports is finished by
linear solves with that set held ("polish"), which restores exact complementarity (4.8).

Usage (from the repository root):
    /usr/bin/python3 -m reference.solve_reference RESULT_DIR -o REFERENCE.h5
"""
import argparse
import logging
import time

import numpy as np
import ufl
from dolfinx import fem
from mpi4py import MPI
from petsc4py import PETSc

import dolfinx.fem.petsc  # noqa: F401  (registers fem.petsc)

from . import common, norms

logging.disable(logging.INFO)  # the JIT compiler logs every build at INFO


class Reference:
    """The (w, s) formulation on one mesh."""

    def __init__(self, points, cells, case):
        self.domain = common.make_mesh(points, cells)
        P1 = ufl.FiniteElement("Lagrange", ufl.triangle, 1)
        self.W = fem.FunctionSpace(self.domain, ufl.MixedElement([P1, P1]))
        self.V, map_w = self.W.sub(0).collapse()
        Vs, map_s = self.W.sub(1).collapse()
        self.map_w, self.map_s = np.asarray(map_w), np.asarray(map_s)
        self.vertex_dof = common.match_points(points, self.V.tabulate_dof_coordinates())  # dof of each vertex
        self.mu = (float(case["mu1"]), float(case["mu2"]))
        # Dirichlet data: w = g_h, s = 0 on the boundary.
        self.bcs, self.boundary, self.g = common.dirichlet(self.W, [self.V, Vs], case)
        self._forms(case)

    def _forms(self, case):
        mu1, mu2 = self.mu
        f1, f2 = common.as_ufl(case["f1"], self.domain), common.as_ufl(case["f2"], self.domain)
        dx = ufl.dx(domain=self.domain)
        dxq = ufl.dx(domain=self.domain, metadata={"quadrature_degree": common.quadrature_degree(case)})
        self.U = fem.Function(self.W)
        w, s = ufl.split(self.U)
        phi, psi = ufl.TestFunctions(self.W)
        u1, u2 = w + s, s
        # Find U = (w, s) ∈ W_h = P1 × P1 with w = g_h, s = 0 on ∂ω and w(a) ≥ 0 at the vertices, where
        #   F(U; φ, ψ) = μ1 (∇(w + s), ∇φ) − (f1, φ)_q + μ1 (∇(w + s), ∇ψ) + μ2 (∇s, ∇ψ) − (f1 + f2, ψ)_q
        # vanishes for every ψ ∈ P1_0(ω), and at every interior vertex a (φ = φ_a)
        #   F(U; φ_a) = λ_a m_a ≥ 0,   w(a) λ_a = 0      ((·,·)_q: the case's quadrature degree).
        F = (mu1 * ufl.inner(ufl.grad(u1), ufl.grad(phi)) * dx - f1 * phi * dxq
             + (mu1 * ufl.inner(ufl.grad(u1), ufl.grad(psi)) + mu2 * ufl.inner(ufl.grad(u2), ufl.grad(psi))) * dx
             - (f1 + f2) * psi * dxq)
        self.F = fem.form(F)
        self.J = fem.form(ufl.derivative(F, self.U))
        v = ufl.TestFunction(self.V)
        # m_a = (1, φ_a);  the loads (f_i, φ_a)_q
        self.mass = fem.petsc.assemble_vector(fem.form(v * dx)).array.copy()
        self.loads = [fem.petsc.assemble_vector(fem.form(f * v * dxq)).array.copy() for f in (f1, f2)]
        self.u2h = fem.Function(self.V)
        # λ2_a m_a = −μ2 (∇u2h, ∇φ_a) + (f2, φ_a)_q   (membrane 2's equation (4.5))
        self.action2 = fem.form(-mu2 * ufl.inner(ufl.grad(self.u2h), ufl.grad(v)) * dx + f2 * v * dxq)

    def residual(self, x):
        """F(x) without boundary conditions (the w-rows give lambda_a m_a)."""
        x.copy(self.U.vector)
        self.U.x.scatter_forward()
        b = fem.petsc.assemble_vector(self.F)
        b.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
        return b.array.copy()

    def _snes(self, max_it):
        """SNES vinewtonrsls with the F/J callbacks and w >= 0."""
        F, J, bcs = self.F, self.J, self.bcs

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

        snes = PETSc.SNES().create(MPI.COMM_SELF)
        snes.setFunction(fcb, fem.petsc.create_vector(F))
        snes.setJacobian(jcb, fem.petsc.create_matrix(J))
        snes.setType("vinewtonrsls")
        lb, ub = self.U.vector.duplicate(), self.U.vector.duplicate()
        lb.array[:] = PETSc.NINFINITY
        lb.array[self.map_w] = 0.0
        ub.array[:] = PETSc.INFINITY
        snes.setVariableBounds(lb, ub)
        snes.setTolerances(atol=1e-11, rtol=1e-13, stol=0.0, max_it=max_it)
        common.lu_solver(ksp=snes.getKSP())
        return snes

    def solve(self, guess=None, max_it=200):
        """SNES-VI solve, then polish; guess = (w, s) arrays on the V dofs, else w = g_h, s = 0."""
        x = self.U.vector.copy()
        x.array[self.map_w] = self.g.x.array if guess is None else np.maximum(guess[0], 0.0)
        x.array[self.map_s] = 0.0 if guess is None else guess[1]
        fem.petsc.set_bc(x, self.bcs)
        snes = self._snes(max_it)
        t = time.perf_counter()
        snes.solve(None, x)
        seconds = time.perf_counter() - t
        reason, its = snes.getConvergedReason(), snes.getIterationNumber()
        snes.destroy()
        if reason <= 0:
            raise RuntimeError("SNES-VI did not converge (reason %d after %d iterations)" % (reason, its))
        polish = self.polish(x.array[self.map_w].copy(), x.array[self.map_s].copy())
        return {"snes_iterations": its, "snes_seconds": seconds, **polish}

    def polish(self, w, s, rounds=5):
        """Linear solves with the active set held at w = 0, until the set is consistent."""
        scale = max(np.abs(w).max(), 1e-300)
        interior = ~self.boundary
        active = interior & (w <= 1e-7 * scale) & (self.residual_for(w, s) > 0.0)
        for k in range(rounds):
            w, s = self.linear_solve(active)
            lam_m = np.where(interior, self.residual_for(w, s), 0.0)
            wrong = (active & (lam_m < 0.0)) | (interior & ~active & (w < 0.0))
            if not wrong.any():
                return {"w": w, "s": s, "active": active, "lambda": lam_m / self.mass,
                        "lambda2": self.membrane_2_action(s), "polish_rounds": k + 1}
            active = interior & ((active & (lam_m > 0.0)) | (~active & (w < 0.0)))
        raise RuntimeError("the polished active set is not consistent after %d rounds" % rounds)

    def membrane_2_action(self, s):
        """lambda2 at the dofs of V (0 on the boundary) from u2h = s."""
        self.u2h.x.array[:] = s
        lam2_m = fem.petsc.assemble_vector(self.action2).array
        return np.where(self.boundary, 0.0, lam2_m / self.mass)

    def residual_for(self, w, s):
        x = self.U.vector.copy()
        x.array[self.map_w] = w
        x.array[self.map_s] = s
        return self.residual(x)[self.map_w]

    def linear_solve(self, active):
        """The affine system F(U) = 0 with w = 0 held on `active` (and the boundary values)."""
        dofs = np.flatnonzero(active).astype(np.int32)
        held = fem.dirichletbc(fem.Function(self.V), [self.map_w[dofs].astype(np.int32), dofs], self.W.sub(0))
        bcs = self.bcs + [held]
        A = fem.petsc.assemble_matrix(self.J, bcs=bcs)
        A.assemble()
        self.U.x.array[:] = 0.0
        rhs = fem.petsc.assemble_vector(self.F)  # F(0) = -b
        rhs.scale(-1.0)
        fem.petsc.apply_lifting(rhs, [self.J], bcs=[bcs])
        rhs.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
        fem.petsc.set_bc(rhs, bcs)
        ksp = common.lu_solver(A)
        x = rhs.duplicate()
        ksp.solve(rhs, x)
        ksp.destroy()
        return x.array[self.map_w].copy(), x.array[self.map_s].copy()


def error_norms(ref, res, rust, lam):
    """The reference's error norms, and the norms of (Rust - reference) that bound their difference."""
    exact = rust["case"]["exact"]
    dual = norms.DualSubmesh(rust["dual_points"], rust["dual_cells"])
    owner = rust["dual_owner"]
    u1, u2 = res["w"] + res["s"], res["s"]
    errors = norms.all_errors(ref.V, u1, u2, lam[owner], dual, exact, ref.mu)
    to_dofs = np.empty_like(ref.vertex_dof)
    to_dofs[ref.vertex_dof] = np.arange(len(ref.vertex_dof))  # Rust vertex at each dof
    boundary = ref.boundary[ref.vertex_dof]
    rust_lam = np.where(boundary, 0.0, rust["lambda"])
    diff = norms.difference_norms(ref.V, rust["u1"][to_dofs] - u1, rust["u2"][to_dofs] - u2,
                                  (rust_lam - lam)[owner], dual, ref.mu)
    return errors, diff


def solve_file(rust_path, out_path, guess=None):
    """Solves the problem of a Rust result; writes reference fields and summary to out_path."""
    rust = common.read_result(rust_path)
    case = rust["case"]
    ref = Reference(rust["points"], rust["cells"], case)
    t = time.perf_counter()
    res = ref.solve(guess)
    total = time.perf_counter() - t
    dof = ref.vertex_dof
    w, s = res["w"][dof], res["s"][dof]
    lam = np.where(ref.boundary, 0.0, res["lambda"])[dof]
    fields = {"u1": w + s, "u2": s, "gap": w, "lambda": lam, "lambda2": res["lambda2"][dof],
              "contact": res["active"][dof].astype(float), "mass": ref.mass[dof],
              "load_f1": ref.loads[0][dof], "load_f2": ref.loads[1][dof]}
    summary = {"snes_iterations": res["snes_iterations"], "seconds": total, "polish_rounds": res["polish_rounds"]}
    attrs = dict(summary)
    if "exact" in case:
        errors, diff = error_norms(ref, res, rust, lam)
        attrs.update({"error_" + k: v for k, v in errors.items()})
        attrs.update({"difference_" + k: v for k, v in diff.items()})
    common.write_reference(out_path, rust, fields, {
        "program": "reference: dolfinx %s + PETSc SNES vinewtonrsls" % common.dolfinx_version(), **attrs})
    return summary


def command_line(doc, solve_file, describe):
    """`-m reference.X RESULT_DIR -o OUT.h5`: solves the problem of a Rust result, prints a line."""
    ap = argparse.ArgumentParser(description=doc.split("\n")[0])
    ap.add_argument("rust_result", help="a result directory of membrane-contact solve")
    ap.add_argument("-o", "--output", required=True)
    a = ap.parse_args()
    print("%s -> %s" % (describe(solve_file(a.rust_result, a.output)), a.output))


if __name__ == "__main__":
    command_line(__doc__, solve_file, lambda s: "reference: %d SNES iterations, %.3f s, polish rounds %d"
                 % (s["snes_iterations"], s["seconds"], s["polish_rounds"]))
