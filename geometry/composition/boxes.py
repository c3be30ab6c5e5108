"""Composition of axis-aligned boxes: the outer map restricted to a sub-box (exact, no products).

When a placed inner patch is a box whose every outer parameter is an affine
function of one inner parameter (a regular paving of box-shaped tile
patches), ``outer(inner)`` is the outer map restricted to a sub-box,
re-expanded by blossoming: it keeps the outer degrees, permuted to the inner
parameter order, far lower than the general degrees of Elber 2017, Eq. 7.
Patches with channels or weights of their own take the general path.
"""

from __future__ import annotations

import numpy as np

from geometry import bernstein as bz
from geometry import knots as kn
from geometry.bspline import BSpline

__all__ = ["axis_aligned", "restrict_batch"]


def axis_aligned(inner: BSpline, placed: np.ndarray, Do: int):
    """Which placed inner patches are axis-aligned boxes in the outer parameters.

    A placed patch qualifies when each outer parameter k is an affine function
    ``alpha_k + beta_k xi_j`` of a single inner parameter j = sigma[k] (its
    control points are then alpha + beta * Greville abscissae), the inner spline
    is polynomial, has no channels and ``inner.dim == Do``.  Returns sigma
    (P, Do) (-1 rows where not aligned), alpha and beta (P, Do).
    """
    nP = placed.shape[0]
    perm = np.full((nP, Do), -1)
    alpha = np.zeros((nP, Do))
    beta = np.zeros((nP, Do))
    if inner.dim != Do or inner.is_rational or inner.channels:
        return perm, alpha, beta
    shape = inner.shape
    idx = np.indices(shape).reshape(inner.dim, -1)
    Y = placed  # (P, n, Do)
    scale = np.abs(Y).max(axis=1).max(axis=1) + 1.0
    match = np.zeros((nP, Do, inner.dim), bool)
    fits = {}
    for j in range(inner.dim):
        g = kn.greville(inner.knots[j], inner.degrees[j])
        last = np.ravel_multi_index(tuple(shape[k] - 1 if k == j else 0 for k in range(inner.dim)), shape)
        bj = (Y[:, last] - Y[:, 0]) / (g[-1] - g[0])  # (P, Do)
        aj = Y[:, 0] - bj * g[0]
        pred = aj[:, None, :] + bj[:, None, :] * g[idx[j]][None, :, None]
        ok = np.abs(Y - pred).max(axis=1) <= 1e-13 * scale[:, None]
        match[:, :, j] = ok & (np.abs(bj) > 1e-12 * scale[:, None])
        fits[j] = (aj, bj)
    unique = match.sum(axis=2) == 1
    sigma = np.argmax(match, axis=2)
    good = np.all(unique, axis=1) & np.array([len(set(r)) == Do for r in sigma])
    perm[good] = sigma[good]
    for k in range(Do):
        for j in range(inner.dim):
            rows = good & (sigma[:, k] == j)
            alpha[rows, k] = fits[j][0][rows, k]
            beta[rows, k] = fits[j][1][rows, k]
    return perm, alpha, beta


def restrict_batch(outer, Q, elo, ehi, inner, sigma, alpha, beta, finish):
    """Outer Bezier piece ``Q`` restricted to the boxes ``alpha + beta * inner domain`` (exact).

    outer(alpha_k + beta_k xi_sigma[k]) has the outer degrees, so the result is
    the piece re-expanded on each sub-box (blossoming), axes permuted to the
    inner parameter order.  Returns one BSpline per placement, built by
    ``finish(outer, inner, degrees, knots, coefficients (B, ...), rational)`` (a list).
    """
    Do = len(sigma)
    dom = inner.domain
    h = ehi - elo
    R = np.broadcast_to(Q[None], (len(alpha),) + Q.shape)  # (B, n_1+1, ..., C)
    for k in range(Do):
        a, b = dom[sigma[k]]
        t0 = (alpha[:, k] + beta[:, k] * a - elo[k]) / h[k]
        t1 = (alpha[:, k] + beta[:, k] * b - elo[k]) / h[k]
        M = bz.subinterval_matrices(Q.shape[k] - 1, t0, t1)  # (B, n+1, n+1)
        X = np.moveaxis(R, k + 1, 1)
        Y = np.matmul(M, X.reshape(X.shape[0], X.shape[1], -1)).reshape(X.shape)  # batched BLAS
        R = np.moveaxis(Y, 1, k + 1)
    inv = np.argsort(sigma)  # result axis j <- outer axis inv[j]
    R = np.transpose(R, (0,) + tuple(1 + int(k) for k in inv) + (Do + 1,))
    degrees = tuple(Q.shape[int(k)] - 1 for k in inv)
    knots = [np.repeat(dom[j], p + 1) for j, p in enumerate(degrees)]
    return finish(outer, inner, degrees, knots, R, outer.is_rational)


