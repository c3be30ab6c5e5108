"""The sections of a pipeline configuration that describe the model: [map], [tile], [paving] (every scheme),
the [[primitive]] tables of a V-rep model, [second_level] and [reduce]; and what the configured model is
(volumes, or surfaces and curves that take no analysis).

Schemes: ``regular`` and ``hierarchical`` (a library tile), ``bifurcation`` (its own tiles), ``vrep`` (a
Boolean expression over named [[primitive]] tables, each a map, a tile, counts and a priority: Hong and
Elber 2021), ``polygons`` (a polygon tile paved by vertex mapping: Elber 2017, Eq. 3), and the implicit
schemes ``random_implicit`` and ``implicit_bifurcation`` (surfaces).  [second_level] paves every trivariate
of the first level again (Massarwi et al. 2018, Fig. 12); [reduce] approximates the model's patches by
degree 2 or 3 (Section 6.3) with its topology and tags kept.
"""

from __future__ import annotations

import inspect
import re
from pathlib import Path

from geometry.errors import show
from geometry.faces import FACE_NAMES
from tiling.errors import TilingError
from tiling.library import TILES
from tiling.members.polygons import PolygonTile, beam_lattice

from iga.app.config_checks import (boolean as _bool, choice as _choice, fail as _fail, formula_table, integer as _int,
                                   ints as _ints, kwargs as _kwargs, number as _number, string as _str, table as _table)
from iga.errors import ProblemError
from iga.app.config_schema import allowed, default, filled, required
from iga.app.maps import MAPS
from iga.tags import parse_expression

__all__ = ["map_section", "tile_section", "paving_section", "primitives", "second_level", "reduce_section",
           "surface_reason", "polygon_tile", "SCHEMES", "NO_TILE", "NO_MAP", "POLYGON_TILES", "takes_faces",
           "width_family"]

SCHEMES = ("hierarchical", "regular", "field_graded", "bifurcation", "vrep", "polygons", "random_implicit",
           "implicit_bifurcation")
#: schemes whose [paving] builds its own tiles or takes them elsewhere: no [tile] section
NO_TILE = ("bifurcation", "vrep", "random_implicit", "implicit_bifurcation")
#: schemes without a [map] section (V-rep primitives carry their maps)
NO_MAP = ("vrep",)
POLYGON_TILES = {"beam_lattice": beam_lattice}


def takes_faces(name: str) -> bool:
    """Whether the library tile ``name`` is a family of the six faces' values (``umin=`` .. ``wmax=``)."""
    return name in TILES and set(FACE_NAMES) <= set(inspect.signature(TILES[name]).parameters)


def width_family(name: str):
    """The library tile ``name`` as a family of one width, ``w -> Tile`` (a tile of one argument, e.g. ``cross``, or
    a family of the six faces' values with all six ``w``), or None when it is neither."""
    if takes_faces(name):
        return lambda w: TILES[name](**{f: w for f in FACE_NAMES})
    if name in TILES and len(inspect.signature(TILES[name]).parameters) == 1:
        return TILES[name]
    return None

#: the keys of each scheme's [paving] (iga.app.config_schema), and every key some scheme takes
_SCHEME_KEYS = {scheme: allowed(f"paving.{scheme}") for scheme in SCHEMES}
_PAVING_KEYS = set().union(*_SCHEME_KEYS.values())
_NAME = re.compile(r"^[A-Za-z_][A-Za-z0-9_]*$")  # a primitive's name: a word the expression can hold


def map_section(m, base_dir, where: str = "map") -> dict:
    """The checked [map] section (or the ``map`` table of a V-rep primitive, named ``where``)."""
    m = _table(m, where, allowed("map"))
    if ("primitive" in m) == ("file" in m):
        raise ProblemError(f"config section {where} needs exactly one of 'primitive' (a built-in map) or 'file' "
                           "(a .npz)")
    if "file" in m:
        if "args" in m:
            _fail(f"{where}.args", "arguments go with 'primitive', not with 'file'")
        out = {"file": Path(base_dir) / _str(m["file"], f"{where}.file")}
    else:
        name = _choice(m["primitive"], f"{where}.primitive", MAPS)
        out = {"primitive": name, "args": _kwargs(m.get("args", {}), f"{where}.args", MAPS[name])}
    if "grading" in m:  # one table, or a list of them (one per graded channel: k, E, nu, alpha, ...)
        many = isinstance(m["grading"], list)
        items = m["grading"] if many else [m["grading"]]
        out["grading"] = [_grading(g, f"{where}.grading[{i}]" if many else f"{where}.grading")
                          for i, g in enumerate(items)]
    return out


def _grading(g, where) -> dict:
    g = _table(g, where, allowed("map.grading"))
    g = filled("map.grading", g)
    return {"channel": _str(g["channel"], f"{where}.channel"), "near": _number(g["near"], f"{where}.near"),
            "far": _number(g["far"], f"{where}.far"), "face": _choice(g["face"], f"{where}.face", FACE_NAMES),
            "mode": _choice(g["mode"], f"{where}.mode", ("parameter", "distance"))}


def random_implicit(p) -> dict:
    """The random implicit scheme (Massarwi et al. 2018, Section 4): a surface, exported by name."""
    _only(p, "random_implicit")
    if "counts" not in p:
        raise ProblemError("config section paving (scheme 'random_implicit') needs 'counts' (cells per direction)")
    p = filled("paving.random_implicit", p)
    return {"scheme": "random_implicit", "counts": _ints(p["counts"], "paving.counts", 3),
            "alpha": _number(p["alpha"], "paving.alpha", lo=0, hi=1, open_lo=False),
            "seed": _int(p["seed"], "paving.seed", 0),
            "continuity": _choice(p["continuity"], "paving.continuity", ("C0", "C1")),
            "connectivity": _int(p["connectivity"], "paving.connectivity", 1),
            "cap": _bool(p["cap"], "paving.cap"), "resolution": _int(p["resolution"], "paving.resolution", 2)}


def implicit_bifurcation(p) -> dict:
    """The implicit bifurcation scheme (Massarwi et al. 2018, Section 5.2, Fig. 16): a surface over the adaptive
    subdivision of ``epsilon``."""
    _only(p, "implicit_bifurcation")
    if "epsilon" not in p:
        raise ProblemError("config section paving (scheme 'implicit_bifurcation') needs 'epsilon' (the largest cell "
                           "edge, model units)")
    p = filled("paving.implicit_bifurcation", p)
    return {"scheme": "implicit_bifurcation", "epsilon": _number(p["epsilon"], "paving.epsilon", lo=0),
            "alpha": _number(p["alpha"], "paving.alpha", lo=0, hi=1, open_lo=False),
            "seed": _int(p["seed"], "paving.seed", 0), "cap": _bool(p["cap"], "paving.cap"),
            "resolution": _int(p["resolution"], "paving.resolution", 2),
            "radius": _number(p["radius"], "paving.radius", lo=0, hi=0.5)}


def bifurcation(p) -> dict:
    """The bifurcation scheme (Massarwi et al. 2018, Section 5): ``epsilon`` (model units) or ``levels`` (one per
    layer), ``kind`` ("1-2", "1-4a", "1-4b"), ``direction`` (0, 1, 2), ``margin``."""
    for key in sorted(set(p) - _SCHEME_KEYS["bifurcation"]):
        _fail(f"paving.{key}", "does not apply to the bifurcation scheme" + (
            " (its layers follow epsilon or levels)" if key in _SCHEME_KEYS["hierarchical"] else ""))
    if ("epsilon" in p) == ("levels" in p):
        raise ProblemError("config section paving (scheme 'bifurcation') needs exactly one of 'epsilon' (the largest "
                           "cell edge, model units) or 'levels' (one per layer)")
    f = filled("paving.bifurcation", p)
    out = {"scheme": "bifurcation", "kind": _choice(f["kind"], "paving.kind", ("1-2", "1-4a", "1-4b")),
           "direction": _int(f["direction"], "paving.direction", 0),
           "margin": _number(f["margin"], "paving.margin", lo=0, hi=0.5)}
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


def tile_section(t, where: str = "tile") -> dict:
    """The checked [tile] section (a library tile), or a tile table named ``where``."""
    t = _table(t, where, allowed("tile"), required("tile"))
    lib = _choice(t["library"], f"{where}.library", TILES)
    return {"library": lib, "args": _kwargs(t.get("args", default("tile", "args")), f"{where}.args", TILES[lib])}


def paving_section(p) -> dict:
    """The checked [paving] section, per scheme."""
    p = _table(p, "paving", set(p) if isinstance(p, dict) else (), ("scheme",))
    scheme = _choice(p["scheme"], "paving.scheme", SCHEMES)
    unknown = sorted(set(p) - _PAVING_KEYS)  # a key no scheme takes (one of another scheme is named below)
    if unknown:
        raise ProblemError(f"unknown config key paving.{show(unknown[0])} for the {scheme} scheme; allowed keys: "
                           f"{sorted(_SCHEME_KEYS[scheme])}")
    if scheme in _SCHEME_CHECKS:
        return _SCHEME_CHECKS[scheme](p)
    for key in sorted(set(p) - _SCHEME_KEYS["regular"] - _SCHEME_KEYS["hierarchical"]):
        takers = [name for name, keys in _SCHEME_KEYS.items() if key in keys and name not in ("regular", "hierarchical")]
        _fail(f"paving.{key}", f"applies to the {' and '.join(takers)} scheme{'s' if len(takers) > 1 else ''} only")
    if "counts" not in p:
        raise ProblemError(f"config section paving (scheme {scheme!r}) needs 'counts'")
    pav = {"scheme": scheme, "counts": _ints(p["counts"], "paving.counts", 2 if scheme == "hierarchical" else 3)}
    if scheme == "hierarchical":
        pav["levels"] = _int(p.get("levels", default("paving.hierarchical", "levels")), "paving.levels", 1)
        pav["scale"] = None if "scale" not in p else _number(p["scale"], "paving.scale", lo=0)
        if ("leaves" in p) != ("field" in p):
            _fail(f"paving.{'leaves' if 'leaves' in p else 'field'}", "graded leaves need both paving.leaves (a "
                  "family of the six faces' values, e.g. \"face_graded_heat_sink\") and paving.field")
        if "leaves" in p:
            if "seal" in p:
                _fail("paving.leaves", "graded leaves are not sealed: drop paving.seal")
            pav["leaves"], pav["field"] = _str(p["leaves"], "paving.leaves"), _wall_field(p["field"])
    else:
        for key in sorted(_SCHEME_KEYS["hierarchical"] - _SCHEME_KEYS["regular"]):
            if key in p:
                takers = [n for n, keys in _SCHEME_KEYS.items() if key in keys and n != "regular"]
                _fail(f"paving.{key}", f"applies to the {' and '.join(takers)} scheme{'s' if len(takers) > 1 else ''}"
                      " only")
    if "seal" in p:
        pav["seal"] = _choice(p["seal"], "paving.seal", ("cap", "shell"))
        pav["thickness"] = _number(p.get("thickness", default(f"paving.{scheme}", "thickness")), "paving.thickness", lo=0,
                                   hi=0.5)
        if pav["seal"] == "shell":  # (passing the six sides on made every shelled pipeline fail)
            if "seal_sides" in p:
                _fail("paving.seal_sides", "applies to seal = \"cap\" only: a shell seals every side")
        else:
            sides = p.get("seal_sides", default(f"paving.{scheme}", "seal_sides"))
            if not isinstance(sides, list) or not sides or any(x not in FACE_NAMES for x in sides):
                _fail("paving.seal_sides", f"must be a list of face names from {list(FACE_NAMES)}, got {show(sides)}")
            pav["seal_sides"] = list(sides)
    else:
        for key in ("thickness", "seal_sides"):
            if key in p:
                _fail(f"paving.{key}", "needs paving.seal = \"cap\" or \"shell\"")
    return pav




def _only(p, scheme: str) -> None:
    """Refuses a [paving] key that ``scheme`` does not take."""
    extra = sorted(set(p) - _SCHEME_KEYS[scheme])
    if extra:
        _fail(f"paving.{extra[0]}", f"does not apply to the {scheme} scheme")


def vrep(p) -> dict:
    """The V-rep scheme (Hong and Elber 2021): ``expression`` over the [[primitive]] names and the options of
    :func:`tiling.vrep.vrep_microstructure`."""
    _only(p, "vrep")
    if "expression" not in p:
        raise ProblemError("config section paving (scheme 'vrep') needs 'expression': the Boolean model over the "
                           "[[primitive]] names, e.g. \"(body | wing) - hole\"")
    f = filled("paving.vrep", p)
    return {"scheme": "vrep", "expression": _str(f["expression"], "paving.expression"),
            "samples": _int(f["samples"], "paving.samples", 2),
            "margin": _number(f["margin"], "paving.margin", lo=0, hi=0.5, open_lo=False),
            "bridges": _bool(f["bridges"], "paving.bridges"),
            "beta": _number(f["beta"], "paving.beta", lo=0, hi=1),
            "d_maxdist": None if f["d_maxdist"] is None else _number(f["d_maxdist"], "paving.d_maxdist", lo=0),
            "phi": _number(f["phi"], "paving.phi", lo=0, hi=1.0000001, open_lo=False),
            "alpha": _number(f["alpha"], "paving.alpha", lo=0, hi=1.5707963267948966)}


def field_graded(p) -> dict:
    """The field-graded scheme (:func:`tiling.field_graded`): ``counts`` and the ``field`` on the cell walls."""
    _only(p, "field_graded")
    for key in ("counts", "field"):
        if key not in p:
            raise ProblemError(f"config section paving (scheme 'field_graded') needs {key!r}")
    return {"scheme": "field_graded", "counts": _ints(p["counts"], "paving.counts", 3), "field": _wall_field(p["field"])}


def _wall_field(v):
    """paving.field: a formula of the position, a channel of the map or a number in (0, 1)."""
    if isinstance(v, dict):
        return formula_table(v, "paving.field")
    if isinstance(v, str):
        return _str(v, "paving.field")  # a channel of the map
    return _number(v, "paving.field", lo=0, hi=1)


def polygons(p) -> dict:
    """The polygon scheme (Elber 2017, Section 2, Eq. 3): ``counts`` copies of the [tile] polygon tile."""
    _only(p, "polygons")
    if "counts" not in p:
        raise ProblemError("config section paving (scheme 'polygons') needs 'counts' (cells per direction)")
    return {"scheme": "polygons", "counts": _ints(p["counts"], "paving.counts", 3)}


def polygon_tile(t) -> dict:
    """The [tile] of the polygon scheme: ``library`` (one of :data:`POLYGON_TILES`), or ``points`` (N x 3 in the
    unit cube) with ``polygons`` and/or ``lines`` (lists of vertex indices), checked by building it."""
    t = _table(t, "tile", allowed("tile.polygons"))
    if ("library" in t) == ("points" in t):
        raise ProblemError("config section tile (scheme 'polygons') needs exactly one of 'library' "
                           f"({sorted(POLYGON_TILES)}) or 'points' with 'polygons' and/or 'lines'")
    if "library" in t:
        extra = sorted(set(t) - {"library"})
        if extra:
            _fail(f"tile.{extra[0]}", "goes with 'points', not with 'library'")
        name = _choice(t["library"], "tile.library", POLYGON_TILES)
        return {"library": name, "facets": bool(POLYGON_TILES[name]().polygons)}
    t = filled("tile.polygons", t)
    out = {"points": t["points"], "polygons": t["polygons"], "lines": t["lines"], "name": _str(t["name"], "tile.name")}
    out["facets"] = bool(out["polygons"])
    try:
        PolygonTile(out["points"], out["polygons"], out["lines"], out["name"])
    except TilingError as exc:  # it names what is wrong (shape, range, indices)
        _fail("tile", str(exc))
    except (ValueError, TypeError) as exc:  # points that are not numbers
        _fail("tile.points", f"must be a list of [x, y, z] numbers in the unit cube ({exc})")
    return out


def primitives(config, base_dir, names_in: str) -> list:
    """The checked [[primitive]] tables of a V-rep model: name, map, tile, counts, priority; every name the
    expression ``names_in`` uses is defined once."""
    items = config.get("primitive")
    if not isinstance(items, list) or not items:
        raise ProblemError("the vrep scheme needs [[primitive]] tables (name, map, tile, counts, priority), one per "
                           "primitive of paving.expression")
    out, seen = [], set()
    for i, v in enumerate(items):
        w = f"primitive[{i}]"
        t = _table(v, w, allowed("primitive"), required("primitive"))
        name = _str(t["name"], f"{w}.name")
        if not _NAME.match(name) or name in seen:
            _fail(f"{w}.name", f"must be a new word of letters, digits and _ (the expression names it), got "
                               f"{show(name)}")
        seen.add(name)
        tile = tile_section(t["tile"], f"{w}.tile")
        if 3 not in _dims(tile):
            _fail(f"{w}.tile", f"{tile['library']!r} has no trivariates; a V-model's tiles are bridged by "
                               "trivariates and analysed: use a volumetric tile such as cross")
        out.append({"name": name, "map": map_section(t["map"], base_dir, f"{w}.map"), "tile": tile,
                    "counts": _ints(t["counts"], f"{w}.counts", 3),
                    "priority": _int(t.get("priority", default("primitive", "priority")), f"{w}.priority", -10**9)})
    parse_expression(names_in, lambda name: {name}, "primitive", "\"(body | wing) - hole\"")  # its syntax
    used = set(re.findall(r"[A-Za-z_][A-Za-z0-9_]*", names_in))
    if used - seen:
        _fail("paving.expression", f"names {sorted(used - seen)[0]!r}, which no [[primitive]] defines; defined: "
                                   f"{sorted(seen)}")
    if seen - used:
        _fail("paving.expression", f"leaves out the primitive {sorted(seen - used)[0]!r}; use every [[primitive]] "
                                   "or remove it")
    return out


def second_level(v) -> dict:
    """[second_level]: every trivariate of the first level paved again by ``tile`` (``counts``), each reduced to
    ``degree`` (2 or 3) or kept exact (``degree = "exact"``), its free sides capped with ``seal = "cap"``."""
    t = _table(v, "second_level", allowed("second_level"), required("second_level"))
    deg = t.get("degree", default("second_level", "degree"))
    if deg != "exact" and (not isinstance(deg, int) or isinstance(deg, bool) or deg not in (2, 3)):
        _fail("second_level.degree", f"must be 2, 3 or \"exact\", got {show(deg)}")
    return {"tile": tile_section(t["tile"], "second_level.tile"), "counts": _ints(t["counts"], "second_level.counts", 3),
            "degree": None if deg == "exact" else deg,
            "seal": None if "seal" not in t else _choice(t["seal"], "second_level.seal", ("cap",))}


def reduce_section(v) -> dict:
    """[reduce]: the model's patches approximated by ``degree`` (2 or 3), deviation measured on ``check`` points
    per direction and piece."""
    t = _table(v, "reduce", allowed("reduce"), required("reduce"))
    deg = t["degree"]
    if not isinstance(deg, int) or isinstance(deg, bool) or deg not in (2, 3):
        _fail("reduce.degree", f"must be 2 or 3, got {show(deg)}")
    return {"degree": deg, "check": _int(t.get("check", default("reduce", "check")), "reduce.check", 2)}


def _dims(tile_cfg) -> set:
    """The parametric dimensions of a library tile's patches (the tile is built: library tiles are small)."""
    return {p.dim for p in TILES[tile_cfg["library"]](**tile_cfg["args"]).patches}


def surface_reason(cfg: dict) -> str | None:
    """Why the configured model has no volume (its outputs are surfaces or curves), or None."""
    scheme = cfg["paving"]["scheme"]
    if scheme in ("random_implicit", "implicit_bifurcation"):
        return f"the {scheme.replace('_', ' ')} structure is a surface (the boundary of an implicit solid)"
    if scheme == "polygons":
        return "a polygonal paving is a mesh of straight edges and facets through mapped vertices"
    for where, tile in (("tile", cfg.get("tile")), ("second_level.tile", (cfg.get("second_level") or {}).get("tile"))):
        if tile and "args" in tile and 3 not in _dims(tile):
            kind = "curves" if _dims(tile) == {1} else "surfaces"
            return (f"{where} {tile['library']!r} is made of {kind}: its paving is {kind} in space (exported as "
                    "such), with no volume to analyse")
    return None


_SCHEME_CHECKS = {"field_graded": field_graded, "bifurcation": bifurcation, "random_implicit": random_implicit,
                  "implicit_bifurcation": implicit_bifurcation, "vrep": vrep, "polygons": polygons}
