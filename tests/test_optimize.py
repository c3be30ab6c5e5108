"""Design by gradient: iga.optimize over the control values of a material channel of the deformation map."""

import numpy as np
import pytest

import iga
import tiling
from geometry import primitives as pr
from iga.errors import ProblemError
from iga.design import DesignStep, channel_volumes, optimize, redesigned
from iga.outputs import HeatFlow, MeanTemperature, TemperatureNorm
from iga.sensitivity import design_map
from tiling import library


def _lattice(k=129.5):
    """A 2 x 2 x 1 lattice of crosses in a box map whose channel k (W/(m K)) the conductivity reads, heated on
    one side and cooled hard on the other (conduction carries most of the rise)."""
    D = pr.box((0.02, 0.02, 0.01), degrees=(2, 2, 1))
    D = D.with_channel("k", np.full(D.control_points.shape[:3], k))
    ms = tiling.regular(D, library.cross(0.4), (2, 2, 1))
    return iga.HeatProblem(ms, conductivity="k").neumann("umin", 2e4).robin("umax", 3000.0, 0.0)


def _sink():
    """The vertical heat sink of pins (Massarwi et al. 2018, Fig. 11) of uniform k = 129.5 W/(m K) (half aluminium,
    half steel), 2 W/cm^2 into the base, h = 3000 W/(m^2 K) to a coolant at 0 C: conduction carries most of the rise."""
    D = pr.box((0.06, 0.06, 0.03), degrees=(2, 2, 2))
    D = D.with_channel("k", np.full(D.control_points.shape[:3], 129.5))
    sink = tiling.hierarchical(D, library.heat_sink_t2(), (1, 1), 2, scale=0.5)
    return iga.HeatProblem(sink, conductivity="k").neumann("branch-in", 2e4).robin("exterior", 3000.0, 0.0)


@pytest.mark.slow
def test_the_optimiser_lowers_the_smooth_maximum_at_a_fixed_mean_within_the_bounds():
    problem = _sink()
    result = optimize(problem, TemperatureNorm(8), "channel:k", (54.0, 205.0), mean=129.5, maxiter=15)
    assert result.improvement > 0.03 and result.objective < result.initial
    v = result.values.ravel()
    assert v.min() >= 54.0 - 1e-9 and v.max() <= 205.0 + 1e-9
    D, placed = design_map(result.solution.problem, "k")
    vol = channel_volumes(result.solution.problem, D, placed)
    assert vol @ v / vol.sum() == pytest.approx(129.5, rel=1e-6)  # the same amount of each material
    # aluminium goes to the heated base: the control values at w = 0 exceed those at the top
    assert result.values[:, :, 0].mean() > result.values[:, :, -1].mean() + 20
    assert all(isinstance(s, DesignStep) for s in result.history) and len(result.history) >= 2
    assert result.history[-1].objective == pytest.approx(result.objective)
    # the returned solution is an analysis of the returned design
    D0 = design_map(problem, "k")[0]
    again = problem.on(redesigned(problem.model, D0, D0.with_channel("k", result.values), True)).solve()
    assert TemperatureNorm(8).value(again) == pytest.approx(result.objective, rel=1e-10)


@pytest.mark.parametrize("kwargs, match", [
    ({"bounds": (0.0, 205.0)}, r"bounds must be \(low, high\)"),
    ({"bounds": (205.0, 54.0)}, r"bounds must be \(low, high\)"),
    ({"bounds": (54.0,)}, r"bounds must be \(low, high\)"),
    ({"mean": 300.0}, "cannot be met within bounds"),
    ({"wrt": "map"}, "wrt must be 'channel:NAME'"),
    ({"wrt": "channel:rho"}, "holding the channel 'rho'"),
    ({"objective": HeatFlow("umin")}, "has no gradient in the solution.s coefficients"),
    ({"maxiter": 0}, "maxiter must be an integer >= 1"),
    ({"bounds": (54.0, 100.0)}, "outside bounds"),
])
def test_bad_design_input_is_refused_naming_it(kwargs, match):
    args = {"objective": TemperatureNorm(8), "wrt": "channel:k", "bounds": (54.0, 205.0), "mean": None,
            "maxiter": 5, **kwargs}
    with pytest.raises(ProblemError, match=match):
        optimize(_lattice(), args.pop("objective"), **args)


def test_a_problem_that_is_not_a_steady_heat_problem_is_refused():
    with pytest.raises(ProblemError, match="optimize takes a steady iga.HeatProblem"):
        optimize("problem", MeanTemperature(), "channel:k")
