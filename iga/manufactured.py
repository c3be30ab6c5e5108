"""Manufactured solutions for convergence studies (exact data in closed form).

``quarter_annulus()`` is the study of ``benchmarks/convergence.py``: the exact
NURBS quarter-annulus shell (r in [1, 2], height 1), variable conductivity
``k = 1 + (x^2 + y^2) / 2``, exact temperature
``T = exp(x/2) sin(0.7 y + 0.3 z)`` and source ``f = -div(k grad T)``
(grad k = (x, y, 0), lap T = -0.33 T).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np

from geometry import BSpline, primitives as pr


@dataclass(frozen=True)
class Manufactured:
    """A manufactured problem: geometry, conductivity k(x), exact temperature T(x), its gradient and the source f."""
    geometry: BSpline
    conductivity: Callable
    temperature: Callable
    gradient: Callable
    source: Callable


def quarter_annulus() -> Manufactured:
    """The exact NURBS quarter shell with k = 1 + (x^2 + y^2) / 2 and T = exp(x / 2) sin(0.7 y + 0.3 z) (module notes)."""
    def k(x):
        return 1 + 0.5 * (x[:, 0] ** 2 + x[:, 1] ** 2)

    def T(x):
        return np.exp(0.5 * x[:, 0]) * np.sin(0.7 * x[:, 1] + 0.3 * x[:, 2])

    def grad(x):
        e = np.exp(0.5 * x[:, 0])
        s, c = np.sin(0.7 * x[:, 1] + 0.3 * x[:, 2]), np.cos(0.7 * x[:, 1] + 0.3 * x[:, 2])
        return np.stack([0.5 * e * s, 0.7 * e * c, 0.3 * e * c], 1)

    def f(x):
        g = grad(x)
        return -(x[:, 0] * g[:, 0] + x[:, 1] * g[:, 1]) + 0.33 * k(x) * T(x)

    return Manufactured(pr.annulus(1.0, 2.0, 1.0), k, T, grad, f)
