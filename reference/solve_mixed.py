"""Second, independent reference: the mixed problem in (u1, u2, lambda), each P1, with lambda a
Lagrange multiplier paired with the lumped (vertex-rule) L2 product, solved by a primal-dual
active-set loop on the assembled saddle-point system (dolfinx 0.5, PETSc LU with MUMPS).

lambda comes out of the solve, not from a residual, and neither the Rust code's v/w split nor
SNES-VI is involved (SNES-VI does not converge on this system: the multiplier row of a vertex whose
lambda is projected to 0 has residual exactly 0 and is never released). Both membrane equations
hold with the same lambda, so it is written as `lambda` and as `lambda2`.

Usage (from the repository root):
    /usr/bin/python3 -m reference.solve_mixed RESULT_DIR -o MIXED.h5
"""
import time

import numpy as np
import ufl
from dolfinx import fem
from petsc4py import PETSc

import dolfinx.fem.petsc  # noqa: F401  (registers fem.petsc)

from . import common
from .solve_reference import command_line


class Mixed:
    """The saddle-point system on one mesh, assembled once."""

    def __init__(self, points, cells, case):
        self.domain = common.make_mesh(points, cells)
        P1 = ufl.FiniteElement("Lagrange", ufl.triangle, 1)
        self.W = fem.FunctionSpace(self.domain, ufl.MixedElement([P1, P1, P1]))
        subs = [self.W.sub(i).collapse() for i in range(3)]
        self.maps = [np.asarray(m) for _, m in subs]
        self.V = subs[0][0]
        self.vertex_dof = common.match_points(points, self.V.tabulate_dof_coordinates())
        # Dirichlet data: u1 = g_h, u2 = 0, lambda = 0 on the boundary.
        bcs, self.boundary, _ = common.dirichlet(self.W, [V for V, _ in subs], case)
        self._assemble(case, bcs)

    def _assemble(self, case, bcs):
        mu1, mu2 = float(case["mu1"]), float(case["mu2"])
        domain = self.domain
        f1, f2 = common.as_ufl(case["f1"], domain), common.as_ufl(case["f2"], domain)
        dx = ufl.dx(domain=domain)
        dxq = ufl.dx(domain=domain, metadata={"quadrature_degree": common.quadrature_degree(case)})
        dxv = ufl.dx(domain=domain, metadata={"quadrature_rule": "vertex", "quadrature_degree": 1})
        (u1, u2, lam), (v1, v2, m) = ufl.TrialFunctions(self.W), ufl.TestFunctions(self.W)
        zero = fem.Constant(domain, PETSc.ScalarType(0.0))  # keeps the lambda-lambda diagonal in the pattern
        # Find (u1, u2, λ) ∈ (P1)³ with u1 = g_h, u2 = 0, λ = 0 on ∂ω such that for all (v1, v2) ∈ (P1_0)²
        #   μ1 (∇u1, ∇v1) − (λ, v1)_h = (f1, v1)_q,
        #   μ2 (∇u2, ∇v2) + (λ, v2)_h = (f2, v2)_q,
        # and (u1 − u2, m)_h = 0 for m = φ_a, a in the active set A; λ_a = 0 off A (rows replaced in
        # `solve`). (·,·)_h is the vertex-rule (lumped) product, (λ, φ_a)_h = λ_a m_a as in (4.5).
        a = (mu1 * ufl.inner(ufl.grad(u1), ufl.grad(v1)) * dx - lam * v1 * dxv
             + mu2 * ufl.inner(ufl.grad(u2), ufl.grad(v2)) * dx + lam * v2 * dxv
             + (u1 - u2) * m * dxv + zero * lam * m * dxv)
        L = f1 * v1 * dxq + f2 * v2 * dxq
        a, L = fem.form(a), fem.form(L)
        self.A = fem.petsc.assemble_matrix(a, bcs=bcs)
        self.A.assemble()
        self.b = fem.petsc.assemble_vector(L)
        fem.petsc.apply_lifting(self.b, [a], bcs=[bcs])
        self.b.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
        fem.petsc.set_bc(self.b, bcs)
        u, v = ufl.TrialFunction(self.V), ufl.TestFunction(self.V)
        # c_a = μ* K_aa / m_a, μ* = μ1 μ2 / (μ1 + μ2), K = (∇u, ∇v), m_a = (1, φ_a): the weight of the
        # active-set rule (as in the Rust code; any c > 0 converges)
        K = fem.petsc.assemble_matrix(fem.form(ufl.inner(ufl.grad(u), ufl.grad(v)) * dx))
        K.assemble()
        mass = fem.petsc.assemble_vector(fem.form(v * dx)).array
        self.c = mu1 * mu2 / (mu1 + mu2) * K.getDiagonal().array / mass

    def solve(self, max_it=200):
        """u1, u2, lambda and the contact set at the input vertices, and the active-set iterations:
        A = {a : lambda_a - c_a (u1 - u2)(a) > 0}, repeated until A is unchanged."""
        interior = ~self.boundary
        active = np.zeros(len(interior), bool)
        ksp = common.lu_solver()
        x, rhs = self.b.duplicate(), self.b.duplicate()
        for it in range(1, max_it + 1):
            # Off the active set the multiplier row becomes lambda_a = 0.
            B = self.A.copy()
            self.b.copy(rhs)
            x.set(0.0)
            B.zeroRows(self.maps[2][interior & ~active].astype(np.int32), diag=1.0, x=x, b=rhs)
            ksp.setOperators(B)
            ksp.solve(rhs, x)
            B.destroy()
            u1h, u2h, lh = (x.array[mp].copy() for mp in self.maps)
            new = interior & (lh - self.c * (u1h - u2h) > 0.0)
            if np.array_equal(new, active):
                ksp.destroy()
                dof = self.vertex_dof
                return {"u1": u1h[dof], "u2": u2h[dof], "lambda": np.where(self.boundary, 0.0, lh)[dof],
                        "contact": active[dof], "iterations": it}
            active = new
        raise RuntimeError("the mixed active-set loop did not converge in %d iterations" % max_it)


def solve_file(rust_path, out_path):
    """Solves the problem of a Rust result; writes its mesh fields in the reference layout."""
    rust = common.read_result(rust_path)
    t = time.perf_counter()
    res = Mixed(rust["points"], rust["cells"], rust["case"]).solve()
    seconds = time.perf_counter() - t
    fields = {"u1": res["u1"], "u2": res["u2"], "gap": res["u1"] - res["u2"], "lambda": res["lambda"],
              "lambda2": res["lambda"], "contact": res["contact"].astype(float)}
    common.write_reference(out_path, rust, fields, {
        "program": "reference: mixed (u1, u2, lambda), primal-dual active sets, dolfinx + MUMPS",
        "iterations": res["iterations"]})
    return {"iterations": res["iterations"], "seconds": seconds}


if __name__ == "__main__":
    command_line(__doc__, solve_file, lambda s: "mixed reference: %d active-set iterations, %.3f s"
                 % (s["iterations"], s["seconds"]))
