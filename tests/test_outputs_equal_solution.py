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


def test_the_temperature_range_is_the_extreme_of_every_patch_evaluated_alone():
    """Solution.temperature_range evaluates the patches sharing a space together: its extremes are those of each
    patch's temperature spline evaluated on its own sample grid (direct evaluation, one patch at a time), on a
    hierarchy (children of several spaces) whose map is rational, and on a rational patch analysed in its NURBS
    basis (its own weights)."""
    from geometry.patches.sampling import sample_axes

    ms = tiling.hierarchical(pr.annulus(0.5, 1.0, 0.3, angle=np.pi / 2), L.heat_sink_t2(), (2, 1), levels=2)
    sink = (HeatProblem(ms, conductivity=200.0, source=1e5, degree_elevation=1).dirichlet("branch-in", 60.0)
            .robin("exterior", 40.0, 20.0).solve())
    ring = HeatProblem(pr.annulus(0.5, 1.0, 0.3, angle=1.5), source=3.0).dirichlet("umin", 1.0).robin("umax", 2.0, 0.0)
    assert ring.weights[0] is not None
    for s, samples in ((sink, 1), (sink, 3), (ring.solve(), 2)):
        ms = s.problem.model
        each = [s.temperature_spline(i).evaluate_grid(sample_axes(s.temperature_spline(i).knots, samples))
                for i in range(len(ms.patches))]
        lo, hi = s.temperature_range(samples)
        assert lo == pytest.approx(min(float(v.min()) for v in each), abs=1e-12 * abs(hi))
        assert hi == pytest.approx(max(float(v.max()) for v in each), abs=1e-12 * abs(hi))
        assert lo < hi


def test_the_mean_temperature_and_the_volume_from_one_pass_are_the_exact_ones():
    """A linear temperature on a box (T = x / L between Dirichlet faces): its mean is 1/2 and the volume of the
    same pass the box's, asked in either order or after the energy identity; on a twisted box the mean is the volume average of x / L."""
    prob = HeatProblem(pr.box((2.0, 1.0, 1.0), degrees=(2, 2, 2))).dirichlet("umin", 0.0).dirichlet("umax", 1.0)
    first, second, third = prob.solve(), prob.solve(), prob.solve()
    assert third.energy_balance().relative_error < 1e-12  # its pass gives the mean temperature and the volume
    assert third.mean_temperature() == pytest.approx(0.5, rel=1e-12)
    assert third.volume() == pytest.approx(2.0, rel=1e-12)
    assert first.mean_temperature() == pytest.approx(0.5, rel=1e-12)
    assert first.volume() == pytest.approx(2.0, rel=1e-12)
    assert second.volume() == pytest.approx(2.0, rel=1e-12)
    assert second.mean_temperature() == pytest.approx(0.5, rel=1e-12)
    D = pr.twisted(pr.box((2.0, 1.0, 1.0), degrees=(2, 2, 2)), 0.3, axis_point=(1.0, 0.5))
    twisted = HeatProblem(D, degree_elevation=1).dirichlet("umin", 0.0).dirichlet("umax", 1.0).solve()
    mean = twisted.mean_temperature()
    assert mean == pytest.approx(twisted.integrate(lambda x, T, g: T) / twisted.volume(), rel=1e-12)
    assert twisted.volume() == pytest.approx(twisted.integrate(lambda x, T, g: np.ones(len(T))), rel=1e-12)


def test_a_weld_that_consumes_its_input_gives_the_same_mesh():
    """weld(..., consume=True) (the sampled grid's: the model not held twice) relabels the cells in place and
    empties the data it was given, and its mesh and averaged data are those of the copying weld; points closer
    than the tolerance merge, others do not."""
    from geometry.patches.sampling import weld

    rng = np.random.default_rng(3)
    base = rng.random((400, 3))
    points = np.concatenate([base, base[:150] + 1e-13, base[:40] - 1e-13, base[:5] + 1e-6])  # 190 to merge
    cells = rng.integers(0, len(points), (700_000, 8))  # more than one block of the in-place relabelling
    data = {"t": rng.random(len(points)), "flux": rng.random((len(points), 3))}
    copy = weld(points, cells, {k: v.copy() for k, v in data.items()})
    given = {k: v.copy() for k, v in data.items()}
    cells_given = cells.copy()
    used = weld(points, cells_given, given, consume=True)
    assert copy[3] == used[3] == 190 and given == {}
    assert used[1] is cells_given and np.array_equal(used[1], copy[1]) and np.array_equal(used[0], copy[0])
    assert all(np.array_equal(used[2][k], copy[2][k]) for k in data)
    # point 0 kept, its twins 400 (+1e-13) and 550 (-1e-13) merged into it and averaged; 590 (+1e-6) kept apart
    assert copy[2]["t"][0] == pytest.approx(data["t"][[0, 400, 550]].mean(), rel=1e-14)
    assert np.abs(copy[0] - points[590]).max(axis=1).min() == 0.0
