"""The [physics] section of a pipeline with its [[support]] and [[load]] tables (the elastic analyses)."""

from __future__ import annotations

import numpy as np

from geometry.errors import show

from iga.app.config_checks import choice as _choice, fail as _fail, formula as _formula, formula_table as _formula_table
from iga.app.config_checks import number as _number, string as _str
from iga.app.config_checks import table as _table, tag as _tag
from iga.app.config_schema import allowed, default, required
from iga.errors import ProblemError

__all__ = ["PHYSICS", "physics"]

PHYSICS = ("heat", "transient-heat", "elasticity", "thermo-elastic", "none")


def _material_value(v, where, lo=None, hi=None):
    """A number (checked against (lo, hi)), a channel name or ``{formula = "..."}`` (checked where evaluated)."""
    if isinstance(v, dict):
        return _formula_table(v, where)
    return _str(v, where) if isinstance(v, str) else _number(v, where, lo=lo, hi=hi)


def physics(config, surface: str | None = None) -> dict:
    """The checked [physics] section with its [[support]] and [[load]] tables (elastic kinds).

    ``surface``: why the configured model has no volume (e.g. "the random implicit structure is a surface (the
    boundary of an implicit solid)"), or None for a volumetric model; such a model takes no analysis."""
    t = _table(config.get("physics", {}), "physics", allowed("physics"))
    kind = _choice(t.get("kind", "none" if surface and "bc" not in config else default("physics", "kind")),
                   "physics.kind", PHYSICS)
    out = {"kind": kind}
    if surface and kind != "none":
        raise ProblemError(f"{surface}, not a volumetric B-spline model: heat and elasticity need trivariate "
                           "patches; drop [[bc]] and [physics] (kind = \"none\"), and write the surface with [output] "
                           "exports = [\"stl\"]")
    if kind in ("none", "heat", "transient-heat"):  # no elastic keys; 'none' takes no conditions at all
        sections = ("bc", "support", "load") if kind == "none" else ("support", "load")
        why = ("needs an analysis; physics.kind = 'none' builds and exports the model only" if kind == "none" else
               "applies to physics.kind = 'elasticity' or 'thermo-elastic'; the heat problem takes [[bc]]")
        for sec in sections:
            if sec in config:
                raise ProblemError(f"config section {sec} {why}")
        extra = sorted(set(t) - {"kind"})
        if extra:
            _fail(f"physics.{extra[0]}", "applies to an analysis, not to physics.kind = 'none'" if kind == "none"
                  else "applies to physics.kind = 'elasticity' or 'thermo-elastic'")
        return out
    for key in ("youngs", "poisson") + (("expansion",) if kind == "thermo-elastic" else ()):
        if key not in t:
            raise ProblemError(f"config section physics (kind {kind!r}) needs {key!r} (a number or a channel name)")
    out["youngs"] = _material_value(t["youngs"], "physics.youngs", lo=0)
    out["poisson"] = _material_value(t["poisson"], "physics.poisson", lo=-1, hi=0.5)
    if kind == "thermo-elastic":
        out["expansion"] = _material_value(t["expansion"], "physics.expansion")
        out["reference"] = _number(t.get("reference", default("physics", "reference")), "physics.reference")
    elif "expansion" in t or "reference" in t:
        _fail("physics.expansion", "applies to physics.kind = 'thermo-elastic'")
    if "macro" in t:
        out["macro"] = _macro(t["macro"], kind, out)
    hold = t.get("hold_rigid", default("physics", "hold_rigid"))
    if not isinstance(hold, bool):
        _fail("physics.hold_rigid", f"must be true or false, got {show(hold)}")
    out["hold_rigid"] = hold
    sup = config.get("support", [])
    sup = sup if isinstance(sup, list) else [sup]
    out["support"] = [_support(s, f"support[{i}]") for i, s in enumerate(sup)]
    loads = config.get("load", [])
    loads = loads if isinstance(loads, list) else [loads]
    out["load"] = [_load(x, f"load[{i}]") for i, x in enumerate(loads)]
    if out["support"] and hold:
        _fail("physics.hold_rigid", "holds a body without [[support]] tables against rigid motion; with supports "
              "the 3-2-1 pins would add supports of their own: drop one or the other")
    if not out["support"] and not hold:
        raise ProblemError("an elastic analysis needs [[support]] tables (tag, value, components) or "
                           "physics.hold_rigid = true; without them the body is free to move")
    return out


def _macro(m, kind: str, out: dict) -> dict:
    """physics.macro: {family (a library tile of one width), values (>= 2 increasing widths in (0, 1)), channel}."""
    if kind != "elasticity":
        _fail("physics.macro", f"applies to physics.kind = 'elasticity' (a cubic macro model), not {kind!r}")
    m = _table(m, "physics.macro", {"family", "values", "channel"}, ("family", "values", "channel"))
    if not all(isinstance(out[k], (int, float)) for k in ("youngs", "poisson")):
        _fail("physics.macro", "tabulates the cells of one solid: physics.youngs and physics.poisson must be numbers")
    values = m["values"]
    if not (isinstance(values, list) and len(values) >= 2):
        _fail("physics.macro.values", f"must be a list of at least two increasing arm widths, got {show(values)}")
    values = [_number(v, "physics.macro.values", lo=0, hi=1) for v in values]
    if np.any(np.diff(values) <= 0):
        _fail("physics.macro.values", f"must increase, got {values}")
    return {"family": _str(m["family"], "physics.macro.family"), "values": values,
            "channel": _str(m["channel"], "physics.macro.channel")}


def _vector(v, where, broadcast: bool):
    """Three numbers or formulas of x, y, z (:mod:`iga.expressions`), or with ``broadcast`` one for all three
    (:class:`iga.elasticity.data.VectorField` takes either)."""
    if broadcast and not isinstance(v, list):
        return _formula(v, where)
    if not (isinstance(v, list) and len(v) == 3):
        _fail(where, f"must be {'a number, a formula or ' if broadcast else ''}a list of three numbers or formulas, "
              f"got {show(v)}")
    return [_formula(x, f"{where}[{i}]") for i, x in enumerate(v)]


_SELECTIONS = ("tag", "edge", "corner", "point", "box")


def _support(v, where) -> dict:
    """A [[support]] table: faces held (``tag``), or the control points of an edge, a corner, a point or a box held
    (``select``: (key, value)) or sprung (``stiffness``)."""
    t = _table(v, where, allowed("support"), required("support"))
    given = [k for k in _SELECTIONS if k in t]
    if len(given) != 1:
        raise ProblemError(f"config {where} needs exactly one of {list(_SELECTIONS)} (what is held), got "
                           f"{given or 'none'}")
    comps = t.get("components", default("support", "components"))
    if not (isinstance(comps, str) and comps and set(comps) <= set("xyz") and len(set(comps)) == len(comps)):
        _fail(f"{where}.components", f"must be distinct letters of 'xyz' (e.g. 'z'), got {show(comps)}")
    out = {"tag": None, "select": None, "components": comps, "stiffness": None,
           "name": None if "name" not in t else _str(t["name"], f"{where}.name")}
    key = given[0]
    if key == "tag":
        out["tag"] = _tag(t["tag"], f"{where}.tag")
        if "stiffness" in t:
            _fail(f"{where}.stiffness", "springs go on nodes: select them by edge, corner, point or box")
    elif key in ("edge", "corner"):
        n = 2 if key == "edge" else 3
        sel = t[key]
        if not (isinstance(sel, list) and len(sel) == n and all(isinstance(x, str) and x for x in sel)):
            _fail(f"{where}.{key}", f"must be a list of {n} face tags (e.g. {['umin', 'wmin', 'vmin'][:n]}), got "
                                    f"{show(sel)}")
        out["select"] = (key, tuple(sel))
    elif key == "point":
        out["select"] = ("point", tuple(_point(t["point"], f"{where}.point")))
    else:
        box = t["box"]
        if not (isinstance(box, list) and len(box) == 2):
            _fail(f"{where}.box", f"must be two corners [[x0, y0, z0], [x1, y1, z1]], got {show(box)}")
        out["select"] = ("box", tuple(tuple(_point(c, f"{where}.box[{i}]")) for i, c in enumerate(box)))
    if "stiffness" in t:
        if "value" in t:
            _fail(f"{where}.value", "a spring holds no displacement; give stiffness or value, not both")
        out["stiffness"] = _number(t["stiffness"], f"{where}.stiffness", lo=0)
        out["value"] = None
    else:
        out["value"] = _vector(t.get("value", default("support", "value")), f"{where}.value", True)
    return out


def _point(v, where) -> list:
    if not (isinstance(v, list) and len(v) == 3):
        _fail(where, f"must be three numbers [x, y, z], got {show(v)}")
    return [_number(x, f"{where}[{i}]") for i, x in enumerate(v)]


def _load(v, where) -> dict:
    t = _table(v, where, allowed("load"), required("load"))
    kind = _choice(t["kind"], f"{where}.kind", ("traction", "pressure", "point"))
    where_value = f"{where}.value"
    if kind == "point":
        if "tag" in t or "point" not in t:
            _fail(f"{where}.{'tag' if 'tag' in t else 'point'}", "a point load takes point = [x, y, z] and value = "
                  "[Fx, Fy, Fz] (N), no tag")
        return {"kind": kind, "tag": None, "point": _point(t["point"], f"{where}.point"),
                "value": _point(t["value"], where_value)}
    if "point" in t or "tag" not in t:
        _fail(f"{where}.{'point' if 'point' in t else 'tag'}", f"a {kind} load takes the faces' tag, not a point")
    value = _formula(t["value"], where_value) if kind == "pressure" else _vector(t["value"], where_value, False)
    return {"kind": kind, "tag": _tag(t["tag"], f"{where}.tag"), "value": value}
