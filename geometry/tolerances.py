"""The toolkit's tolerances, one name per meaning.

Three kinds, each relative to the scale it is compared with:

* **geometric**: lengths, relative to the size of the model, patch or tile
  they belong to (unit-cube tiles: absolute);
* **parametric**: parameter values, relative to the width of their domain
  (knot vectors normalised to [0, 1]: absolute);
* **algebraic**: matrix entries, pivots and residuals, relative to the
  largest magnitude they are compared with.

Everything the toolkit builds is exact up to floating-point round-off
(compositions, knot insertion, degree elevation), so these tolerances separate
"equal, up to the rounding of a few dozen operations" from "different"; they
are not modelling accuracies.
"""

from __future__ import annotations

import numpy as np
from geometry.numbers import TINY

__all__ = ["COINCIDENT", "INTERFACE", "CONTACT", "ON_DOMAIN", "SAME_KNOT", "SAME_SAMPLE", "SNAP", "ROUNDOFF",
           "RANK", "CONSISTENT", "SINGULAR", "same_knots", "same_space", "model_size"]

# ---------------------------------------------------------------- geometric (x size)
COINCIDENT = 1e-9
"""Points, planes and control points closer than this (x size) are one: tile walls on a cell face, cap
and seal plates on a plane, a V-model's inside test, knots of a composed tube."""

INTERFACE = 1e-8
"""Face corners and centres of two patches closer than this (x the model's size, :func:`model_size`) are one
shared face: composing tiles into a map rounds each copy's corners differently, by up to ~1e-12 of the
model, and a user may give faces that meet to ~1e-9."""

CONTACT = 1e-7
"""Free faces closer than this (x size) touch: a face lying on another without an interface is refused
(coarser than :data:`INTERFACE`, so that nearly-touching faces are refused rather than missed)."""

# ---------------------------------------------------------------- parametric (x domain width)
ON_DOMAIN = 1e-12
"""A parameter this close outside its domain is on the boundary (clipped), farther is outside."""

SAME_KNOT = 1e-12
"""Knot values closer than this (normalised to [0, 1]) are one knot: two faces with such knot vectors
have one spline space."""

SAME_SAMPLE = 1e-9
"""Normalised sample parameters closer than this are one sample (a sampled grid conforming across
patches; the weld of written points is finer)."""

SNAP = 1e-10
"""A computed parameter within this (x its range) of a known value (a knot, a loop's start, a domain
side, a layer plane) is that value: box ends and loop ends computed in floating point."""

# ---------------------------------------------------------------- algebraic (x largest magnitude)
ROUNDOFF = 1e-14
"""Entries below this (x the largest, or absolute for O(1) coefficients such as knot-insertion
weights) are round-off zeros and are dropped."""

RANK = 1e-10
"""Pivots below this (x the largest) make a system rank-deficient (column-pivoted QR of constraints)."""

CONSISTENT = 1e-10
"""Two rows prescribing one unknown that differ by more than this contradict each other."""

SINGULAR = 1e-12
"""A 3 x 3 determinant below this (x the largest entry cubed) is zero: a placement or Jacobian that
flattens its patch."""


def model_size(points) -> float:
    """The size geometric tolerances scale with: the extent of ``points`` (..., 3), its largest side, but not
    below 1e-6 of their distance from the origin (where the round-off of the coordinates themselves lives).
    A model a micrometre wide is measured in micrometres, not in metres."""
    pts = np.asarray(points, float).reshape(-1, 3)
    if not len(pts):
        return 1.0
    extent = float(np.ptp(pts, axis=0).max())
    return max(extent, 1e-6 * float(np.abs(pts).max()), TINY)


def same_knots(U, V) -> bool:
    """Whether two knot vectors are one knot vector up to :data:`SAME_KNOT` of their (normalised) width."""
    U, V = np.asarray(U, float), np.asarray(V, float)
    if U.shape != V.shape:
        return False
    wu, wv = U[-1] - U[0], V[-1] - V[0]
    if not (wu > 0 and wv > 0):
        return bool(np.array_equal(U, V))
    return bool(np.abs((U - U[0]) / wu - (V - V[0]) / wv).max() <= SAME_KNOT)


def same_space(a, b) -> bool:
    """Whether two tensor spline spaces, each [(knots, degree)] per direction in order, are one space:
    equal degrees and :func:`same_knots` in every direction (the one definition of "same face space")."""
    return len(a) == len(b) and all(int(p) == int(q) and same_knots(U, V) for (U, p), (V, q) in zip(a, b))
