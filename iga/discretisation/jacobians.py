"""Geometry checks of the analysis: the Jacobian determinant at Gauss points.

The evaluation of a patch's geometry through the chain rule,
x = D(A T(xi) + b), J = J_D A J_T, lives in :mod:`geometry.patches.chain`.
"""

from __future__ import annotations

import numpy as np

from iga.errors import ProblemError

__all__ = ["checked_det"]


def checked_det(det, what: str) -> tuple[float, float]:
    """Check Jacobian determinants; a sign change or a zero means a singular patch (ProblemError).

    Returns ``(min, max)`` of ``det`` (``(inf, -inf)`` when empty), from the
    two passes the check needs: min and max propagate NaN, and a zero or a
    sign change lies in [min, max].
    """
    if det.size == 0:
        return np.inf, -np.inf
    lo, hi = float(det.min()), float(det.max())
    if not (np.isfinite(lo) and np.isfinite(hi)):
        raise ProblemError(f"{what}: the geometry Jacobian is not finite at some quadrature points")
    if lo <= 0 <= hi:
        raise ProblemError(
            f"{what}: the geometry Jacobian vanishes or changes sign inside the patch (folded or degenerate "
            "geometry); check it with geometry.check_regular"
        )
    return lo, hi
