"""Transient heat conduction (iga.TransientHeatProblem): the schemes' orders measured on the decay of one
mode, exactness for solutions linear in time with time-dependent data, the steady state reached, the energy
balance of every kept step, adaptive steps, the ParaView series read back by VTK and meshio, bad input."""

import numpy as np
import pytest

import tiling
from geometry import primitives as pr
from tiling import library as L
from iga import HeatProblem, ProblemError, TransientHeatProblem

K_BAR, RC_BAR, LENGTH = 2.0, 3.0, 1.0  # W/(m K), J/(m^3 K), m
DECAY = K_BAR * np.pi ** 2 / (RC_BAR * LENGTH ** 2)  # 1/s, the first mode's rate


def _bar(elements=16, degree=4):
    return pr.box((LENGTH, 0.2, 0.2), degrees=(degree, 1, 1), elements=(elements, 1, 1))


def _mode(x):
    return np.sin(np.pi * x[:, 0] / LENGTH)


@pytest.mark.parametrize("method, order", [("backward-euler", 1), ("crank-nicolson", 2), ("bdf2", 2),
                                           ("theta", 1)])
def test_one_mode_decays_at_the_schemes_order_in_time(method, order):
    t_end = 0.1
    exact = lambda x: np.exp(-DECAY * t_end) * _mode(x)  # noqa: E731
    errors = []
    for dt in (0.01, 0.005, 0.0025):
        problem = TransientHeatProblem(_bar(), conductivity=K_BAR, capacity=RC_BAR)
        problem.dirichlet("umin", 0.0).dirichlet("umax", 0.0).initial(_mode)
        history = problem.solve(t_end, dt, method=method, theta=0.75 if method == "theta" else None)
        assert history.times[-1] == t_end and len(history.times) == round(t_end / dt) + 1
        errors.append(history.final.l2_error(exact))
    rates = np.log2(np.array(errors[:-1]) / np.array(errors[1:]))
    assert np.all(np.abs(rates - order) < 0.1), (errors, rates)
    # the spatial error (the projected initial mode's) is far below the temporal one
    spatial = history.at(0.0).l2_error(_mode)
    assert spatial < 0.01 * errors[-1], (spatial, errors)


@pytest.mark.parametrize("method", ["backward-euler", "crank-nicolson", "bdf2"])
@pytest.mark.parametrize("boundary", ["dirichlet", "neumann"])
def test_a_solution_linear_in_time_with_time_dependent_data_is_exact(method, boundary):
    # T = t x^2: rho c x^2 - 2 k t = f(x, t); T(0) = 0; at x = L either T = L^2 t or the inflow k 2 L t
    k, rc = 1.5, 2.0
    problem = TransientHeatProblem(pr.box((LENGTH, 0.3, 0.2), degrees=(2, 1, 1), elements=(3, 1, 1)),
                                   conductivity=k, capacity=rc, source=lambda x, t: rc * x[:, 0] ** 2 - 2 * k * t)
    problem.dirichlet("umin", 0.0)
    if boundary == "dirichlet":
        problem.dirichlet("umax", lambda x, t: LENGTH ** 2 * t + 0 * x[:, 0])
    else:
        problem.neumann("umax", lambda x, t: 2 * k * LENGTH * t + 0 * x[:, 0])
    history = problem.initial(0.0).solve(1.0, 0.125, method=method)
    rng = np.random.default_rng(3)
    points = rng.uniform([0, 0, 0], [LENGTH, 0.3, 0.2], (20, 3))
    expected = history.times[:, None] * points[None, :, 0] ** 2
    assert np.abs(history.probe(points) - expected).max() < 1e-9
    state = history.at(0.5)
    # the heat flows at t = 0.5: 2 k L t W/m^2 into umax over its 0.06 m^2, none through umin (dT/dx = 0 there)
    assert state.flux("umax") == pytest.approx(-2 * k * LENGTH * 0.5 * 0.06, rel=1e-9)
    assert abs(state.flux("umin")) < 1e-9
    assert state.balance()["relative_error"] < 1e-9


def _crosses():
    return tiling.regular(pr.twisted(pr.box(degrees=(2, 2, 2)), 0.3, axis_point=(0.5, 0.5)), L.cross(), (2, 2, 1))


def _sink_problem(cls, model=None, **extra):
    problem = cls(model or _crosses(), conductivity=2.0, source=1.0, degree_elevation=1, **extra)
    return problem.dirichlet("wmin", 20.0).robin("wmax", 5.0, 25.0)


def test_the_steady_state_is_reached_and_every_kept_state_balances():
    steady = _sink_problem(HeatProblem).solve(solver="direct")
    problem = _sink_problem(TransientHeatProblem, capacity=1.0).initial(20.0)
    history = problem.solve(t_end=200.0, dt=1e-3, tol=1e-4, method="bdf2")
    final = history.final
    scale = np.abs(steady.u).max()
    assert np.abs(final.u - steady.u).max() < 1e-8 * scale
    assert final.stored_W == pytest.approx(0.0, abs=1e-8 * final.info["balance"]["inflow_W"])
    assert final.flux("wmax") == pytest.approx(steady.flux("wmax"), rel=1e-8)
    # adaptive steps grew as the field settled, and steps of one size shared one prepared solver
    r = history.record
    assert r.steps < 200 and r.prepared < r.steps and r.largest_estimate <= 1e-4
    for t in history.times[1::5]:
        b = history.at(float(t)).balance()  # inflow + source = outflow + stored, the scheme's own rate
        assert b["relative_error"] < 1e-9, (t, b)
    # the heat content grows by what flowed in (trapezoid over the kept steps) to the discretisation error
    E, rate = history.heat_content(), history.stored_rate()
    assert rate[1] > 0 and E[-1] > E[0]
    assert np.trapezoid(rate, history.times) == pytest.approx(E[-1] - E[0], rel=2e-3)  # steps up to ~40 s


def test_the_energy_balance_of_the_steps_converges_with_the_step():
    gaps = []
    for dt in (0.02, 0.01, 0.005):
        problem = _sink_problem(TransientHeatProblem, capacity=1.0).initial(20.0)
        history = problem.solve(t_end=0.4, dt=dt, method="bdf2")
        E, rate = history.heat_content(), history.stored_rate()
        gaps.append(abs(np.trapezoid(rate, history.times) - (E[-1] - E[0])) / (E[-1] - E[0]))
    assert gaps[0] > gaps[1] > gaps[2] and gaps[1] / gaps[2] > 2.5, gaps


def test_adaptive_steps_bound_the_error_by_their_tolerance_and_follow_a_fast_start():
    exact = lambda x: np.exp(-DECAY * 0.5) * _mode(x)  # noqa: E731
    out = {}
    for tol in (1e-4, 1e-6):
        problem = TransientHeatProblem(_bar(), conductivity=K_BAR, capacity=RC_BAR)
        problem.dirichlet("umin", 0.0).dirichlet("umax", 0.0).initial(_mode)
        history = problem.solve(0.5, tol=tol, method="bdf2")
        r = history.record
        out[tol] = (r.steps, history.final.l2_error(exact))
        assert r.largest_estimate <= tol and r.prepared < r.steps
        assert out[tol][1] < r.steps * tol  # the error at the end within the sum of the steps' errors
    (n_loose, e_loose), (n_tight, e_tight) = out[1e-4], out[1e-6]
    assert n_loose < n_tight and e_tight < 0.1 * e_loose
    # an inconsistent start (1 inside, 0 on the ends): short steps through the fast layer, long ones after
    layer = TransientHeatProblem(_bar(), conductivity=K_BAR, capacity=RC_BAR)
    history = layer.dirichlet("umin", 0.0).dirichlet("umax", 0.0).initial(1.0).solve(0.5, tol=1e-4)
    steps = np.diff(history.times)
    assert steps[-3:].min() > 100 * steps[:3].max()
    with pytest.raises(ProblemError, match="max_steps"):
        layer.solve(0.5, tol=1e-12, max_steps=20)


def test_a_steady_solution_starts_a_transient_and_stays_put_without_change():
    steady = _sink_problem(HeatProblem).solve(solver="direct")
    problem = _sink_problem(TransientHeatProblem, steady.problem.model, capacity=3.0).initial(steady)
    with pytest.raises(ProblemError, match="another model object"):
        _sink_problem(TransientHeatProblem, capacity=3.0).initial(steady)
    with pytest.raises(ProblemError, match="another space"):
        _sink_problem(TransientHeatProblem, steady.problem.model, capacity=3.0, refine=1).initial(steady)
    history = problem.solve(t_end=1.0, dt=0.25, method="crank-nicolson")
    assert np.abs(history.final.u - steady.u).max() < 1e-9 * np.abs(steady.u).max()
    assert np.abs(history.stored_rate()).max() < 1e-8


def test_states_between_kept_times_are_interpolated_and_outside_refused():
    problem = TransientHeatProblem(_bar(4, 2), conductivity=K_BAR, capacity=RC_BAR)
    history = problem.dirichlet("umin", 0.0).dirichlet("umax", 0.0).initial(_mode).solve(0.1, 0.01, keep=2)
    assert np.allclose(history.times, [0, 0.02, 0.04, 0.06, 0.08, 0.1])
    mid = history.at(0.03).u
    assert np.allclose(mid, 0.5 * (history.at(0.02).u + history.at(0.04).u))
    with pytest.raises(ProblemError, match="outside the solved interval"):
        history.at(0.2)


@pytest.mark.slow
def test_the_paraview_series_holds_the_kept_states(tmp_path):
    import meshio
    import pyvista as pv

    problem = _sink_problem(TransientHeatProblem, capacity=1.0).initial(20.0)
    history = problem.solve(t_end=0.5, dt=0.05)
    path = history.write_pvd(tmp_path / "warm-up.pvd", every=3, samples=2)
    reader = pv.get_reader(str(path))
    written = [0, 3, 6, 9, 10]
    assert np.allclose(reader.time_values, history.times[written])
    grids = {}
    for i, t in zip(written, reader.time_values):
        reader.set_active_time_value(t)
        grids[i] = grid = reader.read()[0]
        # outputs equal the solution they were written from: the temperature at the grid's points
        pts = np.asarray(grid.points)[::37]
        probe = history.at(float(t)).probe(pts)
        assert np.abs(np.asarray(grid.point_data["temperature"])[::37] - probe).max() < 1e-9
    frame = meshio.read(tmp_path / "warm-up" / "warm-up_00003.vtu")  # a second reader of the same frame
    assert np.array_equal(frame.points, np.asarray(grids[3].points))
    assert np.array_equal(frame.point_data["temperature"], np.asarray(grids[3].point_data["temperature"]))
    assert not np.allclose(frame.point_data["temperature"], np.asarray(grids[0].point_data["temperature"]))
    # written again with fewer frames: the series is replaced whole, no stale frame left
    history.write_pvd(path, every=10, samples=1)
    assert sorted(p.name for p in (tmp_path / "warm-up").iterdir()) == ["warm-up_00000.vtu", "warm-up_00010.vtu"]
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".")]
    with pytest.raises(ProblemError, match=r"\.pvd"):
        history.write_pvd(tmp_path / "warm-up.vtu")
    with pytest.raises(ProblemError, match="folder"):
        history.write_pvd(tmp_path / "missing" / "a.pvd")


@pytest.mark.parametrize("call, match", [
    (lambda p: p.solve(1.0, 0.0), "dt must be a positive"),
    (lambda p: p.solve(1.0, -0.1), "dt must be a positive"),
    (lambda p: p.solve(-1.0, 0.1), "t_end must be a time after the start"),
    (lambda p: p.solve(float("nan"), 0.1), "t_end must be a time after the start"),
    (lambda p: p.solve(1.0), "give the step dt"),
    (lambda p: p.solve(), "give the end time"),
    (lambda p: p.solve(1.0, 0.1, method="rk4"), "unknown time scheme"),
    (lambda p: p.solve(1.0, 0.1, method="theta", theta=0.3), "theta in"),
    (lambda p: p.solve(1.0, 0.1, tol=-1.0), "tol must be a positive"),
    (lambda p: p.solve(1.0, 0.1, keep=0), "keep must be an integer"),
    (lambda p: p.robin("umax", lambda x, t: 1.0 + 0 * t, 0.0), "film coefficient"),
    (lambda p: p.initial(lambda x, t: x[:, 0]), "callable of \\(x, t\\)"),
    (lambda p: p.initial(HeatProblem(pr.box()).dirichlet("umin", 0.0).dirichlet("umax", 1.0).solve()),
     "another model"),
    (lambda p: p.initial("hot"), "initial temperature"),
])
def test_bad_transient_input_is_refused_with_the_fix(call, match):
    problem = TransientHeatProblem(pr.box(degrees=(2, 2, 2)), capacity=2.0).dirichlet("umin", 0.0).initial(1.0)
    with pytest.raises(ProblemError, match=match):
        call(problem)


def test_bad_materials_and_a_missing_start_are_refused():
    with pytest.raises(ProblemError, match="heat capacity"):
        TransientHeatProblem(pr.box(), capacity=-1.0)
    with pytest.raises(ProblemError, match="heat capacity"):
        TransientHeatProblem(pr.box(), capacity=lambda x: 1.0 - 2 * x[:, 0]).dirichlet("umin", 0.0).initial(
            0.0).solve(1.0, 0.5)
    with pytest.raises(ProblemError, match="capacity must not depend on time"):
        TransientHeatProblem(pr.box(), capacity=lambda x, t: 1.0)
    with pytest.raises(ProblemError, match="no initial temperature"):
        TransientHeatProblem(pr.box()).dirichlet("umin", 0.0).solve(1.0, 0.5)
    with pytest.raises(ProblemError, match="source at t = 0.5"):
        TransientHeatProblem(pr.box(), source=lambda x, t: np.full(len(x), np.nan if t > 0.4 else 1.0)).dirichlet(
            "umin", 0.0).initial(0.0).solve(1.0, 0.5)


@pytest.mark.parametrize("name", ["NURBS annulus", "paved crosses"])
def test_the_probe_matrix_evaluates_as_the_solutions_probe(name):
    model = pr.annulus(0.5, 1.0, 0.3, np.pi / 2) if name == "NURBS annulus" else _crosses()
    steady = HeatProblem(model, source=lambda x: 1.0 + x[:, 0], degree_elevation=1).dirichlet("umin", 0.0)
    steady = steady.robin("umax", 3.0, 1.0).solve(solver="direct")
    problem = TransientHeatProblem(model, degree_elevation=1)
    rng = np.random.default_rng(11)
    lo, hi = np.array(steady.to_pyvista(samples=1).bounds).reshape(3, 2).T
    candidates = rng.uniform(lo, hi, (400, 3))
    inside = candidates[np.asarray(steady.to_pyvista(samples=2).find_containing_cell(candidates)) >= 0][:25]
    assert len(inside) >= 10
    E = problem.probe_matrix(inside)
    assert np.abs(E @ steady.u - steady.probe(inside)).max() < 1e-11
    assert np.allclose(np.asarray(E.sum(axis=1)).ravel(), 1.0)  # the basis sums to one at every point


def test_a_solve_stops_when_its_condition_holds():
    problem = TransientHeatProblem(_bar(), conductivity=K_BAR, capacity=RC_BAR).dirichlet("umin", 0.0)
    problem.dirichlet("umax", 0.0).initial(_mode)
    middle = problem.probe_matrix(np.array([[0.5, 0.1, 0.1]]))
    history = problem.solve(10.0, 0.01, until=lambda t, u: (middle @ u)[0] < 0.5)
    stop = np.log(2.0) / DECAY  # the mode halves at ln 2 / rate
    assert history.record.stopped == history.times[-1]
    assert stop <= history.times[-1] < stop + 0.01 + 1e-12
    assert history.probe(np.array([[0.5, 0.1, 0.1]]))[-2, 0] >= 0.5
    with pytest.raises(ProblemError, match="until must be a callable"):
        problem.solve(1.0, 0.1, until=0.5)


def test_the_thermal_stress_of_a_transient_state_at_a_chosen_time():
    # an insulated block with a uniform source warms uniformly, T = 20 + f t / (rho c): held only against rigid
    # motion it expands freely, u = alpha (T - 20) (x - x_A) about its pinned corner, and carries no stress
    from iga import ElasticityProblem

    block = pr.box((0.2, 0.1, 0.05), degrees=(2, 2, 1))
    problem = TransientHeatProblem(block, conductivity=3.0, capacity=2e6, source=4e5).initial(20.0)
    history = problem.solve(10.0, 2.5)
    state = history.at(5.0)
    assert np.allclose(state.probe(np.array([[0.1, 0.05, 0.02]])), 20.0 + 4e5 * 5.0 / 2e6, atol=1e-10)
    alpha = 1.2e-5
    s = ElasticityProblem(block, youngs=7e10, poisson=0.3).thermal(state, alpha, 20.0).hold_rigid().solve()
    points = np.random.default_rng(4).uniform([0, 0, 0], [0.2, 0.1, 0.05], (10, 3))
    u = s.displacement(points)
    strain = alpha * 4e5 * 5.0 / 2e6
    gradient = np.linalg.lstsq(np.c_[points, np.ones(10)], u, rcond=None)[0][:3]
    assert np.abs(np.c_[points, np.ones(10)] @ np.linalg.lstsq(np.c_[points, np.ones(10)], u, rcond=None)[0]
                  - u).max() < 1e-12  # affine
    # its symmetric part is the free thermal strain (the skew part a rigid rotation the 3-2-1 pins leave)
    assert np.allclose(0.5 * (gradient + gradient.T), strain * np.eye(3), atol=1e-12)
    assert np.abs(s.von_mises(points)).max() < 1e-6 * 7e10 * strain
