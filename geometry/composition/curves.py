"""Curves crossing the outer map's knot lines: split at the crossings, compose the pieces, join them.

A curve is split at the parameters where one of its coordinates equals an
interior breakpoint of the outer map (roots of the coordinate's Bernstein
polynomial per curve segment, its ends included: a joint of the curve can
lie on the knot line).  Each piece's image then lies in one knot span
of the outer map, which is located from the piece's midpoint: its control
polygon may still straddle the knot line (the convex hull is not the curve),
and the composition with the span's polynomial piece is exact regardless.
The composed pieces are elevated to one degree and joined C0 into one
B-spline, rational pieces scaled so that each joint has one weight.
"""

from __future__ import annotations

from math import comb

import numpy as np

from geometry.bspline import BSpline
from geometry.tolerances import ON_DOMAIN

__all__ = ["crossings", "compose_curve_split"]


def crossings(curve: BSpline, k: int, value: float, bezier=None) -> np.ndarray:
    """Curve parameters where coordinate ``k`` equals ``value`` (roots per Bezier segment); ``bezier``: the
    curve's ``bezier_patches(homogeneous=True)`` when the caller has them (one extraction for many values)."""
    patches, boxes = curve.bezier_patches(homogeneous=True) if bezier is None else bezier
    roots = []
    for e in range(patches.shape[0]):  # per curve segment (few), roots of a small polynomial
        a, t0, t1 = patches[e], boxes[e, 0, 0], boxes[e, 0, 1]
        p = a.shape[0] - 1
        num = a[:, k] - value * (a[:, -1] if curve.is_rational else 1.0)
        # Bernstein -> power basis in the local variable s
        pw = np.zeros(p + 1)
        for i in range(p + 1):
            for j in range(i, p + 1):
                pw[j] += num[i] * comb(p, i) * comb(p - i, j - i) * (-1) ** (j - i)
        r = np.roots(pw[::-1]) if np.any(pw[1:]) else np.array([])
        r = r[np.abs(r.imag) < 1e-9].real
        # a crossing at a segment's end (a joint of the curve on the knot line) is a cut too: the segments on
        # either side lie in different spans (callers drop the curve's own ends)
        r = r[(r > -ON_DOMAIN) & (r < 1 + ON_DOMAIN)]
        r = np.where(r < ON_DOMAIN, 0.0, np.where(r > 1 - ON_DOMAIN, 1.0, r))  # a root at a joint is the joint
        roots += list(t0 + r * (t1 - t0))
    return np.array(roots)


def compose_curve_split(outer: BSpline, curve: BSpline, compose_piece) -> BSpline:
    """``outer(curve)`` for a curve crossing knot lines; ``compose_piece(outer, piece)`` composes one piece
    whose image lies in one knot span (see the module notes)."""
    breaks = [outer.breakpoints(k) for k in range(outer.dim)]
    params = []
    bezier = curve.bezier_patches(homogeneous=True)
    for k in range(outer.dim):
        lo_k, hi_k = bezier[0][..., k].min(), bezier[0][..., k].max()  # (homogeneous: w = 1 for B-splines)
        for v in breaks[k][1:-1]:
            if curve.is_rational or lo_k <= v <= hi_k:  # the curve lies in its control polygon's hull
                params += list(crossings(curve, k, v, bezier))
    lo, hi = curve.domain[0]
    cuts = np.unique(np.asarray(params, float))
    tol = ON_DOMAIN * (hi - lo)
    if len(cuts):  # none: the control polygon crosses a knot plane while the curve does not (one piece)
        cuts = cuts[np.r_[True, np.diff(cuts) > tol]]  # one cut where roots of neighbouring segments meet
    cuts = cuts[(cuts > lo + tol) & (cuts < hi - tol)]
    edges = np.r_[lo, cuts, hi]
    pieces = [curve.extract([[a, b]]) for a, b in zip(edges[:-1], edges[1:])]
    composed = [compose_piece(outer, piece) for piece in pieces]
    P = max(c.degrees[0] for c in composed)
    composed = [c.elevate(0, P - c.degrees[0]) for c in composed]
    rational = any(c.is_rational for c in composed)
    homs, knots = [], [np.full(P + 1, lo)]
    for i, c in enumerate(composed):
        h = c.homogeneous if (c.is_rational or not rational) else np.concatenate([c.homogeneous, np.ones((c.shape[0], 1))], 1)
        homs.append(h if i == 0 else h[1:])
        inner_knots = c.knots[0][P + 1 : -P - 1]
        a, b = edges[i], edges[i + 1]
        knots.append(a + (inner_knots - c.knots[0][0]) * (b - a) / (c.knots[0][-1] - c.knots[0][0]))
        knots.append(np.full(P, b) if i < len(composed) - 1 else np.full(P + 1, hi))
    if rational:
        # scale each piece's homogeneous coefficients so the shared joint has one weight
        scaled = [homs[0]]
        for i in range(1, len(homs)):
            prev_w = scaled[-1][-1, -1]
            first = composed[i].homogeneous[0] if composed[i].is_rational else np.r_[composed[i].control_points[0], 1.0]
            scaled.append(homs[i] * (prev_w / first[-1]))
        homs = scaled
    hom = np.concatenate(homs, axis=0)
    U = np.concatenate(knots)
    return BSpline._from_hom((P,), [U], hom, rational, channels=composed[0].channels)


