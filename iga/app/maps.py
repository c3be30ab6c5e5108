"""Deformation maps a pipeline may name (``[map] primitive = ...``): built-in primitives and the heat-sink maps.

All lengths in metres.  The heat-sink maps are those of Massarwi et al. 2018
(Section 8, Fig. 11).
"""

from __future__ import annotations

from math import pi

from geometry import BSpline
from geometry import primitives as pr
from geometry.shapes import examples as shapes

__all__ = ["MAPS", "circular_heat_sink_map", "vertical_heat_sink_map"]


def circular_heat_sink_map(r_in=0.02, r_out=0.06, height=0.03, twist=pi / 8) -> BSpline:
    """Twisted cylindrical shell (m): u around the axis, v along it, w radial (Massarwi et al. 2018, Fig. 11(a))."""
    shell = pr.annulus(r_in, r_out, height, angle=2 * pi, exact=True)  # (angle, radius, z)
    return pr.twisted(shell, twist).permute([0, 2, 1])  # (angle, z, radius): right-handed


def vertical_heat_sink_map(width=0.06, depth=0.06, height=0.03) -> BSpline:
    """Box base of the vertical heat sink (m), w upwards (Massarwi et al. 2018, Fig. 11(c)-(d))."""
    return pr.box((width, depth, height), degrees=(2, 2, 2))


MAPS = {"circular_heat_sink": circular_heat_sink_map, "vertical_heat_sink": vertical_heat_sink_map,
        "box": pr.box, "annulus": pr.annulus, "duck": shapes.duck, "cylinder": shapes.cylinder}
