"""Elasticity from a pipeline: the [physics] section, [[support]] and [[load]] tables, and the demo's --stress."""

import json

import numpy as np
import pytest
from commands import iga_command

from iga.app.config import validate
from iga.errors import ProblemError
from iga.app.pipeline import run_pipeline


def _cfg(**physics):
    cfg = {"map": {"primitive": "box", "args": {"size": [2.0, 1.0, 1.0]}}, "tile": {"library": "cross"},
           "paving": {"scheme": "regular", "counts": [2, 1, 1]},
           "physics": {"kind": "elasticity", "youngs": 1e9, "poisson": 0.25, **physics},
           "support": [{"tag": "umin", "value": 0.0}],
           "load": [{"kind": "traction", "tag": "umax", "value": [1e5, 0.0, -2e4]}],
           "output": {"png": False}}
    return cfg


def test_an_elastic_pipeline_reports_reactions_that_balance_the_load(tmp_path):
    cfg = _cfg()
    cfg["output"]["dir"] = str(tmp_path / "out")
    s = run_pipeline(cfg, tmp_path)
    e = s["elasticity"]
    assert np.allclose(np.array(e["reactions_N"]["umin"]), -np.array(e["applied_N"]["umax"]), rtol=1e-8, atol=1e-6)
    assert e["work"]["relative_error"] < 1e-9 and e["max_von_mises_Pa"] > 1e4 and "temperature_C" not in s
    assert (tmp_path / "out" / "result_stress.vtu").exists() and json.loads((tmp_path / "out" / "summary.json")
                                                                           .read_text())["elasticity"]


@pytest.mark.parametrize("change, match", [
    (lambda c: c["physics"].update(kind="plastic"), r"physics\.kind: must be one of"),
    (lambda c: c["physics"].pop("youngs"), r"physics \(kind 'elasticity'\) needs 'youngs'"),
    (lambda c: c["physics"].update(poisson=0.7), r"physics\.poisson"),
    (lambda c: c["physics"].update(expansion=1e-5), r"physics\.expansion: applies to physics\.kind = 'thermo-elastic'"),
    (lambda c: c["support"][0].update(components="xq"), r"support\[0\]\.components: must be distinct letters"),
    (lambda c: c["load"][0].update(kind="moment"), r"load\[0\]\.kind"),
    (lambda c: c["load"][0].update(value=[1, 2]), r"load\[0\]\.value: must be a list of three numbers"),
    (lambda c: c.update(bc=[{"kind": "dirichlet", "tag": "umin", "value": 1.0}]), r"takes \[\[support\]\] and \[\[load\]\]"),
    (lambda c: c.pop("support"), r"needs \[\[support\]\] tables .* or physics\.hold_rigid = true"),
    (lambda c: c["physics"].update(kind="thermo-elastic", expansion=1e-5), r"missing required config section 'bc'"),
    (lambda c: c["physics"].update(hold_rigid="yes"), r"physics\.hold_rigid: must be true or false"),
    (lambda c: c["physics"].update(hold_rigid=True), r"physics\.hold_rigid: holds a body without \[\[support\]\] "
     r"tables"),
])
def test_bad_physics_sections_are_refused_before_any_work(change, match, tmp_path):
    cfg = _cfg()
    change(cfg)
    with pytest.raises(ProblemError, match=match):
        validate(cfg, tmp_path)


def test_a_heat_pipeline_refuses_elastic_tables():
    cfg = _cfg()
    cfg["physics"] = {"kind": "heat"}
    cfg["bc"] = [{"kind": "dirichlet", "tag": "umin", "value": 1.0}]
    with pytest.raises(ProblemError, match="config section support applies to physics.kind"):
        validate(cfg)


@pytest.mark.slow
def test_the_demo_adds_the_thermal_stress_of_the_graded_sink(tmp_path):
    import meshio

    out = iga_command("--quiet", "demo", "heat-sink", "--variant", "vertical", "--levels", "1", "--stress",
                      "--out", tmp_path / "demo")
    assert out.returncode == 0, out.stderr
    assert "elasticity:" in out.stdout and "von Mises up to" in out.stdout
    s = json.loads((tmp_path / "demo" / "summary.json").read_text())
    e = s["elasticity"]
    assert e["work"]["relative_error"] < 1e-9 and e["work"]["thermal"] and e["max_von_mises_Pa"] > 1e3
    assert s["energy_balance_error"] < 1e-8  # the heat analysis the stress stands on
    mesh = meshio.read(tmp_path / "demo" / "heat_sink_stress.vtu")
    assert mesh.point_data["stress"].shape[1] == 6 and np.isfinite(mesh.point_data["von_mises"]).all()
    assert (tmp_path / "demo" / "heat_sink_stress.png").stat().st_size > 10_000
