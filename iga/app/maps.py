"""Deformation maps a pipeline may name (``[map] primitive = ...``): built-in primitives and the heat-sink maps, and
the demo heat sinks' configuration (:func:`heat_sink_config`, ``iga demo heat-sink``).

All lengths in metres.  The heat-sink maps are those of Massarwi et al. 2018
(Section 8, Fig. 11).
"""

from __future__ import annotations

from math import pi

from geometry import BSpline
from geometry.errors import show
from geometry import primitives as pr
from geometry.shapes import examples as shapes

from iga.errors import ProblemError

__all__ = ["MAPS", "circular_heat_sink_map", "vertical_heat_sink_map", "heat_sink_config"]


def circular_heat_sink_map(r_in=0.02, r_out=0.06, height=0.03, twist=pi / 8) -> BSpline:
    """Twisted cylindrical shell (m): u around the axis, v along it, w radial (Massarwi et al. 2018, Fig. 11(a))."""
    shell = pr.annulus(r_in, r_out, height, angle=2 * pi, exact=True)  # (angle, radius, z)
    return pr.twisted(shell, twist).permute([0, 2, 1])  # (angle, z, radius): right-handed


def vertical_heat_sink_map(width=0.06, depth=0.06, height=0.03) -> BSpline:
    """Box base of the vertical heat sink (m), w upwards (Massarwi et al. 2018, Fig. 11(c)-(d))."""
    return pr.box((width, depth, height), degrees=(2, 2, 2))


MAPS = {"circular_heat_sink": circular_heat_sink_map, "vertical_heat_sink": vertical_heat_sink_map,
        "box": pr.box, "annulus": pr.annulus, "duck": shapes.duck, "cylinder": shapes.cylinder}


def heat_sink_config(variant: str = "circular", levels: int | None = None, refine: int = 0,
                     out: str = "heat-sink-out", stress: bool = False, transient: bool = False) -> dict:
    """The heat-sink analysis of Massarwi et al. 2018 (Section 8, Figs. 11 and 18) as a pipeline configuration.

    Aluminium (205 W/(m K)) at the heated face graded to stainless steel
    (54 W/(m K)) away from it; inlet flux 1515.8 W/m^2 on the inner ring
    (circular) or the bottom face (vertical); convection h = 5 W/(m^2 K) to
    air at 30 C on every other external face.  ``stress``: the thermal stress too (thermo-elastic), with
    E, nu and alpha graded like the conductivity: aluminium (69 GPa, 0.33, 23e-6 1/K) at the heated face to
    stainless steel (193 GPa, 0.29, 17.3e-6 1/K) away from it; free to expand, held only against rigid
    motion (:meth:`iga.ElasticityProblem.hold_rigid`), stress free at 20 C.  ``transient``: the sink switched on
    in air at 20 C, starting at 20 C (rho c 2.4e6 J/(m^3 K), aluminium), stepped by adaptive BDF2 (1e-3 K a
    step) until its hottest point has risen by 95% of its steady rise; a ParaView series and the warm-up
    curve.
    """
    if transient and stress:
        raise ProblemError("the transient demo computes no stress; drop --stress or --transient")
    if variant not in ("circular", "vertical"):
        raise ProblemError(f"variant must be 'circular' or 'vertical', got {show(variant)}")
    circ = variant == "circular"
    grading = [{"channel": "k", "near": 205.0, "far": 54.0, "face": "wmin"}]
    if stress:
        grading += [{"channel": c, "near": a, "far": b, "face": "wmin"}
                    for c, a, b in (("E", 69e9, 193e9), ("nu", 0.33, 0.29), ("alpha", 23e-6, 17.3e-6))]
    cfg = {
        "map": {"primitive": "circular_heat_sink" if circ else "vertical_heat_sink", "grading": grading},
        "tile": {"library": "heat_sink_t1" if circ else "heat_sink_t2"},
        "paving": {"scheme": "hierarchical", "counts": [4, 1] if circ else [4, 4],
                   "levels": levels if levels is not None else (3 if circ else 2), "scale": 0.5},
        "material": {"conductivity": "k"},
        "bc": [{"kind": "neumann", "tag": "branch-in", "value": 1515.8},
               {"kind": "robin", "tag": "exterior", "h": 5.0, "ambient": 30.0}],
        "solver": {"method": "auto", "tol": 1e-10, "refine": refine},
        "output": {"dir": out, "name": "heat_sink", "vtu": True, "png": True},
    }
    if transient:
        cfg["bc"][1]["ambient"] = 20.0
        cfg["material"]["capacity"] = 2.4e6
        cfg["physics"] = {"kind": "transient-heat"}
        # 1e-3 K a step: the 95% time within 0.3% of the converged one (58.7, 59.39, 59.55 min at 1e-2, 1e-3,
        # 1e-4 K: 38, 67, 126 steps)
        cfg["time"] = {"end": "steady", "tolerance": 1e-3, "initial": 20.0, "fraction": 0.95}
    if stress:
        cfg["physics"] = {"kind": "thermo-elastic", "youngs": "E", "poisson": "nu", "expansion": "alpha",
                          "reference": 20.0, "hold_rigid": True}
    return cfg
