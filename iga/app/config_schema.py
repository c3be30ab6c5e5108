"""The keys of every section of a pipeline configuration, with what each takes, its default and its meaning: the
one table the validator (:mod:`iga.app.config`, :mod:`iga.app.config_model`, :mod:`iga.app.config_physics`,
:mod:`iga.app.config_time`) reads its allowed keys, required keys and defaults from, and from which the TOML
reference of the documentation is written (``python -m iga.app.config_schema`` prints it,
``docs/pipeline-reference.md``), so the two cannot drift apart.

A section whose keys depend on a choice (the paving's ``scheme``) has one entry per choice, named
``"paving.regular"``, ``"paving.vrep"``, ...; the table of a V-rep primitive is ``"primitive"``, the grading
table of a map ``"map.grading"``.
"""

from __future__ import annotations

from dataclasses import dataclass
from math import pi

import solvers
from iga.app.maps import MAPS

__all__ = ["Key", "Section", "SCHEMA", "REQUIRED", "allowed", "required", "default", "filled", "reference"]


class _Required:
    """The default of a key that must be given."""

    def __repr__(self) -> str:
        return "required"


REQUIRED = _Required()
#: the default of an optional key that has no value when left out (its meaning says what happens then)
UNSET = None


@dataclass(frozen=True)
class Key:
    """One key of a section: ``takes`` says its type and range in words, ``default`` its value when left out
    (:data:`REQUIRED`: it must be given; None: unset, ``meaning`` says what that does)."""
    name: str
    takes: str
    default: object
    meaning: str


@dataclass(frozen=True)
class Section:
    """A section (``[name]``), an array of tables (``[[name]]``, ``many``) or an inner table of one."""
    name: str
    title: str
    meaning: str
    keys: tuple
    many: bool = False

    def key(self, name: str) -> Key:
        return next(k for k in self.keys if k.name == name)


def _one_of(names) -> str:
    names = [f"`{n}`" for n in names]
    return ", ".join(names[:-1]) + " or " + names[-1]


def _K(name, takes, default, meaning) -> Key:
    return Key(name, takes, default, meaning)


_TILE_KEYS = (_K("library", "a tile of `tiling.library` (see [Tiles](tiles.md))", REQUIRED,
                 "the tile paved into every cell"),
              _K("args", "a table of the tile's keyword arguments", {}, "e.g. `{arm = 0.3}`; checked against the "
                 "tile's signature"))
_SEAL = (_K("seal", "`\"cap\"` or `\"shell\"`", UNSET, "seal the paving's free sides (Massarwi et al. 2018, "
            "Section 6.2): caps of the tiles' open ends, or shells around surface tiles"),
         _K("thickness", "a number in (0, 0.5)", 0.1, "the seal's thickness, a fraction of the cell"),
         _K("seal_sides", "a list of face names (`umin` .. `wmax`)", ["umin", "umax", "vmin", "vmax", "wmin", "wmax"],
            "the sides that `seal = \"cap\"` closes"))

_SECTIONS = (
    Section("map", "[map]", "The deformation map: a built-in primitive or a saved trivariate (exactly one).", (
        _K("primitive", _one_of(MAPS), UNSET, "a built-in map (`iga.app.maps`); give this or `file`"),
        _K("args", "a table of the primitive's keyword arguments", {}, "e.g. `{size = [0.03, 0.03, 0.03]}`, "
           "`channels = {k = 205.0}` for a constant material channel"),
        _K("file", "a path to a `.npz` written by `geometry.io.save`", UNSET, "a saved trivariate, relative to "
           "the config file; give this or `primitive`"),
        _K("grading", "a `map.grading` table or a list of them", UNSET, "material channels graded from one face "
           "(one table per channel)"))),
    Section("map.grading", "[map] grading = {...}", "A material channel graded linearly from one face of the map.", (
        _K("channel", "a channel name", "k", "the channel written onto the map's control points"),
        _K("near", "a number", 205.0, "its value on `face`"),
        _K("far", "a number", 54.0, "its value on the opposite face"),
        _K("face", "`umin` .. `wmax`", "wmin", "where the channel takes `near`"),
        _K("mode", "`\"parameter\"` or `\"distance\"`", "parameter", "linear in the map's parameter, or in the "
           "distance from `face`"))),
    Section("tile", "[tile]", "The tile of the `regular` and `hierarchical` schemes (and of `[second_level]`).",
            _TILE_KEYS),
    Section("tile.polygons", "[tile] (scheme \"polygons\")", "The polygon tile: a library tile, or points with "
            "facets and/or lines (Elber 2017, Eq. 3).", (
                _K("library", "`\"beam_lattice\"`", UNSET, "a built-in polygon tile; give this or `points`"),
                _K("points", "a list of [x, y, z] in the unit cube", UNSET, "the tile's vertices"),
                _K("polygons", "a list of vertex-index lists", [], "its facets"),
                _K("lines", "a list of vertex-index lists", [], "its polylines"),
                _K("name", "a string", "polygon tile", "its name in the summary"))),
    Section("paving.regular", "[paving] scheme = \"regular\"", "Copies of the tile in `counts` cells of the map's "
            "parameter domain, each composed into the map (Elber 2017, Eq. 2).", (
                _K("scheme", "`\"regular\"`", REQUIRED, "the paving scheme"),
                _K("counts", "three integers >= 1", REQUIRED, "cells along u, v, w")) + _SEAL),
    Section("paving.hierarchical", "[paving] scheme = \"hierarchical\"", "Tiles paved into tiles, `levels` deep "
            "(Massarwi et al. 2018, Section 3; branch faces glued by refinement matrices).", (
                _K("scheme", "`\"hierarchical\"`", REQUIRED, "the paving scheme"),
                _K("counts", "two integers >= 1", REQUIRED, "cells along u and v of every level"),
                _K("levels", "an integer >= 1", 2, "the depth of the hierarchy"),
                _K("scale", "a number > 0", UNSET, "each level's height relative to the one below (unset: "
                   "equal heights)"),
                _K("leaves", "a library tile of the six faces' values", UNSET, "the last level's tiles from this "
                   "family (e.g. `face_graded_heat_sink`: the finest pins graded), their values from `field` "
                   "(`tiling.leaf_graded`; not with `seal`)"),
                _K("field", "a number, a channel name of the map or `{formula = \"...\"}` of x, y, z (m)", UNSET,
                   "with `leaves`: their face parameter, taken at the centre of every leaf's walls")) + _SEAL),
    Section("paving.field_graded", "[paving] scheme = \"field_graded\"", "Cells whose tile takes its parameters "
            "from a field on the six faces (`tiling.field_graded`): grading in three directions; [tile] names a "
            "family of the six faces, `face_graded_cross` or `face_graded_heat_sink`.", (
                _K("scheme", "`\"field_graded\"`", REQUIRED, "the paving scheme"),
                _K("counts", "three integers >= 1", REQUIRED, "cells along u, v, w"),
                _K("field", "a number, a channel name of the map or `{formula = \"...\"}` of x, y, z (m)", REQUIRED,
                   "the tiles' face parameter (an arm or pin width, a fraction of the cell), taken at the centre of "
                   "every wall of the cell grid"))),
    Section("paving.bifurcation", "[paving] scheme = \"bifurcation\"", "Adaptive bifurcation: the cells split "
            "where the map is large (Massarwi et al. 2018, Section 5); no [tile].", (
                _K("scheme", "`\"bifurcation\"`", REQUIRED, "the paving scheme"),
                _K("epsilon", "a number > 0 (model units)", UNSET, "the largest cell edge; give this or `levels`"),
                _K("levels", "a list of integers >= 0", UNSET, "the level of every layer; give this or `epsilon`"),
                _K("kind", "`\"1-2\"`, `\"1-4a\"` or `\"1-4b\"`", "1-2", "the bifurcation tile"),
                _K("direction", "0, 1 or 2", 2, "the direction of growth"),
                _K("margin", "a number in (0, 0.5)", 0.3, "the tiles' wall margin"))),
    Section("paving.vrep", "[paving] scheme = \"vrep\"", "A Boolean model over [[primitive]] tables, each a paved "
            "map (Hong and Elber 2021); no [map], no [tile].", (
                _K("scheme", "`\"vrep\"`", REQUIRED, "the paving scheme"),
                _K("expression", "a Boolean expression of the primitives' names", REQUIRED,
                   "`|` union, `&` intersection, ` - ` subtraction, parentheses: `\"(body | wing) - hole\"`"),
                _K("samples", "an integer >= 2", 4, "points per direction that classify a cell"),
                _K("margin", "a number in [0, 0.5)", 0.0, "cells this close to a boundary count as cut"),
                _K("bridges", "true or false", True, "bridge the cut cells to the surface"),
                _K("beta", "a number in (0, 1)", 0.5, "the bridges' anchoring fraction"),
                _K("d_maxdist", "a number > 0", UNSET, "the largest bridge length (unset: no bound)"),
                _K("phi", "a number in [0, 1]", 0.0, "the bridges' twist limit"),
                _K("alpha", "an angle in (0, pi/2) rad", pi / 4, "the largest angle between a bridge and the "
                   "surface normal"))),
    Section("paving.polygons", "[paving] scheme = \"polygons\"", "A polygon tile paved by vertex mapping (Elber "
            "2017, Eq. 3): a mesh, no analysis.", (
                _K("scheme", "`\"polygons\"`", REQUIRED, "the paving scheme"),
                _K("counts", "three integers >= 1", REQUIRED, "cells along u, v, w"))),
    Section("paving.random_implicit", "[paving] scheme = \"random_implicit\"", "Random fields around the canonical "
            "tubes (Massarwi et al. 2018, Section 4): a surface, no analysis; no [tile].", (
                _K("scheme", "`\"random_implicit\"`", REQUIRED, "the paving scheme"),
                _K("counts", "three integers >= 1", REQUIRED, "cells along u, v, w"),
                _K("alpha", "a number in [0, 1)", 0.5, "the share of randomness"),
                _K("seed", "an integer >= 0", 0, "the random seed"),
                _K("continuity", "`\"C0\"` or `\"C1\"`", "C0", "the fields' continuity across cells"),
                _K("connectivity", "an integer >= 1", 1, "the components the structure must have at most"),
                _K("cap", "true or false", False, "close the structure at the map's boundary"),
                _K("resolution", "an integer >= 2", 12, "marching-cubes samples per cell and direction"))),
    Section("paving.implicit_bifurcation", "[paving] scheme = \"implicit_bifurcation\"", "Implicit tubes over "
            "the adaptive subdivision (Massarwi et al. 2018, Section 5.2, Fig. 16): a surface, no analysis.", (
                _K("scheme", "`\"implicit_bifurcation\"`", REQUIRED, "the paving scheme"),
                _K("epsilon", "a number > 0 (model units)", REQUIRED, "the largest cell edge"),
                _K("alpha", "a number in [0, 1)", 0.0, "the share of randomness"),
                _K("seed", "an integer >= 0", 0, "the random seed"),
                _K("cap", "true or false", True, "close the structure at the map's boundary"),
                _K("resolution", "an integer >= 2", 8, "marching-cubes samples per cell and direction"),
                _K("radius", "a number in (0, 0.5)", 0.35, "the tubes' radius, a fraction of the cell"))),
    Section("primitive", "[[primitive]]", "One primitive of a V-rep model (scheme \"vrep\").", (
        _K("name", "a word of letters, digits and _", REQUIRED, "the name the expression uses"),
        _K("map", "a table like [map]", REQUIRED, "the primitive's map"),
        _K("tile", "a table like [tile]", REQUIRED, "its tile (volumetric)"),
        _K("counts", "three integers >= 1", REQUIRED, "cells per knot span along u, v, w"),
        _K("priority", "an integer", 0, "the higher priority tiles a V-cell two primitives share")), many=True),
    Section("second_level", "[second_level]", "Every trivariate of the first level paved again (Massarwi et al. "
            "2018, Fig. 12); volumetric first levels.", (
                _K("tile", "a table like [tile]", REQUIRED, "the second level's tile"),
                _K("counts", "three integers >= 1", REQUIRED, "cells per first-level trivariate"),
                _K("degree", "2, 3 or `\"exact\"`", 2, "each first-level trivariate reduced to this degree before "
                   "it is paved, or kept exact"),
                _K("seal", "`\"cap\"`", UNSET, "cap the first level's free faces (surface tiles)"))),
    Section("reduce", "[reduce]", "The model's patches approximated by a lower degree (Massarwi et al. 2018, "
            "Section 6.3), interfaces, slots and tags kept; the summary reports the deviation (m).", (
                _K("degree", "2 or 3", REQUIRED, "the degree of the approximation"),
                _K("check", "an integer >= 2", 9, "points per direction and piece where the deviation is measured"))),
    Section("material", "[material]", "The heat problem's material.", (
        _K("conductivity", "a number > 0 (W/(m K)), a channel name, `{formula = \"...\"}`, six channel names, a "
           "3 x 3 matrix or a table of [T, k] rows", 1.0, "a table of [T, k] rows (T increasing) makes k depend "
           "on the temperature (solved by Newton)"),
        _K("source", "a number or a formula of x, y, z (W/m^3)", 0.0, "the volumetric heat source"),
        _K("capacity", "a number > 0, a channel name or `{formula = \"...\"}` (J/(m^3 K))", UNSET,
           "rho c; `transient-heat` only, where it is required"))),
    Section("bc", "[[bc]]", "One condition of the heat problem; values are numbers or formulas of x, y, z.", (
        _K("kind", "`\"dirichlet\"`, `\"neumann\"`, `\"robin\"` or `\"radiation\"`", REQUIRED, "the condition"),
        _K("tag", "a tag, a tag expression or a list of tags", REQUIRED, "the faces it holds on"),
        _K("value", "a number or a formula", 0.0, "dirichlet: the temperature (C); neumann: the inflowing flux "
           "(W/m^2)"),
        _K("h", "a number >= 0 or a formula (W/(m^2 K))", UNSET, "robin: the film coefficient (required)"),
        _K("ambient", "a number or a formula (C)", UNSET, "robin and radiation: the surroundings' temperature "
           "(required)"),
        _K("emissivity", "a number in [0, 1] or a formula", UNSET, "radiation: the surface's emissivity "
           "(required)"),
        _K("scale", "`\"K\"` or `\"C\"`", "K", "radiation: the temperatures are kelvin, or Celsius (273.15 "
           "added in the Stefan-Boltzmann law)")), many=True),
    Section("physics", "[physics]", "What is analysed.", (
        _K("kind", "`\"heat\"`, `\"transient-heat\"`, `\"elasticity\"`, `\"thermo-elastic\"` or `\"none\"`",
           "heat", "`none` builds and exports the model only (the default for surfaces without [[bc]])"),
        _K("youngs", "a number > 0 (Pa), a channel name or `{formula = \"...\"}`", UNSET,
           "Young's modulus; required by the elastic kinds"),
        _K("poisson", "a number in (-1, 0.5), a channel name or `{formula = \"...\"}`", UNSET,
           "Poisson's ratio; required by the elastic kinds"),
        _K("expansion", "a number (1/K), a channel name or `{formula = \"...\"}`", UNSET,
           "the thermal expansion coefficient; required by `thermo-elastic`"),
        _K("reference", "a number (C)", 20.0, "`thermo-elastic`: the temperature without thermal strain"),
        _K("hold_rigid", "true or false", False, "hold the body against rigid motion only (3-2-1 at three "
           "corners) instead of [[support]] tables"),
        _K("macro", "`{family = \"cross\", values = [...], channel = \"t\"}`", UNSET, "`elasticity` on a lattice's "
           "homogenised macro model: the map alone (`[tile] library = \"cube\"`, one cell) whose material is the "
           "cubic effective stiffness of `family` (`cross`, or a family of six face values with all six alike, "
           "e.g. `face_graded_cross`) made of `youngs` and `poisson`, tabulated at the arm widths `values` (>= 2, "
           "increasing) and read at the map's channel `channel` (`iga.stiffness_table`)"))),
    Section("support", "[[support]]", "A displacement held (the elastic kinds): on faces (`tag`), or on the control "
            "points of a patch edge, a patch corner, a point or a box (exactly one of `tag`, `edge`, `corner`, "
            "`point`, `box`); with `stiffness`, springs instead of a rigid hold.", (
        _K("tag", "a tag, a tag expression or a list of tags", UNSET, "the faces held"),
        _K("edge", "two face tags", UNSET, "the patch edges where a face of each meets: a line support "
           "(e.g. `[\"umin\", \"wmin\"]`)"),
        _K("corner", "three face tags", UNSET, "the patch corners where a face of each meets: a point support"),
        _K("point", "[x, y, z] (m)", UNSET, "the nodes at this point"),
        _K("box", "[[x0, y0, z0], [x1, y1, z1]] (m)", UNSET, "the nodes inside this box"),
        _K("value", "a number, a formula or a list of three (m)", 0.0, "the displacement imposed"),
        _K("components", "distinct letters of `xyz`", "xyz", "the components held (`\"z\"`: free to slide)"),
        _K("stiffness", "a number > 0 (N/m per node)", UNSET, "springs on the selected nodes' `components` instead "
           "of a rigid hold (not with `tag`)"),
        _K("name", "a string", UNSET, "the name of its reaction in the summary (default: the tag, or "
           "`support[i]`)")), many=True),
    Section("load", "[[load]]", "A load (the elastic kinds): on faces, or a force at a point.", (
        _K("kind", "`\"traction\"`, `\"pressure\"` or `\"point\"`", REQUIRED, "a traction vector, a pressure "
           "along the inward normal, or a force at a point"),
        _K("tag", "a tag, a tag expression or a list of tags", UNSET, "the faces loaded (traction, pressure)"),
        _K("point", "[x, y, z] (m)", UNSET, "where a point force acts (kind `\"point\"`); its stress there is "
           "infinite, the summary's largest von Mises stress grows under refinement"),
        _K("value", "traction: a list of three numbers or formulas (Pa); pressure: a number or a formula (Pa); "
           "point: three numbers (N)", REQUIRED, "the load")), many=True),
    Section("time", "[time]", "The time stepping of `physics.kind = \"transient-heat\"` (required there).", (
        _K("end", "a number of seconds > 0, or `\"steady\"`", REQUIRED, "`\"steady\"` runs until the point "
           "of largest steady change (no Dirichlet condition holding it) has changed by `fraction` of that change"),
        _K("step", "a number > 0 (s)", UNSET, "fixed steps (or the first adaptive step); give this or "
           "`tolerance`"),
        _K("tolerance", "a number > 0 (K)", UNSET, "the error allowed per step: adaptive steps; required by "
           "`end = \"steady\"`"),
        _K("method", "`\"bdf2\"`, `\"crank-nicolson\"`, `\"backward-euler\"` or `\"theta\"`", "bdf2",
           "the time scheme"),
        _K("theta", "a number in [0.5, 1]", UNSET, "the theta of `method = \"theta\"` (required there)"),
        _K("initial", "a number or a formula of x, y, z (C)", 0.0, "the initial temperature"),
        _K("every", "an integer >= 1", 1, "every n-th step is kept and written to `NAME.pvd`"),
        _K("fraction", "a number in (0, 1)", 0.95, "`end = \"steady\"`: the share of the steady rise"),
        _K("max_steps", "an integer >= 1", 100_000, "the run stops with an error after this many steps"))),
    Section("adapt", "[adapt]", "Adaptive refinement by tiles of a steady heat analysis (`physics.kind = "
            "\"heat\"`): solve, estimate the error per patch, split the patches that carry most of it, repeat "
            "(`iga.adaptivity`).", (
        _K("tolerance", "a number > 0", REQUIRED, "the relative energy-norm error wanted (the residual estimate "
           "over the solution's energy norm), e.g. `1e-3`"),
        _K("max_unknowns", "an integer >= 1", UNSET, "stop before a step with more DOFs; the best solution so far "
           "is written and the summary says why it stopped"),
        _K("marking", "a number in (0, 1]", 0.5, "Dorfler's fraction: the patches marked carry at least this share "
           "of the squared estimate"),
        _K("refine", "`\"h\"`, `\"h-in-place\"`, `\"p\"` or `\"hp\"`", "h", "`h` splits a marked patch into "
           "2 x 2 x 2 children (patches with discontinuity planes are bisected in place), `h-in-place` bisects its "
           "knot spans, `p` raises its degree by one, `hp` chooses per patch (split where the error did not fall "
           "as predicted)"),
        _K("max_steps", "an integer >= 1", 50, "at most this many solves"),
        _K("goal", "a list of tags of Robin faces", [], "goal-oriented: converge the heat flows through these "
           "tags (the tolerance then bounds their estimated error, each relative to its size) by marking with "
           "the dual-weighted indicators; one more solve per step"))),
    Section("design", "[design]", "Design by gradient of a steady heat analysis (`physics.kind = \"heat\"`) or "
            "an elastic one (`\"elasticity\"`; `iga optimize CONFIG.toml`, or `iga run`): the control values of the "
            "map's channel that the conductivity (or Young's modulus) reads, the map's control points (its shape), or "
            "the field of a `field_graded` paving (its tiles' parameters), optimised for an output "
            "(`iga.optimize`).", (
        _K("variables", "`\"channel:NAME\"`, `\"map\"` or `\"parameters\"`", REQUIRED, "the channel NAME of "
           "the map (the one `material.conductivity` names, `physics.youngs`, or `physics.macro`'s channel), e.g. made "
           "by `map.grading`; or "
           "`map`: the coordinates of the map's control points, at the solid volume of the start; or `parameters`: the control values of "
           "`paving.field` (a number or a channel of the map) of a `field_graded` paving or of a hierarchical one "
           "with `leaves`, at the solid volume of the start"),
        _K("bounds", "[low, high]", UNSET, "the bounds of every control value: of a channel (W/(m K); Pa for "
           "Young's modulus), e.g. `[54, 205]` for steel to aluminium, or of the parameter field, inside the tile "
           "family's range, e.g. `[0.15, 0.6]` arm widths (required for `channel:NAME` and `parameters`)"),
        _K("move", "a number > 0 (m)", UNSET, "the largest move of a control point coordinate (required for "
           "`map`; below a quarter of the control points' spacing)"),
        _K("axes", "some of `x`, `y`, `z` once each", "xyz", "`map`: the coordinates that move (`\"z\"`: "
           "heights only, e.g. where a sink's base ends across it between a held bottom and top)"),
        _K("hold", "a list of the map's faces (`umin` .. `wmax`)", [], "`map` and `parameters`: the faces whose "
           "control points (or the field's control values there) stay, e.g. the heated one (its area, so the power "
           "of a flux per area, is kept)"),
        _K("objective", "heat: `\"temperature_norm\"` or `\"mean_temperature\"`; elasticity: `\"compliance\"` or "
           "`\"von_mises_norm\"`", "temperature_norm",
           "the output minimised: a smooth maximum (int T^p / V)^(1/p), or the mean; the loads' work u . f, or the "
           "smooth maximum of the von Mises stress (int sigma_vm^p / V)^(1/p)"),
        _K("p", "a number >= 1", 8.0, "the exponent of `temperature_norm` and `von_mises_norm`"),
        _K("tag", "a tag (expression)", UNSET, "heat: over the faces of this tag instead of the volume"),
        _K("mean", "a number (W/(m K); Pa)", UNSET, "keep the volume mean of the channel (for a channel between two "
           "materials: the volume, and the mass, of each)"),
        _K("keep_fraction", "true or false", False, "`channel:NAME` of a `physics.macro` model: keep its mean solid "
           "fraction (the lattice's mass) instead of a `mean`"),
        _K("iterations", "an integer >= 1", 30, "SLSQP's iteration limit"))),
    Section("solver", "[solver]", "The discretisation and the linear solver.", (
        _K("method", _one_of(m for m in solvers.backends() if m != "petsc") + " (`petsc` with the [mpi] extra)",
           "auto", "`auto` chooses by the problem's size and structure"),
        _K("tol", "a number in (0, 1)", 1e-10, "the iterative solvers' relative residual"),
        _K("maxiter", "an integer >= 1", UNSET, "the iterative solvers' iteration limit (unset: their own)"),
        _K("refine", "an integer >= 0", 0, "uniform h-refinement rounds of every tile space"),
        _K("degree_elevation", "an integer >= 0", 0, "degrees added to every patch's space"),
        _K("degree", "an integer >= 1", UNSET, "the analysis degree of every patch instead of the tile's"),
        _K("quadrature_extra", "an integer >= 0", 0, "Gauss points per direction beyond degree + 1"))),
    Section("output", "[output]", "What is written, and where.", (
        _K("dir", "a folder, relative to the config file", "out", "the output folder"),
        _K("name", "a plain file name (at most 200 characters)", "result", "the stem of every file written"),
        _K("vtu", "true or false", True, "write `NAME.vtu` (sampled, every field)"),
        _K("bezier", "true or false", False, "also write `NAME_bezier.vtu`: exact Bezier hexahedra"),
        _K("compress", "true or false", False, "zlib-compress the VTU arrays: files about 2.5 times smaller, "
           "written about 30 times slower (raw: every reader takes both)"),
        _K("png", "true or false", True, "render `NAME.png` (needs the VTU)"),
        _K("samples", "an integer >= 1", 3, "VTU samples per element and direction"),
        _K("tolerance", "a number > 0 (m)", UNSET, "instead of `samples`: the samples that keep the written cells "
           "within it of the exact geometry"),
        _K("probes", "a list of [x, y, z] points (m)", [], "temperatures reported at these points"),
        _K("exports", "a list of `stl`, `obj`, `ply`, `vtp`, `iges`, `gismo`", [], "the boundary surface "
           "(stl/obj/ply/vtp), the exact boundary (iges), the heat problem as G+Smo XML (gismo)"))),
    Section("limits", "[limits]", "Resource limits.", (
        _K("max_memory_gib", "a number > 0 (GiB)", UNSET, "the memory a run may use (unset: the memory "
           "available); a model estimated beyond it is refused before it is built"),)),
)

#: every section by name
SCHEMA: dict[str, Section] = {s.name: s for s in _SECTIONS}


def allowed(section: str) -> set:
    """The keys ``section`` takes."""
    return {k.name for k in SCHEMA[section].keys}


def required(section: str) -> tuple:
    """The keys ``section`` cannot do without."""
    return tuple(k.name for k in SCHEMA[section].keys if k.default is REQUIRED)


def default(section: str, key: str):
    """The value of ``key`` when ``section`` leaves it out (a fresh copy of a list or table)."""
    value = SCHEMA[section].key(key).default
    if value is REQUIRED:
        raise KeyError(f"{section}.{key} is required; it has no default")
    return type(value)(value) if isinstance(value, (list, dict)) else value


def filled(section: str, table: dict) -> dict:
    """``table`` with the default of every key of ``section`` it leaves out (None for an optional key without
    one); required keys are left as given."""
    out = dict(table)
    for k in SCHEMA[section].keys:
        if k.name not in out and k.default is not REQUIRED:
            out[k.name] = default(section, k.name)
    return out


def _show(value) -> str:
    if value is REQUIRED:
        return "**required**"
    if value is None:
        return "unset"
    if isinstance(value, bool):
        return f"`{str(value).lower()}`"
    if isinstance(value, str):
        return f'`"{value}"`'
    if isinstance(value, float) and value == pi / 4:
        return "pi/4"
    if isinstance(value, list):
        return "`[" + ", ".join(f'"{v}"' if isinstance(v, str) else str(v) for v in value) + "]`"
    if isinstance(value, dict):
        return "`{}`"
    return f"`{value}`"


def reference() -> str:
    """The TOML reference as Markdown: per section its keys, what each takes, its default and its meaning."""
    lines = ["# Pipeline reference", "",
             "Every key `iga run CONFIG.toml` takes, written from the validator's own table "
             "(`iga/app/config_schema.py`; `python -m iga.app.config_schema` prints this page). A key not listed "
             "is refused, naming the keys its section allows; so is a key of another paving scheme. "
             "How the sections fit together, with examples: [Pipelines](pipelines.md).", ""]
    for s in _SECTIONS:
        lines += [f"## {s.title}", "", s.meaning + (" One table per item (an array of tables)." if s.many else ""),
                  "", "| key | takes | default | meaning |", "|---|---|---|---|"]
        for k in s.keys:
            cells = (f"`{k.name}`", k.takes, _show(k.default), k.meaning)
            lines.append("| " + " | ".join(c.replace("|", "\\|") for c in cells) + " |")
        lines.append("")
    return "\n".join(lines)


if __name__ == "__main__":
    print(reference(), end="")
