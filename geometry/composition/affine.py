"""Composition with an outer map that is affine where the placed patch lies: ``outer(A p + b) = M (A p + b) + c``.

A B-spline is affinely invariant, so the composed patch is the inner spline itself with its control points
mapped: its own degrees and knots, no Bernstein products (Elber 2017's Eq. 7 would give
``(n_1 + ... + n_D) m``).  Boxes and slabs modelled at degree 2 (the vertical heat sink's base,
``primitives.box(degrees=(2, 2, 2))``) are affine on every piece: T2 tiles of degree 2 composed into one
are degree 2, not 12.

A Bezier piece of the outer map is affine when all its weights are equal and each of its control points
(coordinates and channels) is the affine function through its corner values evaluated at the point's
Greville abscissae, to :data:`AFFINE_TOL` of the piece's magnitude: that is round-off of the map's own
representation (a box elevated to degree 2 has control points exact to an ulp or two).
"""

from __future__ import annotations

import numpy as np

__all__ = ["affine_piece", "affine_images", "AFFINE_TOL"]

#: relative deviation (x the piece's largest coefficient magnitude) below which a piece counts as affine
AFFINE_TOL = 1e-14


def affine_piece(Q: np.ndarray, lo: np.ndarray, hi: np.ndarray, rational: bool):
    """``(M (D, m), c (m,))`` with the piece ``x(u) = u @ M + c`` on its parameter box [lo, hi] (D,) when the
    homogeneous Bezier piece Q (p_1 + 1, ..., p_D + 1, m (+ 1 if rational)) is affine, else None."""
    D = len(lo)
    X = np.asarray(Q, float)
    if rational:
        w = X[..., -1]
        if np.ptp(w) > AFFINE_TOL * np.abs(w).max():
            return None
        X = X[..., :-1] / w[..., None]
    degrees = X.shape[:D]
    origin = X[(0,) * D]
    M = np.empty((D, X.shape[-1]))
    for k in range(D):
        corner = [0] * D
        corner[k] = degrees[k] - 1
        M[k] = (X[tuple(corner)] - origin) / (hi[k] - lo[k])
    # the affine function's Bezier coefficients: its values at the Greville points lo + i / p (hi - lo)
    axes = [lo[k] + np.linspace(0.0, 1.0, degrees[k]) * (hi[k] - lo[k]) for k in range(D)]
    c = origin - lo @ M
    tol = AFFINE_TOL * max(float(np.abs(X).max()), 1.0)
    # the far corner and the middle first: a curved piece fails there, without the whole net
    for idx in (tuple(n - 1 for n in degrees), tuple(n // 2 for n in degrees)):
        if np.abs(np.array([axes[k][i] for k, i in enumerate(idx)]) @ M + c - X[idx]).max() > tol:
            return None
    G = np.stack(np.meshgrid(*axes, indexing="ij"), -1)
    if np.abs(G @ M + c - X).max() > tol:
        return None
    return M, c


def affine_images(inner, M: np.ndarray, c: np.ndarray, A: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Homogeneous coefficients of ``outer(A p + b)`` over the inner spline's own basis, for an outer piece
    ``x(u) = u @ M + c``: the inner coordinates placed (``A`` (D, 3), ``b`` (D,)) and mapped, the inner
    channels carried along (result components: outer's coordinates and channels, inner's channels, and the
    weight when the inner spline is rational, as :func:`geometry.composition.core.finish` orders them)."""
    H = np.asarray(inner.homogeneous, float)
    rational = inner.is_rational
    w = H[..., -1:] if rational else np.ones(H.shape[:-1] + (1,))
    u = H[..., :3] @ A.T + w * b  # placed (times the weight: affine maps commute with it)
    mapped = u @ M + w * c
    carried = H[..., 3:-1] if rational else H[..., 3:]
    return np.concatenate([mapped, carried] + ([w] if rational else []), axis=-1)
