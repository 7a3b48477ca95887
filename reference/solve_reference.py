"""Independent reference: the discrete problem solved with dolfinx 0.5 and PETSc SNES-VI, for
both problems of reference/problems.py.

Reads a Rust result (its mesh and its case text), assembles with UFL using the same quadrature
rule for the loads, and solves with bound constraints by `vinewtonrsls` and LU (MUMPS):
  - membranes (3.4): in the variables (w = u1 - u2 >= 0, s = u2) -- not the Rust code's v/w split;
    lambda_a is the w-row residual divided by m_a = int phi_a (4.5), lambda2_a is computed from
    membrane 2's equation;
  - obstacle: in u >= psi_h (psi's vertex interpolant); lambda_a is the u-row residual over m_a.
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

from . import common, norms, problems

logging.disable(logging.INFO)  # the JIT compiler logs every build at INFO
P1 = ufl.FiniteElement("Lagrange", ufl.triangle, 1)


class Bounded:
    """What the SNES-VI references share: the unknown U in a space W of P1 components (`maps`:
    the dofs of W of each component, in the dof order of the collapsed space V), the first one
    held above the bound l_h at the vertices (w >= 0, or u >= psi_h). A subclass states its
    space (`_space`), its forms (`_forms`: the residual F, its Jacobian J, the masses, the loads)
    and the fields it writes (`fields`, `displacements`)."""

    def __init__(self, points, cells, case):
        self.domain = common.make_mesh(points, cells)
        spaces, boundary_values, lower = self._space(case)
        self.V = spaces[0]
        self.vertex_dof = common.match_points(points, self.V.tabulate_dof_coordinates())  # dof of each vertex
        self.mu = problems.tensions(case)
        self.bcs, self.boundary, self.g = common.dirichlet(self.W, spaces, boundary_values)
        self.lower = fem.Function(self.V)
        self.lower.x.array[:] = common.at_points(lower, self.V.tabulate_dof_coordinates())
        self._forms(case)

    def residual(self, x):
        """F(x) without boundary conditions (the bounded component's rows give lambda_a m_a)."""
        x.copy(self.U.vector)
        self.U.x.scatter_forward()
        b = fem.petsc.assemble_vector(self.F)
        b.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
        return b.array.copy()

    def _snes(self, max_it):
        """SNES vinewtonrsls with the F/J callbacks and the bounded component >= l_h."""
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
        lb.array[self.maps[0]] = self.lower.x.array
        ub.array[:] = PETSc.INFINITY
        snes.setVariableBounds(lb, ub)
        snes.setTolerances(atol=1e-11, rtol=1e-13, stol=0.0, max_it=max_it)
        common.lu_solver(ksp=snes.getKSP())
        return snes

    def vector(self, components):
        """A vector of W from arrays on the dofs of V, one per component."""
        x = self.U.vector.copy()
        for m, values in zip(self.maps, components):
            x.array[m] = values
        return x

    def solve(self, guess=None, max_it=200):
        """SNES-VI solve, then polish. guess: arrays on the V dofs, one per component; the bounded
        one is raised to l_h. Without it, zero raised to the bound (SNES-VI's projection of a zero
        iterate, as in Bueler's obstacle.c: w = 0, u = max(0, psi_h)) with the boundary values."""
        start = [np.where(self.boundary, self.g.x.array, np.maximum(self.lower.x.array, 0.0))]
        start += [0.0] * (len(self.maps) - 1)
        if guess is not None:
            start = [np.maximum(guess[0], self.lower.x.array)] + list(guess[1:])
        x = self.vector(start)
        fem.petsc.set_bc(x, self.bcs)
        snes = self._snes(max_it)
        t = time.perf_counter()
        snes.solve(None, x)
        seconds = time.perf_counter() - t
        reason, its = snes.getConvergedReason(), snes.getIterationNumber()
        snes.destroy()
        if reason <= 0:
            raise RuntimeError("SNES-VI did not converge (reason %d after %d iterations)" % (reason, its))
        polish = self.polish([x.array[m].copy() for m in self.maps])
        return {"snes_iterations": its, "snes_seconds": seconds, **polish}

    def polish(self, components, rounds=5):
        """Linear solves with the active set held at the bound, until the set is consistent:
        lambda >= 0 on it, the bound kept off it."""
        gap = components[0] - self.lower.x.array
        scale = max(np.abs(gap).max(), 1e-300)
        interior = ~self.boundary
        active = interior & (gap <= 1e-7 * scale) & (self.residual_for(components) > 0.0)
        for k in range(rounds):
            components = self.linear_solve(active)
            gap = components[0] - self.lower.x.array
            lam_m = np.where(interior, self.residual_for(components), 0.0)
            wrong = (active & (lam_m < 0.0)) | (interior & ~active & (gap < 0.0))
            if not wrong.any():
                return {"components": components, "active": active, "lambda": lam_m / self.mass,
                        "polish_rounds": k + 1}
            active = interior & ((active & (lam_m > 0.0)) | (~active & (gap < 0.0)))
        raise RuntimeError("the polished active set is not consistent after %d rounds" % rounds)

    def residual_for(self, components):
        """The bounded component's rows of F at U = the components."""
        return self.residual(self.vector(components))[self.maps[0]]

    def linear_solve(self, active):
        """The affine system F(U) = 0 with the bounded component = l_h held on `active` (and the
        boundary values)."""
        bcs = self.bcs + [self._held(np.flatnonzero(active).astype(np.int32))]
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
        return [x.array[m].copy() for m in self.maps]

    def _held(self, dofs):
        """The bounded component = l_h at `dofs` (of V), as a boundary condition of W."""
        if len(self.maps) == 1:
            return fem.dirichletbc(self.lower, dofs)
        return fem.dirichletbc(self.lower, [self.maps[0][dofs].astype(np.int32), dofs], self.W.sub(0))

    def _loads_and_masses(self, loads, dx, dxq):
        """m_a = (1, phi_a) and the loads (f, phi_a)_q on the dofs of V."""
        v = ufl.TestFunction(self.V)
        self.mass = fem.petsc.assemble_vector(fem.form(v * dx)).array.copy()
        self.loads = [fem.petsc.assemble_vector(fem.form(f * v * dxq)).array.copy() for f in loads]

    def measures(self, case):
        """dx, and dx with the case's quadrature degree (for the loads)."""
        return (ufl.dx(domain=self.domain),
                ufl.dx(domain=self.domain, metadata={"quadrature_degree": common.quadrature_degree(case)}))


class Reference(Bounded):
    """The membranes in the (w, s) formulation."""

    def _space(self, case):
        """W = P1 x P1; u1 = g_h, u2 = g2_h on the boundary: w = g_h - g2_h, s = g2_h; w >= 0."""
        self.W = fem.FunctionSpace(self.domain, ufl.MixedElement([P1, P1]))
        (V, map_w), (Vs, map_s) = self.W.sub(0).collapse(), self.W.sub(1).collapse()
        self.maps = [np.asarray(map_w), np.asarray(map_s)]
        return [V, Vs], [("-", case["g"], case["g2"]), case["g2"]], 0.0

    def _forms(self, case):
        mu1, mu2 = self.mu
        f1, f2 = common.as_ufl(case["f1"], self.domain), common.as_ufl(case["f2"], self.domain)
        dx, dxq = self.measures(case)
        self.U = fem.Function(self.W)
        w, s = ufl.split(self.U)
        phi, psi = ufl.TestFunctions(self.W)
        u1, u2 = w + s, s
        # Find U = (w, s) ∈ W_h = P1 × P1 with w = g_h − g2_h, s = g2_h on ∂ω and w(a) ≥ 0 at the
        # vertices, where
        #   F(U; φ, ψ) = μ1 (∇(w + s), ∇φ) − (f1, φ)_q + μ1 (∇(w + s), ∇ψ) + μ2 (∇s, ∇ψ) − (f1 + f2, ψ)_q
        # vanishes for every ψ ∈ P1_0(ω), and at every interior vertex a (φ = φ_a)
        #   F(U; φ_a) = λ_a m_a ≥ 0,   w(a) λ_a = 0      ((·,·)_q: the case's quadrature degree).
        F = (mu1 * ufl.inner(ufl.grad(u1), ufl.grad(phi)) * dx - f1 * phi * dxq
             + (mu1 * ufl.inner(ufl.grad(u1), ufl.grad(psi)) + mu2 * ufl.inner(ufl.grad(u2), ufl.grad(psi))) * dx
             - (f1 + f2) * psi * dxq)
        self.F = fem.form(F)
        self.J = fem.form(ufl.derivative(F, self.U))
        self._loads_and_masses((f1, f2), dx, dxq)
        v = ufl.TestFunction(self.V)
        self.u2h = fem.Function(self.V)
        # λ2_a m_a = −μ2 (∇u2h, ∇φ_a) + (f2, φ_a)_q   (membrane 2's equation (4.5))
        self.action2 = fem.form(-mu2 * ufl.inner(ufl.grad(self.u2h), ufl.grad(v)) * dx + f2 * v * dxq)

    def membrane_2_action(self, s):
        """lambda2 at the dofs of V (0 on the boundary) from u2h = s."""
        self.u2h.x.array[:] = s
        lam2_m = fem.petsc.assemble_vector(self.action2).array
        return np.where(self.boundary, 0.0, lam2_m / self.mass)

    def displacements(self, res):
        """{name: dof values on V} of the membranes."""
        w, s = res["components"]
        return {"u1": w + s, "u2": s}

    def fields(self, res):
        """The written fields beside lambda, contact, the masses and loads, on the dofs of V."""
        w, s = res["components"]
        return {**self.displacements(res), "gap": w, "lambda2": self.membrane_2_action(s)}


class Obstacle(Bounded):
    """The obstacle problem in u."""

    def _space(self, case):
        """W = V = P1; u = g_h on the boundary, u >= psi_h."""
        self.W = fem.FunctionSpace(self.domain, P1)
        self.maps = [np.arange(self.W.dofmap.index_map.size_local)]
        return [self.W], [case["g"]], case["psi"]

    def _forms(self, case):
        (mu,) = self.mu
        f = common.as_ufl(case["f"], self.domain)
        dx, dxq = self.measures(case)
        self.U = fem.Function(self.W)
        phi = ufl.TestFunction(self.W)
        # Find u ∈ P1 with u = g_h on ∂ω and u(a) ≥ ψ_h(a) = ψ(a) at the vertices, where at every
        # interior vertex a (φ = φ_a)
        #   F(u; φ_a) = μ (∇u, ∇φ_a) − (f, φ_a)_q = λ_a m_a ≥ 0,   (u − ψ_h)(a) λ_a = 0.
        F = mu * ufl.inner(ufl.grad(self.U), ufl.grad(phi)) * dx - f * phi * dxq
        self.F = fem.form(F)
        self.J = fem.form(ufl.derivative(F, self.U))
        self._loads_and_masses((f,), dx, dxq)

    def displacements(self, res):
        return {"u": res["components"][0]}

    def fields(self, res):
        u = res["components"][0]
        return {"u": u, "psi": self.lower.x.array.copy(), "gap": u - self.lower.x.array}


SOLVERS = {"membranes": Reference, "obstacle": Obstacle}


def solver(points, cells, case):
    """The SNES-VI reference of the case's problem on a mesh."""
    return SOLVERS[problems.of(case).name](points, cells, case)


def error_norms(ref, res, rust, lam):
    """The reference's error norms, the estimated errors of their quadrature, and the norms of
    (Rust - reference) that bound their difference; lam: the reference's lambda at the Rust vertices."""
    dual = norms.DualSubmesh(rust["dual_points"], rust["dual_cells"])
    owner = rust["dual_owner"]
    mine = {k: (v, mu) for (k, v), mu in zip(ref.displacements(res).items(), ref.mu)}
    exact = rust["case"]["exact"]
    at_vertices = {k: (v[ref.vertex_dof], mu) for k, (v, mu) in mine.items()}
    errors, quadrature = norms.exact_errors(rust["points"], rust["cells"], at_vertices, rust["dual_points"],
                                            rust["dual_cells"], lam[owner], exact)
    errors["hminus1_lambda"] = dual.errors(lam[owner], exact["lambda"])[1]
    to_dofs = np.empty_like(ref.vertex_dof)
    to_dofs[ref.vertex_dof] = np.arange(len(ref.vertex_dof))  # Rust vertex at each dof
    rust_lam = np.where(ref.boundary[ref.vertex_dof], 0.0, rust["lambda"])
    differences = {k: (rust[k][to_dofs] - v, mu) for k, (v, mu) in mine.items()}
    return errors, quadrature, norms.difference_norms(ref.V, differences, (rust_lam - lam)[owner], dual)


def solve_file(rust_path, out_path, guess=None):
    """Solves the problem of a Rust result; writes reference fields and summary to out_path."""
    rust = common.read_result(rust_path)
    case = rust["case"]
    ref = solver(rust["points"], rust["cells"], case)
    t = time.perf_counter()
    res = ref.solve(guess)
    total = time.perf_counter() - t
    dof = ref.vertex_dof
    lam = np.where(ref.boundary, 0.0, res["lambda"])[dof]
    fields = {k: v[dof] for k, v in ref.fields(res).items()}
    fields.update({"lambda": lam, "contact": res["active"][dof].astype(float), "mass": ref.mass[dof]})
    fields.update({"load_" + k: load[dof] for k, load in zip(rust["problem"].loads, ref.loads)})
    summary = {"snes_iterations": res["snes_iterations"], "seconds": total, "polish_rounds": res["polish_rounds"]}
    attrs = dict(summary)
    if "exact" in case:
        errors, quadrature, diff = error_norms(ref, res, rust, lam)
        attrs.update({"error_" + k: v for k, v in errors.items()})
        attrs.update({"quadrature_" + k: v for k, v in quadrature.items()})
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
