"""Temperature-dependent conductivity k(x, T) (a callable or a table of (T, k)), solved by Newton's method:
against the Kirchhoff-transform solution of a bar (optimal rates measured), Newton's quadratic convergence,
the energy identity and balance on a micro-structure with convection and radiation, and the refusals."""

import numpy as np
import pytest

import tiling
from geometry import primitives as pr
from iga import HeatProblem, ProblemError, TransientHeatProblem
from tiling import library as L

K0, BETA, LENGTH, T_A, T_B = 2.0, 0.01, 1.0, 20.0, 300.0  # k = K0 (1 + BETA T): 2.4 .. 8 W/(m K)


def _kirchhoff(x):
    """phi(T) = int_0^T k = K0 (T + BETA T^2 / 2) is linear in x across the bar: T and dT/dx from it."""
    phi_a, phi_b = (K0 * (t + BETA * t * t / 2) for t in (T_A, T_B))
    phi = phi_a + (phi_b - phi_a) * x[:, 0] / LENGTH
    T = (-1 + np.sqrt(1 + 2 * BETA * phi / K0)) / BETA
    grad = np.zeros((len(x), 3))
    grad[:, 0] = (phi_b - phi_a) / LENGTH / (K0 * (1 + BETA * T))
    return T, grad


def _bar_solution(p, n, conductivity):
    bar = pr.box((LENGTH, 0.1, 0.1), degrees=(p, 1, 1), elements=(n, 1, 1))
    return HeatProblem(bar, conductivity=conductivity).dirichlet("umin", T_A).dirichlet("umax", T_B).solve()


@pytest.mark.parametrize("p", [1, 2])
def test_a_bar_converges_to_the_kirchhoff_solution_at_the_optimal_rates(p):
    errors = []
    for n in (16, 32, 64):
        s = _bar_solution(p, n, lambda x, T: K0 * (1 + BETA * T))
        errors.append((s.l2_error(lambda x: _kirchhoff(x)[0]), s.h1_error(lambda x: _kirchhoff(x)[1])))
        residuals = np.array(s.info["newton"])
        assert residuals[-1] < 1e-12 * residuals[0]
        # quadratic: each residual about the square of the one before (until round-off)
        live = residuals[1:] > 1e-10 * residuals[0]
        assert np.all(residuals[1:][live] / residuals[:-1][live] ** 2 < 1.0)
        assert s.balance()["relative_error"] < 1e-10 and s.energy_balance().relative_error < 1e-10
    rates = np.log2(np.array(errors[:-1]) / np.array(errors[1:]))
    assert np.all(np.abs(rates[:, 0] - (p + 1)) < 0.15) and np.all(np.abs(rates[:, 1] - p) < 0.1), rates


def test_a_table_of_conductivities_is_interpolated_monotonically():
    temperatures = np.linspace(0.0, 400.0, 41)
    table = np.c_[temperatures, K0 * (1 + BETA * temperatures)]
    by_table = _bar_solution(2, 16, table)
    by_formula = _bar_solution(2, 16, lambda x, T: K0 * (1 + BETA * T))
    assert np.abs(by_table.u - by_formula.u).max() < 1e-9 * T_B  # a linear k is interpolated exactly
    points = np.array([[0.3, 0.05, 0.05]])
    flux = by_table.heat_flux(0, np.array([[0.3, 0.5, 0.5]]))[0, 0]
    assert flux == pytest.approx(-(K0 * (1 + BETA * by_table.probe(points)[0])) *
                                 by_table.evaluate(0, np.array([[0.3, 0.5, 0.5]]))[1][0, 0], rel=1e-12)
    with pytest.raises(ProblemError, match="outside the conductivity table's range"):
        _bar_solution(2, 8, table[:20])  # up to 190: the bar reaches 300


def test_a_micro_structure_with_convection_and_radiation_balances_its_heat():
    ms = tiling.regular(pr.twisted(pr.box(degrees=(2, 2, 2)), 0.3, axis_point=(0.5, 0.5)), L.cross(), (2, 2, 1))
    problem = HeatProblem(ms, conductivity=lambda x, T: 40.0 / (1 + 0.002 * T), degree_elevation=1)
    problem.neumann("wmin", 3e4).robin("wmax", 10.0, 20.0).radiation("wmax", 0.7, 20.0, scale="C")
    s = problem.solve()
    assert s.balance()["relative_error"] < 1e-10
    assert s.flux("wmax") == pytest.approx(-s.flux("wmin"), rel=1e-10)
    residuals = np.array(s.info["newton"])
    assert 3 <= len(residuals) <= 12 and residuals[-1] < 1e-12 * residuals[0]
    # hotter than with k frozen at its 20 C value (k falls as the part warms)
    frozen = HeatProblem(ms, conductivity=40.0 / 1.04, degree_elevation=1).neumann("wmin", 3e4)
    frozen = frozen.robin("wmax", 10.0, 20.0).radiation("wmax", 0.7, 20.0, scale="C").solve()
    assert s.temperature_range()[1] > frozen.temperature_range()[1]


@pytest.mark.parametrize("conductivity, match", [
    (lambda x, T: 1.0 - 0.01 * T, "not positive"),
    (lambda x, T: np.ones(3), "must return"),
    ([[0.0, 1.0], [0.0, 2.0]], "strictly increasing"),
    ([[0.0, 1.0], [100.0, -2.0]], "positive"),
])
def test_bad_temperature_dependent_conductivities_are_refused(conductivity, match):
    with pytest.raises(ProblemError, match=match):
        _bar_solution(2, 4, conductivity)


@pytest.mark.slow
def test_a_transient_with_k_of_t_settles_on_the_steady_newton_state_and_converges_in_time():
    bar = pr.box((LENGTH, 0.1, 0.1), degrees=(2, 1, 1), elements=(8, 1, 1))
    k = lambda x, T: K0 * (1 + BETA * T)  # noqa: E731
    steady = HeatProblem(bar, conductivity=k).dirichlet("umin", T_A).dirichlet("umax", T_B).solve()

    def transient():
        problem = TransientHeatProblem(steady.problem.model, conductivity=k, capacity=3.0)
        problem.dirichlet("umin", T_A).dirichlet("umax", T_B)
        return problem.initial(lambda x: T_A + (T_B - T_A) * x[:, 0] / LENGTH)  # meets the ends' values

    history = transient().solve(20.0, tol=1e-3)
    assert np.abs(history.final.u - steady.u).max() < 1e-8 * T_B
    assert history.at(float(history.times[5])).balance()["relative_error"] < 1e-9 and history.record.newton
    # order 2 in time (BDF2), against a reference of steps 4 times finer than the finest
    middle = np.array([[0.5, 0.05, 0.05]])
    reference = transient().solve(0.2, 0.2 / 128).probe(middle)[-1, 0]
    errors = [abs(transient().solve(0.2, dt).probe(middle)[-1, 0] - reference) for dt in (0.2 / 8, 0.2 / 16, 0.2 / 32)]
    rates = np.log2(np.array(errors[:-1]) / np.array(errors[1:]))
    assert np.all(np.abs(rates - 2) < 0.3), (errors, rates)


def test_where_k_of_t_is_not_available_it_is_refused():
    with pytest.raises(ProblemError, match="NURBS basis"):
        HeatProblem(pr.annulus(0.5, 1.0, 0.3, np.pi / 2), conductivity=lambda x, T: 1.0 + 0 * T).dirichlet(
            "umin", 0.0).dirichlet("umax", 1.0).solve()


def test_a_pipeline_takes_the_conductivity_as_a_table(tmp_path):
    from iga.app.pipeline import run_pipeline

    temperatures = np.linspace(0.0, 400.0, 9)
    cfg = {"map": {"primitive": "box", "args": {"size": [LENGTH, 0.1, 0.1], "degrees": [2, 1, 1],
                                                 "elements": [16, 1, 1]}},
           "tile": {"library": "cube"}, "paving": {"scheme": "regular", "counts": [1, 1, 1]},
           "material": {"conductivity": [[float(t), K0 * (1 + BETA * t)] for t in temperatures]},
           "bc": [{"kind": "dirichlet", "tag": "umin", "value": T_A}, {"kind": "dirichlet", "tag": "umax",
                                                                        "value": T_B}],
           "output": {"dir": str(tmp_path / "o"), "vtu": False, "png": False, "probes": [[0.4, 0.05, 0.05]]}}
    s = run_pipeline(cfg, tmp_path)
    table = np.c_[temperatures, K0 * (1 + BETA * temperatures)]
    # the same in Python: a cube tile on each of the map's 16 knot spans
    ms = tiling.regular(pr.box((LENGTH, 0.1, 0.1), degrees=(2, 1, 1), elements=(16, 1, 1)), L.cube(), (1, 1, 1))
    direct = HeatProblem(ms, conductivity=table).dirichlet("umin", T_A).dirichlet("umax", T_B).solve()
    direct = direct.probe(np.array([[0.4, 0.05, 0.05]]))[0]
    assert s["probes"]["temperature_C"][0] == pytest.approx(direct, rel=1e-10)
    assert s["solver"]["newton_iterations"] >= 3
    cfg["material"]["conductivity"] = [[0.0, 1.0], [0.0, 2.0]]
    with pytest.raises(ProblemError, match="strictly increasing"):
        run_pipeline(cfg, tmp_path)
