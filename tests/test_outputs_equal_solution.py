"""Every file the toolkit writes from a solution holds the solution's values.

For every kind of paving (regular, hierarchical, capped, lidded on each side, shelled, bifurcation, V-rep,
two-level), a linear temperature held on the whole boundary is the exact solution (every space holds the
affine fields), so the sampled VTU's temperature at every written point equals ``probe`` there and the linear
field itself, to 1e-9 of the temperature range; the exact Bezier VTU, which VTK interpolates itself, equals
``probe`` at points VTK evaluates inside random cells.  The elastic VTU (and the figures the pipeline's
summary takes from it) equals the elastic solution's displacement and von Mises stress at its points.
"""

import numpy as np
import pytest
import pyvista as pv

import tiling
from geometry import primitives as pr
from helpers import vtk_cell_values
from iga import ElasticityProblem, HeatProblem, write_vtu
from iga.app.maps import vertical_heat_sink_map
from tiling import library as L

G = np.array([100.0, -50.0, 200.0])
BOX = pr.box((2.0, 1.0, 1.5))  # affine maps: every tile space holds the affine fields of x


def _sink(**kw):
    return tiling.hierarchical(vertical_heat_sink_map(), L.heat_sink_t2(), (2, 2), 2, scale=0.5, **kw)


def _vrep():
    from geometry.primitives import box
    from tiling.vrep import Primitive, vrep_microstructure

    A = Primitive(box((2.0, 1.0, 1.0), elements=(2, 2, 2)), L.cross(), (4, 2, 2), 1, "A")
    B = Primitive(box((0.6, 0.6, 2.0)).translate([0.72, 0.23, -0.5]), L.cross(), (1, 1, 1), 2, "B")
    return vrep_microstructure(A - B).microstructure


def _two_level():
    first = tiling.regular(pr.box((2.0, 1.0, 1.0)), L.cross(), (2, 1, 1))
    return tiling.compose_levels(first, L.cross(), (1, 1, 1), degree=2)


def _lid(side):
    """A paving lidded on ``side``: the hierarchical sink on w (the case whose seams were written wrong), the
    fractal hierarchy on u (its tiles' u walls are plates a lid can seal), a regular paving on v."""
    if side[0] == "w":
        return _sink(seal="cap", seal_sides=(side,))
    if side[0] == "u":
        return tiling.hierarchical(BOX, L.fractal(), (2, 1), 2, scale=0.5, seal="cap", seal_sides=(side,))
    return tiling.regular(BOX, L.cross(), (2, 2, 1), seal="cap", seal_sides=(side,))


MODELS = {
    "regular": lambda: tiling.regular(BOX, L.cross(), (2, 2, 1)),
    "hierarchical": lambda: _sink(),
    "capped": lambda: tiling.regular(BOX, L.cross(), (2, 1, 1), seal="cap"),
    **{f"lid {side}": (lambda side=side: _lid(side)) for side in ("umin", "umax", "vmin", "vmax", "wmin", "wmax")},
    "shelled": lambda: tiling.regular(BOX, L.cross(), (2, 1, 1), seal="shell", thickness=0.15),
    "bifurcation": lambda: tiling.bifurcation(pr.box((2.0, 1.0, 3.0)), levels=[0, 1, 0], tile="1-2"),
    "v-rep": _vrep,
    "two-level": _two_level,
}


def _linear(x):
    return 10.0 + np.asarray(x) @ G


@pytest.mark.slow
@pytest.mark.parametrize("kind", list(MODELS))
def test_every_written_temperature_equals_the_solution(tmp_path, kind):
    ms = MODELS[kind]()
    sol = HeatProblem(ms).dirichlet("boundary", _linear).solve()
    grid = pv.read(write_vtu(tmp_path / "s.vtu", sol, samples=2))
    x = np.asarray(grid.points)
    T = np.asarray(grid.point_data["temperature"])
    span = float(np.ptp(_linear(x)))
    assert np.abs(T - _linear(x)).max() <= 1e-9 * span, kind
    rng = np.random.default_rng(1)
    some = rng.choice(len(x), min(300, len(x)), replace=False)
    assert np.abs(T[some] - sol.probe(x[some])).max() <= 1e-9 * span, kind
    bez = pv.read(write_vtu(tmp_path / "b.vtu", sol, cells="bezier"))
    xb, tb = vtk_cell_values(bez, rng, n_cells=12, n_points=3)
    assert np.abs(tb - sol.probe(xb)).max() <= 1e-9 * span, kind


@pytest.mark.slow
@pytest.mark.parametrize("side", ["wmax", "wmin"])
def test_the_elastic_vtu_equals_the_elastic_solution_on_a_lidded_hierarchy(tmp_path, side):
    # a stress-free expansion (a uniform temperature rise on a body held by a 3-2-1 set of pins): zero stress
    # everywhere; the VTU once showed 15 MPa von Mises at the lid's seams where the solution has none
    from iga.io.vtu import sampled_grid

    ms = _sink(seal="cap", seal_sides=(side,))
    E = 70e9
    es = ElasticityProblem(ms, E, 0.3).thermal(50.0, 2.3e-5, 0.0).hold_rigid().solve()
    grid = sampled_grid(ms, es, 2)
    x = np.asarray(grid.points)
    some = np.random.default_rng(2).choice(len(x), 300, replace=False)
    u = np.asarray(grid.point_data["displacement"])
    assert np.abs(u[some] - es.displacement(x[some])).max() <= 1e-9 * np.abs(u).max()
    vm = np.asarray(grid.point_data["von_mises"])
    assert vm.max() <= 1e-6 * E * 2.3e-5 * 50.0  # stress free: round-off only
