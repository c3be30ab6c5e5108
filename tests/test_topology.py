"""Interfaces by construction: regular and hierarchical pavings glue their patches by cell-grid
arithmetic over layouts matched once in the unit cell (tiling.topology), periodic maps across their seam; the
result equals the geometric search wherever that search works, and holds at any length scale."""

import numpy as np
import pytest

from geometry import MultiPatch, primitives as pr
from geometry.patches.multipatch import detect_interfaces
from iga import HeatProblem
from iga.app.maps import circular_heat_sink_map, vertical_heat_sink_map
from tiling import library as L, regular, hierarchical
from tiling.topology import seams


def _normalised(interfaces) -> set:
    """Identity interfaces as (a, b, swap, flip) with a < b (the orientation read from the lower face)."""
    out = set()
    for i in interfaces:
        if i.kind != "identity":
            continue
        a, b, swap, flip = i.a, i.b, bool(i.swap), tuple(bool(x) for x in i.flip)
        if a > b:
            a, b, flip = b, a, flip[::-1] if swap else flip
        out.add((a, b, swap, flip))
    return out


CASES = {
    "lattice": lambda: regular(pr.box((2.0, 1.0, 1.0)), L.cross(), (3, 2, 2)),
    "closed annulus": lambda: regular(pr.annulus(0.5, 1.0, 0.3, angle=2 * np.pi, exact=True), L.cross(), (6, 1, 1)),
    "capped lattice": lambda: regular(pr.box((2.0, 1.0, 1.0)), L.cross(), (3, 2, 2), seal="cap"),
    "shelled lattice": lambda: regular(pr.box(), L.bent_cross(), (2, 2, 2), seal="shell"),
    "circular sink": lambda: hierarchical(circular_heat_sink_map(), L.heat_sink_t1(), (4, 1), levels=3),
    "capped T2 sink": lambda: hierarchical(vertical_heat_sink_map(), L.heat_sink_t2(), (2, 2), levels=2, seal="cap",
                                           seal_sides=["wmax", "wmin"]),
    "fractal": lambda: hierarchical(pr.box(), L.fractal(), (2, 1), levels=2),
    "skinned": lambda: hierarchical(pr.box(), L.skinned_branching(), (2, 2), levels=2),
}


@pytest.mark.slow
@pytest.mark.parametrize("name", sorted(CASES))
def test_construction_equals_the_geometric_search(name):
    ms = CASES[name]()
    found, bad = detect_interfaces(ms.patches)
    linked = {frozenset([i.a, i.b]) for i in ms.interfaces if i.kind == "branch"}
    searched = _normalised([i for i in found if frozenset([i.a, i.b]) not in linked])
    built = _normalised(ms.interfaces)
    assert built == searched and len(built) > 0
    assert len(built) == sum(i.kind == "identity" for i in ms.interfaces)  # none twice


def test_a_closed_map_is_glued_across_its_seam_even_with_one_cell_around():
    D = pr.annulus(0.5, 1.0, 0.3, angle=2 * np.pi, exact=True)
    assert seams(D) == (True, False, False) and seams(pr.box()) == (False, False, False)
    for n in (1, 2, 6):
        ms = regular(D, L.cross(), (n, 1, 1))
        sol = HeatProblem(ms, 1.0).dirichlet("vmin", 1.0).dirichlet("vmax", 0.0).solve()
        # every copy of the cross glued to both neighbours around the ring: one piece; no arm end on the seam is free
        assert sol.info["components"]["count"] == 1 and not ms.tags["umin"] and not ms.tags["umax"]
        assert not any(i.a[0] == i.b[0] for i in ms.interfaces)  # a patch is never glued to itself


@pytest.mark.parametrize("size", [1e-9, 1e-6, 1.0, 1e6])
def test_pavings_and_user_lists_couple_at_every_length_scale(size):
    """A nanometre lattice, a micrometre one and one a thousand kilometres wide are the same model: the same
    interfaces, one piece, the same heat flow relative to the size; user lists of two boxes are glued too
    (tolerances relative to the model's extent, not to 1 m)."""
    ms = regular(pr.box((size,) * 3, origin=(size, 0.0, 0.0)), L.cross(), (3, 3, 3))
    sol = HeatProblem(ms, 1.0).dirichlet("umin", 1.0).dirichlet("umax", 0.0).solve()
    assert len(ms.interfaces) == 216 and sol.info["components"]["count"] == 1
    ref = regular(pr.box(), L.cross(), (3, 3, 3))
    expected = HeatProblem(ref, 1.0).dirichlet("umin", 1.0).dirichlet("umax", 0.0).solve().flux("umin")
    assert sol.flux("umin") / size == pytest.approx(expected, rel=1e-9)
    pair = MultiPatch.from_splines([pr.box((size,) * 3), pr.box((size,) * 3, origin=(size, 0.0, 0.0))])
    assert len(pair.interfaces) == 1


def test_face_points_of_many_faces_equal_each_face_alone():
    """geometry.patches.placed_points.face_points batches faces by spline, face and sample set: its points equal those
    of every face evaluated alone (placed through its map), whichever way the sample sets are given."""
    from geometry.patches.multipatch import FACE_SAMPLES, ORIENTATIONS, _oriented_samples
    from geometry.patches.placed_points import face_points

    ms = regular(pr.twisted(pr.box((2.0, 1.0, 1.0)), 0.4), L.cross(), (2, 2, 2))
    keys = [(i, f) for i in range(0, len(ms.patches), 3) for f in ("umin", "vmax", "wmax")]
    which = np.random.default_rng(3).integers(0, 8, len(keys))
    sets = np.stack([_oriented_samples(*o) for o in ORIENTATIONS])
    together = face_points(ms.patches, keys, sets, which=which)
    assert np.array_equal(together, face_points(ms.patches, keys, [sets[k] for k in which]))
    for (p, f), k, got in zip(keys, which, together):
        P = ms.patches[p]
        alone = face_points([P], [(0, f)], sets[k])[0]
        assert np.array_equal(got, alone)
        placed = face_points([P], [(0, f)], sets[k], through_outer=False)[0]
        assert np.allclose(P.outer.evaluate(placed)[:, :3], got, atol=1e-14)
    assert face_points(ms.patches, [], FACE_SAMPLES).shape == (0, 5, 3)


def test_the_geometric_search_names_faces_that_touch_without_conforming():
    from geometry.patches.multipatch import PlacedPatch

    # three unit boxes in a row along u: the 1st and 2nd share a face of equal corners but different knots
    # (the 2nd refined along v), the 2nd and 3rd one whose middle differs (the 3rd's control point moved), and a
    # 4th above the 1st glues to it
    a = pr.box()
    b = pr.box(origin=(1.0, 0.0, 0.0), elements=(1, 2, 1)).elevate_to((1, 2, 1))
    c = pr.box(origin=(2.0, 0.0, 0.0), elements=(1, 2, 1)).elevate_to((1, 2, 1))
    cp = c.control_points.copy()
    cp[0, 2, 0, 0] += 0.05  # a point of c's umin face off its corners: the same corners, another surface
    c = type(c)(c.degrees, c.knots, cp)
    d = pr.box(origin=(0.0, 0.0, 1.0))
    found, bad = detect_interfaces([PlacedPatch(s) for s in (a, b, c, d)])
    assert [(i.a, i.b) for i in found] == [((0, "wmax"), (3, "wmin"))]
    assert [(x, y) for x, y, _ in bad] == [((0, "umax"), (1, "umin")), ((1, "umax"), (2, "umin"))]
    assert "spline spaces differ" in bad[0][2] and "surfaces part between the corners" in bad[1][2]
    with pytest.raises(Exception, match="do not conform: their spline spaces differ"):
        detect_interfaces([PlacedPatch(s) for s in (a, b, c, d)], strict=True)
