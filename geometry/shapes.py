"""Named example shapes used by the demonstrations and benchmarks (re-exported by :mod:`geometry.primitives`)."""

from __future__ import annotations

import numpy as np

from . import knots as kn
from .bspline import BSpline
from .errors import SplineError

__all__ = ["duck"]

# (x along the body, centre height, half width, half height) of the cross-sections, tail to beak
_DUCK_SECTIONS = np.array([
    [0.00, 0.35, 0.030, 0.020],   # tail tip: nearly singular
    [0.25, 0.30, 0.250, 0.180],
    [0.60, 0.25, 0.420, 0.320],   # body
    [1.00, 0.25, 0.450, 0.340],
    [1.35, 0.35, 0.300, 0.250],
    [1.60, 0.60, 0.140, 0.140],   # neck, rising
    [1.85, 0.80, 0.200, 0.180],   # head
    [2.10, 0.82, 0.030, 0.030],   # beak tip: nearly singular
])


def duck(length: float = 2.1, channels=None) -> BSpline:
    """A duck-like trivariate (Massarwi et al. 2018, Figs. 14-16): curved, tapered, nearly singular at both ends.

    Degrees (2, 2, 3): u across the body (y), v upwards (z), w along the body
    (x, from the tail to the beak), ``length`` long (model units); each
    cross-section is a rounded square (edge midpoints pushed out by 20%) on a
    curved axis.  The ends shrink to a few hundredths of the body's width, as
    the paper's duck, so that tiles there nearly vanish; the map stays regular.
    ``channels``: {name: constant} extra components.
    """
    if not (np.isfinite(length) and length > 0):
        raise SplineError(f"duck length must be positive, got {length!r}")
    sec = _DUCK_SECTIONS.copy()
    sec[:, 0] *= length / sec[-1, 0]
    s = np.array([-1.0, 0.0, 1.0])
    bulge = np.array([1.0, 1.2, 1.0])  # the middle row and column bulge: a rounded cross-section
    cp = np.zeros((3, 3, len(sec), 3))
    for k, (x, zc, hw, hh) in enumerate(sec):
        cp[:, :, k, 0] = x
        cp[:, :, k, 1] = (s[:, None] * hw) * bulge[None, :]
        cp[:, :, k, 2] = zc + (s[None, :] * hh) * bulge[:, None]
    extra = dict(channels or {})
    if extra:
        cp = np.concatenate([cp] + [np.full(cp.shape[:-1] + (1,), float(v)) for v in extra.values()], axis=-1)
    U = kn.uniform_knots(2, 1)
    W = kn.uniform_knots(3, len(sec) - 3)
    return BSpline((2, 2, 3), [U, U, W], cp, channels=tuple(extra))
