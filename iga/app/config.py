"""Pipeline configuration: the schema of ``iga run CONFIG.toml``, checked whole before any work starts.

:func:`validate` takes the configuration table (a TOML file's content) and
returns a normalised copy with every default filled in, or raises
:class:`iga.ProblemError` naming the key, the value and the allowed values.
Types are checked exactly (``"22"`` is not a list of counts, ``"no"`` is not a
boolean), keyword arguments (``args``) are bound against the signature of the
primitive or tile they configure, and output names may not leave the output
folder.  The keys, their defaults and meanings are one table, :mod:`iga.app.config_schema` (also the
documentation's pipeline reference); the checks of values and of how sections combine are here and in
:mod:`iga.app.config_model`, :mod:`iga.app.config_physics` and :mod:`iga.app.config_time`.
"""

from __future__ import annotations

from pathlib import Path

import solvers
from tiling.library import TILES
from iga.app.config_checks import (boolean as _bool, choice as _choice, fail as _fail, formula as _formula,
                            formula_table as _formula_table, integer as _int, number as _number, string as _str,
                            table as _table, tag as _tag)
from iga.app.config_model import (NO_MAP, NO_TILE, takes_faces, width_family, map_section, paving_section, polygon_tile, primitives, reduce_section,
                           second_level, surface_reason, tile_section)
from iga.app.config_physics import physics as _physics
from iga.app.config_records import Config, config_record
from iga.app.config_schema import SCHEMA, allowed, default, filled, required
from iga.app.config_loops import adapt_section, design_section
from iga.app.config_time import capacity, time_section
from iga.errors import ProblemError
from geometry.errors import show

__all__ = ["validate", "SECTIONS", "OUTPUT_DEFAULTS"]

SECTIONS = ("map", "tile", "paving", "primitive", "second_level", "reduce", "material", "bc", "physics", "support",
            "load", "time", "adapt", "design", "solver", "output", "limits")
OUTPUT_DEFAULTS = {k.name: k.default for k in SCHEMA["output"].keys}
EXPORTS = ("stl", "obj", "ply", "vtp", "iges", "gismo")
SURFACE_SCHEMES = ("random_implicit", "implicit_bifurcation")  # implicit structures: surfaces, no analysis
SOLVER_DEFAULTS = {k.name: k.default for k in SCHEMA["solver"].keys}


def _bc(v, where) -> dict:
    t = _table(v, where, allowed("bc"), required("bc"))
    kind = _choice(t["kind"], f"{where}.kind", ("dirichlet", "neumann", "robin", "radiation"))
    out = {"kind": kind, "tag": _tag(t["tag"], f"{where}.tag")}
    if kind != "radiation":
        extra = sorted(set(t) & {"emissivity", "scale"})
        if extra:
            _fail(f"{where}.{extra[0]}", "applies to a radiation condition (kind = 'radiation')")
    if kind == "radiation":
        for key in ("emissivity", "ambient"):
            if key not in t:
                raise ProblemError(f"config {where} (radiation) needs keys 'emissivity' and 'ambient'")
        extra = sorted(set(t) & {"value", "h"})
        if extra:
            _fail(f"{where}.{extra[0]}", "a radiation condition takes 'emissivity', 'ambient' and 'scale'")
        out["emissivity"] = _formula(t["emissivity"], f"{where}.emissivity", lo=None)
        if isinstance(out["emissivity"], float) and not 0 <= out["emissivity"] <= 1:
            _fail(f"{where}.emissivity", f"must lie in [0, 1], got {show(t['emissivity'])}")
        out["ambient"] = _formula(t["ambient"], f"{where}.ambient")
        out["scale"] = _choice(t.get("scale", default("bc", "scale")), f"{where}.scale", ("K", "C"))
    elif kind == "robin":
        for key in ("h", "ambient"):
            if key not in t:
                raise ProblemError(f"config {where} (robin) needs keys 'h' and 'ambient'")
        if "value" in t:
            _fail(f"{where}.value", "a robin condition takes 'h' and 'ambient', not 'value'")
        out["h"] = _formula(t["h"], f"{where}.h", lo=0)
        out["ambient"] = _formula(t["ambient"], f"{where}.ambient")
    else:
        extra = sorted(set(t) & {"h", "ambient"})
        if extra:
            _fail(f"{where}.{extra[0]}", f"a {kind} condition takes 'value', not {extra}")
        out["value"] = _formula(t.get("value", default("bc", "value")), f"{where}.value")
    return out


def _conductivity(v, where):
    if isinstance(v, dict):
        return _formula_table(v, where)
    if isinstance(v, str):
        return v
    if isinstance(v, list) and len(v) == 6 and all(isinstance(c, str) for c in v):
        return list(v)
    if isinstance(v, list) and len(v) == 3 and all(isinstance(r, list) and len(r) == 3 for r in v):
        return [[_number(x, f"{where}[{i}][{j}]") for j, x in enumerate(r)] for i, r in enumerate(v)]
    if isinstance(v, list) and len(v) >= 2 and all(isinstance(r, list) and len(r) == 2 for r in v):
        # a table of (T, k) rows: the conductivity depends on the temperature (steady heat, by Newton)
        rows = [[_number(x, f"{where}[{i}][{j}]") for j, x in enumerate(r)] for i, r in enumerate(v)]
        if any(b[0] <= a[0] for a, b in zip(rows, rows[1:])) or any(r[1] <= 0 for r in rows):
            _fail(where, "a table of [T, k] rows needs strictly increasing T and positive k")
        return rows
    return _number(v, where, lo=0)


def _output(v, base: Path) -> dict:
    t = _table(v, "output", allowed("output"))
    out = {key: default("output", key) for key in OUTPUT_DEFAULTS}
    if "dir" in t:
        out["dir"] = _str(t["dir"], "output.dir")
    if "name" in t:
        out["name"] = _str(t["name"], "output.name")
    name = out["name"]
    if any(ord(c) < 32 for c in name) or len(name) > 200:
        _fail("output.name", f"must be at most 200 printable characters (files {show(name[:40])}... get suffixes "
                             "such as _bezier.vtu), got one of " + str(len(name)) + " characters"
              if len(name) > 200 else f"must not hold control characters (NUL, newline), got {show(name)}")
    if "\0" in out["dir"]:
        _fail("output.dir", f"must not hold a NUL character, got {show(out['dir'])}")
    if Path(name).is_absolute() or Path(name).name != name or name in (".", ".."):
        _fail("output.name", f"must be a plain file name inside output.dir (no folders, no '..'), got {show(name)}")
    for key in ("vtu", "bezier", "png", "compress"):
        if key in t:
            out[key] = _bool(t[key], f"output.{key}")
    if "samples" in t:
        out["samples"] = _int(t["samples"], "output.samples", 1)
    if "tolerance" in t:
        if "samples" in t:
            _fail("output.tolerance", "choose the samples per element (samples) or a geometric tolerance, not both")
        out["tolerance"] = _number(t["tolerance"], "output.tolerance", lo=0)
    if "exports" in t:
        ex = t["exports"]
        if not isinstance(ex, list) or any(x not in EXPORTS for x in ex) or len(set(ex)) != len(ex):
            _fail("output.exports", f"must be a list of distinct names from {list(EXPORTS)}, got {show(ex)}")
        out["exports"] = list(ex)
    if "probes" in t:
        p = t["probes"]
        if not isinstance(p, list) or not all(isinstance(q, list) and len(q) == 3 for q in p):
            _fail("output.probes", f"must be a list of [x, y, z] points, got {show(p)}")
        out["probes"] = [[_number(x, f"output.probes[{i}][{j}]") for j, x in enumerate(q)] for i, q in enumerate(p)]
    d = Path(out["dir"])
    out["path"] = d if d.is_absolute() else base / d
    if out["png"] and not out["vtu"]:
        _fail("output.png", "the picture is rendered from the VTU file; set vtu = true or png = false")
    return out


def _model(config, base_dir) -> dict:
    """The sections that describe the model (:mod:`iga.app.config_model`): map, tile, paving, primitives, second level,
    reduction; each required or refused by the scheme."""
    if "paving" not in config:
        raise ProblemError("missing required config section 'paving'")
    pav = paving_section(config["paving"])
    scheme = pav["scheme"]
    cfg: dict = {"paving": pav, "map": None, "tile": None, "primitives": None, "second_level": None, "reduce": None}
    if scheme in NO_MAP:
        if "map" in config:
            raise ProblemError("config section map does not apply to the vrep scheme: every [[primitive]] carries "
                               "its own map")
        cfg["primitives"] = primitives(config, base_dir, pav["expression"])
    elif "map" not in config:
        raise ProblemError("missing required config section 'map'")
    else:
        cfg["map"] = map_section(config["map"], base_dir)
    if "primitive" in config and scheme != "vrep":
        raise ProblemError(f"config tables [[primitive]] belong to the vrep scheme, not to {scheme!r}")
    if scheme in NO_TILE and "tile" in config:
        raise ProblemError(f"config section tile does not apply to the {scheme} scheme: "
                           + ("every [[primitive]] carries its own tile" if scheme == "vrep" else
                              "it builds its own tiles (bifurcation: paving.kind '1-2', '1-4a' or '1-4b'; random "
                              "implicit: random fields around the canonical tubes)"))
    if scheme not in NO_TILE:
        if "tile" not in config:
            raise ProblemError("missing required config section 'tile'")
        cfg["tile"] = polygon_tile(config["tile"]) if scheme == "polygons" else tile_section(config["tile"])
        if scheme == "field_graded":
            _face_family(cfg["tile"]["library"], "tile.library", "the field_graded scheme")
            if cfg["tile"]["args"]:
                _fail("tile.args", "the field_graded scheme gives the tile its six face values from paving.field; "
                      "drop args")
        if "leaves" in cfg["paving"]:
            _face_family(cfg["paving"]["leaves"], "paving.leaves", "graded leaves")
    for sec, check in (("second_level", second_level), ("reduce", reduce_section)):
        if sec in config:
            if scheme in ("polygons",) + SURFACE_SCHEMES:
                raise ProblemError(f"config section {sec} needs a model of trivariates; the {scheme} scheme "
                                   "builds a surface mesh")
            cfg[sec] = check(config[sec])
    return cfg


def _macro_model(macro: dict, cfg: dict) -> None:
    """physics.macro: the map alone (one cell of the solid cube) and a family of one arm width."""
    tile, paving = cfg.get("tile") or {}, cfg["paving"]
    if tile.get("library") != "cube" or paving["scheme"] != "regular" or list(paving["counts"]) != [1, 1, 1]:
        _fail("physics.macro", "analyses the map as a continuum: pave it with one solid cell ([tile] library = "
              "\"cube\", [paving] scheme = \"regular\", counts = [1, 1, 1])")
    family = macro["family"]
    if width_family(family) is None:
        _fail("physics.macro.family", f"must be a library tile of one width (e.g. \"cross\") or of six face values "
              f"(e.g. \"face_graded_cross\"), got {family!r}")


def _face_family(name: str, key: str, what: str) -> None:
    """A library tile whose arguments are the six faces' values (a field gives them): refused naming ``key``."""
    if not takes_faces(name):
        family = sorted(n for n in TILES if takes_faces(n))
        _fail(key, f"{what} need{'s' if what.startswith('the') else ''} a tile of the six faces' values (umin .. "
              f"wmax); {name!r} is not one: use one of {family}")


def _exports_fit(cfg: dict, surface: str | None) -> None:
    """Exports that the configured model can hold (a mesh has no B-spline boundary; curves no triangles)."""
    ex, scheme = cfg["output"]["exports"], cfg["paving"]["scheme"]
    if "gismo" in ex and cfg["physics"]["kind"] not in ("heat", "thermo-elastic"):
        _fail("output.exports", "'gismo' writes the heat problem; it needs physics.kind = 'heat' or 'thermo-elastic'")
    if scheme in ("polygons",) + SURFACE_SCHEMES:
        bad = sorted(set(ex) - {"stl", "obj", "ply", "vtp"})
        if bad or cfg["output"]["bezier"]:
            what = "a random implicit structure is a triangulated surface" if scheme != "polygons" else \
                "a polygonal paving is a mesh of straight edges and facets"
            _fail("output.exports" if bad else "output.bezier", f"{what} with no B-spline boundary: "
                  f"{bad or ['bezier']} cannot hold it; use stl, obj, ply or vtp")
    elif surface and cfg["output"]["bezier"]:
        _fail("output.bezier", "Bezier hexahedra hold trivariates; this model has none (" + surface + ")")
    if surface and "made of curves" in surface and set(ex) & {"stl", "obj", "ply"}:
        _fail("output.exports", f"{sorted(set(ex) & {'stl', 'obj', 'ply'})} hold triangles and the model is curves; "
                                "use vtp (polylines) or iges")
    if cfg["paving"]["scheme"] == "polygons" and not cfg["tile"]["facets"] and set(ex) & {"stl", "obj", "ply"}:
        _fail("output.exports", "the polygon tile has lines only: stl, obj and ply hold triangles; use vtp")


def validate(config, base_dir=".") -> Config:
    """The normalised configuration (every default filled in) as frozen records
    (:class:`iga.app.config_records.Config`), or :class:`ProblemError` (see module)."""
    if not isinstance(config, dict):
        raise ProblemError("the configuration must be a table of sections")
    unknown = sorted(set(config) - set(SECTIONS))
    if unknown:
        raise ProblemError(f"unknown config section {show(unknown[0])}; sections: {list(SECTIONS)}")
    cfg = _model(config, base_dir)
    surface = surface_reason(cfg)
    if surface and cfg["reduce"]:
        raise ProblemError(f"config section reduce approximates trivariates; {surface}")
    physics = cfg["physics"] = _physics(config, surface)
    if physics["kind"] in ("heat", "thermo-elastic", "transient-heat") and "bc" not in config:
        raise ProblemError("missing required config section 'bc' (the heat problem's conditions)")
    if physics["kind"] == "elasticity" and "bc" in config:
        raise ProblemError("config section bc holds heat conditions; physics.kind = 'elasticity' takes [[support]] "
                           "and [[load]] (or use kind = 'thermo-elastic')")
    if physics["kind"] == "elasticity" and "material" in config:
        raise ProblemError("config section material holds the heat problem's conductivity and source; physics.kind = "
                           "'elasticity' takes its materials in [physics] (youngs, poisson): drop [material], or "
                           "use kind = 'thermo-elastic'")
    mat = _table(config.get("material", {}), "material", allowed("material"))
    cfg["material"] = {"conductivity": _conductivity(mat.get("conductivity", default("material", "conductivity")),
                                                     "material.conductivity"),
                       "source": _formula(mat.get("source", default("material", "source")), "material.source"),
                       "capacity": capacity(mat, physics["kind"])}
    bcs = config.get("bc", [])
    bcs = bcs if isinstance(bcs, list) else [bcs]
    if not bcs and physics["kind"] in ("heat", "thermo-elastic", "transient-heat"):
        raise ProblemError("config section bc is empty; give at least one [[bc]] table")
    cfg["bc"] = [_bc(b, f"bc[{i}]") for i, b in enumerate(bcs)]
    cfg["solver"] = _solver(config.get("solver", {}))
    cfg["time"] = time_section(config, physics["kind"], cfg["solver"]["method"])
    cfg["adapt"] = adapt_section(config, physics["kind"])
    if "macro" in physics:
        _macro_model(physics["macro"], cfg)
    if physics["kind"] == "elasticity":  # the coefficient a channel design changes
        designed = physics["macro"]["channel"] if "macro" in physics else physics["youngs"]
    else:
        designed = cfg["material"]["conductivity"]
    cfg["design"] = design_section(config, physics["kind"], designed)
    if (cfg["adapt"] or cfg["design"]) is not None and cfg["solver"]["method"] == "petsc":
        raise ProblemError("config sections adapt and design solve serially; use another solver.method than 'petsc'")
    cfg["output"] = _output(config.get("output", {}), Path(base_dir))
    if physics["kind"] == "elasticity":  # outputs of the temperature: the same rule as elastic keys in a heat run
        given = config.get("output", {}) if isinstance(config.get("output", {}), dict) else {}
        for key in ("probes", "bezier"):
            if given.get(key):
                _fail(f"output.{key}", "writes temperatures (probes: the temperature at points; bezier: the exact "
                      "temperature VTU), which physics.kind = 'elasticity' does not compute; drop it, or use "
                      "kind = 'thermo-elastic'")
    _exports_fit(cfg, surface)
    lim = _table(config.get("limits", {}), "limits", allowed("limits"))
    cfg["limits"] = {"max_memory_gib": None if "max_memory_gib" not in lim
                     else _number(lim["max_memory_gib"], "limits.max_memory_gib", lo=0)}
    return config_record(cfg)


def _solver(s) -> dict:
    s = _table(s, "solver", allowed("solver"))
    s = filled("solver", s)
    return {"method": _choice(s["method"], "solver.method", solvers.backends()),
            "tol": _number(s["tol"], "solver.tol", lo=0, hi=1),
            "maxiter": None if s["maxiter"] is None else _int(s["maxiter"], "solver.maxiter", 1),
            "refine": _int(s["refine"], "solver.refine", 0),
            "degree_elevation": _int(s["degree_elevation"], "solver.degree_elevation", 0),
            "degree": None if s["degree"] is None else _int(s["degree"], "solver.degree", 1),
            "quadrature_extra": _int(s["quadrature_extra"], "solver.quadrature_extra", 0)}
