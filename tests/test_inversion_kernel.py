"""The compiled point inversion (geometry.compiled._newton_kernels) against the NumPy iterations it replaces, and against
direct evaluation: the same distances, memberships and foot points, on polynomial and rational trivariates and
on their boundary surfaces, plain and damped."""

import numpy as np
import pytest

from geometry.compiled import _fast
from geometry.maps import inversion
from geometry import primitives as pr
from geometry.faces import FACE_NAMES

pytestmark = [pytest.mark.skipif(not _fast.AVAILABLE, reason="the compiled inversion needs numba (test extra)"),
              pytest.mark.all_threads]  # kernels on every thread: a race would show


def _maps():
    twisted = pr.twisted(pr.box((1.0, 2.0, 1.0), degrees=(2, 3, 2), elements=(3, 2, 4)), 0.4, axis_point=(0.5, 0.5))
    return {"twisted (polynomial)": twisted, "annulus (rational)": pr.annulus(1.0, 2.0, 1.0).refine(1)[0],
            "cylinder": pr.cylinder()}


def _around(S, rng, n):
    """n points about S: half on its image (from random parameters), half in and beyond its bounding box."""
    t = rng.uniform(S.domain[:, 0], S.domain[:, 1], (n // 2, S.dim))
    lo, hi = S.bounding_box()[:, 0], S.bounding_box()[:, 1]
    wide = lo + (hi - lo + 0.2) * (rng.random((n - n // 2, 3)) * 1.4 - 0.2)
    return t, np.vstack([S.evaluate(t)[:, :3], wide])


@pytest.mark.parametrize("name", list(_maps()))
@pytest.mark.parametrize("damped", [False, True])
def test_compiled_inversion_of_a_trivariate_equals_the_numpy_iterations(name, damped):
    D = _maps()[name]
    rng = np.random.default_rng(3)
    t, pts = _around(D, rng, 1200)
    slow, fast = inversion.invert(D, pts, damped=damped), inversion.invert(D, pts, damped=damped, kernel=True)
    size = float(np.abs(D.points).max())
    assert np.abs(fast.distance - slow.distance).max() <= 1e-12 * size
    assert np.array_equal(fast.inside, slow.inside) and fast.inside[: len(t)].all()
    # the points on the image: the parameters they came from (a regular map), and the same as NumPy's
    assert np.abs(fast.params[: len(t)] - t).max() < 1e-9
    assert np.abs(fast.params - slow.params).max() < 1e-9
    # the distance is that of the foot point found, by direct evaluation
    direct = np.linalg.norm(D.evaluate(fast.params)[:, :3] - pts, axis=1)
    assert np.abs(direct - fast.distance).max() <= 1e-14 * size


@pytest.mark.parametrize("name", list(_maps()))
def test_compiled_inversion_of_surfaces_finds_the_nearest_points(name):
    D = _maps()[name]
    rng = np.random.default_rng(5)
    for face in FACE_NAMES:
        S = D.boundary(face)
        t, pts = _around(S, rng, 300)
        for damped in (False, True):
            slow = inversion.invert(S, pts, damped=damped)
            fast = inversion.invert(S, pts, damped=damped, kernel=True)
            assert fast.params.shape == (len(pts), 2)
            assert np.abs(fast.distance - slow.distance).max() <= 1e-12 * max(1.0, float(np.abs(S.points).max()))
            assert np.array_equal(fast.inside, slow.inside)
            assert np.abs(fast.params[: len(t)] - t).max() < 1e-9 and fast.distance[: len(t)].max() < 1e-12
        # off the surface, damped (the projected steps at the domain's bounds included): the distance to a point
        # the surface passes through, and for most points no farther than the nearest of a dense sample grid
        # (a local method: about one point in ten stops in a local minimum, as the NumPy iterations do)
        g = np.linspace(0.0, 1.0, 201)
        grid = np.stack(np.meshgrid(g, g, indexing="ij"), -1).reshape(-1, 2)
        grid = S.domain[:, 0] + grid * (S.domain[:, 1] - S.domain[:, 0])
        samples = S.evaluate(grid)[:, :3]
        off = pts[len(t):][:40]
        fast = inversion.invert(S, off, damped=True, kernel=True)
        sampled = np.linalg.norm(samples[None] - off[:, None], axis=2).min(axis=1)
        assert np.mean(fast.distance <= sampled + 1e-9) >= 0.8
        assert np.allclose(np.linalg.norm(S.evaluate(fast.params)[:, :3] - off, axis=1), fast.distance, atol=1e-13)


def test_nearest_of_several_surfaces_compiled_and_not_agree():
    D = _maps()["cylinder"]
    faces = [D.boundary(f) for f in FACE_NAMES]
    _, pts = _around(D, np.random.default_rng(9), 400)
    w1, slow = inversion.invert_nearest(faces, pts, damped=True)
    w2, fast = inversion.invert_nearest(faces, pts, damped=True, kernel=True)
    assert np.abs(fast.distance - slow.distance).max() <= 1e-12 * float(np.abs(D.points).max())
    # the chosen face differs only where two faces are equally near (an edge or a corner of the solid)
    differ = np.flatnonzero(w1 != w2)
    assert len(differ) < 0.05 * len(pts)


def test_without_numba_the_kernel_request_takes_the_numpy_iterations(monkeypatch):
    D = _maps()["twisted (polynomial)"]
    _, pts = _around(D, np.random.default_rng(2), 200)
    slow = inversion.invert(D, pts, damped=True)
    monkeypatch.setattr(_fast, "AVAILABLE", False)
    same = inversion.invert(D, pts, damped=True, kernel=True)
    assert np.array_equal(same.params, slow.params) and np.array_equal(same.distance, slow.distance)


@pytest.mark.slow
def test_v_model_classification_is_the_same_with_the_compiled_inversion_and_without(monkeypatch):
    from geometry.shapes.examples import cylinder
    from tiling import library as L
    from tiling.vrep import Primitive, classify

    A = Primitive(cylinder(1.0, 4.0, 0), L.cross(), (3, 3, 6), priority=2, name="A")
    B = Primitive(cylinder(1.0, 4.0, 1), L.cross(), (3, 3, 6), priority=1, name="B")
    for model in (A | B, A - B):
        fast = [classify(model, p, margin=0.3).state for p in model.positive()]
        with monkeypatch.context() as m:
            m.setattr(_fast, "AVAILABLE", False)
            slow = [classify(model, p, margin=0.3).state for p in model.positive()]
        assert all(np.array_equal(a, b) for a, b in zip(fast, slow))
        assert any(len(np.unique(a)) >= 3 for a in fast)  # tiles inside, bridged and purged: a real test
