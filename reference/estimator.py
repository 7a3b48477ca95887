"""Guaranteed a posteriori error estimators for the discrete solution of (3.4)/(4.5) AS COMPUTED by
the Rust code (prototype of issue 13; the derivation, with every constant, is docs/a-posteriori.md).

Usage (from the repository root, Debian's python3):
    /usr/bin/python3 -m reference.estimator DIR [DIR ...]        one line per result
    /usr/bin/python3 -m reference.estimator --table DIR [DIR ...] the markdown table of the report
    /usr/bin/python3 -m reference.estimator --per-triangle OUT.npz DIR   also saves the per-triangle terms
    /usr/bin/python3 -m reference.estimator --compare DIR [DIR ...]  the Rust estimator, recomputed
DIR is a result of `membrane-contact solve CASE --n N --flux [--hminus1] -o DIR` (with --estimate
for --compare; --flux is needed only by the fluxes "dual" and "dualmin").

--compare recomputes everything `solve --estimate` writes (the attributes estimator,
estimator_membrane_i, estimator_means_i, estimator_boundary, estimator_contact,
estimator_hminus1_lambda, effectivity, and the cell fields estimator, estimator_flux_i,
estimator_oscillation_i, estimator_boundary, estimator_contact) from the written u1, u2, gap and
lambda, the mesh and the case's expressions, with the choices of the Rust code (`rust_estimate`:
the patch flux with the means lifted, section 4(c'), the case's own rule on the cells of S_h),
prints the differences and exits 1 when one exceeds its tolerance (COMPARED) or when the bound
fails against the energy error computed here from the exact solution.

Bound (docs/a-posteriori.md, Theorem (E)):
    |||u - u_h||| <= eta := (eta_FR^2 + eta_D^2 + 2 eta_C)^(1/2),
    eta_FR^2 = sum_i ( (sum_kappa (eta_F + eta_osc)_kappa^2)^(1/2) + eta_Q,i )^2,
with, per cell kappa of S_h and membrane i (tau_i the equilibrated flux of the variant):
    eta_F   = mu_i^(-1/2) || mu_i grad u_ih + tau_i ||_kappa                         (flux)
    eta_osc = (h_kappa / pi) mu_i^(-1/2) || f_i - Pi_kappa f_i ||_kappa              (oscillation)
    eta_Q,i = C_F mu_i^(-1/2) || c_i ||, c_i = sum_a c_a chi_{D_a} the dual-cell means of the
              residual (Friedrichs, section 4(c)); 0 when they are lifted into tau_i (4(c'))
    eta_C   = (lambda_h, w_h + psi)                                                  (contact)
              (rust_estimate, as the Rust code: lambda_h on the contact set, the rest of
              lambda_h, round-off, in eta_Q,i and eta_w by Friedrichs; docs, section 3)
    eta_D   = mu_1^(1/2) || grad psi ||,  psi the lifting of g - g_h                 (boundary data)
and the action (section 8), mu_bar = mu1 mu2/(mu1 + mu2):
    ||lambda - lambda_h||_H^-1 <= mu_bar^(1/2) eta_w + eta_lambda,
    eta_w = (eta_lambda^2/mu_bar + mu_bar ||grad psi||^2 + 2 eta_C)^(1/2).

Three fluxes (docs, section 7):
    "dual"     t_ih of (4.13) as written by --flux; the piecewise-constant part of its residual is
               lifted separately by sigma on each D_a (min ||sigma||), eta_F -> eta_F + ||sigma||;
               the means by Friedrichs.
    "dualmin"  t_ih + sigma with sigma minimising ||mu grad u_h + t + sigma|| on each D_a (the
               local minimisation of the paper's [14] on the dual cells), means lifted.
    "patch"    the Braess-Schoeberl / Ern-Vohralik equilibration on the vertex patches, RT0 on S_h,
               means (quadrature errors of the loads) lifted. Recommended.
"""
import math
import os
import sys

import basix
import numpy as np

from . import common, cubature, expr

DEGREE = 10  # quadrature on the cells of S_h (the Rust error rule is degree 10 on T_h)
GAUSS_1D = 12  # Gauss-Legendre points per piece for the boundary lifting
CROSS_POINTS = 16  # Gauss-Legendre points per direction of the collapsed rules of a corner triangle
VARIANTS = ("dual", "dualmin", "patch")


# ---------------------------------------------------------------------------------------------
# geometry
# ---------------------------------------------------------------------------------------------

def orient(p):
    """Twice the signed area of triangles p (N x 3 x 2)."""
    return (p[:, 1, 0] - p[:, 0, 0]) * (p[:, 2, 1] - p[:, 0, 1]) - (p[:, 1, 1] - p[:, 0, 1]) * (p[:, 2, 0] - p[:, 0, 0])


def p1_gradients(p):
    """Gradients of the barycentric coordinates of triangles p (N x 3 x 2): N x 3 x 2."""
    two = orient(p)
    g = np.empty_like(p)
    for k in range(3):
        b, c = p[:, (k + 1) % 3], p[:, (k + 2) % 3]
        g[:, k, 0] = (b[:, 1] - c[:, 1]) / two
        g[:, k, 1] = (c[:, 0] - b[:, 0]) / two
    return g


def barycentric(p, x):
    """Barycentric coordinates of points x (N x m x 2) in triangles p (N x 3 x 2): N x m x 3."""
    g = p1_gradients(p)
    out = np.empty(x.shape[:2] + (3,))
    for k in range(3):
        c = p[:, (k + 1) % 3]
        out[:, :, k] = np.einsum("nmd,nd->nm", x - c[:, None, :], g[:, k])
    return out


def dual_submesh(P, T):
    """S_h of Section 4.2, built here from T_h alone, in the layout the Rust code writes (/dual):
    points = the vertices of T_h, the midpoints of its edges, the barycentres; six
    counter-clockwise cells per triangle t of T_h, cells 6t + 2k = [v_k, m(v_k, v_k+1), g] and
    6t + 2k + 1 = [v_k, g, m(v_k+2, v_k)], both owned by v_k. Returns (points, cells, owner,
    th_edge): th_edge[s, e] = the edge (a, b) of T_h that edge e of cell s (from corner e to e + 1)
    halves, or (-1, -1) for an edge inside a triangle of T_h."""
    nv, nt = len(P), len(T)
    e = np.sort(np.concatenate([T[:, [0, 1]], T[:, [1, 2]], T[:, [2, 0]]]), axis=1)
    edges, inv = np.unique(e, axis=0, return_inverse=True)
    mid_of = inv.reshape(3, nt).T  # mid_of[t, k]: the midpoint of (v_k, v_k+1)
    pk = P[T]
    Q = np.concatenate([P, 0.5 * (P[edges[:, 0]] + P[edges[:, 1]]), (pk[:, 0] + pk[:, 1] + pk[:, 2]) / 3.0])
    S = np.empty((nt, 6, 3), np.int64)
    th = -np.ones((nt, 6, 3, 2), np.int64)
    centre = nv + len(edges) + np.arange(nt)
    for k in range(3):
        a, b, c = T[:, k], T[:, (k + 1) % 3], T[:, (k + 2) % 3]
        S[:, 2 * k] = np.stack([a, nv + mid_of[:, k], centre], axis=1)
        S[:, 2 * k + 1] = np.stack([a, centre, nv + mid_of[:, (k + 2) % 3]], axis=1)
        th[:, 2 * k, 0] = np.stack([a, b], axis=1)
        th[:, 2 * k + 1, 2] = np.stack([c, a], axis=1)
    owner = np.repeat(T, 2, axis=1)
    return Q, S.reshape(-1, 3), owner.ravel(), th.reshape(-1, 3, 2)


class Geometry:
    """T_h, S_h, the edges of S_h and everything the estimators share. S_h is built from T_h
    (dual_submesh); a result's /dual must be the same submesh in the same order (checked:
    `dual_mismatch`, the largest distance between corresponding corners, relative to the size
    of the domain). `degree`: the quadrature rule used on the cells of S_h (basix's default)."""

    def __init__(self, r, degree=DEGREE):
        self.P = r["points"][:, :2]
        self.T = r["cells"]
        self.Q, self.S, self.owner, th_edge = dual_submesh(self.P, self.T)
        nt, ns, nv = len(self.T), len(self.S), len(self.P)
        size = float(np.ptp(self.P, axis=0).max())
        if "dual_cells" in r:
            same = r["dual_cells"].shape == self.S.shape and np.array_equal(r["dual_owner"], self.owner)
            self.dual_mismatch = (float(np.abs(r["dual_points"][:, :2][r["dual_cells"]] - self.Q[self.S]).max()) / size
                                  if same else math.inf)
        else:
            self.dual_mismatch = 0.0
        self.tri = np.arange(ns) // 6  # the triangle K of T_h containing each cell of S_h
        self.pk = self.P[self.T]  # nt x 3 x 2
        self.area_K = 0.5 * orient(self.pk)
        self.grad_K = p1_gradients(self.pk)  # nt x 3 x 2
        self.ps = self.Q[self.S]  # ns x 3 x 2
        self.area = 0.5 * orient(self.ps)
        assert (self.area > 0).all() and (self.area_K > 0).all(), "cells must be counter-clockwise"
        self.diam = np.max([np.linalg.norm(self.ps[:, i] - self.ps[:, (i + 1) % 3], axis=1) for i in range(3)], axis=0)
        # edges of T_h, boundary vertices and edges
        e = np.sort(np.concatenate([self.T[:, [0, 1]], self.T[:, [1, 2]], self.T[:, [2, 0]]]), axis=1)
        ue, cnt = np.unique(e, axis=0, return_counts=True)
        self.bedges = ue[cnt == 1]
        self.on_boundary = np.zeros(nv, bool)
        self.on_boundary[self.bedges.ravel()] = True
        # edges of S_h: edge k of a cell runs from its vertex k to k + 1; the global unknown x_e is
        # the flux through e along the right normal of (min -> max); a cell's outward flux is
        # sign * x_e (cells are counter-clockwise: the right normal of each edge points outward)
        ce = np.stack([self.S[:, [0, 1]], self.S[:, [1, 2]], self.S[:, [2, 0]]], axis=1)  # ns x 3 x 2
        key = np.sort(ce, axis=2).reshape(-1, 2)
        uniq, inv, counts = np.unique(key, axis=0, return_inverse=True, return_counts=True)
        self.cell_edge = inv.reshape(ns, 3)
        self.cell_sign = np.where(ce[:, :, 0] < ce[:, :, 1], 1.0, -1.0)
        self.n_edges = len(uniq)
        self.edge_on_boundary = counts == 1
        # the edge of T_h that each edge of S_h halves ((-1, -1) inside the triangles)
        self.edge_th = -np.ones((self.n_edges, 2), np.int64)
        self.edge_th[self.cell_edge.ravel()] = th_edge.reshape(-1, 2)
        # midpoints of the edges of each cell (edge k), and the RT0 basis there
        self.mid = 0.5 * (self.ps + np.roll(self.ps, -1, axis=1))  # ns x 3 x 2, mid[k] of edge k
        # psi_k(x) = (x - P_{k+2}) / (2|kappa|): unit outward flux through edge k
        opp = np.roll(self.ps, -2, axis=1)  # opp[k] = P_{k+2}
        self.psi_mid = (self.mid[:, None, :, :] - opp[:, :, None, :]) / (2 * self.area[:, None, None, None])  # ns x k x m x 2
        # cell mass matrices (midpoint rule: exact for quadratics)
        self.mass = np.einsum("nkmd,njmd->nkj", self.psi_mid, self.psi_mid) * (self.area / 3)[:, None, None]
        # quadrature of degree `degree` on the cells of S_h
        self.degree = degree
        xi, w = basix.make_quadrature(basix.CellType.triangle, degree)
        a, b, c = self.ps[:, 0], self.ps[:, 1], self.ps[:, 2]
        self.xq = a[:, None] + xi[None, :, 0, None] * (b - a)[:, None] + xi[None, :, 1, None] * (c - a)[:, None]
        self.wq = 2 * self.area[:, None] * w[None, :]
        self.lam_q = barycentric(self.pk[self.tri], self.xq)  # barycentric coordinates in K, ns x nq x 3
        self.lam_mid = barycentric(self.pk[self.tri], self.mid)  # ns x 3 x 3
        # the local index of the owner a of each cell in its triangle K
        self.owner_local = np.argmax(self.T[self.tri] == self.owner[:, None], axis=1)
        self.dual_area = np.bincount(self.owner, self.area, minlength=nv)
        self.interior = ~self.on_boundary
        # vertex -> triangles (for the vertex patches)
        order = np.argsort(self.T.ravel(), kind="stable")
        self.vt_ptr = np.concatenate([[0], np.cumsum(np.bincount(self.T.ravel(), minlength=nv))])
        self.vt_tri = order // 3
        self.vt_loc = order % 3
        order = np.argsort(self.owner, kind="stable")
        self.dual_ptr = np.concatenate([[0], np.cumsum(np.bincount(self.owner, minlength=nv))])
        self.dual_cells_of = order
        lo, hi = self.P.min(axis=0), self.P.max(axis=0)
        # Friedrichs: ||v|| <= C_F ||grad v|| on H^1_0 of the bounding box, hence of omega
        self.C_F = 1.0 / (math.pi * math.sqrt(1.0 / (hi[0] - lo[0]) ** 2 + 1.0 / (hi[1] - lo[1]) ** 2))

    def rt0_at(self, F, x, cells=slice(None)):
        """The RT0 field with outward cell fluxes F (ns x 3) at points x (ns x m x 2)."""
        opp = np.roll(self.ps[cells], -2, axis=1)
        return np.einsum("nk,nkmd->nmd", F, (x[:, None, :, :] - opp[:, :, None, :])) / (2 * self.area[cells][:, None, None])

    def cell_fluxes(self, x_edge):
        return self.cell_sign * x_edge[self.cell_edge]

    def l2_affine(self, v_mid):
        """||v||_kappa^2 for v affine on each cell, given at the edge midpoints (ns x 3 x 2)."""
        return (self.area / 3) * np.sum(v_mid ** 2, axis=(1, 2))


# ---------------------------------------------------------------------------------------------
# local mixed problems on patches of S_h
# ---------------------------------------------------------------------------------------------

def solve_patch(geo, cells, target_mid, div, vertex=None):
    """min ||sigma - target|| over sigma in RT0 on `cells` (of S_h) with div sigma = div (per cell),
    sigma.n = 0 on the boundary of the patch except on d(omega) -- only on the halves of the
    boundary edges of T_h that contain `vertex` if it is given. Returns (edge ids, edge fluxes)."""
    ce, cs = geo.cell_edge[cells], geo.cell_sign[cells]
    edges, inv = np.unique(ce.ravel(), return_inverse=True)
    inv = inv.reshape(ce.shape)
    cnt = np.bincount(inv.ravel(), minlength=len(edges))
    open_boundary = geo.edge_on_boundary[edges]
    if vertex is not None:
        open_boundary &= (geo.edge_th[edges] == vertex).any(axis=1)
    free = (cnt == 2) | open_boundary
    closed = not open_boundary.any()
    unk = -np.ones(len(edges), np.int64)
    unk[free] = np.arange(free.sum())
    nu, nc = int(free.sum()), len(cells)
    u = unk[inv]  # nc x 3
    ok = u >= 0
    M = geo.mass[cells] * cs[:, :, None] * cs[:, None, :]
    b = np.einsum("nkmd,nmd->nk", geo.psi_mid[cells], target_mid) * (geo.area[cells] / 3)[:, None] * cs
    n = nu + nc + (1 if closed else 0)
    K = np.zeros((n, n))
    rhs = np.zeros(n)
    for j in range(3):
        for k in range(3):
            m = ok[:, j] & ok[:, k]
            np.add.at(K, (u[m, j], u[m, k]), M[m, j, k])
        m = ok[:, j]
        np.add.at(rhs, u[m, j], b[m, j])
        rows = nu + np.arange(nc)[m]
        np.add.at(K, (rows, u[m, j]), cs[m, j])
        np.add.at(K, (u[m, j], rows), cs[m, j])
    rhs[nu:nu + nc] = div * geo.area[cells]
    if closed:  # the multiplier is defined up to a constant: fix its sum
        K[nu:nu + nc, -1] = 1.0
        K[-1, nu:nu + nc] = 1.0
    x = np.linalg.solve(K, rhs)[:nu]
    return edges[free], x


def equilibrate(geo, G_tri, int_fphi, own_term, touching=False):
    """The patch flux of section 7(c): sum over the vertices a of the minimisers of
    ||Pi_RT(phi_a G) + tau|| on the cells of S_h in supp phi_a, with tau.n = 0 on the patch boundary
    inside omega and div tau = Pi(f phi_a) - G.grad phi_a + own_term[a] on the cells of D_a.
    G_tri: the discrete flux mu grad u_h per triangle; int_fphi: int_kappa f phi_j (ns x 3).
    touching: the normal flux is free only on the halves of the boundary edges of T_h that contain
    a (the Rust code's choice; every other part of the patch boundary is closed, so the patch of an
    interior vertex is closed even where an edge opposite a lies on d(omega)); otherwise on every
    edge of the patch on d(omega). Returns the fluxes through the edges of S_h."""
    nv = len(geo.P)
    x = np.zeros(geo.n_edges)
    G = G_tri[geo.tri]
    g_phi = np.einsum("nd,nkd->nk", G_tri, geo.grad_K)  # G . grad phi_j per triangle
    e_vec = np.roll(geo.ps, -1, axis=1) - geo.ps
    nu = np.stack([e_vec[..., 1], -e_vec[..., 0]], axis=-1)  # outward normals times lengths
    for a in range(nv):
        tris = geo.vt_tri[geo.vt_ptr[a]:geo.vt_ptr[a + 1]]
        locs = geo.vt_loc[geo.vt_ptr[a]:geo.vt_ptr[a + 1]]
        cells = (6 * tris[:, None] + np.arange(6)[None]).ravel()
        j = np.repeat(locs, 6)
        phi_mid = geo.lam_mid[cells, :, j]  # nc x 3 (at the 3 edge midpoints)
        # target: the RT0 interpolant of -phi_a G (fluxes phi_a(m_k) G.nu_k)
        Fi = -phi_mid * np.einsum("nd,nkd->nk", G[cells], nu[cells])
        target = geo.rt0_at(Fi, geo.mid[cells], cells)
        own = geo.owner[cells] == a
        d = int_fphi[cells, j] / geo.area[cells] - g_phi[geo.tri[cells], j] + own * own_term[a]
        edges, xe = solve_patch(geo, cells, target, d, a if touching else None)
        x[edges] += xe
    return x


def stiffness(geo):
    """The P1 stiffness matrix K of T_h (sparse, every vertex)."""
    import scipy.sparse as sps

    nv = len(geo.P)
    k = np.einsum("nid,njd->nij", geo.grad_K, geo.grad_K) * geo.area_K[:, None, None]
    return sps.csr_matrix((k.ravel(), (np.repeat(geo.T, 3, axis=1).ravel(), np.tile(geo.T, (1, 3)).ravel())), shape=(nv, nv))


def poisson_lift(geo, c):
    """z_h in X_0h with (grad z_h, grad phi_b) = (c, phi_b) at every interior vertex b, c constant
    on the cells of S_h, the right-hand side integrated exactly. Returns (K, z_h, int_cphi, b):
    int_cphi = int_kappa c phi_j (ns x 3), b = (c, phi_b) at every vertex."""
    import scipy.sparse.linalg as spl

    nv = len(geo.P)
    K = stiffness(geo)
    cen = barycentric(geo.pk[geo.tri], geo.ps.mean(axis=1)[:, None, :])[:, 0]  # phi_j at the cell centroids
    int_cphi = (c * geo.area)[:, None] * cen  # int_kappa c phi_j, exact
    b = np.zeros(nv)
    np.add.at(b, geo.T[geo.tri].ravel(), int_cphi.ravel())
    inner = np.flatnonzero(geo.interior)
    z = np.zeros(nv)
    z[inner] = spl.spsolve(K[inner][:, inner].tocsc(), b[inner])
    return K, z, int_cphi, b


def lift(geo, c):
    """An RT0 field tau_c on S_h with div tau_c = c exactly (c constant on the cells of S_h): z_h of
    `poisson_lift`, then the patch equilibration of -Delta z = c, which is compatible with no defect
    (c is integrated exactly): (c, v) = -(tau_c, grad v) for v in H^1_0, section 4(c')."""
    _, z, int_cphi, _ = poisson_lift(geo, c)
    grad_z = np.einsum("nkd,nk->nd", geo.grad_K, z[geo.T])
    return equilibrate(geo, grad_z, int_cphi, np.zeros(len(geo.P)))


# ---------------------------------------------------------------------------------------------
# the estimator
# ---------------------------------------------------------------------------------------------

def case_function(source):
    tree = expr.parse(source)
    return lambda x, y: np.broadcast_to(expr.to_numpy(tree, x, y), np.shape(x))


def case_gradient(source):
    """grad g as a NumPy function: the exact derivative of the case expression (forward-mode
    differentiation of its tree, expr.to_numpy_gradient; the case's [let] names substituted)."""
    tree = expr.parse(source)

    def grad(x, y):
        _, gx, gy = expr.to_numpy_gradient(tree, x, y)
        return np.stack([gx, gy], axis=-1)

    return grad


def edge_gradient(g, dg, P, Q, ends, gl, lq, lc, k):
    """grad psi_e = s^(k-1) [k delta(tau) grad s + delta'(tau) v] at barycentric coordinates l
    (rows: points; columns: the local vertices of K), e = [P, Q] (local q = lq, third vertex lc)."""
    gp, gq = ends
    ds = -gl[lc]

    def gradient(l):
        s = 1.0 - l[:, lc]
        tau = l[:, lq] / s
        y = P[None] + tau[:, None] * (Q - P)[None]
        delta = g(y[:, 0], y[:, 1]) - ((1 - tau) * gp + tau * gq)
        ddelta = dg(y[:, 0], y[:, 1]) @ (Q - P) - (gq - gp)
        v = gl[lq][None] - tau[:, None] * ds[None]
        return (s ** (k - 1))[:, None] * (k * delta[:, None] * ds[None] + ddelta[:, None] * v)

    return gradient


def cross_term(area, c1, c2, g1, g2):
    """(grad psi_e1, grad psi_e2)_K on a corner triangle K (c1, c2: the local vertices opposite
    e1, e2): K cut from the common vertex to the midpoint m of c1, c2, each half by a Gauss rule
    collapsed at the vertex where its lifting's gradient depends on the direction (docs, section 5)."""
    t, w = np.polynomial.legendre.leggauss(CROSS_POINTS)
    r, wr = (t + 1) / 2, w / 2
    R, TH = np.meshgrid(r, r, indexing="ij")
    W = np.outer(wr, wr).ravel()
    R, TH = R.ravel(), TH.ravel()
    eye = np.eye(3)
    q = 3 - c1 - c2
    m = 0.5 * (eye[c1] + eye[c2])
    total = 0.0
    for v, a, b in [(eye[c1], eye[q], m), (eye[c2], m, eye[q])]:
        l = v[None] + R[:, None] * ((1 - TH)[:, None] * a[None] + TH[:, None] * b[None] - v[None])
        dot = np.sum(g1(l) * g2(l), axis=1)
        total += np.sum(2 * (area / 2) * R * W * dot)  # each half has area |K|/2
    return float(total)


def boundary_lifting(geo, case, lam, gap):
    """psi, the lifting of g - g_h into the triangles of the boundary edges (docs, section 5):
    per triangle ||grad psi||_K^2 and int_K lambda_h psi. lam: lambda_a (0 at the boundary
    vertices); gap: w_h at the vertices (w_h = g_h at the boundary vertices)."""
    g, dg = case_function(case["g"]), case_gradient(case["g"])
    t, w = np.polynomial.legendre.leggauss(GAUSS_1D)
    tau = np.concatenate([(t + 1) / 4, (t + 3) / 4])  # [0, 1/2] and [1/2, 1]: s* has a kink at 1/2
    wt = np.concatenate([w, w]) / 4
    nt = len(geo.T)
    grad2 = np.zeros(nt)
    lampsi = np.zeros(nt)
    # the triangle and third vertex of each boundary edge
    e = np.concatenate([geo.T[:, [0, 1]], geo.T[:, [1, 2]], geo.T[:, [2, 0]]])
    owner = np.concatenate([np.arange(nt)] * 3)
    key = {tuple(sorted(p)): i for i, p in enumerate(map(tuple, np.sort(e, axis=1)))}
    per_tri = {}
    for (p, q) in geo.bedges:
        i = key[(p, q)]
        K = owner[i]
        per_tri.setdefault(K, []).append((p, q))
    for K, edges in per_tri.items():
        verts = geo.T[K]
        gl = geo.grad_K[K]
        parts = []
        for (p, q) in edges:
            c = [v for v in verts if v != p and v != q][0]
            lp, lq, lc = [int(np.flatnonzero(verts == v)[0]) for v in (p, q, c)]
            P, Qp = geo.P[p], geo.P[q]
            y = P[None] + tau[:, None] * (Qp - P)[None]
            gp, gq = float(g(P[0:1], P[1:2])[0]), float(g(Qp[0:1], Qp[1:2])[0])
            delta = g(y[:, 0], y[:, 1]) - ((1 - tau) * gp + tau * gq)
            ddelta = dg(y[:, 0], y[:, 1]) @ (Qp - P) - (gq - gp)
            ds = -gl[lc]
            v = gl[lq][None] - tau[:, None] * ds[None]
            # psi_e = s^k delta(tau): ||grad psi_e||^2 = |K| (k A + 2 C + B / k), least at k = (B/A)^(1/2)
            A = np.sum(wt * delta ** 2) * float(ds @ ds)
            B = np.sum(wt * ddelta ** 2 * np.sum(v ** 2, axis=1))
            C = np.sum(wt * delta * ddelta * (v @ ds))
            k = max(1.0, math.sqrt(B / A)) if A > 0 else 1.0
            n2 = max(0.0, geo.area_K[K] * (k * A + 2 * C + B / k))
            sstar = 1.0 / (1.0 + np.maximum(tau, 1 - tau))
            lampsi[K] += lam[c] * 2 * geo.area_K[K] * np.sum(wt * delta * sstar ** (k + 2) / (k + 2))
            gradient = edge_gradient(g, dg, P, Qp, (gp, gq), gl, lq, lc, k)
            parts.append((math.sqrt(n2), min(0.0, float(np.min(delta))), lc, gradient))
        if len(parts) == 1:
            grad2[K] = parts[0][0] ** 2  # w_h + psi = (1 - s) w_c + s g >= 0: psi is the lifting
        else:
            # two boundary edges: psi0 = sum of the edge liftings; psi = max(psi0, -w_h)
            wmin = float(gap[verts].min())
            need = sum(max(0.0, -d) for _, d, _, _ in parts)  # d = min(0, min of delta at the Gauss points)
            (n1, _, c1, g1), (n2, _, c2, g2) = parts
            cross = cross_term(geo.area_K[K], c1, c2, g1, g2)
            n = min((n1 + n2) ** 2, max(0.0, n1 ** 2 + n2 ** 2 + 2 * cross))
            if wmin < need:  # max(psi0, -w_h) may differ from psi0: |grad psi|^2 <= |grad psi0|^2 + |grad w_h|^2
                n += geo.area_K[K] * float(np.sum((gap[verts] @ gl) ** 2))
            grad2[K] = n
    return grad2, lampsi


def estimate(path, variants=VARIANTS, lift_means=("dualmin", "patch")):
    r = common.read_result(path)
    geo = Geometry(r)
    assert geo.dual_mismatch <= DUAL_TOL, "the result's /dual is not S_h in the expected order"
    case = r["case"]
    mu = [float(case["mu1"]), float(case["mu2"])]
    sign = [1.0, -1.0]
    u = [r["u1"], r["u2"]]
    gap = r["gap"]
    lam = r["lambda"].copy()
    lam[geo.on_boundary] = 0.0
    lam_cell = r["dual_lambda"]
    nt, ns, nv = len(geo.T), len(geo.S), len(geo.P)
    out = {"path": path, "n_triangles": nt, "C_F": geo.C_F}
    origin = str(r["attrs"].get("case_origin", path))
    out["case_name"] = origin.rsplit("/", 1)[-1].replace(".toml", "")
    m = case["mesh"]
    per_square = 4 if m.get("diagonal", "right") == "crossed" else 2
    out["n"] = int(round(math.sqrt(nt / per_square / (0.75 if m["kind"] == "lshape" else 1.0))))
    attrs = r["attrs"]
    out["error_energy"] = float(attrs.get("error_energy", np.nan))
    out["error_hminus1"] = float(attrs.get("error_hminus1_lambda", np.nan))

    # contact term (lambda_h, w_h + psi) and the boundary lifting; this study of the fluxes takes
    # lambda_h whole (on the shipped cases its part off the contact set is round-off far below
    # eta_C); the bound as the Rust code computes it, with that part by Friedrichs, is
    # rust_estimate's
    w_cent = np.einsum("nk,nk->n", barycentric(geo.pk[geo.tri], geo.ps.mean(axis=1)[:, None, :])[:, 0], gap[geo.T[geo.tri]])
    contact_cell = lam_cell * w_cent * geo.area
    grad_psi2, lampsi = boundary_lifting(geo, case, lam, gap)
    contact_K = np.bincount(geo.tri, contact_cell, minlength=nt) + lampsi
    eta_C = float(contact_K.sum())
    eta_D = math.sqrt(mu[0] * grad_psi2.sum())
    out["eta_C"], out["eta_D"] = eta_C, eta_D

    membrane = []
    for i in range(2):
        f = case_function(case["f%d" % (i + 1)])
        fq = f(geo.xq[..., 0], geo.xq[..., 1])
        int_f = np.sum(geo.wq * fq, axis=1)
        pif = int_f / geo.area
        osc = (geo.diam / math.pi) * np.sqrt(np.maximum(np.sum(geo.wq * (fq - pif[:, None]) ** 2, axis=1), 0.0)) / math.sqrt(mu[i])
        int_fphi = np.einsum("nq,nq,nqk->nk", geo.wq, fq, geo.lam_q)  # int_kappa f phi_j, j the vertices of K
        grad_uh = np.einsum("nkd,nk->nd", geo.grad_K, u[i][geo.T])  # per triangle
        G = mu[i] * grad_uh[geo.tri]  # mu grad u_h per cell
        # t_ih as written: t(c) and div t per cell; edge fluxes through the midpoints
        tc = np.stack([r["t%d_x" % (i + 1)], r["t%d_y" % (i + 1)]], axis=1)
        div_t = r["div_t%d" % (i + 1)]
        cen = geo.ps.mean(axis=1)
        t_mid = tc[:, None, :] + 0.5 * div_t[:, None, None] * (geo.mid - cen[:, None, :])
        e_vec = np.roll(geo.ps, -1, axis=1) - geo.ps
        F_t = t_mid[..., 0] * e_vec[..., 1] - t_mid[..., 1] * e_vec[..., 0]  # outward cell fluxes
        x_t = np.zeros(geo.n_edges)
        x_t[geo.cell_edge.ravel()] = (geo.cell_sign * F_t).ravel()
        # Lemma 17: the loads (f_i, phi_a)_q as computed, from int_{D_a} div t_ih
        int_div = np.bincount(geo.owner, div_t * geo.area, minlength=nv)
        load_q = int_div - sign[i] * lam * geo.dual_area
        rho = pif + sign[i] * lam_cell - div_t  # the piecewise-constant part of the residual
        m_a = np.bincount(geo.owner, rho * geo.area, minlength=nv)
        m_a[geo.on_boundary] = 0.0  # boundary cells: lifted with free flux on d(omega)
        res = {"mean_defect": float(np.abs(m_a).max())}
        for v in variants:
            sig_extra = np.zeros(ns)
            if v in ("dual", "dualmin"):
                x = x_t.copy()
                sig = np.zeros(geo.n_edges)
                target = np.zeros_like(geo.mid) if v == "dual" else -(G[:, None, :] + t_mid)
                for a in range(nv):
                    cells = geo.dual_cells_of[geo.dual_ptr[a]:geo.dual_ptr[a + 1]]
                    d = rho[cells] - m_a[a] / geo.dual_area[a]
                    edges, xe = solve_patch(geo, cells, target[cells], d)
                    sig[edges] += xe
                Fs = geo.cell_fluxes(sig)
                if v == "dual":
                    sig_extra = np.sqrt(geo.l2_affine(geo.rt0_at(Fs, geo.mid))) / math.sqrt(mu[i])
                else:
                    x = x + sig
                mean_cell = m_a[geo.owner] / geo.dual_area[geo.owner]
            else:  # vertex patches (Braess-Schoeberl / Ern-Vohralik), RT0 on S_h
                # e_a = (f, phi_a) - (f, phi_a)_q at interior vertices
                exact_load = np.zeros(nv)
                np.add.at(exact_load, geo.T[geo.tri].ravel(), int_fphi.ravel())
                e_a = np.where(geo.interior, exact_load - load_q, 0.0)
                x = equilibrate(geo, mu[i] * grad_uh, int_fphi, sign[i] * lam - e_a / geo.dual_area)
                mean_cell = e_a[geo.owner] / geo.dual_area[geo.owner]
            eta_Q_friedrichs = geo.C_F * math.sqrt(np.sum(mean_cell ** 2 * geo.area) / mu[i])
            eta_Q = eta_Q_friedrichs
            lifted = v in lift_means and np.abs(mean_cell).max() > 0
            if lifted:  # section 4(c'): tau_c with div tau_c = c, added to the flux; no mean is left
                x_c = lift(geo, mean_cell)
                x = x + x_c
                eta_Q = math.sqrt(geo.l2_affine(geo.rt0_at(geo.cell_fluxes(x_c), geo.mid)).sum() / mu[i])  # for the record
                mean_cell = np.zeros(ns)
            F = geo.cell_fluxes(x)
            tau_mid = geo.rt0_at(F, geo.mid)
            eta_F = np.sqrt(geo.l2_affine(G[:, None, :] + tau_mid)) / math.sqrt(mu[i]) + sig_extra
            # checks: conservation of tau on the cells (div tau = Pi f +- lambda_h - mean)
            div_tau = F.sum(axis=1) / geo.area
            if v != "dual":
                target_div = pif + sign[i] * lam_cell - mean_cell
                res[v + "_div_defect"] = float(np.abs(div_tau - target_div).max() / max(np.abs(target_div).max(), 1e-300))
            res[v] = {"eta_F": eta_F, "eta_osc": osc, "eta_Q": 0.0 if lifted else eta_Q, "eta_Q_record": eta_Q,
                      "eta_Q_friedrichs": eta_Q_friedrichs, "tau_mid": tau_mid, "G_mid": G, "mean_cell": mean_cell,
                      "osc_raw": osc * math.sqrt(mu[i]), "F_raw": eta_F * math.sqrt(mu[i])}
        membrane.append(res)

    for v in variants:
        parts = []
        for i in range(2):
            d = membrane[i][v]
            cell = d["eta_F"] + d["eta_osc"]
            parts.append(math.sqrt(np.sum(cell ** 2)) + d["eta_Q"])
        eta_FR = math.sqrt(parts[0] ** 2 + parts[1] ** 2)
        eta = math.sqrt(eta_FR ** 2 + eta_D ** 2 + 2 * max(eta_C, 0.0))  # (E), docs section 3
        # the action in H^-1: alpha = mu2/(mu1+mu2)
        alpha = mu[1] / (mu[0] + mu[1])
        d1, d2 = membrane[0][v], membrane[1][v]
        zeta = alpha * (d1["G_mid"][:, None, :] + d1["tau_mid"]) - (1 - alpha) * (d2["G_mid"][:, None, :] + d2["tau_mid"])
        zeta_cell = np.sqrt(geo.l2_affine(zeta))
        if v == "dual":  # the separate lifts sigma_i enter with weights alpha, 1 - alpha
            zeta_cell = zeta_cell + alpha * (d1["F_raw"] - np.sqrt(geo.l2_affine(d1["G_mid"][:, None, :] + d1["tau_mid"]))) \
                + (1 - alpha) * (d2["F_raw"] - np.sqrt(geo.l2_affine(d2["G_mid"][:, None, :] + d2["tau_mid"])))
        osc_l = alpha * d1["osc_raw"] + (1 - alpha) * d2["osc_raw"]
        mean_l = -alpha * d1["mean_cell"] + (1 - alpha) * d2["mean_cell"]
        eta_lam = math.sqrt(np.sum((zeta_cell + osc_l) ** 2)) + geo.C_F * math.sqrt(np.sum(mean_l ** 2 * geo.area))
        # the gap w = u1 - u2: mu_bar ||grad(w - w_h)||^2 <= eta_lam^2/mu_bar + mu_bar ||grad psi||^2 + 2 eta_C
        mu_bar = mu[0] * mu[1] / (mu[0] + mu[1])
        eta_w = math.sqrt(eta_lam ** 2 / mu_bar + mu_bar * grad_psi2.sum() + 2 * max(eta_C, 0.0))
        eta_lambda = math.sqrt(mu_bar) * eta_w + eta_lam
        per_tri = np.zeros(nt)
        for i in range(2):
            d = membrane[i][v]
            per_tri += np.bincount(geo.tri, (d["eta_F"] + d["eta_osc"]) ** 2, minlength=nt)
        out[v] = {
            "eta": eta, "eta_FR": eta_FR,
            "eta_F": math.sqrt(sum(np.sum(membrane[i][v]["eta_F"] ** 2) for i in range(2))),
            "eta_osc": math.sqrt(sum(np.sum(membrane[i][v]["eta_osc"] ** 2) for i in range(2))),
            "eta_Q": math.sqrt(sum(membrane[i][v]["eta_Q"] ** 2 for i in range(2))),
            "eta_Q_friedrichs": math.sqrt(sum(membrane[i][v]["eta_Q_friedrichs"] ** 2 for i in range(2))),
            "eta_Q_lifted": math.sqrt(sum(membrane[i][v]["eta_Q_record"] ** 2 for i in range(2))),
            "eta_lambda": eta_lambda, "eta_w": eta_w,
            "per_triangle": {"flux_osc_sq": per_tri, "contact": contact_K, "lifting_sq": mu[0] * grad_psi2},
        }
        for i in range(2):
            if v + "_div_defect" in membrane[i]:
                out[v]["div_defect_%d" % (i + 1)] = membrane[i][v + "_div_defect"]
    out["mean_defect"] = max(membrane[0]["mean_defect"], membrane[1]["mean_defect"])
    return out


# ---------------------------------------------------------------------------------------------
# the estimator as the Rust code computes it (`solve --estimate`), recomputed from a result
# ---------------------------------------------------------------------------------------------

MAX_RULE = 20  # the highest degree of the rules (src/quadrature_tables.rs, reference/gen_quadrature.py)


def on_triangles(geo, degree):
    """Basix's default rule of `degree` mapped onto every triangle of T_h from its corners in
    order (x = p0 + xi (p1 - p0) + eta (p2 - p0), as the Rust code's Quadrature::visit):
    points (nt x nq x 2), weights (nt x nq), barycentric coordinates (nq x 3)."""
    xi, w = basix.make_quadrature(basix.CellType.triangle, degree)
    a, b, c = geo.pk[:, 0], geo.pk[:, 1], geo.pk[:, 2]
    x = a[:, None] + xi[None, :, 0, None] * (b - a)[:, None] + xi[None, :, 1, None] * (c - a)[:, None]
    return x, 2 * geo.area_K[:, None] * w[None, :], np.column_stack([1 - xi.sum(axis=1), xi])


def energy_error(geo, case, u, mu):
    """(|||u - u_h|||, the estimated error of its quadrature) with |||u - u_h||| = (sum_i mu_i
    ||grad u_i - grad u_ih||^2)^(1/2) by the adaptive rule of reference/cubature.py on T_h, from
    the case's exact gradients: None without them."""
    exact = case.get("exact", {})
    if "grad_u1" not in exact or "grad_u2" not in exact:
        return None

    def density(c, x, bary):
        # sum_i mu_i |G_i - grad u_ih|^2 at the points
        flat = x.reshape(-1, 2)
        d = 0.0
        for i in range(2):
            gh = np.einsum("nkd,nk->nd", geo.grad_K[c], u[i][geo.T[c]])
            ge = np.stack([expr.to_numpy(expr.parse(g), flat[:, 0], flat[:, 1]).reshape(x.shape[:2])
                           for g in exact["grad_u%d" % (i + 1)]], axis=-1)
            d = d + mu[i] * np.sum((ge - gh[:, None, :]) ** 2, axis=-1)
        return d[..., None]

    value, error = cubature.integrate(geo.pk, density)
    E = math.sqrt(max(value[0], 0.0))
    return E, (error[0] / (2 * E) if E > 0 else 0.0)


def rust_estimate(r, cell_degree=None):
    """Everything `membrane-contact solve --estimate` writes, recomputed independently from the
    result r (common.read_result) -- the written u1, u2, gap, lambda at the vertices, the mesh and
    the case's expressions -- with the Rust code's choices (docs/a-posteriori.md section 10):
    the patch flux of section 7(c) with the normal flux free only on the halves of the boundary
    edges of T_h that contain a; the case's own rule on the cells of S_h; the means c_i lifted
    (section 4(c'): z_i of `poisson_lift`, the patch problems of mu_i grad u_ih + grad z_i and
    f_i + c_i), what the solve leaves, rho_i, by Friedrichs; h_kappa the longest edge; the
    lifting psi of section 5.
    cell_degree: another rule on the cells of S_h (for experiments; the loads on T_h keep the
    case's). Returns (attributes, cell fields per triangle of T_h, checks, round-off allowances)."""
    case = r["case"]
    degree = min(max(common.quadrature_degree(case), 1), MAX_RULE)
    geo = Geometry(r, cell_degree or degree)
    mu = [float(case["mu1"]), float(case["mu2"])]
    alpha = mu[1] / (mu[0] + mu[1])
    sign = [1.0, -1.0]
    u = [r["u1"], r["u2"]]
    gap = r["gap"]
    lam = np.where(geo.on_boundary, 0.0, r["lambda"])  # lambda_h = 0 on the cells of boundary vertices
    lam_cell = lam[geo.owner]
    nt, nv = len(geo.T), len(geo.P)
    m = geo.dual_area  # m_a = |D_a| = int phi_a
    # the contact term takes lambda_h on the contact set (>= 0, section 3); off it lambda_h is the
    # solve's round-off, whose norm enters each membrane's term by Friedrichs
    lam_c = np.where((r["contact"] > 0.5) & (lam > 0.0), lam, 0.0)
    off_contact = math.sqrt(float(np.sum((lam - lam_c) ** 2 * m)))
    f = [case_function(case["f1"]), case_function(case["f2"])]

    # the loads (f_i, phi_a)_q by the case's rule on T_h (the solver's load vectors)
    xT, wT, lT = on_triangles(geo, degree)
    loads = []
    for i in range(2):
        v = f[i](xT[..., 0], xT[..., 1])
        loads.append(np.bincount(geo.T.ravel(), np.einsum("nq,nq,qk->nk", wT, v, lT).ravel(), minlength=nv))
    # their consistency with the written lambda, lambda2 through (4.5) (interior vertices)
    stiff = np.einsum("nid,njd->nij", geo.grad_K, geo.grad_K) * geo.area_K[:, None, None]
    Ku = [np.bincount(geo.T.ravel(), np.einsum("nij,nj->ni", stiff, ui[geo.T]).ravel(), minlength=nv) for ui in u]
    recovered = [mu[0] * Ku[0] - lam * m, mu[1] * Ku[1] + np.where(geo.on_boundary, 0.0, r.get("lambda2", r["lambda"])) * m]
    inner = geo.interior
    # relative to the terms of (4.5) (the loads, or mu_i K u_i where a membrane is unloaded)
    load_check = max(float(np.abs(recovered[i] - loads[i])[inner].max(initial=0.0))
                     / max(float(np.abs(loads[i][inner]).max(initial=0.0)),
                           float(np.abs(mu[i] * Ku[i][inner]).max(initial=0.0)), 1e-300) for i in range(2))

    # the cells of S_h: int f phi_j, ||v - Pi v||^2 for v = f1, f2, alpha f1 - (1 - alpha) f2
    fq = [f[i](geo.xq[..., 0], geo.xq[..., 1]) for i in range(2)]
    fq.append(alpha * fq[0] - (1 - alpha) * fq[1])
    area_q = geo.wq.sum(axis=1)
    # Two passes, as the Rust code: the mean, then the squares of the deviations.
    raw = [np.sum(geo.wq * (v - (np.sum(geo.wq * v, axis=1) / area_q)[:, None]) ** 2, axis=1) for v in fq]
    osc2 = [np.maximum(v, 0.0) for v in raw]
    # Round-off allowance (generous for the two-pass sums): a relative error of about nq eps of
    # int f^2 (of the sizes of the terms of alpha f1 - (1 - alpha) f2 for the action) moves the
    # root by at most min(sqrt(D), D / root); where f is constant on kappa up to round-off
    # (alpha f1 - (1 - alpha) f2 inside the disk of disk_jump) both values are noise.
    size = [np.sum(geo.wq * fq[0] ** 2, axis=1), np.sum(geo.wq * fq[1] ** 2, axis=1),
            np.sum(geo.wq * (alpha * np.abs(fq[0]) + (1 - alpha) * np.abs(fq[1])) ** 2, axis=1)]
    roundoff = []
    for v, m2 in zip(raw, size):
        D = OSC_ROUNDOFF * (geo.wq.shape[1] + 2) * np.finfo(float).eps * m2
        root = np.sqrt(np.maximum(v, 0.0))
        roundoff.append(geo.diam / math.pi * np.where(root > 0, np.minimum(np.sqrt(D), D / np.where(root > 0, root, 1.0)), np.sqrt(D)))
    int_fphi = [np.einsum("nq,nq,nqk->nk", geo.wq, fq[i], geo.lam_q) for i in range(2)]

    fields = {}
    attrs = {}
    allow = {}  # round-off allowances of the oscillation terms (absolute; per triangle for cell fields)
    allow_K = np.zeros(nt)
    checks = {"dual_mismatch": geo.dual_mismatch, "load_vs_lambda": load_check}
    means, G_mid, tau_mid, sums = [], [], [], []
    indicator2 = np.zeros(nt)
    for i in range(2):
        on_s_h = np.bincount(geo.T[geo.tri].ravel(), int_fphi[i].ravel(), minlength=nv)
        c = np.where(geo.interior, (on_s_h - loads[i]) / m, 0.0)  # c_{i,a}, section 4(c)
        # lifted (section 4(c')): the local problems of mu_i u_ih + z_i with f_i + c_i; what the
        # solve leaves, rho_i, stays bounded by Friedrichs
        K, z, int_cphi, b = poisson_lift(geo, c[geo.owner])
        rho = np.where(geo.interior, (b - K @ z) / m, 0.0)
        means.append(rho)
        grad_uh = np.einsum("nkd,nk->nd", geo.grad_K, u[i][geo.T])
        grad_z = np.einsum("nkd,nk->nd", geo.grad_K, z[geo.T])
        x = equilibrate(geo, mu[i] * grad_uh + grad_z, int_fphi[i] + int_cphi, sign[i] * lam - c - rho, touching=True)
        F = geo.cell_fluxes(x)
        t_mid = geo.rt0_at(F, geo.mid)
        G = mu[i] * grad_uh[geo.tri]
        eta_F = np.sqrt(geo.l2_affine(G[:, None, :] + t_mid)) / math.sqrt(mu[i])
        eta_osc = geo.diam / math.pi * np.sqrt(osc2[i]) / math.sqrt(mu[i])
        # conservation of the flux: div tau_i = Pi f_i +- lambda_h - rho_i on every cell
        div = F.sum(axis=1) / geo.area
        target = np.sum(geo.wq * fq[i], axis=1) / geo.area + sign[i] * lam_cell - rho[geo.owner]
        checks["div_defect_%d" % (i + 1)] = float(np.abs(div - target).max() / max(np.abs(target).max(), 1e-300))
        fields["estimator_flux_%d" % (i + 1)] = np.sqrt(np.bincount(geo.tri, eta_F ** 2, minlength=nt))
        fields["estimator_oscillation_%d" % (i + 1)] = np.sqrt(np.bincount(geo.tri, eta_osc ** 2, minlength=nt))
        a2 = np.bincount(geo.tri, roundoff[i] ** 2, minlength=nt) / mu[i]
        allow["cell estimator_oscillation_%d" % (i + 1)] = np.sqrt(a2)
        allow["attr estimator_membrane_%d" % (i + 1)] = math.sqrt(a2.sum())
        allow_K += a2
        local = (eta_F + eta_osc) ** 2
        indicator2 += np.bincount(geo.tri, local, minlength=nt)
        sums.append(float(local.sum()))
        G_mid.append(G)
        tau_mid.append(t_mid)
        attrs["estimator_means_%d" % (i + 1)] = geo.C_F * (math.sqrt(np.sum(rho ** 2 * m)) + off_contact) / math.sqrt(mu[i])
        attrs["estimator_membrane_%d" % (i + 1)] = math.sqrt(sums[i]) + attrs["estimator_means_%d" % (i + 1)]

    # the boundary data (section 5) and the contact term (section 6)
    grad_psi2, lampsi = boundary_lifting(geo, case, lam_c, gap)
    fields["estimator_boundary"] = np.sqrt(mu[0] * grad_psi2)
    w_cent = np.einsum("nk,nk->n", barycentric(geo.pk[geo.tri], geo.ps.mean(axis=1)[:, None, :])[:, 0], gap[geo.T[geo.tri]])
    fields["estimator_contact"] = np.bincount(geo.tri, lam_c[geo.owner] * geo.area * w_cent, minlength=nt) + lampsi
    fields["estimator"] = np.sqrt(np.maximum(indicator2 + fields["estimator_boundary"] ** 2 + 2 * fields["estimator_contact"], 0.0))
    eta_D = math.sqrt(float(np.sum(fields["estimator_boundary"] ** 2)))
    eta_C = float(fields["estimator_contact"].sum())
    attrs["estimator_boundary"], attrs["estimator_contact"] = eta_D, eta_C
    allow["cell estimator"] = np.sqrt(allow_K)
    allow["attr estimator"] = math.sqrt(allow_K.sum())
    attrs["estimator"] = math.sqrt(max(attrs["estimator_membrane_1"] ** 2 + attrs["estimator_membrane_2"] ** 2
                                       + eta_D ** 2 + 2 * eta_C, 0.0))

    # the action (section 8), what the lifts leave by Friedrichs
    zeta = alpha * (G_mid[0][:, None, :] + tau_mid[0]) - (1 - alpha) * (G_mid[1][:, None, :] + tau_mid[1])
    cell = np.sqrt(geo.l2_affine(zeta)) + geo.diam / math.pi * np.sqrt(osc2[2])
    combined = alpha * means[0] - (1 - alpha) * means[1]
    eta_lam = math.sqrt(float(np.sum(cell ** 2))) + geo.C_F * math.sqrt(float(np.sum(combined ** 2 * m)))
    mu_bar = mu[0] * mu[1] / (mu[0] + mu[1])
    eta_w = eta_lam + geo.C_F * off_contact  # lambda_h off the contact set, by Friedrichs (section 3)
    e_w = math.sqrt(max(eta_w ** 2 / mu_bar + mu_bar * eta_D ** 2 / mu[0] + 2 * eta_C, 0.0))
    attrs["estimator_hminus1_lambda"] = math.sqrt(mu_bar) * e_w + eta_lam
    allow["attr estimator_hminus1_lambda"] = 2.0 * math.sqrt(float(np.sum(roundoff[2] ** 2)))  # d(bound)/d(eta_lambda) <= 2

    # the exact error, here and as written
    checks["error_energy"] = energy_error(geo, case, u, mu)
    # no effectivity where the error is within what a round-off of 1e-13 of u_h's values makes of
    # it (a solution exact in P1): sum_j |grad phi_j| = perimeter / (2 |K|) on each triangle
    corners = geo.P[geo.T]
    perimeter = sum(np.linalg.norm(corners[:, j] - corners[:, (j + 1) % 3], axis=1) for j in range(3))
    shape = float(np.sum((perimeter / (2 * geo.area_K)) ** 2 * geo.area_K))
    round_off = math.sqrt(sum(mu[i] * (1e-13 * np.abs(u[i]).max()) ** 2 for i in range(2)) * shape)
    if "error_energy" in r["attrs"] and float(r["attrs"]["error_energy"]) > round_off:
        attrs["effectivity"] = attrs["estimator"] / float(r["attrs"]["error_energy"])
        allow["attr effectivity"] = allow["attr estimator"] / float(r["attrs"]["error_energy"])
    return attrs, fields, checks, allow


# What --compare checks: (name, where, scale, tolerance). The scale of a difference is the total
# eta ("eta"; for the contact terms eta^2: 2 eta_C enters eta^2, so a change d of eta_C changes
# eta by d/eta), or the value itself ("own").
FLUX_TOL = 1e-9  # flux, oscillation, means: the same formulas at the same points; round-off only
OSC_ROUNDOFF = 8.0  # the round-off of int f^2 - (int f)^2/|kappa|: OSC_ROUNDOFF (nq + 2) eps int f^2
BOUNDARY_TOL = 1e-7  # psi: Rust's delta' is a difference quotient, here the exact derivative
CONTACT_TOL = 1e-9  # lambda_h w_h and int lambda_h psi: no derivative of g, round-off only
COMPARED = (
    ("estimator", "attr", "eta", BOUNDARY_TOL),
    ("estimator_membrane_1", "attr", "eta", FLUX_TOL),
    ("estimator_membrane_2", "attr", "eta", FLUX_TOL),
    ("estimator_means_1", "attr", "eta", FLUX_TOL),
    ("estimator_means_2", "attr", "eta", FLUX_TOL),
    ("estimator_boundary", "attr", "eta", BOUNDARY_TOL),
    ("estimator_contact", "attr", "eta2", CONTACT_TOL),
    ("estimator_hminus1_lambda", "attr", "own", BOUNDARY_TOL),
    ("effectivity", "attr", "own", BOUNDARY_TOL),
    ("estimator", "cell", "eta", BOUNDARY_TOL),
    ("estimator_flux_1", "cell", "eta", FLUX_TOL),
    ("estimator_flux_2", "cell", "eta", FLUX_TOL),
    ("estimator_oscillation_1", "cell", "eta", FLUX_TOL),
    ("estimator_oscillation_2", "cell", "eta", FLUX_TOL),
    ("estimator_boundary", "cell", "eta", BOUNDARY_TOL),
    ("estimator_contact", "cell", "eta2", CONTACT_TOL),
)
DUAL_TOL = 1e-14  # /dual against S_h built here (coordinates relative to the domain's size)
DIV_TOL = 1e-11  # div tau_i = Pi f_i +- lambda_h - rho_i, relative (this code's own equilibration)
ERROR_TOL = 1e-9  # error_energy against the one computed here: round-off, beyond what the two
# quadratures may miss (twice the sum of their estimates: the Rust code's error_quadrature, relative,
# and this one's)


def read_estimate(path):
    """The estimator's attributes and cell fields of a Rust result (h5py)."""
    import h5py

    h5 = os.path.join(path, "solution.h5") if os.path.isdir(path) else path
    with h5py.File(h5, "r") as f:
        attrs = {k: float(f.attrs[k]) for k in f.attrs if k.startswith("estimator") or k in ("effectivity", "error_energy", "error_quadrature")}
        fields = {k: f["mesh"][k][...] for k in f["mesh"] if k.startswith("estimator")}
    return attrs, fields


def compare(path):
    """Recomputes the estimator of the Rust result `path` and compares. Returns (rows, failures,
    summary): rows (name, where, Rust, here, max |difference| / scale, tolerance, round-off
    allowance / scale), failures the messages of every check that fails. A value passes when
    |Rust - here| <= tolerance * scale + allowance (per triangle for the cell fields)."""
    h5 = os.path.join(path, "solution.h5") if os.path.isdir(path) else path
    if not os.path.isfile(h5):
        return [], ["%s: no result there (no %s)" % (path, h5)], {}
    r = common.read_result(path)
    mine, mine_fields, checks, allow = rust_estimate(r)
    theirs, their_fields = read_estimate(path)
    failures = []
    if "estimator" not in theirs:
        return [], ["%s: no estimator in the result (solve with --estimate)" % path], {}
    eta = mine["estimator"]
    scales = {"eta": eta, "eta2": eta * eta}
    rows = []
    for name, where, scale, tol in COMPARED:
        extra = allow.get(where + " " + name, 0.0)
        if where == "attr":
            if name not in mine and name not in theirs:
                continue
            if name not in theirs or name not in mine:
                failures.append("%s: attribute %s only %s" % (path, name, "here" if name in mine else "in the result"))
                continue
            a, b = theirs[name], mine[name]
            s = abs(b) if scale == "own" else scales[scale]
            d = abs(a - b)
            ok = d <= tol * s + extra
        else:
            if name not in their_fields:
                failures.append("%s: cell field %s missing" % (path, name))
                continue
            a, b = their_fields[name], mine_fields[name]
            if a.shape != b.shape:
                failures.append("%s: cell field %s has %s values, %d triangles" % (path, name, a.shape, len(b)))
                continue
            s = scales[scale]
            dk = np.abs(a - b)
            d, ok = float(dk.max()), bool(np.all(dk <= tol * s + extra))
            worst = int(np.argmax(dk / (tol * s + extra + 1e-300)))
            at = (worst, a[worst], b[worst])
            a, b, extra = float(np.abs(a).max()), float(np.abs(b).max()), float(np.max(extra))
        rel = d / s if s > 0 else (0.0 if d == 0 else math.inf)
        rows.append((name, where, a, b, rel, tol, extra / s if s > 0 else 0.0))
        if not ok:
            failures.append("%s: %s %s differs by %.2e (relative to %s) > %.0e + round-off %.1e: %s"
                            % (path, where, name, rel, {"eta": "eta", "eta2": "eta^2", "own": "itself"}[scale], tol,
                               rows[-1][6], "Rust %.10e, here %.10e" % (a, b) if where == "attr" else
                               "on triangle %d Rust %.10e, here %.10e" % at))
    if not checks["dual_mismatch"] <= DUAL_TOL:
        failures.append("%s: /dual is not the submesh S_h of /mesh (mismatch %.2e)" % (path, checks["dual_mismatch"]))
    for i in (1, 2):
        if not checks["div_defect_%d" % i] <= DIV_TOL:
            failures.append("%s: the flux tau_%d recomputed here misses its divergence by %.2e" % (path, i, checks["div_defect_%d" % i]))
    # the bound itself, where the case has an exact solution
    E, quadrature = checks["error_energy"] or (None, 0.0)
    summary = {"eta": eta, "eta_rust": theirs["estimator"], "E": E, "E_rust": theirs.get("error_energy")}
    if E is not None:
        e_rust = theirs.get("error_energy", math.nan)
        summary["E_rel"] = abs(e_rust - E) / E if E > 0 else abs(e_rust - E)
        allowed = ERROR_TOL + 2.0 * (theirs.get("error_quadrature", 0.0) + quadrature / E)
        if not summary["E_rel"] <= allowed:
            failures.append("%s: error_energy = %.10e, here %.10e" % (path, e_rust, E))
        for who, value in (("here", eta), ("Rust", theirs["estimator"])):
            if not value >= E:
                failures.append("%s: the bound fails: eta (%s) = %.6e < |||u - u_h||| = %.6e" % (path, who, value, E))
    summary["checks"] = checks
    return rows, failures, summary


def print_comparison(path, rows, summary, out=sys.stdout):
    print("%s" % path, file=out)
    print("  %-26s %-4s %18s %18s %10s %7s %9s" % ("quantity", "", "Rust (max |.|)", "here (max |.|)", "rel. diff", "tol",
                                                   "round-off"), file=out)
    for name, where, a, b, rel, tol, extra in rows:
        print("  %-26s %-4s %18.10e %18.10e %10.2e %7.0e %9.1e%s" % (name, where, a, b, rel, tol, extra,
                                                                  "" if rel <= tol + extra else "  FAIL"), file=out)
    c = summary.get("checks", {})
    line = "  S_h mismatch %.1e, div defects %.1e %.1e, loads vs (4.5) %.1e" % (
        c.get("dual_mismatch", math.nan), c.get("div_defect_1", math.nan), c.get("div_defect_2", math.nan), c.get("load_vs_lambda", math.nan))
    if summary.get("E") is not None:
        line += "; |||u - u_h||| = %.6e (Rust %.6e, rel. diff %.1e), eta/E = %.4f" % (
            summary["E"], summary["E_rust"], summary["E_rel"], summary["eta"] / summary["E"])
    print(line, file=out, flush=True)


GROUPS = (  # the columns of the summary table: (title, names compared)
    ("η, η_K", ("estimator",)),
    ("η_1, η_2", ("estimator_membrane_1", "estimator_membrane_2")),
    ("η_Q,1, η_Q,2", ("estimator_means_1", "estimator_means_2")),
    ("flux_i (cells)", ("estimator_flux_1", "estimator_flux_2")),
    ("osc_i (cells)", ("estimator_oscillation_1", "estimator_oscillation_2")),
    ("η_D, η_D,K", ("estimator_boundary",)),
    ("η_C, η_C,K", ("estimator_contact",)),
    ("§8 bound", ("estimator_hminus1_lambda",)),
    ("effectivity", ("effectivity",)),
)


def summary_row(label, rows, summary):
    cells = [label]
    for _, names in GROUPS:
        v = [rel for name, _, _, _, rel, _, _ in rows if name in names]
        cells.append("%.1e" % max(v) if v else "—")
    E = summary.get("E")
    cells.append("%.4f" % (summary["eta"] / E) if E else "—")
    return "| " + " | ".join(cells) + " |"


def compare_main(paths):
    if not paths:
        print("usage: python3 -m reference.estimator --compare DIR [DIR ...]", file=sys.stderr)
        return 2
    head = ["| result | " + " | ".join(t for t, _ in GROUPS) + " | η/E |", "|---" * (len(GROUPS) + 2) + "|"]
    table, failures = [], []
    for p in paths:
        rows, fails, summary = compare(p)
        if rows:
            print_comparison(p, rows, summary)
            table.append(summary_row(p, rows, summary))
        failures += fails
    print("\nmax |Rust - here| relative to eta (eta^2 for the contact terms, the value itself for the §8 bound and "
          "the effectivity); tolerances %.0e (flux, oscillation, means), %.0e (contact), %.0e (boundary terms and "
          "what contains them)" % (FLUX_TOL, CONTACT_TOL, BOUNDARY_TOL))
    print("\n".join(head + table))
    if failures:
        print("ESTIMATOR COMPARISON FAILED:")
        for f in failures:
            print("  " + f)
        return 1
    print("estimator comparison: %d result(s) agree" % len(paths))
    return 0


def line(o, variants=VARIANTS):
    e = o["error_energy"]
    s = "%s  err %.4e" % (o["path"], e)
    for v in variants:
        d = o[v]
        s += " | %s eta %.4e eff %.3f (F %.2e osc %.2e Q %.2e) lam %.2e/%.2e" % (
            v, d["eta"], d["eta"] / e, d["eta_F"], d["eta_osc"], d["eta_Q"], d["eta_lambda"], o["error_hminus1"])
    s += " | C %.2e D %.2e" % (o["eta_C"], o["eta_D"])
    return s


def table_row(o):
    """One markdown row: case, n, true error, then per flux eta and effectivity; data terms; action."""
    case = o["case_name"]
    cells = ["%s" % case, "%d" % o["n"], "%.3e" % o["error_energy"]]
    for v in VARIANTS:
        cells += ["%.3e" % o[v]["eta"], "%.3f" % (o[v]["eta"] / o["error_energy"])]
    cells += ["%.1e" % o["eta_D"], "%.1e" % o["eta_C"], "%.1e / %.1e" % (o["patch"]["eta_Q_friedrichs"], o["patch"]["eta_Q_lifted"]), "%.2e" % o["error_hminus1"],
              "%.2e" % o["patch"]["eta_lambda"],
              "%.0f" % (o["patch"]["eta_lambda"] / o["error_hminus1"]) if o["error_hminus1"] > 1e-12 else "—"]
    return "| " + " | ".join(cells) + " |"


TABLE_HEAD = ("| case | n | error | eta dual | eff | eta dualmin | eff | eta patch | eff | eta_D | eta_C | patch: C_F norm of means / norm of their lift "
              "| H-1 error of lambda (Rust, lower bound) | eta_lambda (patch) | ratio |\n" + "|---" * 15 + "|")


def main(argv):
    if argv and argv[0] == "--compare":
        sys.exit(compare_main(argv[1:]))
    table = "--table" in argv
    save = None
    if "--per-triangle" in argv:
        k = argv.index("--per-triangle")
        save = argv[k + 1]
        del argv[k:k + 2]
    paths = [a for a in argv if not a.startswith("--")]
    if table:
        print(TABLE_HEAD, flush=True)
    for p in paths:
        o = estimate(p)
        print(table_row(o) if table else line(o), flush=True)
        if table:
            print(line(o), file=sys.stderr, flush=True)
        if save:
            np.savez(save, **{v + "_" + k: x for v in VARIANTS for k, x in o[v]["per_triangle"].items()})


if __name__ == "__main__":
    main(sys.argv[1:])
