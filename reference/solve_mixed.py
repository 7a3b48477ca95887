"""Second, independent reference: the mixed problem with lambda a Lagrange multiplier paired with
the lumped (vertex-rule) L2 product, every unknown P1, solved by a primal-dual active-set loop on
the assembled saddle-point system (dolfinx 0.5, PETSc LU with MUMPS): (u1, u2, lambda) for the
membranes, (u, lambda) for the obstacle problem.

lambda comes out of the solve, not from a residual, and neither the Rust code's v/w split nor
SNES-VI is involved (SNES-VI does not converge on this system: the multiplier row of a vertex whose
lambda is projected to 0 has residual exactly 0 and is never released). Both membrane equations
hold with the same lambda, so it is written as `lambda` and as `lambda2`.

Usage (from the repository root):
    /usr/bin/python3 -m reference.solve_mixed RESULT_DIR -o MIXED.h5
"""
import time
from functools import cached_property

import numpy as np
import ufl
from dolfinx import fem
from petsc4py import PETSc

import dolfinx.fem.petsc  # noqa: F401  (registers fem.petsc)

from . import common, problems
from .solve_reference import command_line

P1 = ufl.FiniteElement("Lagrange", ufl.triangle, 1)


class Mixed:
    """The saddle-point system on one mesh, assembled once: the displacements and lambda (the last
    component), each P1. A subclass states the boundary values (`boundary_values`), the forms
    (`forms`), the gap at the vertices (`gap`), the tension of the active-set rule (`tension`)
    and the written fields (`fields`)."""

    def __init__(self, points, cells, case):
        self.domain = common.make_mesh(points, cells)
        self.case = case
        self.mu = problems.tensions(case)
        self.W = fem.FunctionSpace(self.domain, ufl.MixedElement([P1] * (len(self.mu) + 1)))
        subs = [self.W.sub(i).collapse() for i in range(len(self.mu) + 1)]
        self.maps = [np.asarray(m) for _, m in subs]
        self.V = subs[0][0]
        self.coords = self.V.tabulate_dof_coordinates()
        self.vertex_dof = common.match_points(points, self.coords)
        # Dirichlet data: the displacements' boundary values, lambda = 0.
        bcs, self.boundary, _ = common.dirichlet(self.W, [V for V, _ in subs], self.boundary_values(case) + [0])
        self._assemble(case, bcs)

    def _assemble(self, case, bcs):
        domain = self.domain
        dx = ufl.dx(domain=domain)
        dxq = ufl.dx(domain=domain, metadata={"quadrature_degree": common.quadrature_degree(case)})
        dxv = ufl.dx(domain=domain, metadata={"quadrature_rule": "vertex", "quadrature_degree": 1})
        a, L = (fem.form(form) for form in self.forms(case, dx, dxq, dxv))
        self.A = fem.petsc.assemble_matrix(a, bcs=bcs)
        self.A.assemble()
        self.b = fem.petsc.assemble_vector(L)
        fem.petsc.apply_lifting(self.b, [a], bcs=[bcs])
        self.b.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
        fem.petsc.set_bc(self.b, bcs)
        u, v = ufl.TrialFunction(self.V), ufl.TestFunction(self.V)
        # c_a = μ* K_aa / m_a, K = (∇u, ∇v), m_a = (1, φ_a): the weight of the active-set rule (as in
        # the Rust code; any c > 0 converges)
        K = fem.petsc.assemble_matrix(fem.form(ufl.inner(ufl.grad(u), ufl.grad(v)) * dx))
        K.assemble()
        mass = fem.petsc.assemble_vector(fem.form(v * dx)).array
        self.c = self.tension() * K.getDiagonal().array / mass

    def solve(self, max_it=200):
        """The fields at the input vertices, the contact set and the active-set iterations:
        A = {a : lambda_a - c_a gap(a) > 0}, repeated until A is unchanged."""
        interior = ~self.boundary
        active = np.zeros(len(interior), bool)
        ksp = common.lu_solver()
        x, rhs = self.b.duplicate(), self.b.duplicate()
        for it in range(1, max_it + 1):
            # Off the active set the multiplier row becomes lambda_a = 0.
            B = self.A.copy()
            self.b.copy(rhs)
            x.set(0.0)
            B.zeroRows(self.maps[-1][interior & ~active].astype(np.int32), diag=1.0, x=x, b=rhs)
            ksp.setOperators(B)
            ksp.solve(rhs, x)
            B.destroy()
            components = [x.array[mp].copy() for mp in self.maps]
            lam = np.where(self.boundary, 0.0, components[-1])
            new = interior & (lam - self.c * self.gap(components) > 0.0)
            if np.array_equal(new, active):
                ksp.destroy()
                fields = {**self.fields(components, lam), "lambda": lam, "contact": active.astype(float)}
                return {k: v[self.vertex_dof] for k, v in fields.items()}, it
            active = new
        raise RuntimeError("the mixed active-set loop did not converge in %d iterations" % max_it)


class Membranes(Mixed):
    """(u1, u2, lambda)."""

    def boundary_values(self, case):
        return [case["g"], case["g2"]]

    def forms(self, case, dx, dxq, dxv):
        mu1, mu2 = self.mu
        f1, f2 = common.as_ufl(case["f1"], self.domain), common.as_ufl(case["f2"], self.domain)
        (u1, u2, lam), (v1, v2, m) = ufl.TrialFunctions(self.W), ufl.TestFunctions(self.W)
        zero = fem.Constant(self.domain, PETSc.ScalarType(0.0))  # keeps the lambda-lambda diagonal in the pattern
        # Find (u1, u2, λ) ∈ (P1)³ with u1 = g_h, u2 = g2_h, λ = 0 on ∂ω such that for all (v1, v2) ∈ (P1_0)²
        #   μ1 (∇u1, ∇v1) − (λ, v1)_h = (f1, v1)_q,
        #   μ2 (∇u2, ∇v2) + (λ, v2)_h = (f2, v2)_q,
        # and (u1 − u2, m)_h = 0 for m = φ_a, a in the active set A; λ_a = 0 off A (rows replaced in
        # `solve`). (·,·)_h is the vertex-rule (lumped) product, (λ, φ_a)_h = λ_a m_a as in (4.5).
        a = (mu1 * ufl.inner(ufl.grad(u1), ufl.grad(v1)) * dx - lam * v1 * dxv
             + mu2 * ufl.inner(ufl.grad(u2), ufl.grad(v2)) * dx + lam * v2 * dxv
             + (u1 - u2) * m * dxv + zero * lam * m * dxv)
        return a, f1 * v1 * dxq + f2 * v2 * dxq

    def tension(self):
        """μ* = μ1 μ2 / (μ1 + μ2), the tension of the gap."""
        mu1, mu2 = self.mu
        return mu1 * mu2 / (mu1 + mu2)

    def gap(self, components):
        return components[0] - components[1]

    def fields(self, components, lam):
        """Both membrane equations hold with the same lambda: it is also lambda2."""
        u1, u2, _ = components
        return {"u1": u1, "u2": u2, "gap": u1 - u2, "lambda2": lam}


class Obstacle(Mixed):
    """(u, lambda)."""

    @cached_property
    def psi(self):
        """psi_h at the dofs of V."""
        return common.at_points(self.case["psi"], self.coords)

    def boundary_values(self, case):
        return [case["g"]]

    def forms(self, case, dx, dxq, dxv):
        (mu,) = self.mu
        f = common.as_ufl(case["f"], self.domain)
        psi_h = fem.Function(self.V)
        psi_h.x.array[:] = self.psi
        (u, lam), (v, m) = ufl.TrialFunctions(self.W), ufl.TestFunctions(self.W)
        zero = fem.Constant(self.domain, PETSc.ScalarType(0.0))  # keeps the lambda-lambda diagonal in the pattern
        # Find (u, λ) ∈ (P1)² with u = g_h, λ = 0 on ∂ω such that for all v ∈ P1_0
        #   μ (∇u, ∇v) − (λ, v)_h = (f, v)_q,
        # and (u − ψ_h, m)_h = 0 for m = φ_a, a in the active set A; λ_a = 0 off A (rows replaced in
        # `solve`); (·,·)_h the vertex-rule product, so that the row says u(a) = ψ(a).
        a = (mu * ufl.inner(ufl.grad(u), ufl.grad(v)) * dx - lam * v * dxv + u * m * dxv
             + zero * lam * m * dxv)
        return a, f * v * dxq + psi_h * m * dxv

    def tension(self):
        return self.mu[0]

    def gap(self, components):
        return components[0] - self.psi

    def fields(self, components, lam):
        u = components[0]
        return {"u": u, "psi": self.psi, "gap": u - self.psi}


SOLVERS = {"membranes": Membranes, "obstacle": Obstacle}


def solve_file(rust_path, out_path):
    """Solves the problem of a Rust result; writes its mesh fields in the reference layout."""
    rust = common.read_result(rust_path)
    t = time.perf_counter()
    fields, iterations = SOLVERS[rust["problem"].name](rust["points"], rust["cells"], rust["case"]).solve()
    seconds = time.perf_counter() - t
    common.write_reference(out_path, rust, fields, {
        "program": "reference: mixed (%s, lambda), primal-dual active sets, dolfinx + MUMPS"
                   % ", ".join(rust["problem"].displacements), "iterations": iterations})
    return {"iterations": iterations, "seconds": seconds}


if __name__ == "__main__":
    command_line(__doc__, solve_file, lambda s: "mixed reference: %d active-set iterations, %.3f s"
                 % (s["iterations"], s["seconds"]))
