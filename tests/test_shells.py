"""Shells of surface tiles (Massarwi et al. 2018, Section 6.2 item 2, Fig. 9(c, d)): one closed skin over D's
boundary into which the tiles' tubes open, welded, with the Euler characteristic the topology predicts."""

import numpy as np
import pytest

import tiling
from geometry import primitives as pr
from tiling import TilingError
from tiling import library as L
from tiling.export import boundary_splines, watertightness, write_iges
from helpers import opencascade, surface_area

TWISTED = pr.twisted(pr.box((2.0, 1.5, 1.0), degrees=(2, 2, 2)), 0.4, axis_point=(1.0, 0.75))


def _predicted_euler(counts) -> int:
    """The solid is the layer (a thickened sphere, Euler characteristic 2) with the cells' tube crosses (one
    contractible node each) attached by tubes: one between neighbouring cells, one from every cell face on D's
    boundary into the layer.  chi(solid) = 2 + cells - tubes, and its boundary has chi = 2 chi(solid)."""
    n = np.array(counts)
    cells = int(np.prod(n))
    tubes = sum(int(np.prod(n)) // n[d] * (n[d] - 1) for d in range(3)) + 2 * sum(cells // n[d] for d in range(3))
    return 2 * (2 + cells - tubes)


@pytest.mark.parametrize("counts", [(1, 1, 1), (2, 1, 1), (2, 2, 2), (3, 2, 1)])
def test_shelled_surface_tiles_give_one_closed_skin_with_the_predicted_euler_characteristic(counts):
    ms = tiling.regular(TWISTED, L.hollow_cross(), counts, seal="shell", thickness=0.15)
    w = watertightness(ms)
    assert w["closed"] and w["manifold"] and w["open_edges"] == 0 and w["nonmanifold_edges"] == 0
    # two sheets: the outside of the skin, and the inside of the skin joined to the tubes' walls
    assert w["components"] == 2
    assert w["euler_characteristic"] == _predicted_euler(counts)


def test_the_layer_is_bounded_by_outward_walls_and_trimmed_inner_planes_of_the_exact_area():
    D = pr.box((3.0, 2.0, 2.0))
    arm, t = 0.3, 0.1
    ms = tiling.regular(D, L.hollow_cross(arm), (1, 1, 1), seal="shell", thickness=t)
    tile = ms.tiles[0]
    assert tile.seal == "shell" and len(tile.seal_patches) == 6 and len(ms.caps) == 6
    size = np.array([3.0, 2.0, 2.0])
    for pc in ms.caps:  # the inner plane of each side: the squeezed cell face less the squeezed arm's opening
        k = "uvw".index(pc.cap.side[0])
        a, b = [size[j] * (1 - 2 * t) for j in range(3) if j != k]
        assert pc.composed().area(1e-3) == pytest.approx(a * b * (1 - arm ** 2), rel=1e-12)
        level = pc.composed().surface.control_points[..., k]
        assert np.allclose(level, size[k] * (t if pc.cap.side.endswith("min") else 1 - t))
    centre = size / 2
    for i in tile.seal_patches:  # the outer walls: the whole cell faces, normals pointing out of D
        S = ms.patches[i].composed
        x = S.evaluate(np.array([[0.5, 0.5]]))[0, :3]
        J = S.jacobian(np.array([[0.5, 0.5]]))[0, :3, :]
        assert np.dot(np.cross(J[:, 0], J[:, 1]), x - centre) > 0


@pytest.mark.slow
def test_the_shell_goes_to_iges_and_opencascade_reads_every_face_with_our_area(tmp_path):
    ms = tiling.regular(TWISTED, L.hollow_cross(), (2, 1, 1), seal="shell", thickness=0.15)
    ours = boundary_splines(ms)
    path = write_iges(tmp_path / "shell.igs", ms, units="mm")
    with opencascade(path) as (gmsh, tags):
        assert len(tags) == len(ours)
        got = np.array([gmsh.model.occ.getMass(2, t) for t in tags])
    want = np.array([S.area(2e-3) if hasattr(S, "loops") else surface_area(S, 10) for S in ours])
    assert np.abs(got / want - 1).max() < 1e-4  # polynomial faces: OpenCASCADE integrates them closely


def test_shell_bad_input():
    with pytest.raises(TilingError, match="hollow_box.*lies in the wall umin"):
        tiling.regular(TWISTED, L.hollow_box(), (2, 1, 1), seal="shell")
    with pytest.raises(TilingError, match="helix.*no surface patches to shell"):
        tiling.regular(TWISTED, L.helix(), (2, 1, 1), seal="shell")
    with pytest.raises(TilingError, match="shell.*thickness"):
        tiling.regular(TWISTED, L.hollow_cross(), (2, 1, 1), seal="shell", thickness=0.5)


def test_fill_rings_keeps_every_vertex_of_a_straight_side():
    """Regression: earcut drops ring vertices between collinear neighbours, so the shell's inner rectangles
    (8 samples per straight side) met their neighbours in T-junctions; every ring vertex is used now."""
    from geometry.shapes.triangulate import fill_rings

    t = np.linspace(0.0, 4.0, 33)[:-1]
    side = np.floor(t).astype(int)
    corners = np.array([[0, 0], [1, 0], [1, 1], [0, 1], [0, 0]], float)
    square = corners[side] + (t - side)[:, None] * (corners[side + 1] - corners[side])
    a = np.linspace(0, 2 * np.pi, 17)[:-1]
    hole = 0.5 + 0.2 * np.c_[np.cos(a), -np.sin(a)]
    pts, tris = fill_rings([square, hole], 0.125)
    edges = np.sort(np.concatenate([tris[:, [0, 1]], tris[:, [1, 2]], tris[:, [2, 0]]]), axis=1)
    uniq, uses = np.unique(edges, axis=0, return_counts=True)
    ring = np.r_[np.c_[np.arange(32), np.roll(np.arange(32), -1)], 32 + np.c_[np.arange(16), np.roll(np.arange(16), -1)]]
    ring = np.sort(ring, axis=1)
    once = {tuple(e) for e in uniq[uses == 1]}
    assert once == {tuple(e) for e in ring}  # exactly the ring edges bound the mesh: no T-junction
    d1, d2 = pts[tris[:, 1]] - pts[tris[:, 0]], pts[tris[:, 2]] - pts[tris[:, 0]]
    area = 0.5 * (d1[:, 0] * d2[:, 1] - d1[:, 1] * d2[:, 0])
    polygon = 1.0 - 0.5 * 16 * 0.2 ** 2 * np.sin(2 * np.pi / 16)
    assert np.all(area > 0) and area.sum() == pytest.approx(polygon, rel=1e-12)
