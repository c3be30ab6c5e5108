"""Trimmed caps of surface tiles (Massarwi et al. 2018, Section 6.2, Fig. 9(a, b)) and two-level structures (Fig. 12)."""

import numpy as np
import pytest

import tiling
from geometry import BSpline, compose, primitives as pr
from geometry.shapes.triangulate import fill_rings
from geometry.shapes.trimmed import join_curves
from iga import HeatProblem
from tiling import TilingError
from tiling import library as L
from tiling.sealing.caps import surface_caps

TWISTED = pr.twisted(pr.box((1.0, 1.0, 1.0), degrees=(2, 2, 2)), 0.4, axis_point=(0.5, 0.5))


def _euler_of_tube_graph(nodes: int, edges: int) -> int:
    """Euler characteristic of the closed surface around a graph of tubes: 2 - 2 * (cycle rank)."""
    return 2 - 2 * (edges - nodes + 1)


def test_fill_rings_keeps_the_rings_and_fills_the_area_exactly():
    rng = np.random.default_rng(3)
    th = np.sort(rng.uniform(0, 2 * np.pi, 30))
    outer = np.c_[np.cos(th), 0.6 * np.sin(th)]
    hole = 0.2 * np.c_[np.cos(th[::-1]), np.sin(th[::-1])] + [0.1, 0.0]
    longest = max(np.linalg.norm(np.diff(np.vstack([r, r[:1]]), axis=0), axis=1).max() for r in (outer, hole))
    pts, tris = fill_rings([outer, hole], longest)
    assert np.array_equal(pts[:60], np.vstack([outer, hole]))  # ring points first and unchanged
    d1, d2 = pts[tris[:, 1]] - pts[tris[:, 0]], pts[tris[:, 2]] - pts[tris[:, 0]]
    area = 0.5 * (d1[:, 0] * d2[:, 1] - d1[:, 1] * d2[:, 0])

    def shoelace(r):
        return 0.5 * np.sum(r[:, 0] * np.roll(r[:, 1], -1) - np.roll(r[:, 0], -1) * r[:, 1])

    assert np.all(area > 0) and area.sum() == pytest.approx(shoelace(outer) + shoelace(hole), rel=1e-12)
    edges = np.sort(np.concatenate([tris[:, [0, 1]], tris[:, [1, 2]], tris[:, [2, 0]]]), axis=1)
    _, uses = np.unique(edges, axis=0, return_counts=True)
    assert np.all(uses <= 2) and np.sum(uses == 1) == 60  # conforming: only the ring edges are used once
    lengths = np.linalg.norm(pts[edges[:, 0]] - pts[edges[:, 1]], axis=1)
    assert len(pts) > 60 and np.median(lengths) <= longest


def test_joined_curves_follow_their_pieces():
    rng = np.random.default_rng(0)
    a = BSpline((1,), [np.array([0, 0, 1, 1.0])], np.array([[0, 0, 0], [1, 0, 0.0]]))
    b = BSpline((2,), [np.array([2, 2, 2, 3, 3, 3.0])], np.array([[1, 0, 0], [1.5, 0.5, 0], [1, 1, 0.0]]),
                np.array([1, 0.6, 1.0]))
    j = join_curves([a, b])
    t = rng.uniform(0, 1, 50)[:, None]
    assert np.abs(j.evaluate(t)[:, :3] - a.evaluate(t)[:, :3]).max() < 1e-14
    assert np.abs(j.evaluate(1 + t)[:, :3] - b.evaluate(2 + t)[:, :3]).max() < 1e-14


def test_a_cap_is_bounded_by_the_tiles_edges_and_encloses_their_area():
    tile = L.hollow_cross(0.3)
    caps = surface_caps(tile, ["umin", "wmax"])
    assert [c.side for c in caps] == ["umin", "wmax"]
    for c in caps:
        assert len(c.trimmed.loops) == 1 and len(c.segments[0]) == 4  # a square of four arm-wall edges
        assert c.trimmed.area(1e-6) == pytest.approx(0.09, rel=1e-9)


def test_composed_caps_on_their_loops_are_the_composed_tile_edges():
    ms = tiling.regular(TWISTED, L.hollow_cross(), (2, 2, 2), seal="cap", seal_sides=("umin", "wmax"))
    assert len(ms.caps) == 2 * 4  # four cells on each capped side
    rng = np.random.default_rng(1)
    for pc in ms.caps[:3]:
        exact = pc.composed()
        loop = exact.loops[0]
        image = compose(exact.surface, loop)
        for j, (patch, edge, rev) in enumerate(pc.cap.segments[0]):
            tau = rng.uniform(0, 1, 20)
            P = ms.patches[pc.first + patch]
            curve = compose(P.outer, P.spline.affine(P.placement[:, :3], P.placement[:, 3]).boundary(edge))
            lo, hi = curve.domain[0]
            s = lo + (1 - tau if rev else tau) * (hi - lo)
            on_loop = image.evaluate((j + tau)[:, None])[:, :3]
            assert np.abs(on_loop - curve.evaluate(s[:, None])[:, :3]).max() < 1e-12


@pytest.mark.parametrize("D,counts", [(TWISTED, (3, 3, 3)), (pr.box((2.0, 1.0, 1.0)), (1, 2, 1))])
def test_a_capped_hollow_lattice_is_one_closed_surface(D, counts):
    ms = tiling.regular(D, L.hollow_cross(), counts, seal="cap")
    w = tiling.export.watertightness(ms, samples=2)
    n = int(np.prod(counts))
    tubes = sum(int(np.prod(counts)) // c * (c - 1) for c in counts)  # connections between neighbouring cells
    assert w["closed"] and w["manifold"] and w["components"] == 1
    assert w["euler_characteristic"] == _euler_of_tube_graph(n, tubes)


@pytest.mark.slow
def test_two_level_capped_structure_is_one_closed_surface(monkeypatch):
    from tiling import paving

    first = tiling.regular(TWISTED, L.cross(), (1, 1, 1))  # 7 blocks, 6 interfaces
    built, variant_for = [], paving.variant_for
    monkeypatch.setattr(paving, "variant_for", lambda tile, sides, *a: built.append(sides) or variant_for(tile, sides, *a))
    ms = tiling.compose_levels(first, L.hollow_cross(), (2, 2, 2), seal="cap")
    # each set of free sides capped once for all seven maps, and the maps' tiles share those variants
    capped = {id(t): t for t in ms.tiles if getattr(t, "caps", None)}
    assert len(built) == len(set(built)) == len(capped) and len(ms.caps) > 7 * len(capped) / 2
    assert len(ms.patches) == 7 * 8 * 24
    with pytest.raises(tiling.TilingError, match=r"built must be a dict \(of sealed variants"):
        tiling.regular(TWISTED, L.hollow_cross(), (2, 1, 1), seal="cap", built=[])
    w = tiling.export.watertightness(ms, samples=2)
    assert w["closed"] and w["manifold"] and w["components"] == 1
    # 8 crosses per block with 12 connections each, 4 more through each of the first level's 6 interfaces
    assert w["euler_characteristic"] == _euler_of_tube_graph(7 * 8, 7 * 12 + 6 * 4)


def test_a_two_level_volumetric_structure_is_a_heat_model():
    first = tiling.regular(pr.box((2.0, 1.0, 1.5)), L.cross(), (2, 1, 1))
    ms = tiling.compose_levels(first, L.cross(), (1, 1, 1), degree=None)
    across = [i for i in ms.interfaces if ms.patches[i.a[0]].outer is not ms.patches[i.b[0]].outer]
    assert len(across) == sum(1 for _ in first.interfaces)  # one arm-end contact per first-level interface

    def linear(x):
        return 1 + 2 * x[:, 0] - x[:, 1] + 0.5 * x[:, 2]

    s = HeatProblem(ms).dirichlet("boundary", linear).solve()
    assert s.l2_error(linear) < 1e-9
    # the first level's face tags carry over: heat in at umin, out at umax, balanced
    assert ms.tags["umin"] and ms.tags["umax"]
    s = HeatProblem(ms, conductivity=10.0).neumann("umin", 100.0).dirichlet("umax", 20.0).solve()
    assert s.info["balance"]["relative_error"] < 1e-9
    assert s.info["components"]["count"] == 1 and not s.info["components"]["idle"]  # one coupled piece: no interface missing


def test_iges_export_writes_the_caps_as_trimmed_surfaces(tmp_path):
    ms = tiling.regular(pr.box((1.0, 1.0, 1.0)), L.hollow_cross(), (1, 1, 1), seal="cap")
    path = tiling.export.write_iges(tmp_path / "capped.igs", ms)
    text = path.read_text()
    directory = [ln for ln in text.splitlines() if ln[72:73] == "D"]
    kinds = [int(ln[:8]) for ln in directory[::2]]
    assert kinds.count(144) == 6 and kinds.count(128) >= 24


def test_cap_bad_input():
    sheet = tiling.Tile([pr.box((1.0, 1.0, 0.5)).boundary("wmax")], name="open sheet")  # the plane z = 0.5
    with pytest.raises(TilingError, match="open sheet.*do not close"):
        tiling.regular(TWISTED, sheet, (2, 2, 2), seal="cap", seal_sides=("umin",))
    ball = tiling.Tile([pr.box((0.5, 0.5, 0.5), (0.25, 0.25, 0.25)).boundary(f) for f in tiling.tile.FACE_NAMES],
                       name="floating box")
    with pytest.raises(TilingError, match="floating box.*no boundary curves on the walls"):
        tiling.regular(TWISTED, ball, (2, 2, 2), seal="cap")
    with pytest.raises(TilingError, match="hollow_box.*lies in the wall umin, so a shell there would double it"):
        tiling.regular(TWISTED, L.hollow_box(), (2, 2, 2), seal="shell")  # (shells: tests/test_shells.py)
    with pytest.raises(TilingError, match="helix.*no surface patches"):
        tiling.regular(TWISTED, L.helix(), (2, 2, 2), seal="cap")
    first = tiling.regular(TWISTED, L.cross(), (1, 1, 1))
    with pytest.raises(TilingError, match="cross.*volumetric.*surface tiles"):
        tiling.compose_levels(first, L.cross(), (1, 1, 1), seal="cap")
    with pytest.raises(TilingError, match="first level"):
        tiling.compose_levels("not a structure", L.hollow_cross(), (1, 1, 1))
