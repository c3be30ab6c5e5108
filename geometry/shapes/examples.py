"""Named example shapes used by the demonstrations and benchmarks (re-exported by :mod:`geometry.primitives`)."""

from __future__ import annotations

import numpy as np

from geometry import knots as kn
from geometry.bspline import BSpline
from geometry.errors import SplineError, show
from geometry.numbers import is_real

__all__ = ["duck", "cylinder"]

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


def with_channels(cp: np.ndarray, channels) -> tuple[np.ndarray, tuple]:
    """``cp`` with one constant column per channel of ``channels`` ({name: finite number} or None)."""
    if channels is None:
        return cp, ()
    if not isinstance(channels, dict):
        raise SplineError(f"channels must be a dict {{name: constant}}, e.g. {{'k': 205.0}}, got {show(channels)}")
    extra = []
    for name, v in channels.items():
        ok = is_real(v) and np.isfinite(v)
        if not ok:
            raise SplineError(f"channel {show(name)} must be a finite number (one value over the whole primitive), got "
                              f"{show(v)}; for a field that varies, set its control values with "
                              "BSpline.with_channel(name, values)")
        extra.append(np.full(cp.shape[:-1] + (1,), float(v)))
    if not extra:
        return cp, ()
    return np.concatenate([cp] + extra, axis=-1), tuple(channels)


def duck(length: float = 2.1, channels=None) -> BSpline:
    """A duck-like trivariate (Massarwi et al. 2018, Figs. 14-16): curved, tapered, nearly singular at both ends.

    Degrees (2, 2, 3): u across the body (y), v upwards (z), w along the body
    (x, from the tail to the beak), ``length`` long (model units); each
    cross-section is a rounded square (edge midpoints pushed out by 20%) on a
    curved axis.  The ends shrink to a few hundredths of the body's width, as
    the paper's duck, so that tiles there nearly vanish; the map stays regular.
    ``channels``: {name: constant} extra components.
    """
    if not is_real(length) or not (np.isfinite(length)
                                                                                         and length > 0):
        raise SplineError(f"duck length must be a positive number (model units), got {show(length)}")
    sec = _DUCK_SECTIONS.copy()
    sec[:, 0] *= length / sec[-1, 0]
    s = np.array([-1.0, 0.0, 1.0])
    bulge = np.array([1.0, 1.2, 1.0])  # the middle row and column bulge: a rounded cross-section
    cp = np.zeros((3, 3, len(sec), 3))
    for k, (x, zc, hw, hh) in enumerate(sec):
        cp[:, :, k, 0] = x
        cp[:, :, k, 1] = (s[:, None] * hw) * bulge[None, :]
        cp[:, :, k, 2] = zc + (s[None, :] * hh) * bulge[:, None]
    cp, names = with_channels(cp, channels)
    U = kn.uniform_knots(2, 1)
    W = kn.uniform_knots(3, len(sec) - 3)
    return BSpline((2, 2, 3), [U, U, W], cp, channels=names)


def cylinder(radius: float = 1.0, length: float = 4.0, axis: int = 2, centre=(0.0, 0.0, 0.0),
             n: int = 5) -> BSpline:
    """A solid cylinder as a regular trivariate (Hong and Elber 2021, Figs. 13-14: orthogonal cylinders).

    The cross-section is a biquadratic disk whose ``n`` x ``n`` control points are the square grid mapped
    by the elliptical grid mapping (x sqrt(1 - y^2 / 2), y sqrt(1 - x^2 / 2)): round to within 3% of
    the radius, with a positive Jacobian everywhere (an exact rational disk is singular at its corners,
    which paving refuses).  Degrees (2, 2, 1); the third parameter runs along ``axis`` (0, 1, 2) over
    ``length`` centred at ``centre`` (model units).
    """
    if not (radius > 0 and length > 0 and axis in (0, 1, 2) and n >= 3):
        raise SplineError(f"cylinder needs radius > 0, length > 0, axis 0/1/2 and n >= 3; got {radius}, {length}, "
                          f"{axis}, {n}")
    s = np.linspace(-1.0, 1.0, n)
    X, Y = np.meshgrid(s, s, indexing="ij")
    d = np.stack([X * np.sqrt(1 - Y**2 / 2), Y * np.sqrt(1 - X**2 / 2)], -1) * radius
    cp = np.zeros((n, n, 2, 3))
    others = [a for a in range(3) if a != axis]
    for k, z in enumerate((-length / 2, length / 2)):
        cp[:, :, k, others[0]] = d[..., 0]
        cp[:, :, k, others[1]] = d[..., 1]
        cp[:, :, k, axis] = z
    cp += np.asarray(centre, float)
    U = kn.uniform_knots(2, n - 2)
    return BSpline((2, 2, 1), [U, U, kn.uniform_knots(1, 1)], cp)

