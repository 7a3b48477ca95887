"""The Rust code's error norms (src/norms/), computed here.

On T_h, for u_h in P1 and an exact u with gradient G (expressions of the case file):

    ||u - u_h||_L2 = ( int (u - u_h)^2 dx )^1/2,    |u - u_h|_H1 = ( int |G - grad u_h|^2 dx )^1/2;

on the dual submesh S_h, for lambda_h constant on each dual cell D_a (zero near the boundary):

    ||lambda - lambda_h||_L2,   ||lambda - lambda_h||_H-1 ~ |z|_H1 = (lambda - lambda_h, z)^1/2,
    z in P1_0(S_h):  (grad z, grad v) = (lambda - lambda_h, v)  for all v in P1_0(S_h),

`exact_errors` integrates the L2 and H1 norms of an exact solution by this reference's own adaptive
rule (reference/cubature.py), with an estimate of its error; the H-1 norm, and every norm of
`all_errors`, by basix's degree-10 rule (dx with quadrature_degree 10). `all_errors` also gives the
norms of the difference of two discrete fields (exact = 0), integrated exactly, which bound the
difference of two codes' error values by the triangle inequality.
"""
import numpy as np
import ufl
from dolfinx import fem
from dolfinx import mesh as dmesh
from petsc4py import PETSc

import dolfinx.fem.petsc  # noqa: F401  (registers fem.petsc)

from . import common, cubature

ERROR_DEGREE = 10  # the H-1 norm's rule, the Rust code's too (ERROR_QUADRATURE in src/norms/mod.rs)


def scalar(form):
    return float(fem.assemble_scalar(fem.form(form)))


def p1_errors(V, values, exact, grad):
    """(||u - u_h||_L2, |u - u_h|_H1 or None) for u_h in V with dof values `values`; exact and
    grad are case expressions (grad a pair, or None)."""
    domain = V.mesh
    dxe = ufl.dx(domain=domain, metadata={"quadrature_degree": ERROR_DEGREE})
    uh = fem.Function(V)
    uh.x.array[:] = values
    u = common.as_ufl(exact, domain)
    # ‖u − u_h‖²_L² = ∫ (u − u_h)² dx
    l2 = np.sqrt(max(scalar((u - uh) ** 2 * dxe), 0.0))
    if grad is None:
        return l2, None
    G = ufl.as_vector([common.as_ufl(c, domain) for c in grad])
    # |u − u_h|²_H¹ = ∫ |G − ∇u_h|² dx
    return l2, np.sqrt(max(scalar(ufl.inner(G - ufl.grad(uh), G - ufl.grad(uh)) * dxe), 0.0))


class DualSubmesh:
    """S_h as a dolfinx mesh, with lambda_h (one value per dual cell, in the Rust cell order) as DG0."""

    def __init__(self, dual_points, dual_cells):
        self.mesh = common.make_mesh(dual_points, dual_cells)
        self.V0 = fem.FunctionSpace(self.mesh, ("DG", 0))
        self.V1 = fem.FunctionSpace(self.mesh, ("Lagrange", 1))
        x = self.mesh.geometry.x
        cells = self.mesh.geometry.dofmap.array.reshape(-1, 3)
        # dolfinx cell i is the Rust cell perm[i]
        self.perm = common.match_points(x[cells].mean(axis=1), dual_points[dual_cells].mean(axis=1))
        self.mesh.topology.create_connectivity(1, 2)
        dofs = fem.locate_dofs_topological(self.V1, 1, dmesh.exterior_facet_indices(self.mesh.topology))
        self.bc = fem.dirichletbc(PETSc.ScalarType(0.0), dofs, self.V1)
        z, v = ufl.TrialFunction(self.V1), ufl.TestFunction(self.V1)
        # the H⁻¹ problem's operator: (∇z, ∇v)
        self.a = ufl.inner(ufl.grad(z), ufl.grad(v)) * ufl.dx(domain=self.mesh)

    def errors(self, cell_values, exact):
        """(||lambda - lambda_h||_L2, ||lambda - lambda_h||_H-1) on S_h."""
        lh = fem.Function(self.V0)
        lh.x.array[:] = cell_values[self.perm]
        lam = common.as_ufl(exact, self.mesh)
        dxs = ufl.dx(domain=self.mesh, metadata={"quadrature_degree": ERROR_DEGREE})
        l2 = np.sqrt(max(scalar((lam - lh) ** 2 * dxs), 0.0))
        v = ufl.TestFunction(self.V1)
        # z ∈ P1_0(S_h): (∇z, ∇v) = (λ − λ_h, v) for all v ∈ P1_0(S_h)
        problem = fem.petsc.LinearProblem(
            self.a, (lam - lh) * v * dxs, bcs=[self.bc],
            petsc_options={"ksp_type": "preonly", "pc_type": "lu", "pc_factor_mat_solver_type": "mumps"})
        zh = problem.solve()
        # ‖λ − λ_h‖_H⁻¹ ≈ |z|_H¹ = (λ − λ_h, z)^½
        return l2, np.sqrt(max(scalar((lam - lh) * zh * dxs), 0.0))


def all_errors(V, displacements, lam_cells, dual, exact):
    """Every norm of the Rust code's `Errors` (the keys of the problem's `error_keys`) for the
    displacements {name: (dof values on V, tension)} (u1, u2 or u), lambda_h on the dual cells and
    an exact solution (the case's [exact]); the energy norm (sum_i mu_i |u_i - u_ih|_H1^2)^1/2."""
    out = {}
    for name, (values, _) in displacements.items():
        out["l2_" + name], h1 = p1_errors(V, values, exact[name], exact.get("grad_" + name))
        if h1 is not None:
            out["h1_" + name] = h1
    if all("h1_" + name in out for name in displacements):
        out["energy"] = np.sqrt(sum(mu * out["h1_" + name] ** 2 for name, (_, mu) in displacements.items()))
    out["l2_lambda"], out["hminus1_lambda"] = dual.errors(lam_cells, exact["lambda"])
    return out


def exact_errors(points, cells, displacements, dual_points, dual_cells, lam_cells, exact):
    """The norms of `all_errors` against an exact solution, but L2 and H1 by the adaptive cubature
    (reference/cubature.py) on T_h (`points`, `cells`) and S_h: ({key: value}, {key: estimated
    error of the value}); the H-1 norm is all_errors' (the Rust code's rule, degree 10).
    displacements = {name: (values at the vertices, tension)}."""
    out, quad = {}, {}

    def norm(key, integral, error):
        out[key] = np.sqrt(max(integral, 0.0))
        quad[key] = error / (2.0 * out[key]) if out[key] > 0 else 0.0

    tri = points[cells][:, :, :2]
    grads = _barycentric_gradients(tri)
    for name, (values, _) in displacements.items():
        u, grad = exact[name], exact.get("grad_" + name)

        def density(c, x, bary):
            flat = x.reshape(-1, 2)
            # (u - u_h)^2 and |G - grad u_h|^2 at the points, u_h = sum_j bary_j u_j
            uh = np.einsum("pqk,pk->pq", bary, values[cells[c]])
            d = [(common.at_points(u, flat).reshape(uh.shape) - uh) ** 2]
            if grad is not None:
                gh = np.einsum("pkd,pk->pd", grads[c], values[cells[c]])
                d.append(sum((common.at_points(g, flat).reshape(uh.shape) - gh[:, None, k]) ** 2
                             for k, g in enumerate(grad)))
            return np.stack(d, axis=2)

        value, error = cubature.integrate(tri, density)
        norm("l2_" + name, value[0], error[0])
        if grad is not None:
            norm("h1_" + name, value[1], error[1])
    if all("h1_" + name in out for name in displacements):
        terms = [(mu, out["h1_" + name], quad["h1_" + name]) for name, (_, mu) in displacements.items()]
        out["energy"] = np.sqrt(sum(mu * e ** 2 for mu, e, _ in terms))
        quad["energy"] = sum(mu * 2 * e * q for mu, e, q in terms) / (2 * out["energy"]) if out["energy"] else 0.0
    lam = exact["lambda"]

    def lam_density(c, x, bary):
        # (lambda - lambda_h)^2, lambda_h constant on each cell of S_h
        return ((common.at_points(lam, x.reshape(-1, 2)).reshape(x.shape[:2]) - lam_cells[c][:, None]) ** 2)[..., None]

    value, error = cubature.integrate(dual_points[dual_cells][:, :, :2], lam_density)
    norm("l2_lambda", value[0], error[0])
    return out, quad


def _barycentric_gradients(tri):
    """The gradients of the barycentric coordinates on each triangle (n x 3 corners x 2)."""
    e1, e2 = tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]
    det = e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0]
    g1 = np.stack([e2[:, 1], -e2[:, 0]], axis=1) / det[:, None]
    g2 = np.stack([-e1[:, 1], e1[:, 0]], axis=1) / det[:, None]
    return np.stack([-g1 - g2, g1, g2], axis=1)


def difference_norms(V, differences, dlam_cells, dual):
    """The same norms of the difference of two discrete solutions (|e_A - e_B| <= these);
    differences = {name: (dof values on V, tension)}."""
    zero = {"lambda": 0, **{n: 0 for n in differences}, **{"grad_" + n: [0, 0] for n in differences}}
    return all_errors(V, differences, dlam_cells, dual, zero)
