"""The catalogue of bad and hostile inputs: every one ends in the toolkit's own error, naming the input.

One parametrised test per category.  Each case asserts the exception class
(a subclass of ``geometry.ToolkitError``), that the message names the input
(a regular expression on it), and that it prints plain numbers (no NumPy
scalar reprs such as ``np.float64(...)``).  Resource cases also assert that the
refusal comes within seconds, before any large allocation; CLI cases assert
exit status 1, one line on stderr and no traceback.
"""

from __future__ import annotations

import os
import re
import subprocess
import sys
import time
from functools import lru_cache

import numpy as np
import pytest
from commands import iga_command

import solvers
import tiling
from geometry import BSpline, MultiPatch, SplineError, ToolkitError, check_regular, compose, compose_many, invert
from geometry import knots as kn
from geometry import resources
from geometry import primitives as pr
from geometry.io.files import load, save
from iga import HeatProblem, ProblemError, SingularProblemError, write_vtu
from iga.app.config import validate
from iga.app.pipeline import heat_sink_config, run_pipeline
from solvers import SolverError
from tiling import BranchFace, Tile, TilingError
from tiling import library as L
from tiling.materials import graded_channel, interpolate_channel

U2 = [0, 0, 0, 1, 1, 1]
ID = np.hstack([np.eye(3), np.zeros((3, 1))])


def case(name, fn, exc, match):
    return pytest.param(fn, exc, match, id=name)


def check(fn, exc, match, tmp_path):
    with pytest.raises(exc) as info:
        fn(tmp_path)
    assert isinstance(info.value, ToolkitError), type(info.value)
    msg = str(info.value)
    assert re.search(match, msg), f"{match!r} not in: {msg}"
    assert "np.float64(" not in msg and "np.int64(" not in msg and "array(" not in msg, msg
    assert "\n" not in msg.strip(), msg


# ------------------------------------------------------------------ shared objects (built once)
@lru_cache
def cube():
    return pr.box(degrees=(2, 2, 2), elements=(2, 2, 2))


@lru_cache
def curve():
    return BSpline((3,), [kn.uniform_knots(3, 2)], np.random.default_rng(0).uniform(0.1, 0.9, (5, 3)))


@lru_cache
def solved():
    return HeatProblem(pr.annulus(0.5, 1.0, 1.0)).dirichlet("vmin", 50.0).robin("vmax", 5.0, 30.0).solve()


@lru_cache
def lattice():
    return tiling.regular(pr.box((2.0, 1.0, 1.0), degrees=(2, 2, 2)), L.cross(), (2, 1, 1))


def folded_patch():
    """A trilinear cube with one corner pulled through the opposite face (Jacobian negative near it)."""
    b = pr.box()
    cp = b.control_points.copy()
    cp[1, 1, 1] = [-0.5, -0.5, -0.5]
    return BSpline(b.degrees, b.knots, cp)


def folded_map():
    bx = pr.box(degrees=(2, 1, 1))
    cp = bx.control_points.copy()
    cp[1, :, :, 0] = 1.6  # x(u) overshoots and comes back: a fold inside
    return BSpline(bx.degrees, bx.knots, cp)


# =================================================================== 1. spline construction
SPLINES = [
    case("ragged control points", lambda t: BSpline((1,), [[0, 0, 1, 1]], [[0, 0, 0], [1, 1]]), SplineError,
         r"one rectangular array: some rows have a different length"),
    case("degree 2.5", lambda t: BSpline((2.5,), [U2], np.zeros((3, 3))), SplineError, r"integers.*2\.5"),
    case("degree bool", lambda t: BSpline((True,), [[0, 0, 1, 1]], np.zeros((2, 3))), SplineError, r"True"),
    case("degree string", lambda t: BSpline(("2",), [U2], np.zeros((3, 3))), SplineError, r"'2'"),
    case("degree 0", lambda t: BSpline((0,), [[0, 1]], np.zeros((1, 3))), SplineError, r"degree must be an integer >= 1"),
    case("too few degrees", lambda t: BSpline((2, 2), [U2], np.zeros((3, 3))), SplineError, r"2 degrees given"),
    case("knot count", lambda t: BSpline((2,), [[0, 0, 0, 1, 1]], np.zeros((3, 3))), SplineError, r"n \+ p \+ 1 = 6"),
    case("decreasing knots", lambda t: BSpline((2,), [[0, 0, 0, .7, .5, 1, 1, 1]], np.zeros((5, 3))), SplineError,
         r"decreases at index 4"),
    case("unclamped knots", lambda t: BSpline((2,), [[0, 0, .1, .5, 1, 1, 1]], np.zeros((4, 3))), SplineError,
         r"not open"),
    case("multiplicity", lambda t: BSpline((1,), [[0, 0, .5, .5, .5, 1, 1]], np.zeros((5, 3))), SplineError,
         r"multiplicity 3 > degree \+ 1 = 2"),
    case("nan knot", lambda t: BSpline((2,), [[0, 0, 0, np.nan, 1, 1, 1]], np.zeros((4, 3))), SplineError,
         r"non-finite value nan"),
    case("empty domain", lambda t: BSpline((1,), [[1, 1, 1, 1]], np.zeros((2, 3))), SplineError, r"empty interval"),
    case("string knots", lambda t: BSpline((1,), [["a", "b", "c", "d"]], np.zeros((2, 3))), SplineError,
         r"knot vector is not numeric"),
    case("2-d knot vector", lambda t: BSpline((1,), [[[0, 0], [1, 1]]], np.zeros((2, 3))), SplineError,
         r"one-dimensional"),
    case("negative weight", lambda t: BSpline((2,), [U2], np.zeros((3, 3)), [1, -1, 1]), SplineError,
         r"weight at \(1,\) must be finite and positive, got -1"),
    case("weights shape", lambda t: BSpline((2,), [U2], np.zeros((3, 3)), [1, 1]), SplineError,
         r"weights must have shape \(3,\)"),
    case("inf control point", lambda t: BSpline((2,), [U2], [[0, 0, 0], [np.inf, 0, 0], [1, 1, 1]]), SplineError,
         r"control point \(1,\) component 0 is not finite"),
    case("complex control points", lambda t: BSpline((2,), [U2], np.zeros((3, 3)) + 1j), SplineError, r"complex"),
    case("text control points", lambda t: BSpline((2,), [U2], [["a"] * 3] * 3), SplineError,
         r"control points must be a numeric array"),
    case("2-d points", lambda t: BSpline((2,), [U2], np.zeros((3, 2))), SplineError, r"\(n_1, \.\.\., n_d, 3\)"),
    case("4-variate", lambda t: BSpline((1,) * 4, [[0, 0, 1, 1]] * 4, np.zeros((2, 2, 2, 2, 3))), SplineError,
         r"parametric dimension must be 1, 2 or 3"),
    case("duplicate channels", lambda t: BSpline((2,), [U2], np.zeros((3, 5)), channels=("k", "k")), SplineError,
         r"unique.*'k', 'k'"),
    case("unnamed channel", lambda t: BSpline((2,), [U2], np.zeros((3, 4)), channels=("",)), SplineError,
         r"non-empty strings, got ''"),
    case("channel count", lambda t: BSpline((2,), [U2], np.zeros((3, 5)), channels=("k",)), SplineError,
         r"3 coordinates \+ channels \['k'\]"),
    case("primitive channel a callable", lambda t: pr.annulus(channels={"k": lambda x: x[:, 0]}), SplineError,
         r"channel 'k' must be a finite number .*with_channel"),
    case("primitive channel a string", lambda t: pr.box(channels={"k": "205"}), SplineError,
         r"channel 'k' must be a finite number.*got '205'"),
    case("primitive channel NaN", lambda t: pr.duck(channels={"k": float("nan")}), SplineError,
         r"channel 'k' must be a finite number.*got nan"),
    case("primitive channels not a dict", lambda t: pr.box(channels=["k"]), SplineError,
         r"channels must be a dict \{name: constant\}.*got \['k'\]"),
    case("duck length a string", lambda t: pr.duck("2"), SplineError, r"duck length must be a positive number.*'2'"),
    case("degree beyond points", lambda t: BSpline((3,), [[0, 0, 0, 0, 1, 1, 1]], np.zeros((3, 3))), SplineError,
         r"n \+ p \+ 1|at least 4 control points"),
    case("box size", lambda t: pr.box((1.0, -1.0, 1.0)), SplineError, r"box size must be three positive numbers"),
    case("annulus radii", lambda t: pr.annulus(1.0, 0.5), SplineError, r"r_inner=1.0, r_outer=0.5"),
    case("annulus angle", lambda t: pr.annulus(angle=7.0), SplineError, r"angle must be in \(0, 2 pi\].*7\.0"),
    case("skin one surface", lambda t: pr.skin([cube().boundary("wmin")]), SplineError, r"at least two surfaces"),
    case("extrude zero", lambda t: pr.extrude(cube().boundary("wmin"), [0, 0, 0]), SplineError, r"non-zero 3-vector"),
    case("tapered scale", lambda t: pr.tapered(cube(), -1.0), SplineError, r"top_scale must be positive, got -1"),
]


@pytest.mark.parametrize("fn, exc, match", SPLINES)
def test_spline_construction(fn, exc, match, tmp_path):
    check(fn, exc, match, tmp_path)


# =================================================================== 2. evaluation and operations
OPERATIONS = [
    case("outside domain", lambda t: cube().evaluate([[0.5, 0.5, 1.5]]), SplineError,
         r"outside the domain.*1\.5"),
    case("nan parameter", lambda t: cube().evaluate([[0.5, np.nan, 0.5]]), SplineError, r"non-finite"),
    case("parameter shape", lambda t: cube().evaluate(np.zeros((4, 2))), SplineError, r"shape \(N, 3\), got \(4, 2\)"),
    case("derivative orders", lambda t: cube().derivative([[0.5] * 3], (1, 0)), SplineError,
         r"3 non-negative integers, got \(1, 0\)"),
    case("negative order", lambda t: cube().derivative([[0.5] * 3], (1, 0, -1)), SplineError, r"\(1, 0, -1\)"),
    case("grid outside", lambda t: cube().evaluate_grid([[0.5], [0.5], [2.0]]), SplineError,
         r"grid axis 2 must be .* inside \[0\.0, 1\.0\]"),
    case("knot at the end", lambda t: cube().insert_knots(0, [1.0]), SplineError, r"knot 1\.0.*strictly inside"),
    case("knot nan", lambda t: cube().insert_knots(0, [np.nan]), SplineError, r"finite.*nan"),
    case("knot multiplicity", lambda t: cube().insert_knots(0, [0.5] * 3), SplineError,
         r"knot 0\.5: it already has multiplicity degree \+ 1 = 3"),
    case("direction 3", lambda t: cube().insert_knots(3, [0.3]), SplineError, r"direction must be .* 0\.\.2, got 3"),
    case("direction 1.0", lambda t: cube().elevate(1.0), SplineError, r"got 1\.0"),
    case("elevate negative", lambda t: cube().elevate(0, -1), SplineError, r"non-negative integer, got -1"),
    case("elevate 1.5 times", lambda t: cube().elevate(0, 1.5), SplineError, r"got 1\.5"),
    case("refine -1", lambda t: cube().refine(-1), SplineError, r"non-negative integer, got -1"),
    case("refine 2.7", lambda t: cube().refine(2.7), SplineError, r"got 2\.7"),
    case("elevate down", lambda t: cube().elevate_to((1, 2, 2)), SplineError, r"from degree 2 down to 1"),
    case("split at end", lambda t: cube().split(0, 1.0), SplineError, r"split parameter 1\.0 must lie strictly inside"),
    case("extract box shape", lambda t: cube().extract([[0, 1]]), SplineError, r"box must have shape \(3, 2\)"),
    case("extract empty", lambda t: cube().extract([[0.5, 0.5], [0, 1], [0, 1]]), SplineError,
         r"direction 0: sub-interval \[0\.5, 0\.5\]"),
    case("boundary name", lambda t: cube().boundary("top"), SplineError, r"unknown boundary 'top'.*umin"),
    case("curve boundary", lambda t: curve().boundary("umin"), SplineError, r"curve's boundary is two points"),
    case("permutation", lambda t: cube().permute([0, 0, 1]), SplineError, r"\[0, 0, 1\] is not a permutation"),
    case("reparametrize empty", lambda t: cube().reparametrize([[0, 1], [1, 1], [0, 1]]), SplineError,
         r"interval \[1\.0, 1\.0\] is empty"),
    case("unknown channel", lambda t: cube().channel("k"), SplineError, r"unknown channel 'k'"),
    case("channel nan", lambda t: cube().with_channel("k", np.nan), SplineError, r"channel 'k' values must be finite"),
    case("affine shape", lambda t: cube().affine(np.eye(2)), SplineError, r"3x3 matrix .* got \(2, 2\)"),
    case("regularity of a curve", lambda t: check_regular(curve()), SplineError, r"got a 1-variate spline"),
    case("invert bad points", lambda t: invert(cube(), [[0, 0]]), SplineError, r"shape \(N, 3\), got shape \(1, 2\)"),
    case("multiply dims", lambda t: __import__("geometry").multiply(cube(), curve()), SplineError,
         r"3-variate spline by a 1-variate"),
]


@pytest.mark.parametrize("fn, exc, match", OPERATIONS)
def test_evaluation_and_operations(fn, exc, match, tmp_path):
    check(fn, exc, match, tmp_path)


# =================================================================== 3. composition
def _placement(*b, scale=0.5):
    M = np.zeros((1, 3, 4))
    M[0, :, :3] = np.eye(3) * scale
    M[0, :, 3] = b
    return M


COMPOSITION = [
    case("channel clash", lambda t: compose(pr.box(channels={"k": 1.0}), pr.box(channels={"k": 2.0})), SplineError,
         r"both define channel\(s\) \['k'\]"),
    case("not a spline", lambda t: compose(cube(), "tile"), SplineError, r"BSpline objects, got BSpline and str"),
    case("curve as outer", lambda t: compose(curve(), cube()), SplineError, r"got a 1-variate spline"),
    case("trivariate into surface", lambda t: compose(cube().boundary("wmin"), cube()), SplineError,
         r"cannot be composed into a surface"),
    case("placement shape", lambda t: compose_many(cube(), pr.box(), np.zeros((2, 3, 3))), SplineError,
         r"shape \(P, 3, 4\), got shape \(2, 3, 3\)"),
    case("no placements", lambda t: compose_many(cube(), pr.box(), np.zeros((0, 3, 4))), SplineError,
         r"non-empty .* got shape \(0, 3, 4\)"),
    case("nan placement", lambda t: compose_many(cube(), pr.box(), np.full((1, 3, 4), np.nan)), SplineError,
         r"finite"),
    case("outside domain", lambda t: compose_many(cube(), pr.box(), _placement(0.8, 0, 0)), SplineError,
         r"placement 0 reaches parameters .*1\.3.* outside the outer domain"),
    case("singular placement", lambda t: compose_many(cube(), pr.box(), _placement(0, 0, 0, scale=0.0)), SplineError,
         r"placement 0 is singular \(det A = 0\)"),
    case("crosses knot line", lambda t: compose_many(cube(), pr.box(), _placement(0.25, 0, 0)), SplineError,
         r"crosses the outer map's knot line u = 0\.5"),
    case("surface crossing", lambda t: compose(cube(), pr.box((0.8, 0.2, 0.2), (0.1, 0.1, 0.1)).boundary("wmin")),
         SplineError, r"knot line u = 0\.5"),
    case("map points shape", lambda t: __import__("geometry").map_points(cube(), np.zeros((3, 1))), SplineError,
         r"shape \(N, 3\) or \(N, 3\), got \(3, 1\)|got \(3, 1\)"),
]


@pytest.mark.parametrize("fn, exc, match", COMPOSITION)
def test_composition(fn, exc, match, tmp_path):
    check(fn, exc, match, tmp_path)


# =================================================================== 4. tiles and pavings
def _variants_bad(t):
    return tiling.regular(pr.box(), L.cross(), (2, 2, 2), variants={(2, 0, 0): L.cross()})


def _a_minus_a():
    from tiling.vrep import Primitive, vrep_microstructure

    return vrep_microstructure(Primitive(pr.box(), L.cross(), (2, 2, 2), 1, "A")
                               - Primitive(pr.box(), L.cross(), (2, 2, 2), 1, "B"))


def _two_boxes(**kw):
    from tiling.vrep import Primitive, vrep_microstructure

    return vrep_microstructure(Primitive(pr.box((2.0, 1.0, 1.0)), L.cross(), (4, 2, 2), 2, "A")
                               | Primitive(pr.box((2.0, 1.0, 1.0)).translate([1.5, 0, 0]), L.cross(), (4, 2, 2), 1, "B"),
                               **kw)


TILING = [
    case("two levels of surface tiles across branch faces", lambda t: __import__("tiling.levels").levels.compose_levels(
        tiling.hierarchical(pr.box((2.0, 1.0, 1.5)), L.heat_sink_t2(), (1, 1), 2), L.hollow_cross(), (1, 1, 1),
        seal="cap"), TilingError, r"has 4 branch interfaces .* the surface would be open inside the model"),
    case("V-rep samples 2000", lambda t: _two_boxes(samples=2000), TilingError,
         r"classifying the 16 tiles of primitive 'A' at 2000 samples per direction needs about"),
    case("V-rep beta 5 without bridges", lambda t: _two_boxes(bridges=False, beta=5), TilingError,
         r"the bend parameter beta must be in \(0, 1\), got 5"),
    case("V-rep primitive counts 1000^3", lambda t: __import__("tiling.vrep").vrep.Primitive(
        pr.box(), L.cross(), (1000, 1000, 1000), 1, "A"), TilingError,
         r"the paving of primitive 'A' \(1e\+09 tiles, 7e\+09 patches\) needs about"),
    case("implicit surface resolution 3000", lambda t: tiling.random_implicit(pr.box(), (2, 2, 2)).surface(3000),
         TilingError, r"sampling the field at resolution 3000 \(2\.16e\+11 grid points\) needs about"),
    case("empty V-model", lambda t: _a_minus_a(), TilingError, r"the V-model \(subtract of A, B\) is empty"),
    case("polygon index True", lambda t: tiling.PolygonTile(np.array([[0, 0, 0.5], [1, 0, 0.5], [1, 1, 0.5]], float),
                                                             polygons=[[0, True, 2]]), TilingError,
         r"polygon 0 must list >= 3 vertex indices in \[0, 2\], got \[0, True, 2\]"),
    case("cap and shell", lambda t: tiling.random_implicit(pr.box(), (2, 2, 2), cap=True, shell=0.2), TilingError,
         r"cap=True and shell are exclusive"),
    case("cap nothing", lambda t: tiling.regular(pr.box(), L.cross(), (2, 2, 2), seal="cap", seal_sides=()),
         TilingError, r"seal_sides=\(\) seals nothing"),
    case("thickness without seal", lambda t: tiling.regular(pr.box(), L.cross(), (2, 2, 2), thickness=0.2),
         TilingError, r"thickness is given but seal is None"),
    case("sides without seal", lambda t: tiling.hierarchical(pr.box(), L.heat_sink_t2(), (1, 1), 2,
                                                             seal_sides=["wmin"]), TilingError,
         r"seal_sides is given but seal is None"),
    case("random implicit in a folded map", lambda t: tiling.random_implicit(folded_map(), (2, 2, 2)), TilingError,
         r"deformation map is singular"),
    case("implicit bifurcation in a folded map", lambda t: tiling.implicit_bifurcation(folded_map(), 0.3),
         TilingError, r"deformation map is singular"),
    case("polygons in a folded map", lambda t: tiling.pave_polygons(folded_map(), tiling.PolygonTile(
        np.array([[0, 0, 0.5], [1, 0, 0.5], [1, 1, 0.5], [0, 1, 0.5]], float), polygons=[[0, 1, 2, 3]]), (1, 1, 1)),
         TilingError, r"deformation map is singular"),
    case("hierarchy scale string", lambda t: tiling.hierarchical(pr.box(), L.heat_sink_t2(), (1, 1), 2, scale="0.5"),
         TilingError, r"scale must be a positive number .* got '0\.5' \(str\)"),
    case("reduced degree float", lambda t: __import__("geometry.composition.reduction").composition.reduction.reduce_degree(
        pr.box(degrees=(3, 3, 3)), 2.0), SplineError, r"integer 2 or 3 .* got 2\.0"),
    case("reduce a list", lambda t: __import__("geometry.composition.reduction").composition.reduction.reduce_model([pr.box()]), SplineError,
         r"takes a multi-patch model .* got list"),
    case("tile outside cube", lambda t: Tile([pr.box().translate([0.5, 0, 0])]), TilingError,
         r"tile 'tile' patch 0 leaves the unit cube"),
    case("tile not a spline", lambda t: Tile(["box"]), TilingError, r"patch 0 is a str"),
    case("empty tile", lambda t: Tile([]), TilingError, r"has no patches"),
    case("tile scale", lambda t: Tile([pr.box()], scale=-2.0), TilingError, r"scale must be positive, got -2\.0"),
    case("branch face name", lambda t: Tile([pr.box()], (0, "bottom"), [(0, "wmax")]), TilingError,
         r"'bottom' is not a face name"),
    case("branch patch index", lambda t: Tile([pr.box()], (3, "wmin"), [(0, "wmax")]), TilingError,
         r"patch 3 is not a trivariate"),
    case("outs without in", lambda t: Tile([pr.box()], None, [(0, "wmax")]), TilingError,
         r"branch-out faces but no branch-in face"),
    case("curved branch face", lambda t: Tile([pr.annulus(0.2, 0.4, 1.0).translate([0.5, 0.5, 0])], (0, "umax"),
                                               [(0, "vmax")]), TilingError, r"planar and axis-aligned"),
    case("bad branch map", lambda t: Tile([pr.box()], (0, "wmin"), [BranchFace(0, "wmax", map=np.column_stack(
        [np.eye(3), [0, 0, 0.5]]))]), TilingError, r"branch-out face 0: its map does not take the branch-in face"),
    case("map not a spline", lambda t: tiling.regular("map", L.cross(), (1, 1, 1)), TilingError,
         r"trivariate geometry\.BSpline, got 'map'"),
    case("folded map", lambda t: tiling.regular(folded_map(), L.cross(), (1, 1, 1)), TilingError,
         r"deformation map is singular.*u in"),
    case("counts string", lambda t: tiling.regular(pr.box(), L.cross(), "22"), TilingError,
         r"counts must be 3 positive integers, got '22'"),
    case("counts zero", lambda t: tiling.regular(pr.box(), L.cross(), (1, 0, 1)), TilingError, r"got \(1, 0, 1\)"),
    case("counts float", lambda t: tiling.regular(pr.box(), L.cross(), (1, 2.5, 1)), TilingError, r"2\.5"),
    case("counts two", lambda t: tiling.regular(pr.box(), L.cross(), (1, 1)), TilingError, r"3 positive integers"),
    case("tile not a Tile", lambda t: tiling.regular(pr.box(), pr.box(), (1, 1, 1)), TilingError,
         r"tiling\.Tile, got BSpline"),
    case("variants key", _variants_bad, TilingError, r"variants keys must be \(ku, kv, kw\).*\(2, 0, 0\)"),
    case("hierarchical flat tile", lambda t: tiling.hierarchical(pr.box(), L.cross(), (1, 1), 2), TilingError,
         r"branch-in face and branch-out faces"),
    case("levels zero", lambda t: tiling.hierarchical(pr.box(), L.heat_sink_t1(), (1, 1), 0), TilingError,
         r"levels must be a positive integer, got 0"),
    case("levels float", lambda t: tiling.hierarchical(pr.box(), L.heat_sink_t1(), (1, 1), 2.0), TilingError,
         r"got 2\.0"),
    case("hierarchy across knot", lambda t: tiling.hierarchical(pr.box(elements=(1, 1, 2)), L.heat_sink_t1(),
                                                                 (1, 1), 2), TilingError,
         r"crosses the deformation map's knot line w = 0\.5"),
    case("cross arm", lambda t: L.cross(1.5), TilingError, r"arm width must be in \(0, 1\), got 1\.5"),
    case("grading face", lambda t: graded_channel(pr.box(), face="top"), TilingError, r"unknown face 'top'"),
    case("grading mode", lambda t: graded_channel(pr.box(), mode="radial"), TilingError,
         r"mode must be 'parameter' or 'distance', got 'radial'"),
    case("channel function", lambda t: interpolate_channel(pr.box(), "k", lambda x: np.ones(3)), TilingError,
         r"channel function for 'k' must return 8 finite values, got shape \(3,\)"),
    case("channel on", lambda t: interpolate_channel(pr.box(), "k", np.sum, on="x"), TilingError,
         r"on must be 'parameters' or 'points', got 'x'"),
]


@pytest.mark.parametrize("fn, exc, match", TILING)
def test_tiles_and_pavings(fn, exc, match, tmp_path):
    check(fn, exc, match, tmp_path)


# =================================================================== 5. heat problems
def cube_patch():
    from geometry import PlacedPatch

    return PlacedPatch(cube())


def _box2():
    a = pr.box()
    b = pr.box(origin=(1.0, 0.0, 0.0))
    return [a, b]


HEAT = [
    case("bases not pairs", lambda t: HeatProblem(pr.box(), bases=[3]), ProblemError,
         r"bases\[0\] must be \(knot vectors, degrees\), got 3"),
    case("bases off the domain", lambda t: HeatProblem(pr.box(), bases=[([[0, 0, 2, 2]] * 3, (1, 1, 1))]),
         ProblemError, r"bases\[0\] must span patch 0's parameter domain"),
    case("not a model", lambda t: HeatProblem("cube"), ProblemError, r"cannot analyse a str"),
    case("empty list", lambda t: HeatProblem([]), ProblemError, r"no patches"),
    case("surface patch", lambda t: HeatProblem(cube().boundary("wmin")), ProblemError,
         r"patch 0 is a 2-variate spline"),
    case("list of junk", lambda t: HeatProblem([cube(), 3]), ProblemError, r"patch 1 is a int"),
    case("touching patches", lambda t: HeatProblem([pr.box(), pr.box((1, 0.5, 1), (1, 0, 0))]), ProblemError,
         r"face umax of patch 0 touches patch 1|face umin of patch 1 touches patch 0"),
    case("refine -1", lambda t: HeatProblem(cube(), refine=-1), ProblemError, r"refine must be an integer >= 0, got -1"),
    case("refine 2.7", lambda t: HeatProblem(cube(), refine=2.7), ProblemError, r"got 2\.7"),
    case("refine bool", lambda t: HeatProblem(cube(), refine=True), ProblemError, r"got True"),
    case("elevation list", lambda t: HeatProblem(cube(), degree_elevation=(1, 1)), ProblemError, r"got \(1, 1\)"),
    case("degree 0", lambda t: HeatProblem(cube(), degree=0), ProblemError, r"degree must be .* >= 1, got 0"),
    case("quadrature", lambda t: HeatProblem(cube(), quadrature_extra=-2), ProblemError, r"got -2"),
    case("conductivity negative", lambda t: HeatProblem(cube(), conductivity=-1.0), ProblemError,
         r"conductivity must be a finite positive number, got -1\.0"),
    case("conductivity nan", lambda t: HeatProblem(cube(), conductivity=float("nan")), ProblemError, r"got nan"),
    case("conductivity channel", lambda t: HeatProblem(cube(), conductivity="k"), ProblemError,
         r"channel 'k', but patch 0 only has channels \[\]"),
    case("conductivity list", lambda t: HeatProblem(cube(), conductivity=[1, 2]), ProblemError,
         r"conductivity must be .* got \[1, 2\]"),
    case("conductivity asymmetric", lambda t: HeatProblem(cube(), conductivity=[[1, 0.5, 0], [0, 1, 0], [0, 0, 1]]),
         ProblemError, r"must be symmetric"),
    case("conductivity indefinite", lambda t: HeatProblem(cube(), conductivity=np.diag([1.0, -1.0, 1.0])),
         ProblemError, r"symmetric positive definite"),
    case("conductivity callable negative",
         lambda t: HeatProblem(cube(), conductivity=lambda x: x[:, 2] - 0.5).dirichlet("wmin", 1.0).solve(),
         ProblemError, r"conductivity must be positive, but is -0\.4"),
    case("conductivity callable shape",
         lambda t: HeatProblem(cube(), conductivity=lambda x: np.ones(3)).dirichlet("wmin", 1.0).solve(),
         ProblemError, r"conductivity callable must return shape"),
    case("conductivity callable raises",
         lambda t: HeatProblem(cube(), conductivity=lambda x: 1 / 0).dirichlet("wmin", 1.0).solve(), ProblemError,
         r"conductivity callable failed on patch 0: division by zero"),
    case("source text", lambda t: HeatProblem(cube(), source=[1.0]), ProblemError, r"source must be .* got \[1\.0\]"),
    case("source nan callable",
         lambda t: HeatProblem(cube(), source=lambda x: np.full(len(x), np.nan)).dirichlet("wmin", 0.0).solve(),
         ProblemError, r"source is not finite"),
    case("unknown tag", lambda t: HeatProblem(cube()).dirichlet("top", 1.0), ProblemError,
         r"unknown boundary tag 'top'"),
    case("tag not a string", lambda t: HeatProblem(cube()).dirichlet(3, 1.0), ProblemError,
         r"a boundary tag must be a non-empty string, an expression or a list of them, got 3"),
    case("empty tag", lambda t: HeatProblem(MultiPatch([cube_patch()], [], {"top": [], "umin": [(0, "umin")]}))
         .dirichlet("top", 1.0), ProblemError, r"tag 'top' has no faces in this model"),
    case("dirichlet twice", lambda t: HeatProblem(cube()).dirichlet("umin", 1.0).dirichlet("umin", 2.0).solve(),
         ProblemError, r"two dirichlet conditions \(tags 'umin' and 'umin'\)"),
    case("dirichlet and neumann", lambda t: HeatProblem(cube()).dirichlet("umin", 1.0).neumann("boundary", 2.0)
         .solve(), ProblemError, r"patch 0 face umin has a Dirichlet condition \(tag 'umin'\) and a neumann condition "
         r"\(tag 'boundary'\); give each face one kind: e.g. neumann on 'boundary - umin'"),
    case("dirichlet text", lambda t: HeatProblem(cube()).dirichlet("umin", "hot"), ProblemError,
         r"Dirichlet value on 'umin' must be a number or a callable .* got 'hot'"),
    case("dirichlet inf", lambda t: HeatProblem(cube()).dirichlet("umin", float("inf")), ProblemError, r"got inf"),
    case("neumann bool", lambda t: HeatProblem(cube()).neumann("umin", True), ProblemError, r"got True"),
    case("robin h negative", lambda t: HeatProblem(cube()).robin("umin", -5.0, 30.0), ProblemError,
         r"film coefficient h on 'umin' must be a finite positive number, got -5\.0"),
    case("robin ambient nan", lambda t: HeatProblem(cube()).robin("umin", 5.0, float("nan")), ProblemError,
         r"ambient temperature on 'umin' .* got nan"),
    case("singular problem", lambda t: HeatProblem(cube()).neumann("umin", 1.0).solve(), SingularProblemError,
         r"no Dirichlet, Robin or radiation condition"),
    case("unknown solver", lambda t: HeatProblem(cube()).dirichlet("umin", 0.0).solve(solver="gauss"), SolverError,
         r"unknown solver 'gauss'"),
    case("tol zero", lambda t: HeatProblem(cube()).dirichlet("umin", 0.0).solve(tol=0.0), ProblemError,
         r"tol must be a number in \(0, 1\), got 0\.0"),
    case("tol nan", lambda t: HeatProblem(cube()).dirichlet("umin", 0.0).solve(tol=float("nan")), ProblemError,
         r"got nan"),
    case("tol text", lambda t: HeatProblem(cube()).dirichlet("umin", 0.0).solve(tol="small"), ProblemError,
         r"got 'small'"),
    case("maxiter zero", lambda t: HeatProblem(cube()).dirichlet("umin", 0.0).solve(maxiter=0), ProblemError,
         r"maxiter must be an integer >= 1, got 0"),
    case("probe outside", lambda t: solved().probe([[5.0, 5.0, 5.0]]), ProblemError,
         r"1 probe point\(s\) lie outside the model, e.g. \[\[5\.0, 5\.0, 5\.0\]\]"),
    case("probe shape", lambda t: solved().probe([1.0, 2.0]), ProblemError, r"shape \(N, 3\), got \(2,\)"),
    case("probe nan", lambda t: solved().probe([[np.nan, 0, 0]]), ProblemError, r"finite array"),
    case("flux unknown tag", lambda t: solved().flux("top"), ProblemError, r"unknown boundary tag 'top'"),
    case("l2_error not callable", lambda t: solved().l2_error(3.0), ProblemError,
         r"exact must be a callable of the points x \(N, 3\), got a float"),
    case("l2_error shape", lambda t: solved().l2_error(lambda x: x[:, :2]), ProblemError,
         r"exact must return shape \(\d+,\) for x of shape \(\d+, 3\), got \(\d+, 2\)"),
    case("h1_error shape", lambda t: solved().h1_error(lambda x: x[:, 0]), ProblemError,
         r"exact_grad must return shape \(\d+, 3\) for x of shape \(\d+, 3\), got \(\d+,\)"),
    case("l2_error failing", lambda t: solved().l2_error(lambda x: x[:, 5]), ProblemError,
         r"exact failed on the model: IndexError"),
    case("l2_error nan", lambda t: solved().l2_error(lambda x: np.where(x[:, 2] > 0.5, np.nan, 0.0)), ProblemError,
         r"exact returned values that are not finite on the model, e\.g\. at x = \["),
]


@pytest.mark.parametrize("fn, exc, match", HEAT)
def test_heat_problems(fn, exc, match, tmp_path):
    check(fn, exc, match, tmp_path)


# =================================================================== 6. silently wrong analysis (refused exactly)
def _singular_placement(t):
    ms = tiling.regular(pr.box(), L.cross(), (1, 1, 1))
    P = ms.patches[0]
    M = P.placement.copy()
    M[2, :3] = 0.0  # flattens the block onto a plane
    bad = tiling.Microstructure(ms.outer, [type(P)(P.spline, M, P.outer, P.tile)], [], {"boundary": []}, ms.tiles)
    return HeatProblem(bad)


def _wedge_solution():
    """A wedge: the edge u = v = 1 collapsed onto u = 1, v = 0 (the Jacobian vanishes there, a set of measure zero)."""
    b = pr.box(degrees=(1, 1, 1))
    cp = b.control_points.copy()
    cp[1, 1, :] = cp[1, 0, :]
    return HeatProblem(BSpline(b.degrees, b.knots, cp), refine=1).dirichlet("umin", 1.0).robin("vmax", 1.0, 0.0).solve()


def _folded_composed(t):
    ms = tiling.regular(pr.box(), L.cross(), (1, 1, 1))
    P = ms.patches[2]  # the arm at u in [0.65, 1], where the folded map's dx/du changes sign (u = 0.73)
    bad = tiling.Microstructure(folded_map(), [type(P)(P.spline, P.placement, folded_map(), P.tile)], [],
                                {"boundary": []}, ms.tiles)
    return HeatProblem(bad)


WRONG = [
    case("folded patch", lambda t: HeatProblem(folded_patch()).dirichlet("umin", 0.0), ProblemError,
         r"patch 0 is folded or degenerate: .* u in \["),
    case("folded patch refined", lambda t: HeatProblem(folded_patch(), refine=3), ProblemError, r"patch 0 is folded"),
    case("folded patch in a list", lambda t: HeatProblem([pr.box((1, 1, 1), (5, 5, 5)), folded_patch()]),
         ProblemError, r"patch 1 is folded"),
    case("folded map", _folded_composed, ProblemError, r"patch 0 lies where the deformation map folds.*u in \["),
    case("singular placement", _singular_placement, ProblemError,
         r"patch 0 has a singular placement \(det A = 0\): it flattens the patch onto the parameter box u in \["),
    case("flux at a collapsed edge", lambda t: _wedge_solution().heat_flux(0, [[1.0, 1.0, 0.5]]), ProblemError,
         r"patch 0: the geometry Jacobian is singular at parameters \[1\.0, 1\.0, 0\.5\]"),
]


@pytest.mark.parametrize("fn, exc, match", WRONG)
def test_silently_wrong_analysis_is_refused(fn, exc, match, tmp_path):
    check(fn, exc, match, tmp_path)


# =================================================================== 7. solvers
def _spd(n=5):
    import scipy.sparse as sp

    return sp.diags([2.0] * n) + sp.diags([-1.0] * (n - 1), 1) + sp.diags([-1.0] * (n - 1), -1)


def _complement(indices):
    from solvers.indexing import complement

    return complement(5, indices)


SOLVERS = [
    case("free unknowns: a negative index", lambda t: _complement([1, -1]), SolverError,
         r"unknown numbers must lie in \[0, 5\), got -1 \.\. 1"),
    case("free unknowns: an index past the end", lambda t: _complement([0, 5]), SolverError,
         r"unknown numbers must lie in \[0, 5\), got 0 \.\. 5"),
    case("overwrite_a string", lambda t: solvers.solve(_spd(), np.ones(5), overwrite_a="no"), SolverError,
         r"overwrite_a must be True or False, got 'no'"),
    case("prolongations string", lambda t: solvers.solve(_spd(), np.ones(5), method="gmg-cg", prolongations="abc"),
         SolverError, r"prolongations must be a list of sparse matrices"),
    case("dense matrix", lambda t: solvers.solve(np.eye(3), np.ones(3)), SolverError, r"scipy sparse matrix, got "
         r"ndarray"),
    case("shapes", lambda t: solvers.solve(_spd(), np.ones(4)), SolverError, r"A \(5, 5\), b \(4,\)"),
    case("nan rhs", lambda t: solvers.solve(_spd(), np.full(5, np.nan)), SolverError, r"non-finite values"),
    case("unknown method", lambda t: solvers.solve(_spd(), np.ones(5), method="qr"), SolverError,
         r"unknown solver 'qr'; choose one of"),
    case("tol negative", lambda t: solvers.solve(_spd(), np.ones(5), method="cg", tol=-1.0), SolverError,
         r"tol must be a number in \(0, 1\), got -1\.0"),
    case("tol nan direct", lambda t: solvers.solve(_spd(), np.ones(5), method="direct", tol=float("nan")),
         SolverError, r"got nan"),
    case("maxiter text", lambda t: solvers.solve(_spd(), np.ones(5), method="cg", maxiter="many"), SolverError,
         r"maxiter must be an integer >= 1, got 'many'"),
    case("singular direct", lambda t: solvers.solve(_spd() * 0 + __import__("scipy.sparse").sparse.diags(
        [1.0, 0, 1, 1, 1]), np.ones(5), method="direct"), SolverError, r"singular"),
    case("indefinite cg", lambda t: solvers.solve(__import__("scipy.sparse").sparse.diags([1.0, -1.0, 1, 1, 1]),
                                                  np.ones(5), method="cg"), SolverError, r"positive diagonal"),
    case("not converged", lambda t: solvers.solve(_spd(200), np.ones(200), method="cg", maxiter=2), SolverError,
         r"did not converge: relative residual .* after 2 iterations"),
    # Hilbert(10), condition number 1.6e13: CG's own residual reaches 1e-12, the true one stays near 1e-10
    case("ill-conditioned", lambda t: solvers.solve(__import__("scipy.sparse").sparse.csr_matrix(
        __import__("scipy.linalg").linalg.hilbert(10)), np.ones(10), method="cg", tol=1e-12), SolverError,
         r"stopped at its tolerance .* true relative residual is .* too ill-conditioned .* loosen tol"),
    case("unknown option", lambda t: solvers.solve(_spd(), np.ones(5), method="cg", smoother="x"), SolverError,
         r"unknown option 'smoother'"),
]


@pytest.mark.parametrize("fn, exc, match", SOLVERS)
def test_solvers(fn, exc, match, tmp_path):
    check(fn, exc, match, tmp_path)


def test_converged_early_is_not_reported_as_failure():
    # amg-cg with maxiter=1 on a system it solves in one iteration: converged, not "did not converge"
    x, info = solvers.solve(__import__("scipy.sparse").sparse.diags([2.0] * 50), np.ones(50), method="amg-cg",
                            maxiter=1)
    assert info.residual < 1e-14 and np.allclose(x, 0.5)


# =================================================================== 8. files
def _forged_npz(t):
    """A 300-byte .npz whose array header claims a 745 GiB array."""
    import io
    import zipfile

    header = np.lib.format.header_data_from_array_1_0(np.zeros(1))
    header["shape"] = (100_000_000_000,)
    buf = io.BytesIO()
    np.lib.format.write_array_header_1_0(buf, header)
    buf.write(b"\0" * 64)
    path = t / "bomb.npz"
    with zipfile.ZipFile(path, "w") as zf:
        zf.writestr("format.npy", buf.getvalue())
    assert path.stat().st_size < 1000
    return load(path)


def _pickled_npz(t):
    path = t / "objects.npz"
    np.savez(path, format=np.array([{"a": 1}], dtype=object))
    return load(path)


def _tampered_npz(t, **entries):
    """A spline file of the unit box with some entries replaced (what a damaged or hand-made file holds)."""
    path = save(t / "s.npz", pr.box())
    data = dict(np.load(path))
    data.update({k: (v(data) if callable(v) else v) for k, v in entries.items()})
    np.savez(t / "t.npz", **data)
    return load(t / "t.npz")


FILES = [
    case("npz float degrees", lambda t: _tampered_npz(t, s0_degrees=np.array([1.7, 1.0, 1.0])), SplineError,
         r"entry 's0_degrees' holds float64 values \[1\.7, 1\.0, 1\.0\], not integers"),
    case("npz negative count", lambda t: _tampered_npz(t, count=np.array(-3)), SplineError,
         r"entry 'count' is -3"),
    case("npz string points", lambda t: _tampered_npz(t, s0_control_points=lambda d: d["s0_control_points"]
                                                        .astype(str)), SplineError,
         r"entry 's0_control_points' holds <U32 values, not numbers"),
    case("load missing", lambda t: load(t / "nothing.npz"), SplineError, r"nothing\.npz does not exist"),
    case("load folder", lambda t: load(t), SplineError, r"is a folder, not a spline file"),
    case("load text", lambda t: (t / "x.npz").write_text("hello") and load(t / "x.npz"), SplineError,
         r"x\.npz is not a spline file: it is not an \.npz archive"),
    case("load foreign npz", lambda t: np.savez(t / "o.npz", a=np.zeros(3)) or load(t / "o.npz"), SplineError,
         r"o\.npz is not an iga-toolkit spline file"),
    case("load forged header", _forged_npz, SplineError, r"claims 8e\+11 bytes but the archive holds"),
    case("load pickled objects", _pickled_npz, SplineError, r"holds Python objects"),
    case("save missing folder", lambda t: save(t / "no" / "x.npz", cube()), SplineError,
         r"folder .*no does not exist"),
    case("save onto folder", lambda t: (t / "d.npz").mkdir() or save(t / "d.npz", cube()), SplineError,
         r"d\.npz: it is a folder"),
    case("save not a spline", lambda t: __import__("geometry").save_all(t / "x.npz", [cube(), "x"]), SplineError,
         r"item 1 is a str"),
    case("vtu missing folder", lambda t: write_vtu(t / "no" / "x.vtu", solved()), ProblemError,
         r"folder .*no does not exist"),
    case("vtu onto folder", lambda t: (t / "x.vtu").mkdir() or write_vtu(t / "x.vtu", solved()), ProblemError,
         r"x\.vtu: it is a folder"),
    case("vtu suffix", lambda t: write_vtu(t / "x.vtk", solved()), ProblemError, r"x\.vtk: VTU files end in \.vtu"),
    case("vtu samples", lambda t: write_vtu(t / "x.vtu", solved(), samples=0), ProblemError,
         r"samples must be a positive integer, got 0"),
    case("vtu cells", lambda t: write_vtu(t / "x.vtu", solved(), cells="quadratic"), ProblemError,
         r"cells must be 'linear' or 'bezier', got 'quadratic'"),
    case("surface suffix", lambda t: __import__("tiling.export").export.write_surfaces(t / "s.dxf", lattice()),
         TilingError, r"cannot export s\.dxf"),
    case("surface samples", lambda t: __import__("tiling.export").export.surface(lattice(), samples=-1),
         TilingError, r"samples must be a positive integer, got -1"),
]


@pytest.mark.parametrize("fn, exc, match", FILES)
def test_files(fn, exc, match, tmp_path):
    check(fn, exc, match, tmp_path)
    assert not [p for p in tmp_path.rglob(".*") if p.is_file()], "a temporary file was left behind"


def test_full_disk_leaves_nothing(tmp_path, monkeypatch):
    import geometry.io.files as gio

    def full(*a, **k):
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(np, "savez", full)
    with pytest.raises(SplineError, match=r"x\.npz: No space left on device; nothing was written"):
        gio.save(tmp_path / "x.npz", cube())
    assert list(tmp_path.iterdir()) == []


# =================================================================== 9. pipelines (TOML configurations)
def _cfg(**changes):
    cfg = heat_sink_config(levels=1, out="o")
    for path, value in changes.items():
        *head, key = path.split("__")
        node = cfg
        for h in head:
            node = node[int(h)] if h.isdigit() else node.setdefault(h, {})
        if value is KeyError:
            del node[key]
        else:
            node[key] = value
    return cfg


def _validate(**changes):
    return lambda t: validate(_cfg(**changes), t)


def _elastic_cfg(**extra):
    cfg = {k: v for k, v in _cfg().items() if k not in ("bc", "material")}
    cfg["physics"] = {"kind": "elasticity", "youngs": 1e9, "poisson": 0.3}
    cfg["support"] = [{"tag": "branch-in", "value": 0.0}]
    cfg.update(extra)
    return cfg


CONFIG = [
    case("elastic run with a material table", lambda t: validate(_elastic_cfg(material={"source": "1/0"}), t),
         ProblemError, r"config section material holds the heat problem's conductivity and source"),
    case("elastic run with probes", lambda t: validate(_elastic_cfg(output={"probes": [[0.0, 0.0, 0.0]]}), t),
         ProblemError, r"output\.probes: writes temperatures .* physics\.kind = 'elasticity' does not compute"),
    case("elastic run with bezier", lambda t: validate(_elastic_cfg(output={"bezier": True}), t),
         ProblemError, r"output\.bezier: writes temperatures"),
    case("unknown section", lambda t: validate({**_cfg(), "mesh": {}}, t), ProblemError,
         r"unknown config section 'mesh'"),
    case("missing section", lambda t: validate({k: v for k, v in _cfg().items() if k != "tile"}, t), ProblemError,
         r"missing required config section 'tile'"),
    case("unknown key", _validate(paving__count=[1, 1]), ProblemError, r"unknown config key paving\.'count'"),
    case("missing key", _validate(tile__library=KeyError), ProblemError, r"missing required config key tile\.'library'"),
    case("section not a table", _validate(solver=[1]), ProblemError, r"config key solver: must be a table"),
    case("map primitive", _validate(map__primitive="sphere"), ProblemError,
         r"map\.primitive: must be one of \['annulus', 'box'.* got 'sphere'"),
    case("map file and primitive", _validate(map__file="m.npz"), ProblemError, r"exactly one of 'primitive'"),
    case("map args unknown", _validate(map__args={"radius": 1.0}), ProblemError,
         r"map\.args\.radius: is not an argument of circular_heat_sink_map; allowed: \['height', 'r_in'"),
    case("map args string", _validate(map__args={"r_in": "0.02"}), ProblemError,
         r"map\.args\.r_in: must be a finite number, got '0\.02'"),
    case("map args table", _validate(map__args=[1, 2]), ProblemError, r"map\.args: must be a table"),
    case("tolerance and samples", _validate(output__samples=2, output__tolerance=1e-5), ProblemError,
         r"output\.tolerance: choose the samples per element \(samples\) or a geometric tolerance, not both"),
    case("tolerance zero", _validate(output__tolerance=0.0), ProblemError, r"output\.tolerance"),
    case("grading face", _validate(map__grading__0__face="top"), ProblemError, r"map\.grading\[0\]\.face: must be one of"),
    case("grading near text", _validate(map__grading__0__near="hot"), ProblemError, r"map\.grading\[0\]\.near.*'hot'"),
    case("grading one table", _validate(map__grading={"channel": "k", "near": 1.0, "face": "up"}), ProblemError,
         r"map\.grading\.face: must be one of"),
    case("tile class", _validate(tile__library="Tile"), ProblemError, r"tile\.library: must be one of .*got 'Tile'"),
    case("tile helper", _validate(tile__library="_hexa"), ProblemError, r"got '_hexa'"),
    case("tile args unknown", _validate(tile__args={"width": 2}), ProblemError,
         r"tile\.args\.width: is not an argument of heat_sink_t1; allowed: \['scale'\]"),
    case("scheme", _validate(paving__scheme="random"), ProblemError, r"paving\.scheme: must be one of"),
    case("counts string", _validate(paving__counts="22"), ProblemError,
         r"paving\.counts: must be a list of 2 integers >= 1, got '22'"),
    case("counts float", _validate(paving__counts=[1, 1.5]), ProblemError, r"paving\.counts\[1\].*1\.5"),
    case("levels text", _validate(paving__levels="2"), ProblemError, r"paving\.levels: must be an integer >= 1, got '2'"),
    case("scale string", _validate(paving__scale="0.5"), ProblemError, r"paving\.scale: must be a finite number, got '0\.5'"),
    case("scale negative", _validate(paving__scale=-1.0), ProblemError, r"paving\.scale: must be > 0, got -1\.0"),
    case("conductivity text", _validate(material__conductivity=True), ProblemError,
         r"material\.conductivity: must be a finite number, got True"),
    case("source text", _validate(material__source="heat"), ProblemError,
         r"material\.source: 'heat' names 'heat', which is neither a coordinate nor a constant"),
    case("bc kind", _validate(bc__0__kind="fixed"), ProblemError, r"bc\[0\]\.kind: must be one of"),
    case("bc value text", _validate(bc__0__value="hot"), ProblemError, r"bc\[0\]\.value: 'hot' names 'hot', which is "
         r"neither a coordinate nor a constant"),
    case("bc value list", _validate(bc__0__value=[1.0]), ProblemError, r"bc\[0\]\.value: must be a finite number or a "
         r"formula"),
    case("bc robin without h", _validate(bc__1__h=KeyError), ProblemError, r"bc\[1\] \(robin\) needs keys 'h'"),
    case("bc robin value", _validate(bc__1__value=3.0), ProblemError, r"bc\[1\]\.value: a robin condition"),
    case("bc empty", _validate(bc=[]), ProblemError, r"config section bc is empty"),
    case("solver method", _validate(solver__method="gauss"), ProblemError,
         r"solver\.method: must be one of \['amg-cg', 'auto', 'cg', 'direct', 'fd-cg', 'gmg-cg', 'petsc'\], got 'gauss'"),
    case("tol small", _validate(solver__tol="small"), ProblemError, r"solver\.tol: must be a finite number, got 'small'"),
    case("tol negative", _validate(solver__tol=-1e-8), ProblemError, r"solver\.tol: must be > 0"),
    case("refine float", _validate(solver__refine=1.5), ProblemError, r"solver\.refine: .*got 1\.5"),
    case("refine negative", _validate(solver__refine=-1), ProblemError, r"solver\.refine: .*got -1"),
    case("vtu string", _validate(output__vtu="no"), ProblemError, r"output\.vtu: must be true or false, got 'no'"),
    case("png without vtu", _validate(output__vtu=False), ProblemError, r"output\.png: the picture is rendered"),
    case("name escapes", _validate(output__name="../../x"), ProblemError,
         r"output\.name: must be a plain file name .* got '\.\./\.\./x'"),
    case("absolute name", _validate(output__name="/tmp/x"), ProblemError, r"got '/tmp/x'"),
    case("samples zero", _validate(output__samples=0), ProblemError, r"output\.samples: must be an integer >= 1"),
    case("probes shape", _validate(output__probes=[[0, 0]]), ProblemError, r"output\.probes: must be a list of \[x, y, z\]"),
    case("memory limit", lambda t: validate({**_cfg(), "limits": {"max_memory_gib": -1}}, t), ProblemError,
         r"limits\.max_memory_gib: must be > 0"),
]


@pytest.mark.parametrize("fn, exc, match", CONFIG)
def test_pipeline_configuration(fn, exc, match, tmp_path):
    check(fn, exc, match, tmp_path)


def test_probe_outside_is_refused_before_the_solve_and_no_folder_is_left(tmp_path):
    cfg = _cfg(output__probes=[[5.0, 5.0, 5.0]], output__dir=str(tmp_path / "out"))
    t = time.perf_counter()
    with pytest.raises(ProblemError, match=r"output\.probes point\(s\) lie outside the model"):
        run_pipeline(cfg, progress=False)
    assert not (tmp_path / "out").exists()  # nothing written, no empty folder left behind
    assert time.perf_counter() - t < 30


# =================================================================== 10. resources: refused within seconds
RESOURCES = [
    case("paving 10^6 tiles", lambda t: tiling.regular(pr.box(), L.cross(), (1000, 1000, 1)), TilingError,
         r"regular paving \(1e\+06 tiles, 7e\+06 patches\) needs about .* GiB"),
    case("hierarchy 40 levels", lambda t: tiling.hierarchical(pr.box(), L.heat_sink_t1(), (1, 1), 40), TilingError,
         r"40-level hierarchical paving .* needs about"),
    case("refine 10", lambda t: HeatProblem(cube(), refine=10), ProblemError,
         r"the analysis \(.* DOFs on 1 patch\) needs about .* GiB"),
    case("elevation 30", lambda t: HeatProblem(cube(), degree_elevation=30, refine=4), ProblemError,
         r"needs about .* GiB"),
    case("memory limit", lambda t: __import__("geometry").resources.set_memory_limit(0), SplineError,
         r"positive number of GiB, got 0"),
    case("pipeline counts", lambda t: run_pipeline(_cfg(paving__counts=[1000, 1000], output__dir=str(t / "o")),
                                                   progress=False), TilingError, r"hierarchical paving"),
    case("pipeline refine", lambda t: run_pipeline(_cfg(solver__refine=10, output__dir=str(t / "o")),
                                                   progress=False), ProblemError, r"the analysis"),
    case("tessellation 1e-9", lambda t: _bent_disc().tessellate(1e-9), SplineError,
         r"tessellation at tolerance 1e-09 needs at least about [\d,]+ triangles \(estimated"),
    case("scale bounds pieces", lambda t: __import__("geometry").scale_bounds(
        _fine_box(), np.tile(_fine_box().domain, (20000, 1, 1)), subdivide=8), SplineError,
         r"scale bounds of 20,000 boxes over 512 elements cut into 8\^3 sub-boxes .* needs about"),
    case("elastic samples", lambda t: write_vtu(t / "e.vtu", _elastic_solution(), samples=100000), ProblemError,
         r"the sampled VTU grid .* needs about"),
]


def _bent_disc():
    """A disc trimmed from a curved quadratic sheet (z = 0.3 u^2), loop an exact NURBS circle."""
    from geometry.shapes.trimmed import TrimmedSurface

    w = np.array([1, np.sqrt(0.5)] * 4 + [1])
    pts = np.array([[1, 0], [1, 1], [0, 1], [-1, 1], [-1, 0], [-1, -1], [0, -1], [1, -1], [1, 0]], float) * 0.3
    circle = BSpline((2,), [np.r_[0, 0, 0, 0.25, 0.25, 0.5, 0.5, 0.75, 0.75, 1, 1, 1]],
                     np.c_[pts + 0.5, np.zeros(9)], w)
    bent = BSpline((2, 2), [kn.uniform_knots(2, 1)] * 2,
                   np.array([[[x, y, 0.3 * x * x] for y in (0, 0.5, 1)] for x in (0, 0.5, 1)], float))
    return TrimmedSurface(bent, [circle])


def _fine_box() -> BSpline:
    return pr.box(degrees=(2, 2, 2)).refine(3)[0]


@lru_cache(maxsize=1)
def _elastic_solution():
    from iga import ElasticityProblem

    return ElasticityProblem(pr.box(degrees=(2, 2, 2)), 1.0, 0.3).dirichlet("umin", 0.0).traction(
        "umax", (1.0, 0.0, 0.0)).solve()


@pytest.mark.parametrize("fn, exc, match", RESOURCES)
def test_resources_are_refused_within_seconds(fn, exc, match, tmp_path, monkeypatch):
    t = time.perf_counter()
    with resources.memory_budget(8.0):  # the same budget on every machine
        check(fn, exc, match, tmp_path)
    assert time.perf_counter() - t < 5.0
    assert not (tmp_path / "o").exists()


# =================================================================== 11. the command line
def _cli(tmp_path, *args, toml=None):
    if toml is not None:
        (tmp_path / "c.toml").write_text(toml)
    return iga_command(*args, cwd=tmp_path)


GOOD_TOML = """
[map]
primitive = "box"
[tile]
library = "cross"
[paving]
scheme = "regular"
counts = [1, 1, 1]
[[bc]]
kind = "dirichlet"
tag = "wmin"
value = 1.0
[output]
png = false
"""

CLI = [
    ("missing config", ["run", "missing.toml"], None, r"config file missing\.toml does not exist"),
    ("config is a folder", ["run", "."], None, r"config file \. is a folder"),
    ("bad TOML", ["run", "c.toml"], "[map\nprimitive = 1", r"c\.toml is not valid TOML"),
    ("unknown solver", ["run", "c.toml"], GOOD_TOML + "[solver]\nmethod = 'gauss'\n", r"solver\.method"),
    ("tol string", ["run", "c.toml"], GOOD_TOML + "[solver]\ntol = 'small'\n", r"solver\.tol"),
    ("tag without faces", ["run", "c.toml"], GOOD_TOML.replace('tag = "wmin"', 'tag = "nowhere"'),
     r"unknown boundary tag 'nowhere'"),
    ("args string", ["run", "c.toml"], GOOD_TOML.replace('primitive = "box"', 'primitive = "box"\nargs = {size = "1"}'),
     r"map\.args\.size"),
    ("name escapes", ["run", "c.toml"], GOOD_TOML + "name = '../x'\n", r"output\.name"),
    ("name with NUL", ["run", "c.toml"], GOOD_TOML + 'name = "a\\u0000b"\n', r"output\.name: must not hold control"),
    ("name of 300 characters", ["run", "c.toml"], GOOD_TOML + f"name = '{'a' * 300}'\n",
     r"output\.name: must be at most 200 printable characters"),
    ("memory budget", ["--max-memory", "0.001", "run", "c.toml"], GOOD_TOML.replace("[1, 1, 1]", "[20, 20, 20]"),
     r"needs about .* GiB, more than the 0\.001 GiB"),
    ("levels zero", ["demo", "heat-sink", "--levels", "0", "--out", "d"], None, r"--levels must be >= 1, got 0"),
    ("levels 40", ["demo", "heat-sink", "--levels", "40", "--out", "d"], None,
     r"40-level hierarchical paving .* needs about .* GiB"),
    ("refine 10", ["demo", "heat-sink", "--refine", "10", "--out", "d"], None, r"the analysis .* needs about"),
    ("info missing", ["info", "none.npz"], None, r"none\.npz does not exist"),
    ("info not npz", ["info", "c.toml"], "x = 1", r"not an \.npz archive"),
    ("homogenize poisson alone", ["homogenize", "--tile", "cross", "--poisson", "0.3"], None,
     r"--poisson applies to the effective stiffness, which --youngs asks for"),
    ("homogenize arg twice", ["homogenize", "--tile", "cross", "--arg", "arm=0.3", "--arg", "arm=0.2"], None,
     r"--arg arm is given twice \(arm=0\.3 and arm=0\.2\)"),
    ("homogenize unknown arg", ["homogenize", "--tile", "cross", "--arg", "n=16"], None,
     r"tile 'cross' does not take \['n'\]; its parameters are \['arm'\]"),
]


@pytest.mark.slow
@pytest.mark.parametrize("name, args, toml, match", CLI, ids=[c[0] for c in CLI])
def test_command_line_errors_are_one_line(name, args, toml, match, tmp_path):
    out = _cli(tmp_path, *args, toml=toml)
    assert out.returncode == 1, out
    lines = out.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("iga: error: "), out.stderr
    assert re.search(match, lines[0]), lines[0]
    assert "Traceback" not in out.stderr and "np.float64(" not in out.stderr
    assert not (tmp_path / "out").exists() and not (tmp_path / "d").exists()


def test_the_catalogue_names_each_case_once_and_expects_the_toolkits_own_errors():
    groups = {"SPLINES": SPLINES, "OPERATIONS": OPERATIONS, "COMPOSITION": COMPOSITION, "TILING": TILING,
              "HEAT": HEAT, "WRONG": WRONG, "SOLVERS": SOLVERS, "FILES": FILES, "CONFIG": CONFIG,
              "RESOURCES": RESOURCES, "FORMULAS": FORMULAS, "DROPPED": DROPPED, "RAW": RAW}
    for name, cases in groups.items():
        ids = [c.id for c in cases]
        assert cases and len(set(ids)) == len(ids), f"{name}: duplicate case names {sorted(ids)}"
        for c in cases:
            exc = c.values[1]
            assert isinstance(exc, type) and issubclass(exc, ToolkitError), f"{name} {c.id}: expects {exc!r}"
    assert len({c[0] for c in CLI}) == len(CLI)


def test_conforming_patches_are_coupled_and_reported():
    a, b = _box2()
    prob = HeatProblem([a, b]).dirichlet("umin", 0.0).dirichlet("umax", 2.0)
    assert len(prob.model.interfaces) == 1 and prob.model.interfaces[0].a == (0, "umax")
    sol = prob.solve()
    x = np.array([[0.5, 0.5, 0.5], [1.0, 0.3, 0.2], [1.5, 0.5, 0.5]])
    assert np.allclose(sol.probe(x), x[:, 0], atol=1e-10)  # linear across both patches: they are coupled
    assert MultiPatch.from_splines([a, b], couple=False).interfaces == []
    assert ToolkitError in SolverError.__mro__ and issubclass(SplineError, ValueError)


# ------------------------------------------------------------------ formulas (iga.expressions)
def _formula(text, where="config key bc[0].value"):
    from iga.expressions import Expression

    return Expression(text, where)


FORMULAS = [
    case("formula minimum with one arg", lambda t: _formula("minimum(x)"), ProblemError,
         r"calls minimum with 1 argument; minimum takes 2 or more arguments"),
    case("formula unary with two args", lambda t: _formula("sin(x, y)"), ProblemError,
         r"bc\[0\]\.value: 'sin\(x, y\)' calls sin with 2 arguments; sin takes 1 argument"),
    case("formula arctan2 with three args", lambda t: _formula("arctan2(x, y, z)"), ProblemError,
         r"calls arctan2 with 3 arguments; arctan2 takes 2 arguments"),
    case("formula where with two args", lambda t: _formula("where(x < 1, 2)"), ProblemError,
         r"calls where with 2 arguments; where takes 3 arguments"),
    case("formula starred args", lambda t: _formula("hypot(*x)"), ProblemError, r"calls hypot with 1 argument"),
    case("formula incomplete", lambda t: _formula("80 + "), ProblemError, r"'80 \+ ' is not a formula \(.* at its end\)"),
    case("formula points of shape (3, 2)", lambda t: _formula("x")(np.zeros((3, 2))), ProblemError,
         r"evaluated at points given as an array of shape \(N, 3\); got shape \(3, 2\)"),
    case("formula points 1-D", lambda t: _formula("x")(np.zeros(3)), ProblemError,
         r"array of shape \(N, 3\); got shape \(3,\)"),
    case("formula points not numbers", lambda t: _formula("x")("abc"), ProblemError,
         r"array of shape \(N, 3\); got str"),
]


@pytest.mark.parametrize("fn, exc, match", FORMULAS)
def test_formulas(fn, exc, match, tmp_path):
    check(fn, exc, match, tmp_path)


def test_a_formula_never_writes_into_the_callers_points():
    from iga.expressions import Expression

    P = np.random.default_rng(0).random((50, 3))
    before = P.copy()
    v = Expression("minimum(x, y, z) + maximum(z, y, x, 0.5)")(P)  # variadic: not NumPy's out= argument
    assert np.array_equal(P, before)
    assert np.array_equal(v, np.minimum(np.minimum(P[:, 0], P[:, 1]), P[:, 2])
                          + np.maximum(np.maximum(np.maximum(P[:, 2], P[:, 1]), P[:, 0]), 0.5))


def test_gismo_formulas_keep_exprtks_meaning_of_remainder_and_variadic_max():
    from iga.expressions import Expression

    x = np.array([[-7.0, 3.0, 2.0], [7.0, -3.0, 1.0], [-7.5, 2.0, -1.0]])
    got = Expression.from_exprtk("x % y")(x)  # exprtk truncates: -7 % 3 = -1 (Python floors: 2)
    assert np.array_equal(got, np.fmod(x[:, 0], x[:, 1])) and got[0] == -1.0
    assert np.array_equal(Expression.from_exprtk("max(x, y, z)")(x), x.max(axis=1))
    # and back: Python's floored % leaves as a - b floor(a / b), exprtk's truncated one as %
    assert "floor" in Expression("x % y").exprtk() and Expression.from_exprtk("x % y").exprtk() == "(x % y)"


def test_a_long_flat_formula_reads_and_evaluates_without_recursion():
    from iga.expressions import Expression

    text = "+".join(["x"] * 999)  # 1,997 characters: under the documented 2,000
    assert Expression(text)(np.ones((2, 3)))[0] == 999
    assert len(Expression(text).exprtk()) > 999


# ------------------------------------------------------------------ numbers: NumPy's scalars are numbers, bools are not
def test_numpy_scalars_are_numbers_and_bools_are_not():
    # one helper per concern (geometry.numbers): a NumPy scalar is taken where a number is asked for (np.int64(1)
    # as a radius was "not a positive length"), a bool is refused where a count or a size is (True was 1)
    from geometry.numbers import is_flag, is_integer, is_real

    assert is_real(np.int64(1)) and is_real(np.float32(0.5)) and not is_real(True) and not is_real(np.bool_(1))
    assert is_integer(np.uint8(3)) and not is_integer(3.0) and not is_integer(False)
    assert is_flag(np.bool_(False)) and not is_flag(0)
    sol = solved()
    box = pr.box((2.0, 1.0, 1.0), degrees=(2, 2, 2))
    tiling.regular(box, L.cross(), (np.int64(2), np.int64(1), np.int64(1)), seal="cap", thickness=np.float32(0.1))
    tiling.bifurcation(pr.box((2.0, 1.0, 3.0)), levels=[0, np.int64(1), 0], tile="1-2", margin=np.float64(0.3))
    HeatProblem(box, refine=np.int64(1), degree_elevation=np.int32(0))
    for fn, match in [
        (lambda: tiling.regular(box, L.cross(), (2, 1, 1), seal="cap", thickness=True), "thickness"),
        (lambda: tiling.bifurcation(pr.box((2.0, 1.0, 3.0)), levels=[0, True, 0], tile="1-2"), "levels"),
        (lambda: tiling.bifurcation(pr.box((2.0, 1.0, 3.0)), levels=[0, 1, 0], tile="1-2", margin=True), "margin"),
        (lambda: write_vtu("x.vtu", sol, samples=True), "samples"),
        (lambda: HeatProblem(box, refine=True), "refine"),
        (lambda: solvers.solve(sp_eye(3), np.ones(3), method="cg", maxiter=True), "maxiter"),
        (lambda: tiling.random_implicit(box, (1, 1, 1), seed=True), "seed"),
    ]:
        with pytest.raises(ToolkitError, match=match):
            fn()


def sp_eye(n):
    import scipy.sparse as sp

    return sp.identity(n, format="csr")


def test_an_elastic_solution_at_no_points_gives_empty_arrays_and_solver_advice_names_both_physics():
    from iga import ElasticityProblem

    s = ElasticityProblem(cube(), 1e9, 0.3).dirichlet("umin", 0.0).traction("umax", [0.0, 0.0, -1e3]).solve()
    assert s.stress([]).shape == (0, 3, 3) and s.von_mises([]).shape == (0,)  # None and a raw error before
    assert s.displacement(np.zeros((0, 3))).shape == (0, 3) and s.strain([]).shape == (0, 3, 3)
    import scipy.sparse as sp

    singular = sp.csr_matrix(np.array([[1.0, -1.0], [-1.0, 1.0]]))
    with pytest.raises(SolverError, match="an elastic one supports against every rigid motion"):
        solvers.solve(singular, np.array([1.0, 0.0]), method="direct")


def _polygon_with(polygons):
    from tiling.members.polygons import PolygonTile

    return PolygonTile(np.array([[0.1, 0.1, 0.5], [0.9, 0.1, 0.5], [0.9, 0.9, 0.5], [0.1, 0.9, 0.5]]), polygons)


DROPPED = [
    case("bifurcation without a level-0 layer", lambda t: tiling.bifurcation(pr.box((2.0, 1.0, 3.0)), levels=[1],
                                                                              tile="1-4a"), TilingError,
         r"levels \[1\] have no layer at level 0, so nothing joins the columns of level 1"),
    case("homogenise a list with a surface", lambda t: __import__("iga").effective_conductivity(
        [pr.box(), pr.box().boundary("umin")]), ProblemError,
        r"tile list item 1 is a BSpline of dimension 2; a list of patches to homogenise holds trivariate"),
    case("homogenise a list with a number", lambda t: __import__("iga").effective_conductivity([pr.box(), 3]),
         ProblemError, r"tile list item 1 is a int"),
    case("thermal strain from another model", lambda t: __import__("iga").ElasticityProblem(
        pr.box((2.0, 1.0, 1.0)), 1e9, 0.3).thermal(
        HeatProblem(pr.box()).dirichlet("umin", 1.0).solve(), 1e-5), ProblemError,
        r"the heat solution was computed on another model \(its patches are not this elastic problem's"),
    case("polygon repeats a vertex", lambda t: _polygon_with([[0, 1, 1, 2]]), TilingError,
         r"polygon 0 repeats a vertex \(\[0, 1, 1, 2\]: vertices 1 and 1 at one place"),
    case("polygon closes on itself", lambda t: _polygon_with([[0, 1, 2, 0]]), TilingError,
         r"polygon 0 repeats a vertex"),
]


@pytest.mark.parametrize("fn, exc, match", DROPPED)
def test_nothing_is_dropped_or_mixed_up_without_a_word(fn, exc, match, tmp_path):
    check(fn, exc, match, tmp_path)


def _table():
    from iga import effective_table

    return effective_table(L.cross, [0.2, 0.3], degree_elevation=0)


def _graded_map():
    from tiling.materials import graded_channel

    return graded_channel(pr.box(), "t", near=0.2, far=0.3)


def _gismo_with_index(tmp_path, index):
    from geometry.io.gismo import read_gismo, write_gismo

    path = write_gismo(tmp_path / "box.xml", [cube()])
    text = path.read_text()
    assert 'index="1"' in text
    path.write_text(text.replace('index="1"', f'index="{index}"', 1))
    return read_gismo(path)


def _describe(tmp_path, text, name="s.json"):
    from iga.io.describe import describe

    path = tmp_path / name
    path.write_text(text)
    return describe(path)


def _failing_family(p):
    raise ValueError("no tile for that")


RAW = [
    case("macro_map spans as text", lambda t: __import__("iga").macro_map(_graded_map(), _table(), "t", spans="8"),
         ProblemError, r"spans must be an integer in \[1, 500\] .* got '8'"),
    case("macro_map spans beyond memory", lambda t: __import__("iga").macro_map(_graded_map(), _table(), "t",
                                                                                 spans=3000),
         ProblemError, r"spans must be an integer in \[1, 500\]"),
    case("macro_map table as a dict", lambda t: __import__("iga").macro_map(_graded_map(), {"a": 1}, "t"),
         ProblemError, r"macro_map needs an EffectiveTable"),
    case("clip_walls of None", lambda t: __import__("tiling.sealing.clipping").sealing.clipping.clip_walls(None), TilingError,
         r"clip_walls needs a list of walls .* got None"),
    case("export_gismo of an elastic problem", lambda t: __import__("iga.io.gismo").io.gismo.export_gismo(
        __import__("iga").ElasticityProblem(cube(), 1e9, 0.3), t / "e.xml"), ProblemError,
        r"G\+Smo export writes heat problems \(iga.HeatProblem\), not ElasticityProblem"),
    case("write_pieces without a communicator", lambda t: __import__("iga").write_pieces(t / "a.pvtu", solved(), None),
         ProblemError, r"write_pieces needs the MPI communicator of the solve .* got None"),
    case("write_pieces of a spline", lambda t: __import__("iga").write_pieces(t / "a.pvtu", cube(), None),
         ProblemError, r"write_pieces writes a solution .* got a BSpline"),
    case("G+Smo basis index not a number", lambda t: _gismo_with_index(t, "x"), SplineError,
         r"has a <Basis index='x'>; the index of a direction's basis is a whole number"),
    case("iga info of a summary laid out otherwise", lambda t: _describe(t, '{"tiles": 3, "temperature_C": 5}'),
         ProblemError, r"s\.json is not laid out as a pipeline summary \(KeyError: 'dofs'\)"),
    case("iga info of a summary nested too deeply", lambda t: _describe(t, "[" * 100000 + "]" * 100000),
         ProblemError, r"s\.json as a pipeline summary: its JSON is nested too deeply"),
    case("iga info of an OBJ face naming a missing vertex", lambda t: _describe(
        t, "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 7\n", "bad.obj"), ProblemError,
         r"bad\.obj is damaged: a cell names point 7 \(counting from 1, as OBJ does\) but the file has 3 points"),
    case("vtu samples beyond memory", lambda t: write_vtu(t / "x.vtu", solved(), samples=100000), ProblemError,
         r"the sampled VTU grid \([\d,]+ points\) needs about .* GiB, more than"),
    case("effective_table family raising", lambda t: __import__("iga").effective_table(_failing_family, [0.2, 0.3]),
         ProblemError, r"the family '_failing_family' failed at p = 0.2: ValueError: no tile for that"),
]


@pytest.mark.parametrize("fn, exc, match", RAW)
def test_raw_errors_become_the_projects_own(fn, exc, match, tmp_path):
    check(fn, exc, match, tmp_path)


def test_hold_rigid_refuses_loads_that_do_not_balance_and_takes_those_that_do():
    from iga import ElasticityProblem

    b = pr.box((2.0, 1.0, 1.0))
    with pytest.raises(ProblemError, match=r"net force of \[0.0, 0.0, -1000.0\] N \('umax' \[0.0, 0.0, -1000.0\] N\)"):
        ElasticityProblem(b, 1e9, 0.3).traction("umax", [0, 0, -1e3]).hold_rigid().solve()
    with pytest.raises(ProblemError, match=r"net moment of \[0.0, 2000.0, 0.0\] N m about the origin"):
        ElasticityProblem(b, 1e9, 0.3).traction("umax", [0, 0, -1e3]).traction("umin", [0, 0, 1e3]).hold_rigid().solve()
    s = ElasticityProblem(b, 1e9, 0.3).traction("umax", [1e3, 0, 0]).traction("umin", [-1e3, 0, 0]).hold_rigid().solve()
    # a bar pulled at both ends: uniaxial stress 1e3 Pa, the pins carry nothing
    assert s.stress(np.array([[1.0, 0.5, 0.5]]))[0, 0, 0] == pytest.approx(1e3, rel=1e-9)


@pytest.mark.parametrize("args, hint", [(["rnu", "c.toml"], "rnu: did you mean run?"),
                                        (["homogenize", "--tile", "cross", "--poison", "0.3"],
                                         "--poison: did you mean --poisson?")])
def test_a_mistyped_command_or_option_gets_a_did_you_mean(args, hint, tmp_path):
    out = _cli(tmp_path, *args)
    assert out.returncode == 2 and "Traceback" not in out.stderr
    assert out.stderr.strip().splitlines()[-1].endswith(hint), out.stderr


def test_warnings_reach_command_line_users_as_one_line(capsys, monkeypatch):
    # a warning raised while a command runs (e.g. G+Smo extensions written by iga run) is one line on stderr, not
    # Python's "file.py:251: GismoExtensionWarning" and its source line
    import warnings

    from iga.app import cli

    def warn(args):
        warnings.warn("the G+Smo file carries extensions", UserWarning, stacklevel=2)
        return 0

    monkeypatch.setattr(cli, "_cmd_info", warn)
    with warnings.catch_warnings():
        warnings.simplefilter("always")
        assert cli.main(["info", "x.npz"]) == 0
    assert capsys.readouterr().err == "iga: warning: the G+Smo file carries extensions\n"


def test_a_rank_without_patches_fails_its_piece_without_leaving_the_others_waiting(tmp_path):
    # one process stands for rank 1 of 2; the other rank "wrote" its piece (allreduce adds its 1): the empty rank
    # must reach the collective and every rank then raises, instead of rank 1 dying before it
    from iga import write_pieces

    class Comm:
        def Get_rank(self):
            return 1

        def Get_size(self):
            return 2

        def allreduce(self, v):
            self.reached = True
            return v + 1

        def Barrier(self):
            pass

    sol = HeatProblem(lattice()).dirichlet("umin", 0.0).dirichlet("umax", 1.0).solve()
    sol.record.partition = np.zeros(len(sol.problem.model.patches), int)  # every patch on rank 0
    comm = Comm()
    with pytest.raises(ProblemError, match=r"rank 1 of 2 solved no patch \(14 patches on 2 ranks\)"):
        write_pieces(tmp_path / "a.pvtu", sol, comm)
    assert comm.reached and not list(tmp_path.iterdir())


def test_the_heat_flux_at_a_collapsed_face_is_its_limit_not_zero(tmp_path):
    # a wedge: the box's umax face collapsed onto a line; T = 2 x + 3 y is in its (trilinear) space, so the flux
    # is (-2, -3, 0) everywhere, and on the collapsed face the VTU writes the limit from inside (it wrote 0)
    import pyvista as pv

    b = pr.box(degrees=(1, 1, 1))
    cp = b.control_points.copy()
    cp[1, :, :, 2] = 0.5
    wedge = BSpline(b.degrees, b.knots, cp)
    T = lambda x: 2 * x[:, 0] + 3 * x[:, 1]  # noqa: E731
    s = HeatProblem(wedge).dirichlet("umin | vmin | vmax", T).solve()
    g = pv.read(write_vtu(tmp_path / "wedge.vtu", s, samples=2))
    x, q = np.asarray(g.points), np.asarray(g.point_data["heat_flux"])
    edge = np.isclose(x[:, 0], 1.0)
    assert edge.sum() >= 3 and np.abs(q[edge] - [-2.0, -3.0, 0.0]).max() < 1e-6


# ------------------------------------------------------------------ surfaces: consistently oriented, outward normals
def _mirrored(D: BSpline) -> BSpline:
    """D with x negated: det J < 0 everywhere."""
    return BSpline(D.degrees, D.knots, D.control_points * np.array([-1.0, 1.0, 1.0]), D.weights, D.channels)


def _gauss_volume(ms) -> float:
    """The volume of a volumetric paving by the problem's Gauss rule (no surface involved)."""
    from iga.discretisation.fields import integrate_fields

    prob = HeatProblem(ms)
    return integrate_fields(prob, lambda i: np.zeros((1,) + prob.spaces[i].shape), 1,
                            lambda x, v, g: np.ones(len(x)))


@pytest.mark.parametrize("mirror", [False, True], ids=["det J > 0", "det J < 0"])
def test_capped_surfaces_are_oriented_outwards_and_enclose_the_solids_volume(mirror, tmp_path):
    import pyvista as pv

    from geometry.shapes.orientation import orientation_check

    D = pr.box((1.0, 1.0, 1.0), degrees=(2, 2, 2))
    D = _mirrored(D) if mirror else D
    capped = tiling.regular(D, L.hollow_cross(0.3), (2, 2, 1), seal="cap")
    solid = _gauss_volume(tiling.regular(D, L.cross(0.3), (2, 2, 1)))
    written = pv.read(tiling.export.write_surfaces(tmp_path / "capped.stl", capped, 2))
    for mesh, rel in ((capped.surface(2), 1e-9), (written.clean(), 1e-6)):  # STL stores float32
        c = orientation_check(mesh)
        assert c.repeated_edges == 0 and c.sheets == 1
        # the caps close the hollow cross around exactly the volume of the solid cross (planar faces: exact)
        assert c.signed_volume == pytest.approx(solid, rel=rel) and solid > 0.2


@pytest.mark.slow
def test_shells_orient_the_cavity_inwards_and_open_tubes_consistently():
    from geometry.shapes.orientation import orientation_check, orient_outward

    twisted = pr.twisted(pr.box((1.0, 1.0, 1.0), degrees=(2, 2, 2)), 0.4, axis_point=(0.5, 0.5))
    shell = tiling.regular(_mirrored(twisted), L.hollow_cross(), (2, 1, 1), seal="shell", thickness=0.15).surface(2)
    c = orientation_check(shell)
    assert c.repeated_edges == 0 and c.sheets == 2
    # the skin's outside encloses the box, its inside (joined to the tubes) the void left: the solid between them
    outer, inner = (shell.extract_cells(np.flatnonzero(shell.connectivity()["RegionId"] == r)).extract_surface(algorithm="dataset_surface")
                    for r in (0, 1))
    v = sorted(abs(orientation_check(orient_outward(m)).signed_volume) for m in (outer, inner))
    assert c.signed_volume == pytest.approx(v[1] - v[0], rel=1e-9) and 0 < c.signed_volume < v[1]
    duck = pr.duck()
    tubes = tiling.bifurcation(duck, 0.35, "1-4a", surfaces=True).surface(2)
    t = orientation_check(tubes)
    assert t.repeated_edges == 0 and t.signed_volume > 0  # open ends: positive about the sheet's centre


def test_implicit_and_polygon_surfaces_face_outwards_under_any_map():
    from geometry.shapes.orientation import orientation_check
    from tiling.members.polygons import PolygonTile, pave_polygons

    cube = PolygonTile(np.array([[i, j, k] for i in (0.2, 0.8) for j in (0.2, 0.8) for k in (0.2, 0.8)]),
                       polygons=[[0, 1, 3, 2], [4, 6, 7, 5], [0, 4, 5, 1], [2, 3, 7, 6], [0, 2, 6, 4], [1, 5, 7, 3]],
                       name="box")
    D = pr.box((2.0, 1.0, 1.0), degrees=(2, 2, 2))
    implicit = []
    for E in (D, _mirrored(D)):  # the mirror keeps every volume; outward normals keep its sign
        c = orientation_check(pave_polygons(E, cube, (2, 1, 1)))
        assert c.repeated_edges == 0 and c.sheets == 2 and c.signed_volume == pytest.approx(2 * 0.6 ** 3, rel=1e-12)
        implicit.append(orientation_check(tiling.random_implicit(E, (2, 1, 1), seed=1).surface(6)))
    assert all(s.repeated_edges == 0 for s in implicit)
    assert implicit[0].signed_volume > 0 and implicit[1].signed_volume == pytest.approx(implicit[0].signed_volume,
                                                                                          rel=1e-9)


# ------------------------------------------------------------------ geometric validity: no solid folds onto itself
def _quarter_arc():
    """(arc, quarter cylinder): an exact NURBS quarter circle of radius 1 and its extrusion along z (n outward)."""
    p, U, P, w = pr.arc(1.0, np.pi / 2)
    arc = BSpline((p,), [U], P, w)
    cyl = BSpline((p, 1), [U, [0, 0, 1, 1.0]], np.stack([P, P + [0, 0, 1.0]], 1), np.stack([w, w], 1))
    return arc, cyl


def test_tubes_and_offsets_past_a_radius_of_curvature_are_refused_with_the_bound():
    from geometry.shapes.offset import offset
    from geometry.shapes.sweep import sweep

    arc, cyl = _quarter_arc()
    rng = np.random.default_rng(4)
    # inside the bound: the offset is the concentric cylinder (exact radius check at random points)
    for d in (-0.9, 2.0):
        o = offset(cyl, d)
        x = o.surface.evaluate(rng.uniform(0, 1, (200, 2)))[:, :3]
        assert np.abs(np.hypot(x[:, 0], x[:, 1]) - (1 + d)).max() <= o.tolerance
    for d in (-1.0, -1.5):  # onto or past the axis of the cylinder: folds
        with pytest.raises(SplineError, match=r"reaches the surface's radius of curvature 1 at parameters .* "
                                              r"offset by less than 1"):
            offset(cyl, d)
    assert sweep(arc, radius=0.99).surface.dim == 2
    for r in (1.0, 1.2):
        with pytest.raises(SplineError, match=rf"section reaches {r:g} from the axis, to or past the axis's radius "
                                              r"of curvature 1 at v = "):
            sweep(arc, radius=r)
    # a round strut thicker than the bend of its (composed) axis: the toolkit's error naming the strut
    helices = tiling.regular(pr.box(), L.helix(), (1, 1, 1))
    with pytest.raises(TilingError, match=r"strut through patch 0 .*to or past the axis's radius of curvature"):
        tiling.round_struts(helices, 0.45)


def test_the_memory_budget_of_the_environment_is_read_by_the_command_not_by_library_calls(tmp_path, monkeypatch):
    monkeypatch.setenv("IGA_MAX_MEMORY_GIB", "1e-6")
    assert resources.memory_limit() > 1e6  # a library call sees the budget set, not the environment
    assert resources.environment_limit() == 1e-6
    out = subprocess.run([sys.executable, "-m", "iga", "--quiet", "demo", "heat-sink", "--out", str(tmp_path / "o")],
                         capture_output=True, text=True, timeout=120, env={**os.environ, "IGA_MAX_MEMORY_GIB": "1e-6"})
    assert out.returncode == 1 and "GiB this run may use" in out.stderr, out.stderr
    monkeypatch.setenv("IGA_MAX_MEMORY_GIB", "lots")
    with pytest.raises(SplineError, match="IGA_MAX_MEMORY_GIB must be a positive number"):
        resources.environment_limit()
