"""Boolean sealing of surface tiles with oblique walls (Elber 2017, Section 2): planar walls cut exactly by the
cell's six planes, the cuts capped; the result closed, one sphere per tube."""

import numpy as np
import pytest

import tiling
from geometry import BSpline, primitives as pr
from tiling import TilingError
from tiling import library as L
from tiling.sealing.clipping import clip_polygon, clip_walls
from tiling.export import boundary_splines, watertightness

TWISTED = pr.twisted(pr.box((3.0, 1.0, 2.0), degrees=(2, 2, 2)), 0.3, axis_point=(1.5, 0.5))


def _tubes(counts) -> int:
    """Tubes of library.oblique_tubes in a paving: the lines Z = 1/4 + X/2 + j/2 that cross the open domain
    (0, nx) x (0, nz), once per row along y."""
    nx, ny, nz = counts
    j = np.arange(-2 * nx - 4, 2 * nz + 4)
    return ny * int(np.sum((0.25 + 0.5 * (nx + j) > 0) & (0.25 + 0.5 * j < nz)))


def test_the_cut_pieces_are_the_walls_parts_inside_the_cell_exactly():
    rng = np.random.default_rng(8)
    tile = L.oblique_tubes(0.16)
    d = np.array([1.0, 0.0, 0.5]) / np.linalg.norm([1.0, 0.0, 0.5])
    total = 0.0
    for P in tile.patches:
        uv = rng.random((500, 2))
        x = P.evaluate(uv)[:, :3]
        assert x.min() >= -1e-15 and x.max() <= 1 + 1e-15  # inside the cell
        J = P.jacobian(uv)[:, :3, :]
        n = np.cross(J[:, :, 0], J[:, :, 1])
        n /= np.linalg.norm(n, axis=1)[:, None]
        assert np.abs(n @ d).max() < 1e-12  # every tube wall contains the tube's direction: the angle is kept
        c = P.control_points[..., :3]
        total += 0.5 * float(np.linalg.norm(np.cross(c[1, 1] - c[0, 0], c[0, 1] - c[1, 0])))  # a planar quad
    # the walls' area inside the cell: each tube's four walls, 4 * width * (its length inside the cell);
    # the three pieces' lengths add up to one crossing of the cell along (1, 0, 1/2): |(1, 0, 1/2)| * 2
    assert total == pytest.approx(4 * 0.16 * np.linalg.norm([1.0, 0.0, 0.5]) * 2, rel=1e-12)


def test_clip_polygon_against_a_direct_half_space_test():
    rng = np.random.default_rng(9)
    for _ in range(50):
        c, u, v = rng.uniform(-0.5, 1.5, 3), rng.normal(size=3), rng.normal(size=3)
        quad = np.array([c - u - v, c + u - v, c + u + v, c - u + v])
        poly = clip_polygon(quad)
        if len(poly) < 3:
            continue
        assert poly.min() >= -1e-12 and poly.max() <= 1 + 1e-12
        normal = np.cross(u, v)
        assert np.abs((poly - c) @ normal).max() < 1e-12 * np.linalg.norm(normal)  # on the plane
        # points of the quad inside the cube lie in the polygon (same side of every edge)
        s, t = rng.uniform(-1, 1, (2, 2000))
        pts = c + s[:, None] * u + t[:, None] * v
        inside = np.all((pts >= 0) & (pts <= 1), axis=1)
        e = np.roll(poly, -1, axis=0) - poly
        rel = pts[:, None, :] - poly[None]
        turn = np.einsum("nij,j->ni", np.cross(np.broadcast_to(e, rel.shape), rel), normal)
        in_poly = np.all(turn >= 0, axis=1) | np.all(turn <= 0, axis=1)  # same side of every edge: convex
        margin = np.min(np.minimum(np.abs(pts), np.abs(pts - 1)), axis=1) > 1e-9  # off the cube's planes
        assert np.array_equal(inside[margin], in_poly[margin])


@pytest.mark.slow
@pytest.mark.parametrize("counts", [(1, 1, 1), (3, 1, 2), (3, 2, 3)])  # (3, 2, 3): cells sealed on y alone
def test_boolean_sealed_oblique_tubes_are_closed_one_sphere_per_tube(counts):
    ms = tiling.regular(TWISTED, L.oblique_tubes(), counts, seal="cap")
    w = watertightness(ms)
    assert w["closed"] and w["manifold"] and w["open_edges"] == 0 and w["nonmanifold_edges"] == 0
    assert w["components"] == _tubes(counts)
    assert w["euler_characteristic"] == 2 * w["components"]  # every capped tube is a sphere
    # unsealed, the tubes stay open only at D's boundary: two openings per tube
    open_ = watertightness(tiling.regular(TWISTED, L.oblique_tubes(), counts))
    assert not open_["closed"] and open_["components"] == _tubes(counts)
    assert len(ms.caps) == 2 * _tubes(counts)
    assert all(hasattr(T, "loops") for T in boundary_splines(ms)[-len(ms.caps):])


def test_clip_walls_bad_input():
    flat = pr.box().boundary("wmin")
    with pytest.raises(TilingError, match="wall 0 must be a bilinear surface"):
        clip_walls([pr.box().elevate_to((2, 2, 2)).boundary("wmin")])
    bent = BSpline((1, 1), [np.array([0.0, 0.0, 1.0, 1.0])] * 2,
                   np.array([[[0, 0, 0], [0, 1, 0]], [[1, 0, 0], [1, 1, 0.5]]], float))
    with pytest.raises(TilingError, match="wall 0 is not planar"):
        clip_walls([bent])
    with pytest.raises(TilingError, match="none of the 1 walls passes through the unit cell"):
        clip_walls([flat.translate(np.array([0.0, 0.0, 3.0]))])
    with pytest.raises(TilingError, match="at least one wall"):
        clip_walls([])
    with pytest.raises(TilingError, match="width must be in"):
        L.oblique_tubes(0.5)


@pytest.mark.slow
def test_the_boolean_sealed_tubes_go_to_iges_and_opencascade_reads_every_face_with_our_area(tmp_path):
    from helpers import opencascade, surface_area
    from tiling.export import write_iges

    ms = tiling.regular(TWISTED, L.oblique_tubes(), (3, 1, 2), seal="cap")
    ours = boundary_splines(ms)
    path = write_iges(tmp_path / "tubes.igs", ms, units="mm")
    with opencascade(path) as (gmsh, tags):
        assert len(tags) == len(ours) == len(ms.patches) + len(ms.caps)
        got = np.array([gmsh.model.occ.getMass(2, t) for t in tags])
    want = np.array([S.area(2e-3) if hasattr(S, "loops") else surface_area(S, 10) for S in ours])
    assert np.abs(got / want - 1).max() < 1e-4  # polynomial faces: OpenCASCADE integrates them closely
