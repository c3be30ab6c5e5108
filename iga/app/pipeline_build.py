"""What a pipeline builds: the map, then the model of its [paving] scheme, a second level and a reduction.

:func:`build` returns a :class:`Built`: the model to analyse (a
``tiling.Microstructure``, or after ``[reduce]`` a ``geometry.MultiPatch``
with the micro-structure's interfaces and tags), the micro-structure it came
from (for tile and level counts), or a surface mesh for schemes that build
no volumes (random implicit and implicit bifurcation structures, polygon
pavings), and a summary of the construction.  The configuration was checked
whole before (:func:`iga.app.config.validate`); what fails here is geometry
(a map that folds, tiles that do not meet), reported by the builders' own
errors.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

import tiling
from geometry import BSpline, load, reduced_model
from tiling.library import TILES
from tiling.materials import graded_channel
from tiling.members.polygons import PolygonTile
from tiling.vrep import Primitive, vrep_microstructure

from iga.app.config_model import POLYGON_TILES, width_family
from iga.app.maps import MAPS
from iga.tags import parse_expression

__all__ = ["Built", "build", "build_map", "build_maps"]


@dataclass
class Built:
    """A pipeline's model: ``model`` (analysed), ``structure`` (the micro-structure or implicit structure it came
    from), ``mesh`` (the surface of a surface-only scheme, else None), ``info`` (construction summary)."""

    model: object
    structure: object
    mesh: object = None
    info: dict = field(default_factory=dict)

    @property
    def volumetric(self) -> bool:
        """Whether the model has trivariates to analyse."""
        return self.mesh is None and any(P.spline.dim == 3 for P in self.model.patches)


def build_map(cfg) -> BSpline:
    """The [map] (or a primitive's map table): a built-in map or a saved one, with its graded channels."""
    D = load(cfg.file) if "file" in cfg else MAPS[cfg.primitive](**cfg.args)
    for g in cfg.get("grading", []):
        D = graded_channel(D, g["channel"], g["near"], g["far"], g["face"], g["mode"])
    return D


def _tile(t):
    return TILES[t.library](**t.args)


def macro_material(macro, youngs: float, poisson: float):
    """physics.macro's :class:`iga.CubicMaterial`: the cubic stiffness of the family (one width, or six face values
    alike) made of ``youngs`` (Pa) and ``poisson``, tabulated at its ``values`` and read at its ``channel``."""
    from iga.homogenisation.macro import stiffness_table

    return stiffness_table(width_family(macro["family"]), macro["values"], youngs, poisson,
                           name=macro["family"]).material(macro["channel"])


def build_maps(cfg):
    """The deformation map of the configuration; for the vrep scheme {primitive name: map}."""
    if cfg.paving.scheme == "vrep":
        return {q["name"]: build_map(q["map"]) for q in cfg.primitives}
    return build_map(cfg.map)


def _vrep(cfg, maps: dict) -> Built:
    """The V-model of the [[primitive]] tables combined by ``paving.expression`` (Hong and Elber 2021)."""
    p = cfg.paving
    prims = {q["name"]: Primitive(maps[q["name"]], _tile(q["tile"]), tuple(q["counts"]), q["priority"], q["name"])
             for q in cfg.primitives}
    model = parse_expression(p.expression, prims.__getitem__, "primitive", "\"(body | wing) - hole\"")
    res = vrep_microstructure(model, samples=p.samples, margin=p.margin, bridges=p.bridges, beta=p.beta,
                              d_maxdist=p.d_maxdist, phi=p.phi, alpha=p.alpha)
    ms = res.microstructure
    info = {"vrep": {"model": repr(model), "tiles_per_primitive": res.counts(), "bridges": res.bridges.as_dict(),
                     "timings_s": {k: float(v) for k, v in res.timings.items()}}}
    return Built(ms, ms, None, info)


def _polygons(cfg, D) -> Built:
    t = cfg.tile
    tile = POLYGON_TILES[t.library]() if "library" in t else PolygonTile(t.points, t.polygons, t.lines,
                                                                            t.name)
    mesh = tiling.pave_polygons(D, tile, cfg.paving.counts)
    facets = int(mesh.n_cells - mesh.n_lines - mesh.n_verts)
    info = {"tiles": int(np.prod(cfg.paving.counts)), "polygon_tile": tile.name,
            "mesh": {"points": int(mesh.n_points), "lines": int(mesh.n_lines), "facets": facets}}
    return Built(mesh, mesh, mesh, info)


def _scheme(cfg, D):
    """The model of the [paving] scheme in the map D."""
    p = cfg.paving
    if p.scheme == "implicit_bifurcation":
        s = tiling.implicit_bifurcation(D, p.epsilon, alpha=p.alpha, seed=p.seed, cap=p.cap,
                                        resolution=p.resolution, radius=p.radius)
        return Built(s, s, s.surface())  # contoured once: every file and the report use this mesh
    if p.scheme == "random_implicit":
        s = tiling.random_implicit(D, p.counts, alpha=p.alpha, seed=p.seed, continuity=p.continuity,
                                   connectivity=p.connectivity, cap=p.cap, resolution=p.resolution)
        # the summary says whether the connectivity is certified on the spline, and what the certificate changed
        cert = {k: (list(v) if isinstance(v, tuple) else v) for k, v in s.stats["certificate"].items()}
        return Built(s, s, s.surface(), {"certificate": cert})
    if p.scheme == "polygons":
        return _polygons(cfg, D)
    if p.scheme == "bifurcation":
        ms = tiling.bifurcation(D, p.epsilon, p.kind, direction=p.direction, levels=p.levels,
                                margin=p.margin)
        return Built(ms, ms)
    if p.scheme == "field_graded":
        ms = tiling.field_graded(D, TILES[cfg.tile.library], p.counts, _wall_field(D, p.field))
        return Built(ms, ms)
    tile = _tile(cfg.tile)
    seal = {k: p[k] for k in ("seal", "thickness", "seal_sides") if k in p}
    if p.scheme == "hierarchical" and "leaves" in p:
        ms = tiling.leaf_graded(D, tile, p.counts, p.levels, TILES[p.leaves], _wall_field(D, p.field), scale=p.scale)
    elif p.scheme == "hierarchical":
        ms = tiling.hierarchical(D, tile, p.counts, p.levels, p.scale, **seal)
    else:
        ms = tiling.regular(D, tile, p.counts, **seal)
    return Built(ms, ms)


def _wall_field(D, field):
    """paving.field for :func:`tiling.field_graded` (and graded leaves, :func:`tiling.leaf_graded`): a number or a channel name as they are, a formula of the
    position as a callable of the normalised parameters (evaluated where D maps them)."""
    if not callable(field):
        return field
    dom = D.domain

    def at(s):
        x = D.evaluate(dom[:, 0] + np.asarray(s) * (dom[:, 1] - dom[:, 0]))[:, :3]
        return field(x)

    return at


def build(cfg, maps) -> Built:
    """The configured model (module notes) on the map(s) of :func:`build_maps`."""
    built = _vrep(cfg, maps) if cfg.paving.scheme == "vrep" else _scheme(cfg, maps)
    second = cfg.get("second_level")
    if second:
        ms = tiling.compose_levels(built.structure, _tile(second["tile"]), second["counts"], degree=second["degree"],
                                   seal=second["seal"])
        built = Built(ms, ms, None, {**built.info, "second_level": {"tiles": ms.n_tiles, "patches": len(ms.patches)}})
    if not built.volumetric and built.mesh is None:
        built.mesh = built.structure.surface()  # surface and curve tiles: their paving is the output
    red = cfg.get("reduce")
    if red:
        model, report = reduced_model(built.model, red["degree"], red["check"])
        built.model = model
        built.info["reduction"] = {"degree": red["degree"], "deviation_m": report["deviation"],
                                   "branch_gap_m": report["branch_gap"],
                                   "control_points": list(report["control_points"]),
                                   "degrees_before": [list(d) for d in report["degrees_before"]]}
    return built
