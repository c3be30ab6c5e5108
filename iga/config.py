"""Pipeline configuration: the schema of ``iga run CONFIG.toml``, checked whole before any work starts.

:func:`validate` takes the configuration table (a TOML file's content) and
returns a normalised copy with every default filled in, or raises
:class:`iga.ProblemError` naming the key, the value and the allowed values.
Types are checked exactly (``"22"`` is not a list of counts, ``"no"`` is not a
boolean), keyword arguments (``args``) are bound against the signature of the
primitive or tile they configure, and output names may not leave the output
folder.  The schema (README, "Pipelines")::

    [map]      primitive = one of MAPS, args = {...}   or   file = "map.npz"
               grading = {channel, near, far, face, mode}        (optional)
    [tile]     library = one of tiling.library.TILES, args = {...}
    [paving]   scheme = "hierarchical" | "regular", counts, levels, scale;
               seal = "cap" | "shell", thickness, seal_sides (either scheme)
    [material] conductivity = number | channel | 6 channels | 3 x 3 matrix, source = number
    [[bc]]     kind = "dirichlet" | "neumann" | "robin", tag, value | (h, ambient)
    [solver]   method, tol, maxiter, refine, degree_elevation
    [output]   dir, name, vtu, bezier, png, samples, probes
    [limits]   max_memory_gib
"""

from __future__ import annotations

from pathlib import Path

import solvers
from geometry.faces import FACE_NAMES
from tiling.library import TILES

from .config_checks import (boolean as _bool, choice as _choice, fail as _fail, integer as _int, ints as _ints,
                            kwargs as _kwargs, number as _number, string as _str, table as _table, tag as _tag)
from .config_physics import physics as _physics
from .errors import ProblemError
from .maps import MAPS
from geometry.errors import show

__all__ = ["validate", "SECTIONS", "OUTPUT_DEFAULTS"]

SECTIONS = ("map", "tile", "paving", "material", "bc", "physics", "support", "load", "solver", "output", "limits")
OUTPUT_DEFAULTS = {"dir": "out", "name": "result", "vtu": True, "bezier": False, "png": True, "samples": 3,
                   "tolerance": None, "probes": [], "exports": []}
EXPORTS = ("stl", "obj", "ply", "vtp", "iges", "gismo")
SURFACE_SCHEMES = ("random_implicit", "implicit_bifurcation")  # implicit structures: surfaces, no analysis
SOLVER_DEFAULTS = {"method": "auto", "tol": 1e-10, "maxiter": None, "refine": 0, "degree_elevation": 0}


def _bc(v, where) -> dict:
    t = _table(v, where, {"kind", "tag", "value", "h", "ambient"}, ("kind", "tag"))
    kind = _choice(t["kind"], f"{where}.kind", ("dirichlet", "neumann", "robin"))
    out = {"kind": kind, "tag": _tag(t["tag"], f"{where}.tag")}
    if kind == "robin":
        for key in ("h", "ambient"):
            if key not in t:
                raise ProblemError(f"config {where} (robin) needs keys 'h' and 'ambient'")
        if "value" in t:
            _fail(f"{where}.value", "a robin condition takes 'h' and 'ambient', not 'value'")
        out["h"] = _number(t["h"], f"{where}.h", lo=0)
        out["ambient"] = _number(t["ambient"], f"{where}.ambient")
    else:
        extra = sorted(set(t) & {"h", "ambient"})
        if extra:
            _fail(f"{where}.{extra[0]}", f"a {kind} condition takes 'value', not {extra}")
        out["value"] = _number(t.get("value", 0.0), f"{where}.value")
    return out


def _conductivity(v, where):
    if isinstance(v, str):
        return v
    if isinstance(v, list) and len(v) == 6 and all(isinstance(c, str) for c in v):
        return list(v)
    if isinstance(v, list) and len(v) == 3 and all(isinstance(r, list) and len(r) == 3 for r in v):
        return [[_number(x, f"{where}[{i}][{j}]") for j, x in enumerate(r)] for i, r in enumerate(v)]
    return _number(v, where, lo=0)


def _output(v, base: Path) -> dict:
    t = _table(v, "output", set(OUTPUT_DEFAULTS))
    out = dict(OUTPUT_DEFAULTS)
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
    for key in ("vtu", "bezier", "png"):
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


def _map(m, base_dir) -> dict:
    """The checked [map] section."""
    m = _table(m, "map", {"primitive", "args", "file", "grading"})
    if ("primitive" in m) == ("file" in m):
        raise ProblemError("config section map needs exactly one of 'primitive' (a built-in map) or 'file' (a .npz)")
    if "file" in m:
        if "args" in m:
            _fail("map.args", "arguments go with 'primitive', not with 'file'")
        out = {"file": Path(base_dir) / _str(m["file"], "map.file")}
    else:
        name = _choice(m["primitive"], "map.primitive", MAPS)
        out = {"primitive": name, "args": _kwargs(m.get("args", {}), "map.args", MAPS[name])}
    if "grading" in m:  # one table, or a list of them (one per graded channel: k, E, nu, alpha, ...)
        many = isinstance(m["grading"], list)
        items = m["grading"] if many else [m["grading"]]
        out["grading"] = [_grading(g, f"map.grading[{i}]" if many else "map.grading") for i, g in enumerate(items)]
    return out


def _grading(g, where) -> dict:
    g = _table(g, where, {"channel", "near", "far", "face", "mode"})
    return {"channel": _str(g.get("channel", "k"), f"{where}.channel"),
            "near": _number(g.get("near", 205.0), f"{where}.near"),
            "far": _number(g.get("far", 54.0), f"{where}.far"),
            "face": _choice(g.get("face", "wmin"), f"{where}.face", FACE_NAMES),
            "mode": _choice(g.get("mode", "parameter"), f"{where}.mode", ("parameter", "distance"))}


def _random_implicit(p) -> dict:
    """The random implicit scheme (Massarwi et al. 2018, Section 4): a surface, exported by name."""
    allowed = {"scheme", "counts", "alpha", "seed", "continuity", "connectivity", "cap", "resolution"}
    extra = sorted(set(p) - allowed)
    if extra:
        _fail(f"paving.{extra[0]}", "does not apply to the random_implicit scheme")
    if "counts" not in p:
        raise ProblemError("config section paving (scheme 'random_implicit') needs 'counts' (cells per direction)")
    return {"scheme": "random_implicit", "counts": _ints(p["counts"], "paving.counts", 3),
            "alpha": _number(p.get("alpha", 0.5), "paving.alpha", lo=0, hi=1, open_lo=False),
            "seed": _int(p.get("seed", 0), "paving.seed", 0),
            "continuity": _choice(p.get("continuity", "C0"), "paving.continuity", ("C0", "C1")),
            "connectivity": _int(p.get("connectivity", 1), "paving.connectivity", 1),
            "cap": _bool(p.get("cap", False), "paving.cap"),
            "resolution": _int(p.get("resolution", 12), "paving.resolution", 2)}


def _implicit_bifurcation(p) -> dict:
    """The implicit bifurcation scheme (Massarwi et al. 2018, Section 5.2, Fig. 16): a surface over the adaptive
    subdivision of ``epsilon``."""
    extra = sorted(set(p) - {"scheme", "epsilon", "alpha", "seed", "cap", "resolution", "radius"})
    if extra:
        _fail(f"paving.{extra[0]}", "does not apply to the implicit_bifurcation scheme")
    if "epsilon" not in p:
        raise ProblemError("config section paving (scheme 'implicit_bifurcation') needs 'epsilon' (the largest cell "
                           "edge, model units)")
    return {"scheme": "implicit_bifurcation", "epsilon": _number(p["epsilon"], "paving.epsilon", lo=0),
            "alpha": _number(p.get("alpha", 0.0), "paving.alpha", lo=0, hi=1, open_lo=False),
            "seed": _int(p.get("seed", 0), "paving.seed", 0), "cap": _bool(p.get("cap", True), "paving.cap"),
            "resolution": _int(p.get("resolution", 8), "paving.resolution", 2),
            "radius": _number(p.get("radius", 0.35), "paving.radius", lo=0, hi=0.5)}


def _bifurcation(p) -> dict:
    """The bifurcation scheme (Massarwi et al. 2018, Section 5): ``epsilon`` (model units) or ``levels`` (one per
    layer), ``kind`` ("1-2", "1-4a", "1-4b"), ``direction`` (0, 1, 2), ``margin``."""
    for key in ("counts", "scale", "seal", "thickness", "seal_sides"):
        if key in p:
            _fail(f"paving.{key}", "does not apply to the bifurcation scheme (its layers follow epsilon or levels)")
    if ("epsilon" in p) == ("levels" in p):
        raise ProblemError("config section paving (scheme 'bifurcation') needs exactly one of 'epsilon' (the largest "
                           "cell edge, model units) or 'levels' (one per layer)")
    out = {"scheme": "bifurcation", "kind": _choice(p.get("kind", "1-2"), "paving.kind", ("1-2", "1-4a", "1-4b")),
           "direction": _int(p.get("direction", 2), "paving.direction", 0),
           "margin": _number(p.get("margin", 0.3), "paving.margin", lo=0, hi=0.5)}
    if out["direction"] > 2:
        _fail("paving.direction", f"must be 0, 1 or 2 (the growth direction), got {out['direction']}")
    if "epsilon" in p:
        out["epsilon"], out["levels"] = _number(p["epsilon"], "paving.epsilon", lo=0), None
    else:
        lv = p["levels"]
        if not (isinstance(lv, list) and lv and all(isinstance(x, int) and not isinstance(x, bool) and x >= 0
                                                    for x in lv)):
            _fail("paving.levels", f"must be a list of levels >= 0, one per layer, got {show(lv)}")
        out["epsilon"], out["levels"] = None, list(lv)
    return out


def _tile(t) -> dict:
    """The checked [tile] section."""
    t = _table(t, "tile", {"library", "args"}, ("library",))
    lib = _choice(t["library"], "tile.library", TILES)
    return {"library": lib, "args": _kwargs(t.get("args", {}), "tile.args", TILES[lib])}


def _paving(p) -> dict:
    """The checked [paving] section."""
    p = _table(p, "paving", {"scheme", "counts", "levels", "scale", "seal", "thickness", "seal_sides", "epsilon",
                             "kind", "direction", "margin", "alpha", "seed", "continuity", "connectivity", "cap",
                             "resolution", "radius"}, ("scheme",))
    scheme = _choice(p["scheme"], "paving.scheme", ("hierarchical", "regular", "bifurcation", "random_implicit",
                                                     "implicit_bifurcation"))
    if scheme == "bifurcation":
        return _bifurcation(p)
    if scheme == "random_implicit":
        return _random_implicit(p)
    if scheme == "implicit_bifurcation":
        return _implicit_bifurcation(p)
    for key in ("alpha", "seed", "continuity", "connectivity", "cap", "resolution", "radius"):
        if key in p:
            _fail(f"paving.{key}", "applies to the random_implicit scheme only")
    for key in ("epsilon", "kind", "direction", "margin"):
        if key in p:
            _fail(f"paving.{key}", "applies to the bifurcation scheme only")
    if "counts" not in p:
        raise ProblemError(f"config section paving (scheme {scheme!r}) needs 'counts'")
    pav = {"scheme": scheme, "counts": _ints(p["counts"], "paving.counts", 2 if scheme == "hierarchical" else 3)}
    if scheme == "hierarchical":
        pav["levels"] = _int(p.get("levels", 2), "paving.levels", 1)
        pav["scale"] = None if "scale" not in p else _number(p["scale"], "paving.scale", lo=0)
    else:
        for key in ("levels", "scale"):
            if key in p:
                _fail(f"paving.{key}", "applies to the hierarchical scheme only")
    if "seal" in p:
        pav["seal"] = _choice(p["seal"], "paving.seal", ("cap", "shell"))
        pav["thickness"] = _number(p.get("thickness", 0.1), "paving.thickness", lo=0, hi=0.5)
        sides = p.get("seal_sides", list(FACE_NAMES))
        if not isinstance(sides, list) or not sides or any(x not in FACE_NAMES for x in sides):
            _fail("paving.seal_sides", f"must be a list of face names from {list(FACE_NAMES)}, got {show(sides)}")
        pav["seal_sides"] = list(sides)
    else:
        for key in ("thickness", "seal_sides"):
            if key in p:
                _fail(f"paving.{key}", "needs paving.seal = \"cap\" or \"shell\"")
    return pav


def validate(config, base_dir=".") -> dict:
    """The normalised configuration (every default filled in), or :class:`ProblemError` (see module)."""
    if not isinstance(config, dict):
        raise ProblemError("the configuration must be a table of sections")
    unknown = sorted(set(config) - set(SECTIONS))
    if unknown:
        raise ProblemError(f"unknown config section {show(unknown[0])}; sections: {list(SECTIONS)}")
    bifurcating = isinstance(config.get("paving"), dict) and config["paving"].get("scheme") in (
        "bifurcation", "random_implicit", "implicit_bifurcation")
    for sec in ("map", "paving") + (() if bifurcating else ("tile",)):
        if sec not in config:
            raise ProblemError(f"missing required config section {show(sec)}")
    if bifurcating and "tile" in config:
        raise ProblemError(f"config section tile does not apply to the {config['paving']['scheme']} scheme: it builds "
                           "its own tiles (bifurcation: paving.kind '1-2', '1-4a' or '1-4b'; random implicit: "
                           "random fields around the canonical tubes)")
    physics = _physics(config)
    if physics["kind"] in ("heat", "thermo-elastic") and "bc" not in config:
        raise ProblemError("missing required config section 'bc' (the heat problem's conditions)")
    if physics["kind"] == "elasticity" and "bc" in config:
        raise ProblemError("config section bc holds heat conditions; physics.kind = 'elasticity' takes [[support]] "
                           "and [[load]] (or use kind = 'thermo-elastic')")
    cfg: dict = {"map": _map(config["map"], base_dir), "tile": None if bifurcating else _tile(config["tile"]),
                 "paving": _paving(config["paving"]), "physics": physics}
    mat = _table(config.get("material", {}), "material", {"conductivity", "source"})
    cfg["material"] = {"conductivity": _conductivity(mat.get("conductivity", 1.0), "material.conductivity"),
                       "source": _number(mat.get("source", 0.0), "material.source")}
    bcs = config.get("bc", [])
    bcs = bcs if isinstance(bcs, list) else [bcs]
    if not bcs and physics["kind"] in ("heat", "thermo-elastic"):
        raise ProblemError("config section bc is empty; give at least one [[bc]] table")
    cfg["bc"] = [_bc(b, f"bc[{i}]") for i, b in enumerate(bcs)]
    s = _table(config.get("solver", {}), "solver", set(SOLVER_DEFAULTS))
    cfg["solver"] = {
        "method": _choice(s.get("method", "auto"), "solver.method", solvers.backends()),
        "tol": _number(s.get("tol", 1e-10), "solver.tol", lo=0, hi=1),
        "maxiter": None if s.get("maxiter") is None else _int(s["maxiter"], "solver.maxiter", 1),
        "refine": _int(s.get("refine", 0), "solver.refine", 0),
        "degree_elevation": _int(s.get("degree_elevation", 0), "solver.degree_elevation", 0)}
    cfg["output"] = _output(config.get("output", {}), Path(base_dir))
    if "gismo" in cfg["output"]["exports"] and physics["kind"] not in ("heat", "thermo-elastic"):
        _fail("output.exports", "'gismo' writes the heat problem; it needs physics.kind = 'heat' or 'thermo-elastic'")
    if cfg["paving"]["scheme"] in SURFACE_SCHEMES:
        bad = sorted(set(cfg["output"]["exports"]) - {"stl", "obj", "ply", "vtp"})
        if bad or cfg["output"]["bezier"]:
            _fail("output.exports" if bad else "output.bezier", f"a random implicit structure is a triangulated surface "
                  f"with no B-spline boundary: {bad or ['bezier']} cannot hold it; use stl, obj, ply or vtp")
    lim = _table(config.get("limits", {}), "limits", {"max_memory_gib"})
    cfg["limits"] = {"max_memory_gib": None if "max_memory_gib" not in lim
                     else _number(lim["max_memory_gib"], "limits.max_memory_gib", lo=0)}
    return cfg
