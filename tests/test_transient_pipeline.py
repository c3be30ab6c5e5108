"""Transient heat from pipelines and the command line: physics.kind = "transient-heat" with [time], the
summary's series against the Python API, the ParaView series read back, a run to the steady state and its
settling time against fixed small steps, the demo's warm-up, and the configuration's refusals."""

import json

import numpy as np
import pytest
from commands import iga_command

from geometry import primitives as pr
from iga import ProblemError, TransientHeatProblem
from iga.app.pipeline import heat_sink_config, run_pipeline

K, RC, Q, H = 4.0, 2.0, 3.0, 5.0  # W/(m K), J/(m^3 K), W/m^2 in at x = 0, W/(m^2 K) to 0 C at x = 1


def _bar_config(out, time, probes=((0.0, 0.1, 0.1), (0.5, 0.1, 0.1))):
    return {"map": {"primitive": "box", "args": {"size": [1.0, 0.2, 0.2], "degrees": [2, 1, 1],
                                                  "elements": [6, 1, 1]}},
            "tile": {"library": "cube"}, "paving": {"scheme": "regular", "counts": [1, 1, 1]},
            "material": {"conductivity": K, "capacity": RC}, "physics": {"kind": "transient-heat"},
            "time": time, "bc": [{"kind": "neumann", "tag": "umin", "value": Q},
                                 {"kind": "robin", "tag": "umax", "h": H, "ambient": 0.0}],
            "output": {"dir": str(out), "name": "bar", "samples": 2, "probes": [list(p) for p in probes]}}


def _bar_problem(ms):
    problem = TransientHeatProblem(ms, conductivity=K, capacity=RC)
    return problem.neumann("umin", Q).robin("umax", H, 0.0).initial(0.0)


@pytest.mark.slow
def test_a_pipeline_run_equals_the_python_api_and_writes_its_series(tmp_path):
    import pyvista as pv

    s = run_pipeline(_bar_config(tmp_path, {"end": 0.5, "step": 0.05, "every": 2}), tmp_path)
    tr = s["transient"]
    assert tr["steps"] == 10 and np.allclose(tr["times_s"], np.arange(0, 0.51, 0.1))
    # the same problem in Python, on the model the pipeline built (a one-tile regular paving of the bar)
    import tiling
    from tiling import library as L

    ms = tiling.regular(pr.box((1.0, 0.2, 0.2), degrees=(2, 1, 1), elements=(6, 1, 1)), L.cube(), (1, 1, 1))
    history = _bar_problem(ms).solve(0.5, 0.05, keep=2)
    probes = np.array(s["probes"]["points"])
    assert np.abs(np.array(s["probes"]["temperature_C"]).T - history.probe(probes)).max() < 1e-12
    assert s["stored_W"] == pytest.approx(history.final.stored_W, rel=1e-10)
    assert s["energy_balance_error"] < 1e-10  # inflow = outflow + stored at the end state
    assert s["energy_identity"]["relative_error"] < 1e-10 and s["connected_pieces"] == 1
    reader = pv.get_reader(s["files"]["pvd"])
    assert np.allclose(reader.time_values, tr["times_s"])
    reader.set_active_time_value(reader.time_values[-1])
    last = reader.read()[0]
    final = pv.read(s["files"]["vtu"])
    assert np.allclose(last.point_data["temperature"], final.point_data["temperature"], atol=1e-12)
    assert (tmp_path / "bar_history.png").stat().st_size > 10_000 and (tmp_path / "bar.png").is_file()


@pytest.mark.slow
def test_a_run_to_the_steady_state_reports_when_the_hottest_point_settled(tmp_path):
    time = {"end": "steady", "tolerance": 1e-5, "fraction": 0.9}
    s = run_pipeline(_bar_config(tmp_path, time, probes=()), tmp_path)
    tr = s["transient"]
    # steady: T(x) = Q / H + Q (1 - x) / K, hottest at x = 0 (the heated end)
    assert tr["watched_point"][0] == pytest.approx(0.0, abs=1e-12)
    assert tr["steady_watched_C"] == pytest.approx(Q / H + Q / K, rel=1e-10)
    # independently: fixed small steps, the first time x = 0 reaches 90% of its rise, by interpolation
    import tiling
    from tiling import library as L

    ms = tiling.regular(pr.box((1.0, 0.2, 0.2), degrees=(2, 1, 1), elements=(6, 1, 1)), L.cube(), (1, 1, 1))
    fine = _bar_problem(ms).solve(1.5 * tr["settle_time_s"], 1e-3)
    T = fine.probe(np.array([[0.0, 0.1, 0.1]]))[:, 0]
    i = int(np.argmax(T >= 0.9 * tr["steady_watched_C"]))
    crossing = np.interp(0.9 * tr["steady_watched_C"], T[i - 1:i + 1], fine.times[i - 1:i + 1])
    assert tr["settle_time_s"] == pytest.approx(crossing, rel=2e-3)
    assert tr["watched_C"][-1] >= 0.9 * tr["steady_watched_C"] > tr["watched_C"][-2]


@pytest.mark.slow
def test_a_part_held_at_a_temperature_settles_at_the_point_the_condition_does_not_hold(tmp_path):
    # the bar held at 1 C at x = 0 (from 0 C), cooled by Robin at x = 1: the held face takes its steady value at
    # the first step, so the watched point is the free one of largest change, and the run takes many steps
    cfg = _bar_config(tmp_path, {"end": "steady", "tolerance": 1e-5, "fraction": 0.9}, probes=())
    cfg["bc"][0] = {"kind": "dirichlet", "tag": "umin", "value": 1.0}
    tr = run_pipeline(cfg, tmp_path)["transient"]
    assert tr["watched_point"][0] > 0.05  # not on the held face x = 0 (samples: the element corners, 1/6 apart)
    assert tr["steps"] > 10 and tr["settle_time_s"] > 1e-3
    assert tr["watched_C"][-1] >= 0.9 * tr["steady_watched_C"] > tr["watched_C"][-2]


@pytest.mark.slow
def test_the_demo_follows_the_sink_warming_up(tmp_path):
    out = iga_command("demo", "heat-sink", "--variant", "vertical", "--levels", "1", "--transient",
                      "--out", tmp_path / "demo")
    assert out.returncode == 0, out.stderr
    s = json.loads((tmp_path / "demo" / "summary.json").read_text())
    tr = s["transient"]
    assert "95% of its steady rise" in out.stdout and f"{tr['settle_time_s'] / 60:.1f} min" in out.stdout
    assert tr["watched_C"][0] == pytest.approx(20.0, abs=1e-9)
    assert 0.95 * (tr["steady_watched_C"] - 20.0) <= tr["watched_C"][-1] - 20.0 < tr["steady_watched_C"] - 20.0
    assert 0 < s["stored_W"] < s["inflow_W"]  # still warming: part of the inflow is stored
    for key in ("pvd", "vtu", "png", "history_png"):
        assert (tmp_path / "demo").joinpath(s["files"][key]).exists()


@pytest.mark.parametrize("change, match", [
    (lambda c: c.pop("time"), "needs a \\[time\\] section"),
    (lambda c: c["material"].pop("capacity"), "material.capacity"),
    (lambda c: c["material"].update(capacity=-1.0), "material.capacity"),
    (lambda c: c["time"].update(end="forever"), "time.end"),
    (lambda c: c["time"].update(end="steady"), "time.tolerance"),
    (lambda c: c["time"].update(end=-1.0), "time.end"),
    (lambda c: c["time"].pop("step"), "step .* or tolerance"),
    (lambda c: c["time"].update(method="rk4"), "time.method"),
    (lambda c: c["time"].update(method="theta"), "time.theta"),
    (lambda c: c["time"].update(fraction=0.9), "time.fraction"),
    (lambda c: c.update(solver={"method": "fd-cg"}), "solver.method"),
    (lambda c: c["physics"].update(kind="heat"), "capacity"),
    (lambda c: (c["physics"].update(kind="heat"), c["material"].pop("capacity")), "config section time"),
])
def test_bad_transient_configurations_are_refused(tmp_path, change, match):
    cfg = _bar_config(tmp_path / "o", {"end": 0.5, "step": 0.05})
    change(cfg)
    with pytest.raises(ProblemError, match=match):
        run_pipeline(cfg, tmp_path)
    assert not (tmp_path / "o").exists()


def test_the_transient_demo_takes_no_stress():
    with pytest.raises(ProblemError, match="no stress"):
        heat_sink_config(transient=True, stress=True)
