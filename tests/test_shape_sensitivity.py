"""Shape sensitivities wrt="map": the adjoint derivative of heat outputs with respect to the deformation map's
control points equals central finite differences of fresh analyses of moved maps (the exact composition moves
every tile; interface, branch-face and slot constraints stay parametric)."""

import numpy as np
import pytest

import tiling
from geometry import BSpline, MultiPatch
from geometry import primitives as pr
from iga import HeatProblem, ProblemError
from iga.app.maps import circular_heat_sink_map, vertical_heat_sink_map
from iga.outputs import Compliance, HeatFlow, MeanTemperature, TemperatureNorm, Volume
from tiling import library


def _moved(D, P):
    return BSpline(D.degrees, D.knots, P, D.weights, channels=D.channels)


def _agrees(D, build, conditions, output, entries, h, rtol, conductivity="k"):
    """The adjoint gradient against central differences at ``entries`` (control index + coordinate), relative
    to the gradient's largest entry."""
    P0 = np.array(D.control_points)
    sol = conditions(HeatProblem(build(D), conductivity=conductivity)).solve(tol=1e-13)
    g = sol.gradient(output, wrt="map")
    assert g.shape == D.control_points.shape[:3] + (3,)
    scale = np.abs(g).max()
    assert scale > 0 and np.all(np.isfinite(g))
    for c in entries:
        vals = []
        for step in (h, -h):
            P = P0.copy()
            P[c] += step
            vals.append(output.value(conditions(HeatProblem(build(_moved(D, P)), conductivity=conductivity))
                                     .solve(tol=1e-13)))
        fd = (vals[0] - vals[1]) / (2 * h)
        assert abs(g[c] - fd) <= rtol * scale, (output, c, g[c], fd)
    return g


@pytest.mark.parametrize("output", [MeanTemperature(), TemperatureNorm(4), MeanTemperature("umax"), Volume(),
                                    Compliance()], ids=repr)
def test_on_one_curved_patch_every_output_s_shape_gradient_is_its_finite_difference(output):
    box = pr.twisted(pr.box((1.0, 0.6, 0.5), degrees=(2, 2, 2), elements=(2, 2, 2)), 0.4, axis_point=(0.5, 0.3))
    rng = np.random.default_rng(7)
    entries = [tuple(int(v) for v in rng.integers(0, 4, 3)) + (int(rng.integers(0, 3)),) for _ in range(3)]
    _agrees(box, lambda D: D, lambda p: p.dirichlet("umin", 1.0).neumann("umax", 5.0).robin("vmin", 4.0, 0.5),
            output, entries, 1e-6, 1e-7, conductivity=3.0)


@pytest.mark.slow
def test_on_a_hierarchical_sink_with_branch_faces_and_slots_the_shape_gradient_is_exact():
    D = vertical_heat_sink_map()
    D = D.with_channel("k", np.full(D.control_points.shape[:3], 129.5))
    g = _agrees(D, lambda D: tiling.hierarchical(D, library.heat_sink_t2(), counts=(2, 2), levels=1, scale=0.5),
                lambda p: p.neumann("branch-in", 2e4).robin("exterior", 3000.0, 0.0), TemperatureNorm(8),
                [(2, 1, 1, 0), (0, 2, 1, 2), (1, 1, 2, 2)], 1e-6, 1e-8)
    # moving the whole map rigidly changes nothing: the gradient sums to zero in each coordinate
    assert np.abs(g.sum(axis=(0, 1, 2))).max() <= 1e-8 * np.abs(g).max()


@pytest.mark.slow
def test_on_the_rational_circular_map_with_a_graded_channel_the_shape_gradient_is_exact():
    D = circular_heat_sink_map()
    D = D.with_channel("k", np.linspace(54, 205, D.control_points[..., 0].size).reshape(D.control_points.shape[:3]))
    assert D.is_rational
    _agrees(D, lambda D: tiling.hierarchical(D, library.heat_sink_t1(), counts=(4, 1), levels=1, scale=0.5),
            lambda p: p.neumann("branch-in", 1515.8).robin("exterior", 5.0, 30.0), Compliance(),
            [(4, 1, 1, 2), (2, 1, 1, 0)], 1e-6, 1e-6)


def test_a_regular_lattice_with_dirichlet_and_a_face_output():
    D = pr.twisted(pr.box((2.0, 1.0, 1.0), degrees=(2, 2, 2)), 0.3, axis_point=(1.0, 0.5))
    D = D.with_channel("k", np.full(D.control_points.shape[:3], 2.0))
    _agrees(D, lambda D: tiling.regular(D, library.cross(), (2, 2, 1)),
            lambda p: p.dirichlet("umin", 0.0).robin("umax", 2.0, 1.0), TemperatureNorm(4, "umax"),
            [(2, 1, 1, 0), (0, 2, 1, 2)], 1e-6, 1e-7)


def test_what_the_shape_derivative_does_not_cover_is_refused():
    box = pr.box(degrees=(2, 2, 2), elements=(2, 2, 2))

    def grad(problem, output=None):
        return problem.solve().gradient(output or MeanTemperature(), wrt="map")

    with pytest.raises(ProblemError, match="callable of x"):
        grad(HeatProblem(box, conductivity=lambda x: 1.0 + x[:, 0]).dirichlet("umin", 0.0).neumann("umax", 1.0))
    with pytest.raises(ProblemError, match="Dirichlet value"):
        grad(HeatProblem(box).dirichlet("umin", lambda x: x[:, 1]).neumann("umax", 1.0))
    with pytest.raises(ProblemError, match="nonlinear"):
        grad(HeatProblem(box).dirichlet("umin", 0.0).radiation("umax", 0.5, 20.0, scale="C"))
    with pytest.raises(ProblemError, match="knows the shape terms"):
        grad(HeatProblem(box).dirichlet("umin", 0.0).neumann("umax", 1.0), HeatFlow("umax"))
    from iga import ElasticityProblem
    from iga.shape_sensitivity import shape_sensitivity

    elastic = ElasticityProblem(box, 1.0, 0.3).dirichlet("umin", 0.0).traction("umax", (1.0, 0.0, 0.0)).solve()
    with pytest.raises(ProblemError, match="elastic shape derivative is of Compliance"):
        shape_sensitivity(elastic, MeanTemperature())
    # the volume is geometry alone: an elastic solution's shape gradient of it is the heat solution's
    heat = HeatProblem(box).dirichlet("umin", 0.0).neumann("umax", 1.0).solve()
    assert np.allclose(shape_sensitivity(elastic, Volume()), shape_sensitivity(heat, Volume()), rtol=0, atol=1e-14)
    with pytest.raises(ProblemError, match="steady heat solution"):
        shape_sensitivity(object(), Volume())
    two = MultiPatch.from_splines([box, pr.box(origin=(1.0, 0.0, 0.0), degrees=(2, 2, 2), elements=(2, 2, 2))])
    with pytest.raises(ProblemError, match="one deformation map"):
        grad(HeatProblem(two).dirichlet("umin", 0.0).neumann("umax", 1.0))
