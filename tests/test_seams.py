"""What leaves the toolkit arrives intact: VTU for every reader, probes on slot walls, the demo sinks' volume."""

import numpy as np
import pytest

import tiling
from geometry import primitives as pr
from geometry.chain import patch_geometry_points, gradient_and_det
from iga import HeatProblem, write_vtu
from iga.config import validate
from iga.pipeline import _build_map, _build_tiling, heat_sink_config
from tiling import library as L


def _demo_problem(variant):
    cfg = validate(heat_sink_config(variant, out="unused"), ".")
    ms = _build_tiling(cfg, _build_map(cfg["map"]))
    return HeatProblem(ms, conductivity="k").neumann("branch-in", 1515.8).robin("exterior", 5.0, 30.0)


@pytest.fixture(scope="module", params=["circular", "vertical"])
def demo(request):
    """The demo sink (both variants) as the demo builds it, solved."""
    return _demo_problem(request.param).solve()


def test_meshio_reads_the_sampled_vtu_like_pyvista(tmp_path):
    meshio = pytest.importorskip("meshio")
    import pyvista as pv

    ms = tiling.hierarchical(pr.box((2.0, 2.0, 1.0)), L.heat_sink_t2(), (2, 2), 2)
    sol = HeatProblem(ms).dirichlet("wmin", 1.0).robin("exterior", 1.0, 0.0).solve()
    path = write_vtu(tmp_path / "s.vtu", sol)
    a, b = pv.read(path), meshio.read(path)
    assert np.array_equal(a.points, b.points)
    assert [c.type for c in b.cells] == ["hexahedron"]
    assert np.array_equal(b.cells[0].data, a.cell_connectivity.reshape(-1, 8))
    assert set(b.point_data) == set(a.point_data) == {"temperature", "heat_flux", "conductivity"}
    for k in a.point_data:
        assert np.array_equal(np.asarray(b.point_data[k]).reshape(a.n_points, -1),
                              np.asarray(a.point_data[k]).reshape(a.n_points, -1))
    for k in ("patch", "tile", "level"):
        assert np.array_equal(b.cell_data[k][0], a.cell_data[k])
    assert 'compressor="vtkZLibDataCompressor"' in path.read_bytes()[:400].decode("ascii", "replace")


def test_bezier_vtu_arrays_decode_with_a_second_reader(tmp_path):
    """meshio 5.3.5 has no reader for variable-order cells (VTK_BEZIER_HEXAHEDRON), so the exact file is decoded
    here from its XML and zlib blocks (the VTK format as documented) and compared with what VTK reads."""
    import pyvista as pv

    ms = tiling.hierarchical(pr.box((2.0, 2.0, 1.0)), L.heat_sink_t2(), (1, 1), 2)
    sol = HeatProblem(ms).dirichlet("wmin", 1.0).robin("exterior", 1.0, 0.0).solve()
    path = write_vtu(tmp_path / "b.vtu", sol, cells="bezier")
    grid = pv.read(path)
    arrays = _decode_appended_vtu(path)
    assert np.array_equal(arrays["Points"].reshape(-1, 3), grid.points)
    assert np.array_equal(arrays["temperature"], grid.point_data["temperature"])
    assert np.array_equal(arrays["types"], grid.celltypes) and set(arrays["types"]) == {79}
    assert np.array_equal(arrays["HigherOrderDegrees"].reshape(-1, 3), grid.cell_data["HigherOrderDegrees"])


def _decode_appended_vtu(path) -> dict:
    """Every DataArray of a VTU with raw appended, zlib-compressed data (UInt32 headers), by name."""
    import xml.etree.ElementTree as ET
    import zlib

    raw = path.read_bytes()
    start = raw.index(b"<AppendedData")
    head = raw[:start].decode() + "</VTKFile>"
    data = raw[raw.index(b"_", start) + 1:]
    dtypes = {"Float64": "<f8", "Float32": "<f4", "Int32": "<i4", "Int64": "<i8", "UInt8": "u1"}
    out = {}
    for el in ET.fromstring(head).iter("DataArray"):
        off = int(el.get("offset"))
        nb = int(np.frombuffer(data[off:off + 4], "<u4")[0])
        sizes = np.frombuffer(data[off + 12:off + 12 + 4 * nb], "<u4")
        pos, chunks = off + 12 + 4 * nb, []
        for s in sizes:
            chunks.append(zlib.decompress(data[pos:pos + int(s)]))
            pos += int(s)
        out[el.get("Name")] = np.frombuffer(b"".join(chunks), dtypes[el.get("type")])
    return out


def test_every_boundary_point_of_the_demo_sinks_can_be_probed(demo, tmp_path):
    """Slot walls included: the points on either side of a discontinuity plane are found on their own side."""
    import pyvista as pv

    grid = pv.read(write_vtu(tmp_path / "d.vtu", demo, samples=2))
    surf = grid.extract_surface(algorithm="dataset_surface")
    T = demo.probe(surf.points)
    assert np.abs(T - surf.point_data["temperature"]).max() < 1e-9 * np.abs(T).max()


def test_the_sampled_demo_vtu_holds_the_exact_volume(demo, tmp_path):
    import pyvista as pv

    grid = pv.read(write_vtu(tmp_path / "d.vtu", demo))
    exact = demo.volume()
    assert abs(grid.volume / exact - 1) < 5e-3


def test_flux_at_welded_interface_points_is_the_mean_of_both_sides(tmp_path):
    """Two tiles of different conductivity: the flux jumps across their interface; the VTU holds the mean."""
    import pyvista as pv

    a = pr.box((1.0, 1.0, 1.0), channels={"k": 1.0})
    b = pr.box((1.0, 1.0, 1.0), origin=(1.0, 0.0, 0.0), channels={"k": 3.0})
    sol = HeatProblem([a, b], conductivity="k", degree=2) \
        .dirichlet("umin", 0.0).dirichlet("umax", 1.0).robin("vmin", 4.0, 2.0).solve()
    grid = pv.read(write_vtu(tmp_path / "w.vtu", sol, samples=4))
    on = np.flatnonzero(np.abs(grid.points[:, 0] - 1.0) < 1e-12)
    assert len(on) > 10
    sides = []
    for pi, k in ((0, 1.0), (1, 3.0)):
        xi = grid.points[on] - np.array([pi, 0.0, 0.0])
        xi[:, 0] = 1.0 - pi
        x, J, _ = patch_geometry_points(sol.problem.model.patches[pi], xi)
        T = sol.temperature_spline(pi)
        dT = np.stack([T.derivative(xi, o)[:, 0] for o in ((1, 0, 0), (0, 1, 0), (0, 0, 1))], 1)
        grad, _ = gradient_and_det([J[:, :, 0], J[:, :, 1], J[:, :, 2]], dT)
        sides.append(-k * grad)
    assert np.abs(sides[0] - sides[1]).max() > 0.05  # the flux does jump here
    written = grid.point_data["heat_flux"][on]
    assert np.abs(written - 0.5 * (sides[0] + sides[1])).max() < 1e-9
