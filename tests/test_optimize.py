"""Design by gradient: iga.optimize over the control values of a material channel of the deformation map, and over
the map's control points (a shape design at a fixed solid volume)."""

import numpy as np
import pytest
from commands import iga_command

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
    ({"wrt": "map"}, "largest move of a control point"),
    ({"wrt": "shape"}, "wrt must be 'channel:NAME' .*, 'map' .* or 'parameters'"),
    ({"wrt": "channel:rho"}, "does not read the channel 'rho'"),
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


DESIGN = """
[map]
primitive = "vertical_heat_sink"
grading = {channel = "k", near = 129.5, far = 129.5, face = "wmin"}

[tile]
library = "heat_sink_t2"

[paving]
scheme = "hierarchical"
counts = [1, 1]
levels = 2

[material]
conductivity = "k"

[[bc]]
kind = "neumann"
tag = "branch-in"
value = 2e4

[[bc]]
kind = "robin"
tag = "exterior"
h = 3000.0
ambient = 0.0

[design]
variables = "channel:k"
bounds = [54.0, 205.0]
mean = 129.5
iterations = 8

[output]
dir = "out"
name = "sink"
"""


@pytest.mark.slow
def test_iga_optimize_designs_the_channel_and_writes_the_design(tmp_path):
    import json

    import meshio

    (tmp_path / "sink.toml").write_text(DESIGN)
    done = iga_command("--quiet", "optimize", "sink.toml", cwd=tmp_path)
    assert done.returncode == 0, done.stderr[-2000:]
    assert "design: TemperatureNorm(8)" in done.stdout
    summary = json.loads((tmp_path / "out" / "summary.json").read_text())
    d = summary["design"]
    assert d["final"] < d["initial"] and d["improvement"] > 0.01 and 1 <= len(d["steps"]) <= 8
    k = meshio.read(tmp_path / "out" / "sink.vtu").point_data["k"]
    assert k.min() < 120 and k.max() > 140  # the written design is graded, at the uniform design's mean
    assert (tmp_path / "out" / "sink_design.png").stat().st_size > 0
    assert abs(summary["energy_balance_error"]) < 1e-9


@pytest.mark.parametrize("change, match", [
    ({"design": {"variables": "channel:rho", "bounds": [54.0, 205.0]}}, "names the channel 'rho'"),
    ({"design": {"variables": "k", "bounds": [54.0, 205.0]}}, r"design.variables: must be \"channel:NAME\""),
    ({"design": {"variables": "channel:k", "bounds": [205.0, 54.0]}}, "low < high"),
    ({"design": {"variables": "channel:k", "bounds": [54.0, 205.0], "mean": 300.0}}, "cannot be met"),
    ({"design": {"variables": "channel:k"}}, "bounds"),
    ({"design": {"variables": "map", "bounds": [54.0, 205.0]}}, "belongs to a channel design"),
    ({"design": {"variables": "map"}}, "design.move: is required"),
    ({"design": {"variables": "map", "move": 0.001, "hold": ["bottom"]}}, "design.hold: must be a list"),
    ({"design": {"variables": "channel:k", "bounds": [54.0, 205.0], "move": 0.001}}, "belongs to a shape design"),
    ({"design": {"variables": "channel:k", "bounds": [54.0, 205.0], "objective": "peak"}}, "design.objective"),
    ({"adapt": {"tolerance": 0.01}}, "adapt and design cannot both"),
])
def test_a_bad_design_section_is_refused_naming_the_key(change, match):
    import tomllib

    from iga.app.config import validate

    cfg = tomllib.loads(DESIGN)
    cfg.update(change)
    with pytest.raises(ProblemError, match=match):
        validate(cfg)


def test_iga_optimize_without_a_design_section_says_what_is_missing(tmp_path):
    from iga.app.cli import _cmd_optimize

    (tmp_path / "plain.toml").write_text(DESIGN.split("[design]")[0] + '[output]\ndir = "out"\n')
    with pytest.raises(ProblemError, match=r"iga optimize needs a \[design\] section"):
        _cmd_optimize(type("Args", (), {"config": str(tmp_path / "plain.toml")})())


def test_an_adjoint_through_the_kept_factorisation_equals_one_assembled_again():
    from iga.sensitivity import channel_sensitivity

    problem = _lattice()
    kept, plain = problem.solve(keep=True), problem.solve()
    assert kept.record.again is not None and plain.record.again is None
    assert np.allclose(kept.u, plain.u, rtol=0, atol=1e-10 * np.abs(plain.u).max())
    for out in (TemperatureNorm(8), MeanTemperature("umin")):
        a, b = channel_sensitivity(kept, out, "k"), channel_sensitivity(plain, out, "k")
        assert np.allclose(a, b, rtol=1e-8, atol=1e-12 * np.abs(b).max())


def _lattice_problem(degree=2):
    B = pr.box((0.02, 0.02, 0.01), degrees=(degree,) * 3)
    B = B.with_channel("k", np.full(B.control_points.shape[:3], 205.0))
    ms = tiling.regular(B, library.cross(0.4), (2, 2, 1))
    return iga.HeatProblem(ms, conductivity="k").neumann("wmin", 2e4).robin("rest", 500.0, 0.0), B


@pytest.mark.slow
def test_a_shape_design_lowers_the_smooth_maximum_at_the_same_volume_and_keeps_the_held_face():
    from iga.outputs import Volume
    from iga.shape_design import moved_map

    problem, B = _lattice_problem()
    move = 0.001
    result = iga.optimize(problem, TemperatureNorm(16), wrt="map", bounds=move, hold=("wmin",), maxiter=6)
    P0, P = np.array(B.control_points)[..., :3], result.values
    assert P.shape == P0.shape and np.abs(P - P0).max() <= move * (1 + 1e-12)
    assert np.array_equal(P[:, :, 0], P0[:, :, 0])  # the heated face's control points stay
    assert result.objective < 0.995 * result.initial  # 0.9% lower after six SLSQP steps
    V0 = Volume().value(problem.solve())
    assert abs(Volume().value(result.solution) - V0) <= 1e-5 * V0
    # the returned solution is an exact analysis of the returned map
    again = problem.on(redesigned(problem.model, B, moved_map(B, P), True)).solve()
    assert TemperatureNorm(16).value(again) == pytest.approx(result.objective, rel=1e-9)
    assert [s.iteration for s in result.history] == list(range(1, len(result.history) + 1))


def test_a_shape_design_of_heights_alone_moves_only_the_free_heights():
    """axes="z" between held bottom and top: only the middle layer's heights move (where the tiles' layers
    land), and the output falls.  The crosses are symmetric in w, so moving where their layers land leaves the
    volume unchanged to first order: keeping it is refused as an equality that cannot bind."""
    problem, B = _lattice_problem()
    with pytest.raises(ProblemError, match="does not change to first order"):
        iga.optimize(problem, TemperatureNorm(16), wrt="map", bounds=0.001, hold=("wmin", "wmax"), axes="z")
    result = iga.optimize(problem, TemperatureNorm(16), wrt="map", bounds=0.001, hold=("wmin", "wmax"), axes="z",
                          keep_volume=False, maxiter=4)
    P0, P = np.array(B.control_points)[..., :3], result.values
    assert np.array_equal(P[..., :2], P0[..., :2]) and np.array_equal(P[:, :, [0, -1]], P0[:, :, [0, -1]])
    assert np.abs(P[:, :, 1, 2] - P0[:, :, 1, 2]).max() > 1e-5  # the middle heights moved
    assert result.objective < result.initial


def test_bad_shape_designs_are_refused():
    problem, _ = _lattice_problem(degree=1)
    with pytest.raises(ProblemError, match="largest move"):
        iga.optimize(problem, TemperatureNorm(8), wrt="map", bounds=(54.0, 205.0))
    with pytest.raises(ProblemError, match="not a face of the map"):
        iga.optimize(problem, TemperatureNorm(8), wrt="map", bounds=0.001, hold=("bottom",))
    with pytest.raises(ProblemError, match="axes names the coordinates"):
        iga.optimize(problem, TemperatureNorm(8), wrt="map", bounds=0.001, axes="zz")
    with pytest.raises(ProblemError, match="holds every control point"):
        iga.optimize(problem, TemperatureNorm(8), wrt="map", bounds=0.001,
                     hold=("umin", "umax", "vmin", "vmax", "wmin", "wmax"))


@pytest.mark.slow
def test_iga_optimize_designs_the_shape_from_a_pipeline(tmp_path):
    import json

    head = DESIGN.split("[design]")[0]
    tail = DESIGN.split("[design]")[1].split("\n[", 1)[1]
    (tmp_path / "shape.toml").write_text(head + '[design]\nvariables = "map"\nmove = 0.001\nhold = ["wmin"]\n'
                                         'iterations = 4\n\n[' + tail)
    done = iga_command("--quiet", "optimize", "shape.toml", cwd=tmp_path)
    assert done.returncode == 0, done.stderr[-2000:]
    d = json.loads((tmp_path / "out" / "summary.json").read_text())["design"]
    assert d["final"] < d["initial"] and 1 <= len(d["steps"]) <= 4
    volumes = [s["mean"] for s in d["steps"]]  # a shape design's steps record the solid volume (m^3)
    assert max(volumes) - min(volumes) <= 1e-5 * max(volumes)
    import meshio

    written = meshio.read(tmp_path / "out" / "sink.vtu")  # the final (moved) design, read back by meshio
    assert len(written.points) > 0 and np.all(np.isfinite(written.point_data["temperature"]))


GRADED = """
[map]
primitive = "box"
args = {size = [0.04, 0.04, 0.01], degrees = [2, 2, 1], channels = {t = 0.35}}

[tile]
library = "face_graded_cross"

[paving]
scheme = "field_graded"
counts = [1, 1, 1]
field = "t"

[material]
conductivity = 205.0

[[bc]]
kind = "neumann"
tag = "wmin"
value = 2e4

[[bc]]
kind = "robin"
tag = "wmax"
h = 3000.0
ambient = 0.0

[design]
variables = "parameters"
bounds = [0.15, 0.6]
hold = ["wmin"]
iterations = 5

[output]
dir = "out"
name = "lattice"
"""


@pytest.mark.slow
def test_iga_optimize_grades_a_field_graded_lattice_from_a_pipeline(tmp_path):
    """variables = "parameters": the arm widths of a field-graded paving, read from a channel of the map, at the
    start's solid volume with the heated face held; the final design's VTU read back by meshio."""
    import json

    import meshio

    (tmp_path / "graded.toml").write_text(GRADED)
    done = iga_command("--quiet", "optimize", "graded.toml", cwd=tmp_path)
    assert done.returncode == 0, done.stderr[-2000:]
    d = json.loads((tmp_path / "out" / "summary.json").read_text())["design"]
    assert d["final"] < 0.9 * d["initial"] and 1 <= len(d["steps"]) <= 5
    D = pr.box((0.04, 0.04, 0.01), degrees=(2, 2, 1), channels={"t": 0.35})
    start = iga.HeatProblem(tiling.field_graded(D, library.face_graded_cross, (1, 1, 1), "t")).robin(
        "wmax", 1.0, 0.0).solve().volume()
    assert abs(d["steps"][-1]["mean"] - start) <= 1e-6 * start  # SLSQP ends on its volume constraint
    written = meshio.read(tmp_path / "out" / "lattice.vtu")
    assert len(written.points) > 0 and np.all(np.isfinite(written.point_data["temperature"]))


LEAVES = """
[map]
primitive = "box"
args = {size = [0.06, 0.06, 0.03], degrees = [2, 2, 2], channels = {t = 0.4}}

[tile]
library = "heat_sink_t2"

[paving]
scheme = "hierarchical"
counts = [2, 2]
levels = 2
scale = 0.5
leaves = "face_graded_heat_sink"
field = "t"

[material]
conductivity = 129.5

[[bc]]
kind = "neumann"
tag = "branch-in"
value = 2e4

[[bc]]
kind = "robin"
tag = "exterior"
h = 3000.0
ambient = 0.0

[design]
variables = "parameters"
bounds = [0.1, 0.49]
iterations = 3

[output]
dir = "out"
name = "sink"
"""


@pytest.mark.slow
def test_iga_optimize_grades_the_leaves_of_a_hierarchical_sink_and_moves_its_heights_from_a_pipeline(tmp_path):
    """paving.leaves: the two-level sink's finest pins from a channel of the map, designed by their field at the
    start's solid volume; then variables = "map" with axes = "z" between the held bottom and top (the base's
    thickness), whose x and y stay."""
    import json
    import tomllib

    import meshio

    (tmp_path / "leaves.toml").write_text(LEAVES)
    done = iga_command("--quiet", "optimize", "leaves.toml", cwd=tmp_path)
    assert done.returncode == 0, done.stderr[-2000:]
    summary = json.loads((tmp_path / "out" / "summary.json").read_text())
    d = summary["design"]
    assert d["final"] < d["initial"] and summary["tiles_per_level"] == [4, 16]
    assert max(s["mean"] for s in d["steps"]) - min(s["mean"] for s in d["steps"]) <= 1e-5 * d["steps"][0]["mean"]
    from iga.app.pipeline import run_pipeline

    cfg = tomllib.loads(LEAVES)
    cfg["design"] = {"variables": "map", "move": 0.003, "hold": ["wmin", "wmax"], "axes": "z", "iterations": 2}
    cfg["output"]["dir"] = str(tmp_path / "heights")
    heights = run_pipeline(cfg, tmp_path)["design"]
    assert heights["final"] <= heights["initial"] and heights["steps"]
    moved = meshio.read(tmp_path / "heights" / "sink.vtu").points
    start = meshio.read(tmp_path / "out" / "sink.vtu").points  # (another design of the same sink: its x, y range)
    assert np.allclose(moved[:, :2].min(0), start[:, :2].min(0)) and np.allclose(moved[:, :2].max(0),
                                                                                 start[:, :2].max(0))


@pytest.mark.parametrize("change, match", [
    ({"paving": {"scheme": "hierarchical", "counts": [2, 2], "leaves": "face_graded_heat_sink"},
      "tile": {"library": "heat_sink_t2"}}, "paving.leaves: graded leaves need both"),
    ({"paving": {"scheme": "hierarchical", "counts": [2, 2], "leaves": "cross", "field": 0.3},
      "tile": {"library": "heat_sink_t2"}}, "paving.leaves: graded leaves need a tile of the six faces"),
    ({"paving": {"scheme": "regular", "counts": [1, 1, 1], "field": 0.3}, "tile": {"library": "cross"}},
     "applies to the hierarchical and field_graded schemes only"),
    ({"design": {"variables": "map", "move": 0.001, "axes": "w"}}, "design.axes"),
    ({"design": {"variables": "parameters", "bounds": [0.15, 0.6], "axes": "z"}}, "design.axes: belongs to a shape"),
    ({"paving": {"scheme": "regular", "counts": [1, 1, 1]}, "tile": {"library": "cross"}}, "field_graded"),
    ({"paving": {"scheme": "field_graded", "counts": [1, 1, 1], "field": {"formula": "0.3 + x"}}}, "a formula"),
    ({"design": {"variables": "parameters", "hold": ["wmin"]}}, "design.bounds: is required"),
    ({"design": {"variables": "parameters", "bounds": [0.15, 0.6], "move": 0.001}}, "design.move"),
    ({"design": {"variables": "parameters", "bounds": [0.15, 0.6], "hold": "wmin"}}, "design.hold"),
])
def test_a_bad_parameter_design_is_refused_naming_the_key(change, match):
    import tomllib

    from iga.app.config import validate

    cfg = tomllib.loads(GRADED)
    cfg.update(change)
    with pytest.raises(ProblemError, match=match):
        validate(cfg)


ELASTIC_DESIGN = """
[map]
primitive = "box"
args = {size = [0.04, 0.01, 0.01], degrees = [2, 2, 2]}
grading = [{channel = "E", near = 1.5e9, far = 1.5e9, face = "umin"}]

[tile]
library = "cross"

[paving]
scheme = "regular"
counts = [4, 1, 1]

[physics]
kind = "elasticity"
youngs = "E"
poisson = 0.3

[[support]]
tag = "umin"

[[support]]
tag = "umax"
value = 1e-5
components = "x"

[[load]]
kind = "traction"
tag = "umax"
value = [0.0, 0.0, -1e4]

[design]
variables = "channel:E"
objective = "von_mises_norm"
bounds = [1e9, 2e9]
mean = 1.5e9
iterations = 4

[output]
dir = "out"
name = "beam"
"""


@pytest.mark.slow
def test_an_elastic_pipeline_designs_its_modulus_for_its_von_mises_norm(tmp_path):
    """[design] on an elastic analysis: the lattice beam pushed and loaded at its end, E graded in [1, 2] GPa at its
    mean for a lower smooth maximum of the von Mises stress; the summary's final objective is a fresh analysis's
    of the design written, and the refusals name the keys."""
    import json
    import tomllib

    import meshio

    from iga.app.config import validate
    from iga.app.pipeline import run_pipeline

    cfg = tomllib.loads(ELASTIC_DESIGN)
    (tmp_path / "beam.toml").write_text(ELASTIC_DESIGN)
    done = iga_command("--quiet", "optimize", "beam.toml", cwd=tmp_path)
    assert done.returncode == 0, done.stderr[-2000:]
    assert "design: VonMisesNorm(8)" in done.stdout
    d = json.loads((tmp_path / "out" / "summary.json").read_text())["elasticity"]["design"]
    assert d["objective"] == "VonMisesNorm(8)" and d["final"] < d["initial"] and 1 <= len(d["steps"]) <= 4
    assert (tmp_path / "out" / "beam_design.png").stat().st_size > 0
    E = meshio.read(tmp_path / "out" / "beam_stress.vtu").point_data["E"]
    assert E.min() < 1.45e9 and E.max() > 1.55e9  # the written design is graded
    # the compliance is differentiated as self-adjoint: supports at zero (clamped only, the push dropped)
    clamped = {**cfg, "support": cfg["support"][:1]}
    compliance = run_pipeline({**clamped, "design": {**cfg["design"], "objective": "compliance"}, "output": {
        **cfg["output"], "dir": "out2", "png": False}}, tmp_path)["elasticity"]["design"]
    assert compliance["objective"] == "Compliance()" and compliance["final"] < compliance["initial"]
    for change, match in (({"objective": "temperature_norm"}, r"design.objective: must be one of \['compliance', "
                                                             r"'von_mises_norm'\]"),
                          ({"variables": "channel:k"}, "physics.youngs is 'E'"),
                          ({"tag": "umax"}, "design.tag: belongs to the heat outputs")):
        with pytest.raises(ProblemError, match=match):
            validate({**cfg, "design": {**cfg["design"], **change}}, tmp_path)
