"""The sections of a pipeline that wrap its steady heat solve in a loop: [adapt] and [design].

    [adapt]   tolerance = relative energy-norm error, max_unknowns = n, marking = fraction, refine = "h" | "p" | "hp" |
              "h-in-place", max_steps = n
    [design]  variables = "channel:NAME" | "map" | "parameters", objective = "temperature_norm" | "mean_temperature"
              (heat) | "compliance" | "von_mises_norm" (elasticity), p, tag, bounds = [low, high], mean (a channel),
              move, hold (the map), iterations

[adapt] solves by :func:`iga.adaptivity.loop.adaptive_solve` (the summary holds every step and why the loop
stopped, the VTU the refinement of every patch); [design] by :func:`iga.design.optimize` (the summary holds the
objective before and after and every iteration, the VTU the final design with its channel).
"""

from __future__ import annotations

from iga.app.config_checks import choice, fail, integer, number, table
from iga.app.config_schema import allowed, filled, required
from iga.errors import ProblemError
from iga.shape_design import valid_axes

__all__ = ["adapt_section", "design_section"]

OBJECTIVES = ("temperature_norm", "mean_temperature")
ELASTIC_OBJECTIVES = ("compliance", "von_mises_norm")


def adapt_section(config: dict, kind: str) -> dict | None:
    """The checked [adapt] section (None when absent); only a steady heat analysis adapts."""
    if "adapt" not in config:
        return None
    if kind != "heat":
        raise ProblemError(f"config section adapt refines a steady heat analysis (physics.kind = 'heat'), not "
                           f"{kind!r}; drop [adapt] or the other physics")
    a = filled("adapt", table(config["adapt"], "adapt", allowed("adapt"), required("adapt")))
    return {"tolerance": number(a["tolerance"], "adapt.tolerance", lo=0),
            "max_unknowns": None if a["max_unknowns"] is None else integer(a["max_unknowns"], "adapt.max_unknowns", 1),
            "marking": _marking(a["marking"]),
            "refine": choice(a["refine"], "adapt.refine", ("h", "h-in-place", "p", "hp")),
            "max_steps": integer(a["max_steps"], "adapt.max_steps", 1), "goal": _goal(a["goal"])}


def _goal(v) -> list:
    """adapt.goal: the tags whose heat flows the loop converges (empty: the energy norm)."""
    if not (isinstance(v, list) and all(isinstance(t, str) and t.strip() for t in v)):
        fail("adapt.goal", f"must be a list of tags (Robin faces whose heat flows to converge), got {v!r}")
    return list(v)


def _marking(v) -> float:
    m = number(v, "adapt.marking", lo=0)
    if m > 1:
        fail("adapt.marking", f"must lie in (0, 1] (the share of the squared estimate the marked patches carry), "
             f"got {m:g}")
    return m


def design_section(config: dict, kind: str, material) -> dict | None:
    """The checked [design] section (None when absent): a steady heat analysis whose conductivity is the channel
    the variables name, or an elastic one whose Young's modulus is (``material``: that coefficient's spec)."""
    if "design" not in config:
        return None
    if kind not in ("heat", "elasticity"):
        raise ProblemError(f"config section design optimises a steady heat analysis or an elastic one "
                           f"(physics.kind = 'heat' or 'elasticity'), not {kind!r}")
    if "adapt" in config:
        raise ProblemError("config sections adapt and design cannot both drive the solve; drop one")
    d = filled("design", table(config["design"], "design", allowed("design"), required("design")))
    wrt = d["variables"]
    heat = kind == "heat"
    common = {"variables": wrt,
              "objective": choice(d["objective"], "design.objective", OBJECTIVES if heat else ELASTIC_OBJECTIVES),
              "p": number(d["p"], "design.p", lo=1, open_lo=False), "tag": d["tag"],
              "iterations": integer(d["iterations"], "design.iterations", 1)}
    if not heat and d["tag"] is not None:
        fail("design.tag", "belongs to the heat outputs (a face's mean or norm of the temperature); the elastic ones "
             "are over the whole model: drop it")
    if d["keep_fraction"] is not False and not (isinstance(wrt, str) and wrt.startswith("channel:")):
        fail("design.keep_fraction", "belongs to a channel design of a macro model; drop it")
    if wrt != "map" and d["axes"] != "xyz":
        fail("design.axes", "belongs to a shape design (variables = \"map\"); drop it")
    if wrt == "map":
        return {**common, **_shape_design(d)}
    if wrt == "parameters":
        return {**common, **_parameter_design(d, config)}
    if not (isinstance(wrt, str) and wrt.startswith("channel:") and len(wrt) > len("channel:")):
        fail("design.variables", f"must be \"channel:NAME\" (the map's channel NAME the conductivity reads), "
             f"\"map\" (its control points) or \"parameters\" (the field of a field_graded paving), got {wrt!r}")
    coefficient = "material.conductivity" if heat else "physics.youngs"
    if wrt.split(":", 1)[1] != material:
        fail("design.variables", f"names the channel {wrt.split(':', 1)[1]!r}, but {coefficient} is "
             f"{material!r}; the design changes the channel {coefficient} reads")
    for key in ("move", "hold"):
        if d[key]:
            fail(f"design.{key}", "belongs to a shape design (variables = \"map\"); drop it")
    keep = d["keep_fraction"]
    if not isinstance(keep, bool) or (keep and heat):
        fail("design.keep_fraction", f"must be true or false, and true only for an elastic macro model "
             f"(physics.macro), got {keep!r}")
    low, high = _bounds(d["bounds"], "W/(m K)" if heat else "Pa, or the macro channel's units")
    mean = None if d["mean"] is None else number(d["mean"], "design.mean", lo=0)
    if mean is not None and keep:
        fail("design.mean", "and design.keep_fraction both constrain the design: keep one")
    if mean is not None and not low <= mean <= high:
        fail("design.mean", f"{mean:g} cannot be met within bounds [{low:g}, {high:g}]")
    return {**common, "bounds": (low, high), "mean": mean, "keep_fraction": keep}


def _bounds(b, unit: str) -> tuple:
    """design.bounds: [low, high] with 0 <= low < high."""
    if not (isinstance(b, list) and len(b) == 2):
        fail("design.bounds", f"must be [low, high] ({unit}), got {b!r}")
    low, high = number(b[0], "design.bounds[0]", lo=0), number(b[1], "design.bounds[1]", lo=0)
    if not low < high:
        fail("design.bounds", f"must be [low, high] with low < high, got {b!r}")
    return low, high


def _hold(hold) -> list:
    """design.hold: a list of the map's faces."""
    faces = ("umin", "umax", "vmin", "vmax", "wmin", "wmax")
    if not (isinstance(hold, list) and all(isinstance(f, str) and f in faces for f in hold)):
        fail("design.hold", f"must be a list of the map's faces {list(faces)}, got {hold!r}")
    return list(hold)


def _parameter_design(d, config: dict) -> dict:
    """The keys of a parameter design (variables = "parameters"): ``bounds`` of the field's control values and
    ``hold``; the paving must be field_graded with a number or a channel as its field (a formula has no control
    values)."""
    paving = config.get("paving", {}) if isinstance(config.get("paving"), dict) else {}
    if paving.get("scheme") != "field_graded" and not (paving.get("scheme") == "hierarchical" and "leaves" in paving):
        fail("design.variables", "\"parameters\" designs the field of a field_graded paving or of a hierarchical "
             "one's graded leaves; set paving.scheme = \"field_graded\" or paving.leaves and paving.field (got "
             f"scheme {paving.get('scheme')!r})")
    if isinstance(paving.get("field"), dict):
        fail("design.variables", "\"parameters\" needs paving.field as a number or a channel of the map (its "
             "control values are the variables); a formula has none")
    for key in ("move", "mean"):
        if d[key] is not None:
            fail(f"design.{key}", "belongs to another design; a parameter design takes bounds and hold")
    if d["bounds"] is None:
        fail("design.bounds", "is required for variables = \"parameters\": [low, high] of the field's control "
             "values, inside the tile family's range (e.g. [0.15, 0.6] arm widths)")
    return {"bounds": _bounds(d["bounds"], "the field's units"), "hold": _hold(d["hold"])}


def _shape_design(d) -> dict:
    """The keys of a shape design (variables = "map"): ``move`` (m) and ``hold`` (faces of the map)."""
    for key in ("bounds", "mean"):
        if d[key] is not None:
            fail(f"design.{key}", "belongs to a channel design; a shape design (variables = \"map\") takes move "
                 "(m) and hold")
    if d["move"] is None:
        fail("design.move", "is required for variables = \"map\": the largest move of a control point "
             "coordinate (m)")
    axes = d["axes"]
    if not valid_axes(axes):
        fail("design.axes", f"must name the coordinates that move, some of x, y, z once each (e.g. \"z\"), got "
             f"{axes!r}")
    return {"move": number(d["move"], "design.move", lo=0), "hold": _hold(d["hold"]), "axes": axes}
