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


import numpy as np

from geometry.cache import memo

from geometry import SplineFunction
from geometry import knots as kn
from geometry.faces import FACE_NAMES

from .errors import TilingError
from geometry.tolerances import SAME_KNOT

__all__ = ["merge_pieces", "boolean_sum", "grid_values", "scalar_surface"]


@memo(2048)
def _unit_basis(U: bytes, degree: int, x: bytes) -> np.ndarray:
    """Dense basis values (len(x), n) of knots U on [0, 1] at x (cached: cells repeat their relative samples)."""
    return kn.basis_matrix(np.frombuffer(U), degree, np.frombuffer(x)).toarray()


def grid_values(f: SplineFunction, axes) -> np.ndarray:
    """The scalar trivariate f on the grid of ``axes`` (tensor contractions with cached, normalised bases)."""
    B = []
    for U, p, x in zip(f.knots, f.degrees, axes):
        lo, hi = U[0], U[-1]
        B.append(_unit_basis(np.round((U - lo) / (hi - lo), 13).tobytes(), int(p),
                             np.clip(np.round((x - lo) / (hi - lo), 13), 0.0, 1.0).tobytes()))
    # direction 3, 2, then 1, each a matrix product on the array as it lies (no axis moves)
    return np.tensordot(B[0], B[1] @ (f.coefficients[..., 0] @ B[2].T), axes=(1, 0))


def scalar_surface(c, degree, box=((0.0, 1.0), (0.0, 1.0))) -> SplineFunction:
    """The bicubic (``degree``) scalar surface with the square coefficients ``c`` (n, n) (finite) on uniform
    knots over ``box`` ((lo, hi), (lo, hi)), lo < hi: knots valid by construction, built without the checks."""
    n = c.shape[0]
    U = _unit_knots(int(degree), int(n))
    # the unit box's knots: one shared object, so that the Boolean sum sees equal knots at once
    knots = [U if box[d][0] == 0.0 and box[d][1] == 1.0 else box[d][0] + (box[d][1] - box[d][0]) * U
             for d in range(2)]
    return SplineFunction._trusted((degree, degree), knots, c[..., None], False)


@memo(64)
def _unit_knots(degree: int, n: int) -> np.ndarray:
    """The uniform open knots of n coefficients of ``degree`` on [0, 1] (read-only, shared)."""
    U = kn.uniform_knots(degree, n - degree)
    U.setflags(write=False)
    return U


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


@memo(4096)
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


@memo(4096)
def _missing_cached(want: bytes, have: bytes) -> bytes:
    want, have = np.frombuffer(want), np.frombuffer(have)
    w, wc = np.unique(np.round(np.asarray(want, float), 12), return_counts=True)
    h, hc = np.unique(np.round(np.asarray(have, float), 12), return_counts=True)
    pos = np.clip(np.searchsorted(h, w), 0, max(len(h) - 1, 0))
    present = np.where((len(h) > 0) & (h[pos] == w if len(h) else False), hc[pos] if len(h) else 0, 0)
    return np.repeat(w, np.maximum(wc - present, 0)).astype(float).tobytes()


# per direction k: the faces spanning it, each with the index (0 or 1) of its own direction that runs along k
_SPANNING = tuple(tuple((f, [j for j in range(3) if j != i // 2].index(k)) for i, f in enumerate(FACE_NAMES)
                        if i // 2 != k) for k in range(3))


@memo(256)
def _greville(U: bytes, degree: int) -> np.ndarray:
    """Greville abscissae of the knots ``U`` (read-only: cached, cells repeat their knots)."""
    g = kn.greville(np.frombuffer(U), degree)
    g.setflags(write=False)
    return g


def boolean_sum(faces, degree, box, rim) -> SplineFunction:
    """Volumetric Boolean sum of six scalar faces with the constant rim ``rim``: P_u + P_v + P_w - 2 rim (on the net).

    ``faces``: {face name: surface over [0, 1]^2}; ``box``: the cell's parameter box (3, 2).
    """
    knots = []
    for k in range(3):  # the union of the knots of the four faces spanning direction k
        allk = [faces[f].knots[d] for f, d in _SPANNING[k]]
        U = allk[0]
        for V in allk[1:]:
            if V is not U:  # (validated knot vectors are shared objects: the same knots, mostly)
                U = np.sort(np.concatenate([U, _missing(V, U)]))
        knots.append(U)
    for i, f in enumerate(FACE_NAMES):  # refine every face to the cell's knots
        rest = [j for j in range(3) if j != i // 2]
        for d in range(2):
            if knots[rest[d]] is not faces[f].knots[d]:
                extra = _missing(knots[rest[d]], faces[f].knots[d])
                if len(extra):
                    faces[f] = _insert(faces[f], d, extra)
    g = [_greville(np.asarray(U, float).tobytes(), int(degree)) for U in knots]
    C = np.full(tuple(len(x) for x in g), -2.0 * rim)
    for k in range(3):
        lo, hi = faces[FACE_NAMES[2 * k]].coefficients[..., 0], faces[FACE_NAMES[2 * k + 1]].coefficients[..., 0]
        t = g[k][:, None, None]  # (n_k, 1, 1)
        term = (1 - t) * lo[None] + t * hi[None]  # (n_k, n_a, n_b) with a < b the remaining directions
        C += np.moveaxis(term, 0, k)
    # an increasing affine map of valid knots is valid: built without the checks
    mapped = [box[k, 0] + (box[k, 1] - box[k, 0]) * knots[k] for k in range(3)]
    return SplineFunction._trusted((degree,) * 3, mapped, C[..., None], False)
