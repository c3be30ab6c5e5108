"""Regularity of trivariate (and planar bivariate) maps: is the Jacobian never zero?

The Jacobian determinant of a polynomial map is itself a polynomial,

    |J| = < dT/du x dT/dv, dT/dw >,

which we form *exactly* in Bernstein form on every Bezier element with
products of derivative splines.  For a NURBS map ``T = X / w`` the sign of
``|J|`` equals the sign of the homogeneous determinant

    det [ (w, X, Y, Z); d/du (w, X, Y, Z); d/dv (...); d/dw (...) ] = w^4 |J|,

a polynomial as well.  Bernstein coefficients bound the polynomial (convex
hull property): all positive (or all negative) coefficients prove the sign;
corner coefficients are exact values, so two corners of opposite sign prove a
zero.  Inconclusive boxes are subdivided (de Casteljau) up to ``max_depth``
rounds, batched over all boxes.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import lru_cache

import numpy as np

from . import bernstein as bz
from .errors import SplineError
from .spline import SplineFunction

__all__ = ["check_regular", "RegularityResult", "jacobian_bezier"]


@dataclass
class RegularityResult:
    """Outcome of :func:`check_regular`.

    status : "regular", "singular" or "undecided"
    regular : True only when proven regular
    orientation : +1 / -1, the sign of the Jacobian where it is definite (0 if none)
    boxes : (K, d, 2) parameter boxes where the Jacobian vanishes or flips sign
        (singular) or where the test stayed inconclusive (undecided)
    jacobian_bounds : (lower, upper) bounds of the Jacobian polynomial's
        Bernstein coefficients (local element parameters), a cheap quality measure
    message : a sentence saying what was found and where
    """

    status: str
    orientation: int
    boxes: np.ndarray
    jacobian_bounds: tuple[float, float]
    message: str
    depth: int = field(default=0)

    @property
    def regular(self) -> bool:
        """True only when regularity is proven."""
        return self.status == "regular"

    def __bool__(self) -> bool:
        return self.regular


def _det(rows, ndim):
    """Determinant of a square matrix of Bernstein arrays by Laplace expansion with memoised minors.

    ``rows[i][j]``: (E, bern...) with all entries of a row of equal degree.
    """
    n = len(rows)

    @lru_cache(maxsize=None)
    def minor(r: int, cols: tuple[int, ...]):
        if len(cols) == 1:
            return rows[r][cols[0]]
        acc = None
        for j, c in enumerate(cols):
            rest = cols[:j] + cols[j + 1 :]
            term = bz.multiply(rows[r][c], minor(r + 1, rest), ndim)
            acc = term if acc is None else (acc + term if j % 2 == 0 else acc - term)
        return acc

    return minor(0, tuple(range(n)))


def jacobian_bezier(spline: SplineFunction):
    """Per-element Bernstein coefficients of the Jacobian determinant (or a positive multiple).

    Returns ``(J, boxes)``: J (E, q_1+1, ..., q_d+1), boxes (E, d, 2).  Uses the
    first ``d`` components as coordinates (d = 2: planar map in x, y).
    Derivatives are taken in local element coordinates, which scales each
    element's Jacobian by a positive constant and leaves every sign intact.
    """
    d = spline.dim
    if d not in (2, 3):
        raise SplineError(f"check_regular needs a planar surface or a trivariate, got a {d}-variate spline")
    hom, boxes = spline.bezier_patches(homogeneous=True)
    E = int(np.prod(hom.shape[:d]))
    hom = hom.reshape((E,) + hom.shape[d:])
    bern = hom.shape[1 : 1 + d]
    if spline.is_rational:
        comps = [hom[..., -1]] + [hom[..., c] for c in range(d)]  # (w, X, Y[, Z])
    else:
        comps = [hom[..., c] for c in range(d)]

    def deriv(a, k):
        return (bern[k] - 1) * np.diff(a, axis=1 + k)

    rows = [[deriv(c, k) for c in comps] for k in range(d)]
    if spline.is_rational:
        rows = [comps] + rows
    J = _det(rows, d)
    return J, boxes.reshape(E, d, 2)


def _corners(J, d):
    """Exact values at the 2^d corners of each box: the corner Bernstein coefficients."""
    ends = [np.array([0, J.shape[k + 1] - 1]) for k in range(d)]
    return J[np.ix_(np.arange(J.shape[0]), *ends)].reshape(J.shape[0], -1)


def check_regular(spline: SplineFunction, max_depth: int = 9, allow_zeros: bool = False) -> RegularityResult:
    """Decide whether ``spline`` (trivariate, or planar surface) has a non-vanishing Jacobian.

    Returns a :class:`RegularityResult`; ``bool(result)`` is True only when
    regularity is proven.  ``max_depth`` bounds the subdivision rounds (each
    round halves the undecided boxes along one direction, cycling u, v, w).

    ``allow_zeros``: prove only that the Jacobian never changes sign (it may
    vanish on a set of measure zero, e.g. a collapsed edge or the axis of a
    solid cylinder, where analysis still works); "singular" then means a
    proven fold (values of both signs) or a box where the Jacobian vanishes
    identically.
    """
    J, boxes = jacobian_bezier(spline)
    d = spline.dim
    lo_all, hi_all = float(J.min()), float(J.max())
    scale = max(abs(lo_all), abs(hi_all), 1e-300)
    pos_boxes, neg_boxes, zero_boxes = [], [], []
    depth = 0
    cur, cur_boxes = J, boxes
    while True:
        flat = cur.reshape(cur.shape[0], -1)
        corners = _corners(cur, d)
        mixed = (corners.max(axis=1) > 0) & (corners.min(axis=1) < 0)
        if allow_zeros:  # one-signed bounds prove no sign change; an identically zero box is degenerate
            pos = np.all(flat >= 0, axis=1) & np.any(flat > 0, axis=1)
            neg = np.all(flat <= 0, axis=1) & np.any(flat < 0, axis=1)
            zero_corner = np.all(flat == 0, axis=1)
        else:
            pos = np.all(flat > 0, axis=1)
            neg = np.all(flat < 0, axis=1)
            zero_corner = np.any(corners == 0, axis=1)
        pos_boxes.append(cur_boxes[pos])
        neg_boxes.append(cur_boxes[neg])
        crossing = (mixed | zero_corner) & ~pos & ~neg  # a zero is proven inside
        todo = ~(pos | neg | mixed | zero_corner)
        if depth >= max_depth or not (todo | crossing).any():
            zero_boxes.append(cur_boxes[crossing])
            undecided = cur_boxes[todo]
            break
        # keep splitting inconclusive boxes (to decide) and crossing boxes (to localise the zero set)
        todo = todo | crossing
        # split in half along direction depth % d (batched de Casteljau)
        k = depth % d
        q = cur.shape[1 + k] - 1
        L, R = bz.split_matrices(q, 0.5)
        sub = cur[todo]
        left = np.moveaxis(np.tensordot(L, np.moveaxis(sub, 1 + k, 0), axes=(1, 0)), 0, 1 + k)
        right = np.moveaxis(np.tensordot(R, np.moveaxis(sub, 1 + k, 0), axes=(1, 0)), 0, 1 + k)
        b = cur_boxes[todo]
        mid = 0.5 * (b[:, k, 0] + b[:, k, 1])
        bl, br = b.copy(), b.copy()
        bl[:, k, 1] = mid
        br[:, k, 0] = mid
        cur = np.concatenate([left, right])
        cur_boxes = np.concatenate([bl, br])
        depth += 1
    P = np.concatenate(pos_boxes)
    N = np.concatenate(neg_boxes)
    Z = np.concatenate(zero_boxes)
    def vol(B):
        return float(np.prod(B[:, :, 1] - B[:, :, 0], axis=1).sum()) if len(B) else 0.0

    orientation = 1 if vol(P) >= vol(N) else -1
    if vol(P) == 0 and vol(N) == 0:
        orientation = 0
    wrong = N if orientation > 0 else P
    bounds = (lo_all, hi_all)
    if len(Z) or (len(P) and len(N)):
        where = np.concatenate([Z, wrong])
        hull = np.stack([where[:, :, 0].min(0), where[:, :, 1].max(0)], axis=1)
        msg = (
            f"singular: the Jacobian vanishes or changes sign in {len(where)} parameter box(es) within "
            + " x ".join(f"{'uvw'[k]} in [{hull[k, 0]:.4g}, {hull[k, 1]:.4g}]" for k in range(d))
        )
        return RegularityResult("singular", orientation, where, bounds, msg, depth)
    if len(undecided):
        msg = (
            f"undecided after {depth} subdivision rounds: {len(undecided)} box(es) such as "
            f"{np.round(undecided[0], 6).tolist()} have Jacobian near zero (relative {abs(lo_all) / scale:.1e}); "
            "raise max_depth or inspect the map there"
        )
        return RegularityResult("undecided", orientation, undecided, bounds, msg, depth)
    msg = f"regular: the Jacobian is {'positive' if orientation > 0 else 'negative'} everywhere"
    return RegularityResult("regular", orientation, np.zeros((0, d, 2)), bounds, msg, depth)
