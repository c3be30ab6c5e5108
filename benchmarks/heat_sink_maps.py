"""Deformation maps of the seed's examples (shared by the example and benchmark scripts).

Lengths in metres.  ``circular_map``: a twisted cylindrical shell with u
around the axis, v along the axis and w radial (000 Fig. 11(a): the fins grow
radially outwards from the inner ring).  ``vertical_map``: the box base of
the vertical heat sink (Fig. 11(c)-(d)), w upwards.
"""

from __future__ import annotations

from math import pi

import numpy as np

from geometry import BSpline, primitives as pr


def circular_map(r_in=0.02, r_out=0.06, height=0.03, twist=pi / 8) -> BSpline:
    shell = pr.annulus(r_in, r_out, height, angle=2 * pi, exact=True)  # (angle, radius, z)
    return pr.twisted(shell, twist).permute([0, 2, 1])  # (angle, z, radius): right-handed


def vertical_map(width=0.06, depth=0.06, height=0.03) -> BSpline:
    return pr.box((width, depth, height), degrees=(2, 2, 2))


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
