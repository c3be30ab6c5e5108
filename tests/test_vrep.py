"""V-rep Boolean models (Hong and Elber 2021, Section 3.1): membership, tile classification, kept tiles."""

import numpy as np
import pytest

from geometry.shapes import cylinder
from tiling import TilingError
from tiling import library as L
from tiling.vrep import (INSIDE, INTERSECTING, MARGIN, OUTSIDE, TO_BE_BRIDGED, Primitive, classify,
                         vrep_microstructure)


def _cylinders(counts=(3, 3, 6)):
    A = Primitive(cylinder(1.0, 4.0, 0), L.cross(), counts, priority=3, name="A")
    B = Primitive(cylinder(1.0, 4.0, 1), L.cross(), counts, priority=2, name="B")
    C = Primitive(cylinder(0.8, 4.0, 2), L.cross(), counts, priority=1, name="C")
    return A, B, C


def _random_points(prim, cls, tiles, n, rng):
    """n random physical points in each of the given tiles' cells (uniform in parameters)."""
    boxes = cls.cells[tiles]  # (T, 3, 2)
    u = rng.random((len(tiles), n, 3))
    params = boxes[:, None, :, 0] + u * (boxes[:, None, :, 1] - boxes[:, None, :, 0])
    return prim.D.evaluate(params.reshape(-1, 3))[:, :3].reshape(len(tiles), n, 3)


@pytest.mark.parametrize("op", ["union", "subtract"])
def test_classification_agrees_with_brute_force_membership(op):
    A, B, C = _cylinders()
    model = (A | B | C) if op == "union" else (A - B - C)
    rng = np.random.default_rng(7)
    for prim in model.positive():
        cls = classify(model, prim)
        for state, want in ((INSIDE, True), (TO_BE_BRIDGED, True), (OUTSIDE, False)):
            tiles = np.flatnonzero(cls.state == state)
            if not len(tiles):
                continue
            pick = rng.choice(tiles, size=min(12, len(tiles)), replace=False)
            pts = _random_points(prim, cls, pick, 150, rng)
            inside = model.territory(prim, pts.reshape(-1, 3)).reshape(len(pick), -1)
            assert np.all(inside == want), (prim.name, state)
        # an intersecting tile really straddles a trimming surface (dense samples on both sides)
        tiles = np.flatnonzero(cls.state == INTERSECTING)
        if len(tiles):
            pick = rng.choice(tiles, size=min(8, len(tiles)), replace=False)
            pts = _random_points(prim, cls, pick, 400, rng)
            inside = model.territory(prim, pts.reshape(-1, 3)).reshape(len(pick), -1)
            assert np.all(inside.any(axis=1) & ~inside.all(axis=1))


def test_a_subtraction_keeps_no_tile_inside_the_subtracted_primitives():
    A, B, C = _cylinders()
    res = vrep_microstructure(A - B - C)
    ms = res.microstructure
    assert len(ms.patches) > 0 and set(res.counts()) == {"A"}
    rng = np.random.default_rng(3)
    pts = np.concatenate([P.image(P.spline.domain[:, 0] + rng.random((20, 3)) * np.ptp(P.spline.domain, axis=1))
                          for P in ms.patches])
    assert not B.contains(pts).any() and not C.contains(pts).any()
    assert A.contains(pts).all()


def test_union_tiles_each_v_cell_from_the_primitive_of_highest_priority():
    A, B, C = _cylinders()
    res = vrep_microstructure(A | B | C)
    counts = res.counts()
    assert counts["A"]["outside"] == counts["A"]["intersecting"] == 0  # A is first: all its tiles stay
    assert counts["B"]["outside"] > 0 and counts["C"]["outside"] > 0  # what A already tiles
    ms = res.microstructure
    for name in "ABC":
        assert ms.tags[name] and set(ms.tags[f"anchor:{name}"]) <= set(ms.tags[name])
    assert ms.tags["anchor"] and not ms.tags["anchor:A"]  # only B and C are cut by higher priorities
    # every anchor face is a free face (its neighbour tile was purged)
    assert set(ms.tags["anchor"]) <= set(ms.tags["boundary"])


def test_a_margin_purges_bridged_tiles_too_close_to_the_surface():
    A, B, C = _cylinders()
    model = A - B
    plain, purged = classify(model, A), classify(model, A, margin=0.4)
    assert np.sum(purged.state == MARGIN) > 0 and np.sum(purged.state == TO_BE_BRIDGED) > 0
    assert np.sum(purged.state == TO_BE_BRIDGED) + np.sum(purged.state == MARGIN) == np.sum(plain.state == TO_BE_BRIDGED)
    # independent check: dense points of the kept bridged tiles stay at least the margin away from B
    rng = np.random.default_rng(5)
    kept = np.flatnonzero(purged.state == TO_BE_BRIDGED)
    pts = _random_points(A, purged, kept, 100, rng).reshape(-1, 3)
    assert B.distance(pts).min() >= 0.4 - 0.05  # samples of 4^3 per tile bound the distance within a tile's step


def test_v_model_bad_input():
    A, B, C = _cylinders()
    far = Primitive(cylinder(0.5, 1.0, 2, centre=(10.0, 10.0, 0.0)), L.cross(), (2, 2, 2), priority=5, name="far")
    with pytest.raises(TilingError, match="intersection.*empty"):
        vrep_microstructure(A & far)
    same = Primitive(cylinder(1.0, 4.0, 1), L.cross(), (2, 2, 2), priority=3, name="B3")
    with pytest.raises(TilingError, match="'A' and 'B3' overlap and have the same priority 3"):
        vrep_microstructure(A | same)
    with pytest.raises(TilingError, match="names must be distinct"):
        vrep_microstructure(A | Primitive(cylinder(1.0, 4.0, 1), L.cross(), (2, 2, 2), priority=1, name="A"))
    with pytest.raises(TilingError, match="operands"):
        A | "cylinder"
    with pytest.raises(TilingError, match="no primitive that carries tiles|V-model"):
        vrep_microstructure(A)
    with pytest.raises(TilingError, match="priority must be an integer"):
        Primitive(cylinder(), L.cross(), (2, 2, 2), priority=1.5, name="bad")
