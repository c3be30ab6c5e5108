"""Deformation maps of the heat-sink examples of Massarwi et al. 2018 (shared by the example and benchmark scripts).

Lengths in metres.  ``circular_map``: a twisted cylindrical shell with u
around the axis, v along the axis and w radial (Massarwi et al. 2018, Fig. 11(a): the fins grow
radially outwards from the inner ring).  ``vertical_map``: the box base of
the vertical heat sink (Fig. 11(c)-(d)), w upwards.
"""

from __future__ import annotations

from math import pi

import numpy as np

from geometry import BSpline, primitives as pr
from iga.app.pipeline import circular_heat_sink_map, vertical_heat_sink_map


def circular_map() -> BSpline:
    return circular_heat_sink_map()


def vertical_map() -> BSpline:
    return vertical_heat_sink_map()


def bent_map() -> BSpline:
    """A curved (2, 2, 2) map for Fig. 2(d)-like examples: a box bent upwards along u."""
    b = pr.box((2.0, 1.0, 1.0), degrees=(2, 2, 2))
    cp = b.control_points.copy()
    cp[1, :, :, 2] += 0.6
    cp[:, 1, :, 0] += 0.15
    return BSpline(b.degrees, b.knots, cp)


def fractal_map() -> BSpline:
    """A (3, 3, 2) map for the Fig. 3 fractal: a bulged block."""
    b = pr.box((2.0, 1.0, 2.0), degrees=(3, 3, 2))
    cp = b.control_points.copy()
    x = (cp[..., 0] - 1.0)
    cp[..., 2] += 0.3 * (1 - x**2) * (cp[..., 2] / 2.0)
    cp[..., 1] += 0.2 * np.sin(pi * cp[..., 0] / 2.0) * (cp[..., 1] - 0.5)
    return BSpline(b.degrees, b.knots, cp)
