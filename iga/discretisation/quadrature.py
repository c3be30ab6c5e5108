"""Gauss-Legendre quadrature per Bezier element.

Rule: in each parametric direction, ``g = p + 1 + extra`` Gauss-Legendre
points per element, where ``p`` is the degree of the solution space in that
direction and ``extra`` (default 0) is a user option (``HeatProblem(...,
quadrature_extra=...)``).  ``p + 1`` points integrate the stiffness of an
affinely mapped element with constant conductivity exactly and keep the
optimal convergence rates on curved (NURBS or composed) geometry, where the
integrand is rational and no finite rule is exact; raise ``extra`` for very
distorted or high-degree composed geometry.  Points and weights come from
``numpy.polynomial.legendre.leggauss``.
"""

from __future__ import annotations


import numpy as np

from geometry.cache import memo


@memo(64)
def gauss_legendre(n: int) -> tuple[np.ndarray, np.ndarray]:
    """``n`` Gauss-Legendre points and weights on [0, 1] (read-only arrays)."""
    x, w = np.polynomial.legendre.leggauss(n)
    x, w = 0.5 * (x + 1.0), 0.5 * w
    x.setflags(write=False)
    w.setflags(write=False)
    return x, w


def element_rule(breaks: np.ndarray, n: int) -> tuple[np.ndarray, np.ndarray]:
    """Points (E * n,) and weights (E * n,) of the ``n``-point rule on every element of ``breaks``."""
    x, w = gauss_legendre(n)
    h = np.diff(breaks)
    pts = breaks[:-1, None] + h[:, None] * x[None, :]
    wts = h[:, None] * w[None, :]
    return pts.ravel(), wts.ravel()
