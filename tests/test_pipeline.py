"""End-to-end heat-sink pipeline: `iga run CONFIG.toml` and `iga demo heat-sink`."""

import json
import subprocess
import sys

import numpy as np
import pytest

from iga import ProblemError
from iga.app.pipeline import heat_sink_config, run_pipeline

REDUCED = """
[map]
primitive = "circular_heat_sink"
args = {r_in = 0.02, r_out = 0.05, height = 0.02, twist = 0.0}
grading = {channel = "k", near = 205.0, far = 54.0, face = "wmin"}

[tile]
library = "heat_sink_t1"

[paving]
scheme = "hierarchical"
counts = [1, 1]
levels = 2
scale = 0.5

[material]
conductivity = "k"

[[bc]]
kind = "neumann"
tag = "branch-in"
value = 1515.8

[[bc]]
kind = "robin"
tag = "exterior"
h = 5.0
ambient = 30.0

[solver]
method = "auto"
tol = 1e-11

[output]
dir = "out"
name = "sink"
png = false
bezier = true
probes = [[0.0, 0.0205, 0.01]]
"""


@pytest.mark.slow
def test_iga_run_reduced_heat_sink(tmp_path):
    import pyvista as pv

    cfg = tmp_path / "sink.toml"
    cfg.write_text(REDUCED)
    out = subprocess.run([sys.executable, "-m", "iga", "run", str(cfg)], capture_output=True, text=True)
    assert out.returncode == 0, out.stderr
    s = json.loads((tmp_path / "out" / "summary.json").read_text())
    for key in ("dofs", "tiles", "levels", "temperature_C", "inflow_W", "outflow_W", "energy_balance_error",
                "timings_s", "peak_memory_MiB", "analysis_peak_memory_MiB", "solver"):
        assert key in s
    assert 0 < s["analysis_peak_memory_MiB"] <= s["peak_memory_MiB"]
    assert s["tiles"] == 4 + 8 and s["levels"] == 2
    assert s["energy_balance_error"] < 1e-8
    assert s["energy_identity"]["relative_error"] < 1e-9 and s["energy_identity"]["internal"] > 0
    assert s["connected_pieces"] == 1  # the paving is one coupled piece
    area = 2 * np.pi * 0.02 * 0.02  # inner ring: an exact cylinder without twist
    assert s["inflow_W"] == pytest.approx(1515.8 * area, rel=1e-5)  # Gauss quadrature of a rational area element
    exact = pv.read(s["files"]["bezier_vtu"])  # exact Bezier hexahedra beside the sampled file
    assert set(exact.celltypes) == {79} and "temperature" in exact.point_data and "k" in exact.point_data
    assert exact.point_data["temperature"].min() > 30.0
    m = pv.read(tmp_path / "out" / "sink.vtu")
    for name in ("temperature", "heat_flux", "conductivity", "k"):
        assert name in m.point_data
    for name in ("patch", "tile", "level"):
        assert name in m.cell_data
    T = m.point_data["temperature"]
    assert T.min() > 30.0
    # the hottest points are on the heated inner ring, and temperature falls level by level along the fins
    r = np.hypot(m.points[:, 0], m.points[:, 1])
    assert r[np.argmax(T)] < 0.0201
    cells = m.cell_data["level"]
    mean_by_level = []
    cc = m.point_data_to_cell_data()
    for lev in range(2):
        mean_by_level.append(cc.cell_data["temperature"][cells == lev].mean())
    assert mean_by_level[0] > mean_by_level[1]
    assert s["probes"]["temperature_C"][0] > 30.0
    k = m.point_data["conductivity"]
    assert 54.0 - 1e-9 <= k.min() and k.max() <= 205.0 + 1e-9
    # the summary's extremes are sampled values (the VTU's points), its mean a volume average in between
    t = s["temperature_C"]
    assert t["min"] == pytest.approx(T.min(), abs=1e-9) and t["max"] == pytest.approx(T.max(), abs=1e-9)
    assert t["min"] < t["mean"] < t["max"]
    assert_one_welded_piece(m)


def assert_one_welded_piece(grid):
    """The VTU is one welded mesh: its surface has no open edges (holes) and no non-manifold edges, which
    is what internal faces between unwelded neighbours (or T-junctions on branch faces) would produce."""
    surf = grid.extract_surface(algorithm="dataset_surface")
    edges = {kind: surf.extract_feature_edges(boundary_edges=kind == "open", non_manifold_edges=kind == "nm",
                                              feature_edges=False, manifold_edges=False).n_cells
             for kind in ("open", "nm")}
    assert edges == {"open": 0, "nm": 0}, edges
    assert int(surf.connectivity().cell_data["RegionId"].max()) == 0  # one piece


def test_config_errors_name_the_key(tmp_path):
    cfg = heat_sink_config(levels=1, out=str(tmp_path / "o"))
    cfg["paving"]["count"] = [1, 1]
    with pytest.raises(ProblemError, match="unknown config key paving.'count'"):
        run_pipeline(cfg, progress=False)
    cfg = heat_sink_config(levels=1, out=str(tmp_path / "o"))
    del cfg["tile"]["library"]
    with pytest.raises(ProblemError, match="missing required config key tile.'library'"):
        run_pipeline(cfg, progress=False)
    bad = tmp_path / "bad.toml"
    bad.write_text("[map]\nprimitive = 'sphere'\n[tile]\nlibrary='cross'\n[paving]\nscheme='regular'\ncounts=[1,1,1]\n"
                   "[[bc]]\nkind='dirichlet'\ntag='umin'\n")
    out = subprocess.run([sys.executable, "-m", "iga", "run", str(bad)], capture_output=True, text=True)
    assert out.returncode == 1 and "map.primitive" in out.stderr and "Traceback" not in out.stderr


@pytest.mark.slow
def test_demo_command_reduced(tmp_path):
    import pyvista as pv

    out = subprocess.run([sys.executable, "-m", "iga", "demo", "heat-sink", "--variant", "vertical", "--levels", "2",
                          "--out", str(tmp_path / "demo")], capture_output=True, text=True)
    assert out.returncode == 0, out.stderr
    s = json.loads((tmp_path / "demo" / "summary.json").read_text())
    assert s["energy_balance_error"] < 1e-8 and s["temperature_C"]["min"] > 30.0
    assert s["connected_pieces"] == 1  # the paving is one coupled piece
    assert (tmp_path / "demo" / "heat_sink.png").stat().st_size > 10_000
    assert out.stderr == ""  # no progress display when not on a terminal
    assert "2 levels" in out.stdout and "16 + 64" not in out.stdout
    # independent: the inflow is q times the 60 x 60 mm base
    assert s["inflow_W"] == pytest.approx(1515.8 * 0.06 * 0.06, rel=1e-10)
    grid = pv.read(tmp_path / "demo" / "heat_sink.vtu")
    assert_one_welded_piece(grid)
    vol = s["volume_m3"]  # the written mesh's volume against the exact one, as reported
    assert vol["vtu"] == pytest.approx(grid.volume, rel=1e-12) and abs(vol["vtu_relative_error"]) < 5e-3


def test_progress_lines_when_asked(tmp_path, capsys):
    cfg = heat_sink_config(variant="vertical", levels=1, out=str(tmp_path / "o"))
    cfg["output"].update(png=False)
    run_pipeline(cfg, progress=True)
    err = capsys.readouterr().err
    for stage in ("[1/6] deformation map", "[2/6] tiling", "[3/6] assembly and solve", "[4/6] VTU output"):
        assert stage in err
    run_pipeline(cfg, progress=False)
    assert capsys.readouterr().err == ""


@pytest.mark.slow
def test_summary_statistics_without_vtu_are_temperatures_and_a_volume_mean(tmp_path):
    import pyvista as pv

    cfg = heat_sink_config(variant="vertical", levels=2, out=str(tmp_path / "a"))
    cfg["output"].update(png=False)
    with_vtu = run_pipeline(cfg, progress=False)
    cfg["output"].update(dir=str(tmp_path / "b"), vtu=False)
    without = run_pipeline(cfg, progress=False)
    grid = pv.read(with_vtu["files"]["vtu"])
    T = grid.point_data["temperature"]
    # extremes are sampled temperatures whether or not a VTU is written (not control coefficients)
    for s in (with_vtu, without):
        assert s["temperature_C"]["min"] == pytest.approx(T.min(), abs=1e-9)
        assert s["temperature_C"]["max"] == pytest.approx(T.max(), abs=1e-9)
    # the mean is the volume average: against VTK's integral of the sampled field over the welded mesh
    integral = grid.integrate_data()
    vtk_mean = float(integral.point_data["temperature"][0] / integral.cell_data["Volume"][0])
    assert without["temperature_C"]["mean"] == pytest.approx(vtk_mean, abs=1e-3)
    assert abs(float(T.mean()) - vtk_mean) > 5 * abs(without["temperature_C"]["mean"] - vtk_mean)


def test_peak_memory_is_guarded_where_the_platform_lacks_it(monkeypatch):
    import builtins

    from geometry import resources

    real_import = builtins.__import__

    def no_resource(name, *args, **kwargs):
        if name == "resource":
            raise ImportError("no module named resource (Windows)")
        return real_import(name, *args, **kwargs)

    monkeypatch.setattr(builtins, "__import__", no_resource)
    assert resources.peak_memory_mib() is None
    monkeypatch.setattr(builtins, "__import__", real_import)
    linux = resources.peak_memory_mib()
    monkeypatch.setattr(resources.sys, "platform", "darwin")  # macOS reports bytes, Linux KiB
    assert resources.peak_memory_mib() == pytest.approx(linux / 1024, rel=0.5)
