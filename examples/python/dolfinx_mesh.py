"""Solve a contact case on a mesh made by dolfinx, and check λ_h against dolfinx's own assembly.

    make python
    .venv/bin/python examples/python/dolfinx_mesh.py
"""

import dolfinx.fem.petsc  # noqa: F401 (assemble_vector)
import numpy as np
import ufl
from dolfinx import fem, mesh
from mpi4py import MPI

import membrane_contact as mc

# A mesh of the unit square, made by dolfinx.
domain = mesh.create_unit_square(MPI.COMM_WORLD, 16, 16)
mu1, f1 = 1.0, -20.0
case = {"mu1": mu1, "mu2": 2.0, "f1": f1, "f2": 5.0, "g": 0.05}
r = mc.solve(case, domain)  # the case's [mesh] is the dolfinx mesh; its vertex order is kept
print(r.summary())

# u1h as a dolfinx Function: r.u1[i] is the value at the geometry node i of the mesh.
V = fem.FunctionSpace(domain, ("Lagrange", 1))
u1 = fem.Function(V)
nodes = domain.geometry.dofmap.array.reshape(-1, 3)
dofs = V.dofmap.list.array.reshape(-1, 3)
u1.x.array[dofs.ravel()] = r.u1[nodes.ravel()]

# λ_a = (∫μ1 ∇u1h·∇φ_a − ∫f1 φ_a) / ∫φ_a, (4.5), by dolfinx's assembly.
v = ufl.TestFunction(V)
residual = fem.petsc.assemble_vector(fem.form(mu1 * ufl.inner(ufl.grad(u1), ufl.grad(v)) * ufl.dx - f1 * v * ufl.dx))
mass = fem.petsc.assemble_vector(fem.form(v * ufl.dx))
lam = np.empty(len(r.points))
lam[nodes.ravel()] = (residual.array / mass.array)[dofs.ravel()]
boundary = fem.locate_dofs_geometrical(V, lambda x: np.isclose(x[0] * (1 - x[0]) * x[1] * (1 - x[1]), 0))
on_boundary = np.zeros(len(r.points), dtype=bool)
node_of_dof = np.empty(len(dofs.ravel()), dtype=np.int64)
node_of_dof[dofs.ravel()] = nodes.ravel()
on_boundary[node_of_dof[boundary]] = True
difference = np.abs(lam - r.lambda_)[~on_boundary].max() / np.abs(r.lambda_).max()
print(f"λ_h at {r.contact.sum()} contact vertices, max {r.lambda_.max():.6f}; "
      f"dolfinx's assembly of (4.5) agrees to {difference:.1e}")
assert difference < 1e-12
