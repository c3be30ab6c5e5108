"""Polygonal tiles paved by vertex mapping (Elber 2017, Section 2, Eq. 3)."""

import numpy as np
import pytest

import tiling
from geometry import BSpline, primitives as pr
from tiling import TilingError
from tiling.members.polygons import PolygonTile, beam_lattice, pave_polygons


def _map():
    b = pr.box((2.0, 1.0, 1.0), degrees=(2, 2, 2))
    cp = b.control_points.copy()
    cp[..., 2] += 0.2 * np.sin(cp[..., 0])
    T = 20.0 + cp[..., :1]
    return BSpline(b.degrees, b.knots, np.concatenate([cp, T], -1), channels=("T",))


def test_beam_lattice_vertices_are_exact_and_welded(tmp_path):
    D = _map()
    mesh = pave_polygons(D, beam_lattice(), (3, 2, 2))
    # the corners of a (3+1)(2+1)(2+1) grid (the diagonals join corners)
    assert mesh.n_points == 4 * 3 * 3
    params = np.c_[mesh["u"], mesh["v"], mesh["w"]]
    assert np.allclose(mesh.points, D.evaluate(params)[:, :3], atol=1e-13)
    assert np.allclose(mesh["T"], D.evaluate(params)[:, 3])
    # the grid's edges once each (27 + 24 + 24 for 4 x 3 x 3 vertices), plus 4 diagonals per cell
    assert mesh.n_lines == 27 + 24 + 24 + 4 * 12
    assert mesh.connectivity().n_points == mesh.n_points  # one connected lattice
    path = tiling.export.write_mesh(tmp_path / "lattice.vtp", mesh)
    import pyvista as pv

    assert pv.read(path).n_lines == mesh.n_lines


def test_polygons_are_paved_and_exported():
    square = PolygonTile(np.array([[0, 0, 0.5], [1, 0, 0.5], [1, 1, 0.5], [0, 1, 0.5]], float), polygons=[[0, 1, 2, 3]])
    mesh = pave_polygons(_map(), square, (2, 2, 1))
    assert mesh.n_cells == 4 and mesh.n_points == 9  # four quads welded into a 3 x 3 grid of vertices
    assert mesh.triangulate().n_cells == 8


def test_polygonal_bad_input():
    with pytest.raises(TilingError, match="unit cube"):
        PolygonTile(np.array([[0, 0, 2.0]]), lines=[[0, 0]])
    with pytest.raises(TilingError, match="neither"):
        PolygonTile(np.zeros((3, 3)))
    with pytest.raises(TilingError, match="polygon 0"):
        PolygonTile(np.zeros((3, 3)), polygons=[[0, 1]])
    with pytest.raises(TilingError, match="line 0"):
        PolygonTile(np.zeros((3, 3)), lines=[[0, 7]])
    with pytest.raises(TilingError, match="counts"):
        pave_polygons(_map(), beam_lattice(), (0, 1, 1))
    with pytest.raises(TilingError, match="PolygonTile"):
        pave_polygons(_map(), tiling.library.cross(), (1, 1, 1))
