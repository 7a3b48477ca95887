"""Checks of the flux reconstruction t_ih (Section 4.2) from the fields the Rust code WRITES on the
dual submesh S_h: t_ih at the cell centroids (ti_x, ti_y) and div t_ih (div_ti), per cell; above an
obstacle the one flux t_h of u (t_x, t_y, div_t). Each membrane's names, tension, load and sign
of lambda come from problems.Problem.fluxes (suffix "1", "2", or "").

A lowest-order Raviart-Thomas field on a triangle K is t(x) = a + b x with div t = 2 b, so

    t(x) = t(c_K) + (div t / 2) (x - c_K)          (c_K the centroid of K),

which rebuilds t_ih on every cell from the two written fields. Then:

(a) normal continuity (t_ih in H(div)): on every interior edge e of S_h, with midpoint m and unit
    normal n, t_K(m).n = t_K'(m).n for the two cells K, K' sharing e (relative to the flux scale
    max |t_ih(c_K)|). An identity of the reconstruction: only round-off may remain.
(b) local conservation (Lemma 17): at every interior vertex a,
        sum over the cells K of D_a of div t_ih |K|  =  (f_i, phi_a)_q  +/-  lambda_a |D_a|
    (+ for membrane 1 and above an obstacle, - for membrane 2), with the loads (f_i, phi_a)_q and lambda_a those of the
    REFERENCE (dolfinx, the case's quadrature degree), relative to max_a |(f_i, phi_a)| + |lambda_a| |D_a|.
(c) approximation: ||t_ih + mu_i grad u_i||_L2 against the exact gradient (cases that give it),
    by basix's degree-10 rule on S_h; validate checks its rate between successive levels.
"""
import basix
import numpy as np

from . import common

ERROR_DEGREE = 10


def named(base, s):
    """The name of a per-membrane quantity: base_1, base_2 (suffix s), or base alone (s = "")."""
    return base + "_" + s if s else base


def rt0_field(result, s):
    """(centroids, t(c), div t) of the flux with suffix s (t1h, t2h, th) on the cells of S_h."""
    p = result["dual_points"][result["dual_cells"]][:, :, :2]
    tc = np.stack([result["t%s_x" % s], result["t%s_y" % s]], axis=1)
    return p.mean(axis=1), tc, result["div_t%s" % s]


def edges_of(cells):
    """The edges of the cells (3 per cell, edge k from vertex k to k + 1), the distinct edges
    (sorted vertex pairs), the distinct edge of each, and how many cells share each distinct edge."""
    edges = np.stack([cells[:, [0, 1]], cells[:, [1, 2]], cells[:, [2, 0]]], axis=1).reshape(-1, 2)
    uniq, inv, counts = np.unique(np.sort(edges, axis=1), axis=0, return_inverse=True, return_counts=True)
    return edges, uniq, inv.ravel(), counts


def edge_pairs(cells):
    """(cell A, local edge of A, cell B) for every edge shared by two cells, and the number of
    edges that belong to one cell only."""
    _, _, inv, counts = edges_of(cells)
    if counts.max() > 2:
        raise RuntimeError("an edge is shared by more than two cells")
    order = np.argsort(inv, kind="stable")
    k = np.flatnonzero(inv[order][1:] == inv[order][:-1])
    first, second = order[k], order[k + 1]
    return (first // 3, first % 3, second // 3), int(np.sum(counts == 1))


def normal_jump(result, s):
    """(a): max over interior edges of |[t_ih . n]| at the midpoint, relative to max |t_ih(c)|;
    inf when S_h does not join its cells across the edges of T_h (it must have exactly twice as
    many boundary edges as T_h), where the check would otherwise pass vacuously."""
    pts, cells = result["dual_points"][:, :2], result["dual_cells"]
    (a, k, b), boundary = edge_pairs(cells)
    if boundary != 2 * edge_pairs(result["cells"])[1]:
        return float("inf")
    c, tc, div = rt0_field(result, s)
    p0, p1 = pts[cells[a, k]], pts[cells[a, (k + 1) % 3]]
    mid = 0.5 * (p0 + p1)
    n = np.stack([p1[:, 1] - p0[:, 1], p0[:, 0] - p1[:, 0]], axis=1)
    n /= np.linalg.norm(n, axis=1)[:, None]
    ta = tc[a] + 0.5 * div[a][:, None] * (mid - c[a])
    tb = tc[b] + 0.5 * div[b][:, None] * (mid - c[b])
    scale = max(np.linalg.norm(tc, axis=1).max(), 1e-300)
    return np.abs(np.sum((ta - tb) * n, axis=1)).max() / scale


def conservation_defect(result, ref, s, load_key, sign):
    """(b): (max over interior vertices of the defect of Lemma 17, max of |lambda_Rust - lambda_ref| |D_a|),
    both relative to max_a |(f_i, phi_a)| + |lambda_a| |D_a|; `ref` a reference file
    (common.read_reference) on the mesh of `result`; the flux of suffix s, its load's case key, the
    sign of lambda_a |D_a|."""
    owner = result["dual_owner"]
    area = common.areas(result["dual_points"], result["dual_cells"])
    nv = len(result["points"])
    integral = np.bincount(owner, weights=result["div_t%s" % s] * area, minlength=nv)
    measure = np.bincount(owner, weights=area, minlength=nv)  # |D_a|
    perm = common.match_points(result["points"], ref["points"])
    load, lam = ref["load_" + load_key][perm], ref["lambda"][perm]
    interior = ~boundary_vertices(result)
    # sum_{K in D_a} div t_ih |K| - (f_i, phi_a)_q -/+ lambda_a |D_a|
    defect = np.abs(integral - load - sign * lam * measure)[interior]
    scale = max((np.abs(load) + np.abs(lam) * measure)[interior].max(), 1e-300)
    lam_term = (np.abs(result["lambda"] - lam) * measure)[interior].max()
    return defect.max() / scale, lam_term / scale


def boundary_vertices(result):
    """Vertices of T_h on the boundary (ends of edges that belong to one triangle only)."""
    _, uniq, _, counts = edges_of(result["cells"])
    out = np.zeros(len(result["points"]), bool)
    out[uniq[counts == 1].ravel()] = True
    return out


def flux_error(result, s, mu, grad):
    """(c): ||t_ih + mu_i grad u_i||_L2 (flux of suffix s) on S_h, grad = the case's exact gradient (two expressions)."""
    xi, wts = basix.make_quadrature(basix.CellType.triangle, ERROR_DEGREE)
    p = result["dual_points"][result["dual_cells"]][:, :, :2]
    c, tc, div = rt0_field(result, s)
    x = p[:, None, 0] + xi[None, :, 0, None] * (p[:, None, 1] - p[:, None, 0]) \
        + xi[None, :, 1, None] * (p[:, None, 2] - p[:, None, 0])  # cells x points x 2
    t = tc[:, None, :] + 0.5 * div[:, None, None] * (x - c[:, None, :])
    flat = x.reshape(-1, 2)
    G = np.stack([common.at_points(g, flat).reshape(x.shape[:2]) for g in grad], axis=2)
    jac = 2.0 * common.areas(result["dual_points"], result["dual_cells"])
    return np.sqrt(np.sum(jac[:, None] * wts[None, :] * np.sum((t + mu * G) ** 2, axis=2)))


def check_level(result, ref):
    """Every flux check of one Rust result: {suffix: {"jump", "conservation", "error"}} for the
    suffixes of its problem's fluxes ("1", "2"; "" above an obstacle), "error" only where the case
    gives grad_u<suffix>."""
    case = result["case"]
    out = {}
    for s, mu, load, sign in result["problem"].fluxes:
        out[s] = {"jump": normal_jump(result, s), "conservation": conservation_defect(result, ref, s, load, sign)}
        grad = case.get("exact", {}).get("grad_u" + s)
        if grad is not None:
            out[s]["error"] = flux_error(result, s, float(case[mu]), grad)
    return out
