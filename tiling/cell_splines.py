"""Scalar spline pieces of the implicit bifurcation cells: merged faces, Boolean sums, cached bases.

* :func:`merge_pieces`: one B-spline surface equal to pieces that tile
  [0, 1]^2 (Massarwi et al. 2018, Fig. 6): every piece refined to the union of
  the knots (multiplicity d at the junctions) by knot insertion, exact;
* :func:`boolean_sum`: the volumetric Boolean sum of six scalar faces whose
  rims are one constant, computed on the control net with Greville abscissae
  (exact: splines reproduce linear blends);
* :func:`grid_values`: a scalar trivariate on a grid, by tensor contractions
  with normalised bases cached across cells (cells repeat their knots and
  relative samples).
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np

from geometry import SplineFunction
from geometry import knots as kn
from geometry.faces import FACE_NAMES

from .errors import TilingError
from geometry.tolerances import SAME_KNOT

__all__ = ["merge_pieces", "boolean_sum", "grid_values", "scalar_surface"]


@lru_cache(maxsize=2048)
def _unit_basis(U: bytes, degree: int, x: bytes) -> np.ndarray:
    """Dense basis values (len(x), n) of knots U on [0, 1] at x (cached: cells repeat their relative samples)."""
    return kn.basis_matrix(np.frombuffer(U), degree, np.frombuffer(x)).toarray()


def grid_values(f: SplineFunction, axes) -> np.ndarray:
    """The scalar trivariate f on the grid of ``axes`` (tensor contractions with cached, normalised bases)."""
    C = f.coefficients[..., 0]
    for k, (U, p, x) in enumerate(zip(f.knots, f.degrees, axes)):
        lo, hi = U[0], U[-1]
        B = _unit_basis(np.round((U - lo) / (hi - lo), 13).tobytes(), int(p),
                        np.clip(np.round((x - lo) / (hi - lo), 13), 0.0, 1.0).tobytes())
        C = np.moveaxis(np.tensordot(B, C, axes=(1, k)), 0, k)
    return C


def scalar_surface(c, degree, box=((0.0, 1.0), (0.0, 1.0))) -> SplineFunction:
    n = c.shape[0]
    U = kn.uniform_knots(degree, n - degree)
    knots = [box[d][0] + (box[d][1] - box[d][0]) * U for d in range(2)]
    return SplineFunction((degree, degree), knots, c[..., None])


def merge_pieces(pieces, degree) -> SplineFunction:
    """One B-spline surface over [0, 1]^2 equal to the given pieces (which tile it and agree on their junctions).

    Knots: the union of all pieces' knots, multiplicity ``degree`` at every
    junction (C0); each piece is refined to the union by knot insertion
    (exact) and its coefficients written into the common net.
    """
    cuts = [np.unique(np.concatenate([p.knots[d][[0, -1]] for p in pieces])) for d in range(2)]
    knots = []
    for d in range(2):
        inner = np.unique(np.concatenate([p.knots[d][degree + 1:-degree - 1] for p in pieces]))
        inner = inner[np.abs(inner[:, None] - cuts[d][None, :]).min(axis=1) > SAME_KNOT]
        knots.append(np.sort(np.concatenate([[0.0] * (degree + 1), inner, np.repeat(cuts[d][1:-1], degree),
                                             [1.0] * (degree + 1)])))
    g = [kn.greville(U, degree) for U in knots]
    C = np.full((len(g[0]), len(g[1])), np.nan)
    for p in pieces:
        q = p
        for d in range(2):
            lo, hi = q.knots[d][0], q.knots[d][-1]
            want = knots[d][(knots[d] > lo + SAME_KNOT) & (knots[d] < hi - SAME_KNOT)]
            have = q.knots[d][degree + 1:-degree - 1]
            extra = _missing(want, have)
            if len(extra):
                q = _insert(q, d, extra)
        i0 = [int(np.argmin(np.abs(g[d] - q.knots[d][0]))) for d in range(2)]
        c = q.coefficients[..., 0]
        C[i0[0]:i0[0] + c.shape[0], i0[1]:i0[1] + c.shape[1]] = c
    if np.isnan(C).any():
        raise TilingError("the neighbours' faces do not cover the complex face; this is a bug in the subdivision")
    return SplineFunction((degree, degree), knots, C[..., None])


@lru_cache(maxsize=4096)
def _insertion(U: bytes, degree: int, extra: bytes):
    """Knot insertion (new knots, matrix) for a knot vector and knots to insert, cached: cells repeat them."""
    return kn.insertion_matrix(np.frombuffer(U), degree, np.frombuffer(extra))


def _insert(f: SplineFunction, d: int, extra) -> SplineFunction:
    """``f`` with the knots ``extra`` inserted along direction d (exact)."""
    U, R = _insertion(np.asarray(f.knots[d], float).tobytes(), int(f.degrees[d]), np.asarray(extra, float).tobytes())
    knots = list(f.knots)
    knots[d] = U
    return SplineFunction(f.degrees, knots, kn.apply_along(f.coefficients, d, R))


def _missing(want, have) -> np.ndarray:
    """Knots of ``want`` (with multiplicity) not present in ``have`` (values compared to 1e-12)."""
    return np.frombuffer(_missing_cached(np.asarray(want, float).tobytes(), np.asarray(have, float).tobytes()))


@lru_cache(maxsize=4096)
def _missing_cached(want: bytes, have: bytes) -> bytes:
    want, have = np.frombuffer(want), np.frombuffer(have)
    w, wc = np.unique(np.round(np.asarray(want, float), 12), return_counts=True)
    h, hc = np.unique(np.round(np.asarray(have, float), 12), return_counts=True)
    pos = np.clip(np.searchsorted(h, w), 0, max(len(h) - 1, 0))
    present = np.where((len(h) > 0) & (h[pos] == w if len(h) else False), hc[pos] if len(h) else 0, 0)
    return np.repeat(w, np.maximum(wc - present, 0)).astype(float).tobytes()


def boolean_sum(faces, degree, box, rim) -> SplineFunction:
    """Volumetric Boolean sum of six scalar faces with the constant rim ``rim``: P_u + P_v + P_w - 2 rim (on the net).

    ``faces``: {face name: surface over [0, 1]^2}; ``box``: the cell's parameter box (3, 2).
    """
    knots = []
    for k in range(3):  # the union of the knots of the four faces spanning direction k
        users = [(f, [j for j in range(3) if j != FACE_NAMES.index(f) // 2].index(k)) for f in FACE_NAMES
                 if FACE_NAMES.index(f) // 2 != k]
        allk = [faces[f].knots[d] for f, d in users]
        U = allk[0]
        for V in allk[1:]:
            U = np.sort(np.concatenate([U, _missing(V, U)]))
        knots.append(U)
    for f in FACE_NAMES:  # refine every face to the cell's knots
        k = FACE_NAMES.index(f) // 2
        rest = [j for j in range(3) if j != k]
        for d in range(2):
            extra = _missing(knots[rest[d]], faces[f].knots[d])
            if len(extra):
                faces[f] = _insert(faces[f], d, extra)
    g = [kn.greville(U, degree) for U in knots]
    C = -2.0 * rim * np.ones(tuple(len(x) for x in g))
    for k in range(3):
        lo, hi = faces[FACE_NAMES[2 * k]].coefficients[..., 0], faces[FACE_NAMES[2 * k + 1]].coefficients[..., 0]
        t = np.moveaxis(g[k][:, None, None], 0, 0)  # (n_k, 1, 1)
        term = (1 - t) * lo[None] + t * hi[None]  # (n_k, n_a, n_b) with a < b the remaining directions
        C += np.moveaxis(term, 0, k)
    return SplineFunction((degree,) * 3, [box[k, 0] + (box[k, 1] - box[k, 0]) * knots[k] for k in range(3)],
                          C[..., None])
