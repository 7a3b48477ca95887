"""Adaptive cubature of the error norms' densities over triangles, written apart from the Rust
code's (src/norms/cubature.rs: two rules per cell, signatures of the expressions' branches):
here basix's degree-10 rule on a piece and on its four quarters (cut at the edges' midpoints). A
piece whose two values differ by more than its share of the tolerance (its part of the area) is
replaced by its quarters, round after round. The value is the sum of the quarters' values over the
pieces kept, and the estimate of its error the sum of |quarters - piece| there: the error of the
coarser value, which the finer about halves across a jump and divides by about 2^11 where the density is
smooth.

Pieces are triangles in the reference coordinates of the cell they lie in, so that a density can
use the cell's barycentric coordinates (a P1 field) at the points.
"""
import basix
import numpy as np

DEGREE = 10
RTOL = 1e-7  # of the integral, spread over the area
MAX_ROUNDS = 5  # a jump: about 2^-5 of the first error left, which the estimate states
MAX_PIECES = 250_000  # pieces cut in one round at most (the rest are kept, with their error)
CHUNK = 4096  # pieces evaluated at once
UNIT = np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]])
QUARTERS = np.array([[[0, 0], [.5, 0], [0, .5]], [[.5, 0], [1, 0], [.5, .5]],
                     [[0, .5], [.5, .5], [0, 1]], [[.5, .5], [0, .5], [.5, 0]]])


def _cross(a, b):
    return a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0]


def integrate(corners, density):
    """(value, error) arrays (M components) of the integral over the triangles `corners` (n x 3 x 2)
    of density(cells, x, bary) -> (p x q x M) >= 0, at points x (p x q x 2) of pieces of the cells
    `cells` (p), bary their barycentric coordinates in the cell (p x q x 3)."""
    xi, w = basix.make_quadrature(basix.CellType.triangle, DEGREE)
    p0, e1, e2 = corners[:, 0], corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0]
    jac = np.abs(_cross(e1, e2))

    def rule(cells, ref):
        """The rule's value on each piece (p x M)."""
        out = []
        for s in range(0, len(cells), CHUNK):
            c, r = cells[s:s + CHUNK], ref[s:s + CHUNK]
            a, b = r[:, 1] - r[:, 0], r[:, 2] - r[:, 0]
            X = r[:, None, 0] + xi[None, :, 0, None] * a[:, None] + xi[None, :, 1, None] * b[:, None]
            bary = np.concatenate([1 - X.sum(axis=2, keepdims=True), X], axis=2)
            x = p0[c][:, None] + X[..., :1] * e1[c][:, None] + X[..., 1:] * e2[c][:, None]
            scale = jac[c] * np.abs(_cross(a, b))
            out.append(np.einsum("pqm,q->pm", density(c, x, bary), w) * scale[:, None])
        return np.concatenate(out)

    def quarters(ref):
        a, b = ref[:, 1] - ref[:, 0], ref[:, 2] - ref[:, 0]
        q = ref[:, None, None, 0] + QUARTERS[None, ..., :1] * a[:, None, None] + QUARTERS[None, ..., 1:] * b[:, None, None]
        return q.reshape(-1, 3, 2)

    cells, ref = np.arange(len(corners)), np.repeat(UNIT[None], len(corners), axis=0)
    coarse = rule(cells, ref)
    value, error = np.zeros(coarse.shape[1]), np.zeros(coarse.shape[1])
    for round_ in range(MAX_ROUNDS + 1):
        kids, kid_cells = quarters(ref), np.repeat(cells, 4)
        fine = rule(kid_cells, kids).reshape(len(cells), 4, -1)
        fine_sum = fine.sum(axis=1)
        diff = np.abs(fine_sum - coarse)
        total = value + fine_sum.sum(axis=0)
        share = jac[cells] * np.abs(_cross(ref[:, 1] - ref[:, 0], ref[:, 2] - ref[:, 0])) / jac.sum()
        cut = np.any(diff > RTOL * total[None, :] * share[:, None], axis=1)
        if round_ == MAX_ROUNDS:
            cut[:] = False
        elif cut.sum() > MAX_PIECES:  # the largest differences first
            order = np.argsort(-(diff / np.maximum(total, 1e-300)).max(axis=1))
            cut[order[MAX_PIECES:]] = False
        keep = ~cut
        value += fine_sum[keep].sum(axis=0)
        error += diff[keep].sum(axis=0)
        if not cut.any():
            break
        chosen = np.repeat(cut, 4)
        cells, ref, coarse = kid_cells[chosen], kids[chosen], fine[cut].reshape(-1, fine.shape[2])
    return value, error
