"""Data per physical group of a Gmsh mesh, read independently of the Rust code: the .msh file the
case names is read with meshio (its `gmsh:physical` cell data and `field_data` names), and each
point where a datum is needed is located in it.

  - a table keyed by physical surfaces (f1, f2, f, psi) is, in UFL, sum_g chi_g f_g with chi_g the
    DG0 indicator of the cells of the dolfinx mesh whose midpoint lies in a triangle of surface g
    (so each cell's load is integrated with its own group's expression, as a `meshtags` /
    `Measure("dx", subdomain_data=...)` sum would; nothing is smeared across the interface); at
    points (psi at the vertices) the surface of a triangle containing the point;
  - a table keyed by physical curves (g, g2) at a boundary point: the curve of the nearest line
    element of the file (a corner shared by two curves: either, the Rust code checks that they
    agree there).

A case's tables are trees ("table", {name: tree}) of reference/expr.py; `use(result_path, case)`
makes the groups of the case's mesh file those that `to_numpy` and `to_ufl` evaluate them with.
"""
import os

import numpy as np

CURRENT = None


class Groups:
    def __init__(self, path):
        import matplotlib.tri as mtri
        import meshio

        m = meshio.read(path)
        names = {(int(v[1]), int(v[0])): k for k, v in m.field_data.items()}
        self.path = path
        self.points = m.points[:, :2]
        tri, tri_group, seg, seg_group = [], [], [], []
        for block, tags in zip(m.cells, m.cell_data["gmsh:physical"]):
            if block.type == "triangle":
                tri.append(block.data)
                tri_group += [names.get((2, int(t)), str(int(t))) for t in tags]
            elif block.type == "line":
                seg.append(block.data)
                seg_group += [names.get((1, int(t)), str(int(t))) for t in tags]
        self.triangles = np.concatenate(tri)
        self.triangle_group = np.array(tri_group, dtype=object)
        self.segments = np.concatenate(seg) if seg else np.zeros((0, 2), int)
        self.segment_group = np.array(seg_group, dtype=object)
        self.surfaces, self.curves = set(tri_group), set(seg_group)
        self.finder = mtri.Triangulation(self.points[:, 0], self.points[:, 1], self.triangles).get_trifinder()

    def surface_at(self, x, y):
        t = self.finder(np.asarray(x, float), np.asarray(y, float))
        if np.any(t < 0):
            raise RuntimeError("%s: a point lies in no triangle of the file" % self.path)
        return self.triangle_group[t]

    def curve_at(self, x, y):
        p = np.stack([np.ravel(x), np.ravel(y)], axis=1)
        a, b = self.points[self.segments[:, 0]], self.points[self.segments[:, 1]]
        d = b - a
        s = np.clip(np.einsum("nk,mk->nm", p, d) - np.einsum("mk,mk->m", a, d), 0, None) / np.einsum("mk,mk->m", d, d)
        s = np.minimum(s, 1.0)
        near = a[None] + s[..., None] * d[None]
        dist = np.linalg.norm(near - p[:, None], axis=2)
        return self.segment_group[np.argmin(dist, axis=1)].reshape(np.shape(x))

    def _which(self, entries):
        keys = set(entries)
        if keys <= self.surfaces:
            return self.surface_at
        if keys <= self.curves:
            return self.curve_at
        raise RuntimeError("%s: the table's keys %s are not all physical surfaces or all curves"
                           % (self.path, sorted(keys)))

    def numpy(self, entries, x, y, build):
        x, y = np.broadcast_arrays(np.asarray(x, float), np.asarray(y, float))
        group = self._which(entries)(x, y)
        out = np.full(x.shape, np.nan)
        for name, tree in entries.items():
            mask = group == name
            out[mask] = np.broadcast_to(build(tree), x.shape)[mask]
        return out

    def ufl(self, entries, mesh, build):
        if self._which(entries) != self.surface_at:
            raise RuntimeError("a table per curve is a boundary value, not integrated")
        from dolfinx import fem
        from dolfinx import mesh as dmesh
        import ufl

        cells = np.arange(mesh.topology.index_map(2).size_local, dtype=np.int32)
        mid = dmesh.compute_midpoints(mesh, 2, cells)
        group = self.surface_at(mid[:, 0], mid[:, 1])
        DG0 = fem.FunctionSpace(mesh, ("DG", 0))
        total = 0
        for name, tree in entries.items():
            chi = fem.Function(DG0)
            chi.x.array[DG0.dofmap.list.array] = (group == name).astype(float)
            total = total + chi * ufl.as_ufl(build(tree))
        return total


def has_tables(case):
    return any(isinstance(v, dict) for k, v in case.items() if k in ("f1", "f2", "f", "psi", "g", "g2"))


def use(result_path, case, origin):
    """Reads the groups of the case's mesh file (relative to the case file `origin`) when the case
    (a dict from TOML) has tables."""
    global CURRENT
    if not has_tables(case):
        return
    path = os.path.join(os.path.dirname(origin), case["mesh"]["path"])
    if CURRENT is None or CURRENT.path != path:
        CURRENT = Groups(path)
