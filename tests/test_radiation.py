"""Radiation from faces (HeatProblem.radiation): the Stefan-Boltzmann condition solved by Newton's method,
against closed forms (a thin plate radiating to 0 K; a bar held at one end, whose far end's temperature solves
a scalar equation found independently by bracketing), quadratic convergence measured, temperatures in K and C,
a radiating micro-structure's balance, and the refusals."""

import json

import numpy as np
import pytest
from scipy.optimize import brentq

import tiling
from geometry import primitives as pr
from iga import HeatProblem, ProblemError, TransientHeatProblem
from iga.heat.radiation import STEFAN_BOLTZMANN as SIGMA
from tiling import library as L


def test_a_thin_plate_radiating_to_absolute_zero_settles_where_its_radiation_equals_the_inflow():
    q, eps, k, t = 1000.0, 0.8, 20.0, 0.01  # W/m^2, -, W/(m K), m
    plate = pr.box((0.1, 0.1, t), degrees=(1, 1, 2))
    s = HeatProblem(plate, conductivity=k).neumann("wmin", q).radiation("wmax", eps, 0.0).solve()
    top = (q / (SIGMA * eps)) ** 0.25  # sigma eps T^4 = q at the radiating face, T linear through the plate
    points = np.random.default_rng(1).uniform([0, 0, 0], [0.1, 0.1, t], (20, 3))
    assert np.abs(s.probe(points) - (top + q * (t - points[:, 2]) / k)).max() < 1e-8 * top
    assert s.flux("wmax") == pytest.approx(q * 0.01, rel=1e-10) and s.balance()["relative_error"] < 1e-10


@pytest.mark.parametrize("scale, offset", [("K", 0.0), ("C", 273.15)])
def test_a_bar_held_hot_at_one_end_radiates_from_the_other_and_newton_converges_quadratically(scale, offset):
    k, length, hot, air, eps = 2.0, 0.5, 1000.0, 300.0, 0.9  # K
    far = brentq(lambda T: k * (hot - T) / length - SIGMA * eps * (T ** 4 - air ** 4), air, hot)
    bar = pr.box((length, 0.1, 0.1), degrees=(2, 1, 1))
    s = HeatProblem(bar, conductivity=k).dirichlet("umin", hot - offset)
    s = s.radiation("umax", eps, air - offset, scale=scale).solve()
    points = np.random.default_rng(2).uniform([0, 0, 0], [length, 0.1, 0.1], (20, 3))
    exact = hot + (far - hot) * points[:, 0] / length - offset
    assert np.abs(s.probe(points) - exact).max() < 1e-8 * hot
    assert s.flux("umax") == pytest.approx(SIGMA * eps * (far ** 4 - air ** 4) * 0.01, rel=1e-9)
    residuals = np.array(s.info["newton"])
    assert len(residuals) >= 4 and residuals[-1] < 1e-12 * residuals[0]
    before_roundoff = residuals[:-1][residuals[1:] > 1e-10 * residuals[0]]
    after = residuals[1:len(before_roundoff) + 1]
    assert np.all(after / before_roundoff ** 2 < 0.1), after / before_roundoff ** 2  # e_{k+1} <= C e_k^2


def test_a_radiating_and_convecting_micro_structure_balances_its_heat():
    ms = tiling.regular(pr.twisted(pr.box(degrees=(2, 2, 2)), 0.3, axis_point=(0.5, 0.5)), L.cross(), (2, 2, 1))
    problem = HeatProblem(ms, conductivity=50.0, degree_elevation=1).neumann("wmin", 2e4)
    problem.robin("wmax", 10.0, 20.0).radiation("wmax", lambda x: 0.5 + 0.3 * x[:, 0], 20.0, scale="C")
    s = problem.solve()
    b = s.balance()
    area = sum(float(fd.dAw.sum()) for fd in problem.faces(problem.tag_faces("wmin")))
    assert b["relative_error"] < 1e-9 and b["inflow_W"] == pytest.approx(2e4 * area, rel=1e-12)
    assert s.flux("wmax") == pytest.approx(-s.flux("wmin"), rel=1e-9)
    # the same faces with convection only stay hotter: radiation carries part of the heat
    convect = HeatProblem(ms, conductivity=50.0, degree_elevation=1).neumann("wmin", 2e4).robin("wmax", 10.0, 20.0)
    assert convect.solve().temperature_range()[1] > s.temperature_range()[1] + 1.0
    assert len(s.info["newton"]) >= 3 and s.info["newton"][-1] < 1e-9 * s.info["newton"][0]


@pytest.mark.parametrize("call, match", [
    (lambda p: p.radiation("umax", 1.5, 300.0), "emissivity .* \\[0, 1\\]"),
    (lambda p: p.radiation("umax", -0.1, 300.0), "emissivity .* \\[0, 1\\]"),
    (lambda p: p.radiation("umax", 0.5, 300.0, scale="F"), "scale must be 'K' or 'C'"),
    (lambda p: p.radiation("umax", lambda x: 2.0 + 0 * x[:, 0], 300.0).solve(), "emissivity .* \\[0, 1\\]"),
    (lambda p: p.radiation("umin", 0.5, 300.0).solve(), "one kind"),
    (lambda p: p.radiation("umax", 0.5, -200.0).solve(), "below absolute zero"),
    (lambda p: p.neumann("umax", -5e4).radiation("umax", 0.5, 1.0).solve(), "no temperature above absolute zero"),
    (lambda p: p.radiation("nowhere", 0.5, 300.0), "nowhere"),
])
def test_bad_radiation_input_is_refused_with_the_fix(call, match):
    problem = HeatProblem(pr.box(degrees=(2, 1, 1))).dirichlet("umin", 20.0)  # a Celsius value, scale K below
    with pytest.raises(ProblemError, match=match):
        call(problem)


@pytest.mark.slow
@pytest.mark.parametrize("method, order", [("bdf2", 2), ("backward-euler", 1)])
def test_a_thin_plate_cools_by_radiation_as_the_lumped_closed_form(method, order):
    # rho c L dT/dt = -sigma eps T^4 (conduction across the plate far faster: Biot number 2e-6), so
    # T(t) = (T0^-3 + 3 sigma eps t / (rho c L))^(-1/3)
    rc, thick, eps, T0, t_end = 2e6, 0.01, 0.8, 1000.0, 300.0
    exact = (T0 ** -3 + 3 * SIGMA * eps * t_end / (rc * thick)) ** (-1 / 3)
    errors = []
    for dt in (20.0, 10.0, 5.0):
        plate = pr.box((0.05, 0.05, thick), degrees=(1, 1, 1))
        problem = TransientHeatProblem(plate, conductivity=1e6, capacity=rc).radiation("wmax", eps, 0.0)
        history = problem.initial(T0).solve(t_end, dt, method=method)
        errors.append(abs(history.probe(np.array([[0.02, 0.02, 0.005]]))[-1, 0] - exact))
        assert history.record.newton and max(history.record.newton[-1:]) <= 1e-10
        state = history.at(t_end)  # the radiated heat is the heat lost from store
        assert state.flux("wmax") == pytest.approx(-state.stored_W, rel=1e-7)
    rates = np.log2(np.array(errors[:-1]) / np.array(errors[1:]))
    assert np.all(np.abs(rates - order) < 0.15), (errors, rates)


@pytest.mark.slow
def test_a_radiating_transient_settles_to_the_steady_radiating_state():
    bar = pr.box((0.5, 0.1, 0.1), degrees=(2, 1, 1))
    steady = HeatProblem(bar, conductivity=2.0).dirichlet("umin", 1000.0).radiation("umax", 0.9, 300.0).solve()
    problem = TransientHeatProblem(steady.problem.model, conductivity=2.0, capacity=1e5)
    problem.dirichlet("umin", 1000.0).radiation("umax", 0.9, lambda x, t: 300.0 + 0 * x[:, 0] + 0 * t)
    history = problem.initial(300.0).solve(5e5, tol=1e-3)
    assert np.abs(history.final.u - steady.u).max() < 1e-8 * 1000.0
    assert history.final.balance()["relative_error"] < 1e-9
    with pytest.raises(ProblemError, match="emissivity .* must not depend on time"):
        problem.radiation("umax", lambda x, t: 0.5, 300.0)


def test_a_pipeline_radiates_as_the_python_api_does_and_gismo_export_refuses_it(tmp_path):
    from iga.app.pipeline import run_pipeline
    from iga.io.gismo import export_gismo

    cfg = {"map": {"primitive": "box", "args": {"size": [0.5, 0.1, 0.1], "degrees": [2, 1, 1]}},
           "tile": {"library": "cube"}, "paving": {"scheme": "regular", "counts": [1, 1, 1]},
           "material": {"conductivity": 2.0},
           "bc": [{"kind": "dirichlet", "tag": "umin", "value": 726.85},
                  {"kind": "radiation", "tag": "umax", "emissivity": 0.9, "ambient": 26.85, "scale": "C"}],
           "output": {"dir": str(tmp_path / "o"), "vtu": False, "png": False}}
    s = run_pipeline(cfg, tmp_path)
    far = brentq(lambda T: 2.0 * (1000.0 - T) / 0.5 - SIGMA * 0.9 * (T ** 4 - 300.0 ** 4), 300.0, 1000.0)
    assert s["flux_W"]["umax"] == pytest.approx(SIGMA * 0.9 * (far ** 4 - 300.0 ** 4) * 0.01, rel=1e-9)
    assert s["energy_balance_error"] < 1e-10
    for bad, match in ((dict(emissivity=1.2), "emissivity"), (dict(scale="F"), "scale"), (dict(h=3.0), "h")):
        wrong = {**cfg, "bc": [cfg["bc"][0], {**cfg["bc"][1], **bad}]}
        with pytest.raises(ProblemError, match=match):
            run_pipeline(wrong, tmp_path)
    problem = HeatProblem(pr.box()).dirichlet("umin", 300.0).radiation("umax", 0.5, 300.0)
    with pytest.raises(ProblemError, match="no G\\+Smo XML form"):
        export_gismo(problem, tmp_path / "p.xml")


def test_iga_run_prints_the_newton_iterations_of_a_radiating_pipeline(tmp_path, capsys):
    from iga.app.cli import main

    (tmp_path / "bar.toml").write_text(
        '[map]\nprimitive = "box"\nargs = {size = [0.5, 0.1, 0.1], degrees = [2, 1, 1]}\n[tile]\nlibrary = "cube"\n'
        '[paving]\nscheme = "regular"\ncounts = [1, 1, 1]\n[material]\nconductivity = 2.0\n'
        '[[bc]]\nkind = "dirichlet"\ntag = "umin"\nvalue = 1000.0\n'
        '[[bc]]\nkind = "radiation"\ntag = "umax"\nemissivity = 0.9\nambient = 300.0\n'
        '[output]\nvtu = false\npng = false\n')
    assert main(["--quiet", "run", str(tmp_path / "bar.toml")]) == 0
    out = capsys.readouterr().out
    n = json.loads((tmp_path / "out" / "summary.json").read_text())["solver"]["newton_iterations"]
    assert n >= 3 and f"Newton: {n} iterations" in out


def test_a_faint_radiation_beside_a_held_temperature_stops_at_round_off():
    # 1 K held at x = 0, a face radiating 0.5 sigma T^4 (28 nW/m^2) at x = 1: the loads' own scale is tiny, so
    # the residual's floor is the round-off of the conduction term; T(1) = 1 - sigma eps T(1)^4 / k
    from geometry import primitives as pr
    from iga import HeatProblem

    s = HeatProblem(pr.box(), conductivity=1.0).dirichlet("umin", 1.0).radiation("umax", 0.5, 0.0).solve()
    assert len(s.info.newton) <= 3
    assert s.probe(np.array([[1.0, 0.5, 0.5]]))[0] == pytest.approx(1 - 5.670374419e-8 * 0.5, abs=1e-14)
