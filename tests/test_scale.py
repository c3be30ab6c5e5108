"""Bounds on the local scale of a map (Elber 2017, Section 4): guaranteed against sampled singular values
of the Jacobian at 10^5 random points, and tight."""

import numpy as np
import pytest

from geometry import SplineError, primitives
from geometry.maps.scale import scale_bounds
from tiling import library, regular


def _sampled(D, n=100_000, seed=0):
    rng = np.random.default_rng(seed)
    dom = D.domain
    x = dom[:, 0] + rng.random((n, D.dim)) * (dom[:, 1] - dom[:, 0])
    J = D.jacobian(x)[:, :3, :]
    return x, np.linalg.svd(J, compute_uv=False), np.linalg.norm(J, axis=1)  # (n, d) descending, (n, d)


def _owner(x, boxes):
    inside = np.all((x[:, None, :] >= boxes[None, :, :, 0]) & (x[:, None, :] <= boxes[None, :, :, 1]), axis=2)
    return inside  # (n, K)


def _test_map():
    """A tapered, twisted triquadratic block on 2 x 2 x 3 spans (polynomial, degree 3 along w)."""
    box = primitives.box((1.0, 1.0, 1.0), degrees=(2, 2, 2), elements=(2, 2, 3))
    return primitives.tapered(primitives.twisted(box, 0.6), 0.5)


@pytest.mark.parametrize("D", [_test_map(), primitives.annulus()], ids=["tapered-twist", "NURBS-annulus"])
def test_bounds_contain_the_sampled_singular_values_and_are_tight(D):
    sb = scale_bounds(D)
    x, sv, stretch = _sampled(D)
    inside = _owner(x, sb.boxes)
    assert inside.any(1).all()
    eps = 1e-12
    lo = np.where(inside, sb.lower[None, :], -np.inf).max(1)  # a point on a shared knot plane obeys its tightest box
    hi = np.where(inside, sb.upper[None, :], np.inf).min(1)
    assert np.all(sv[:, -1] >= lo * (1 - eps)) and np.all(sv[:, 0] <= hi * (1 + eps))
    alo = np.where(inside[..., None], sb.axis_lower[None], -np.inf).max(1)
    ahi = np.where(inside[..., None], sb.axis_upper[None], np.inf).min(1)
    assert np.all(stretch >= alo * (1 - eps)) and np.all(stretch <= ahi * (1 + eps))
    # tight: the extremes over the map within 10% of the sampled ones (the bounds converge as h^2)
    assert sb.lower.min() >= 0.9 * sv[:, -1].min() and sb.upper.max() <= 1.1 * sv[:, 0].max()
    assert np.all(sb.axis_lower.min(0) >= 0.9 * stretch.min(0)) and np.all(sb.axis_upper.max(0) <= 1.1 * stretch.max(0))
    # and on every span
    for k in range(len(sb.boxes)):
        s = sv[inside[:, k]]
        assert sb.lower[k] >= 0.85 * s[:, -1].min() and sb.upper[k] <= 1.1 * s[:, 0].max(), k


def test_bounds_tighten_under_subdivision_and_a_similarity_is_exact():
    gaps = [scale_bounds(primitives.annulus(), subdivide=s) for s in (1, 2, 4)]
    width = [float((g.upper - g.lower).sum()) for g in gaps]
    assert width[0] > width[1] >= width[2] - 1e-12
    assert all(b.lower.min() >= a.lower.min() - 1e-12 for a, b in zip(gaps, gaps[1:]))
    sim = primitives.box((2.0, 2.0, 2.0), degrees=(3, 2, 2), elements=(2, 1, 3)).affine(
        np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]]))  # a rotation of a cube: every scale is 2
    sb = scale_bounds(sim)
    assert np.allclose(sb.lower, 2.0, atol=1e-12) and np.allclose(sb.upper, 2.0, atol=1e-12)
    assert np.allclose(sb.distortion, 1.0)


def test_each_placed_tile_is_bounded_on_its_own_box():
    D = _test_map()
    ms = regular(D, library.cross(), (1, 1, 1))
    sb = ms.scale_bounds()
    assert len(sb.tiles) == ms.n_tiles == 12 and sb.boxes.shape == (12, 3, 2)
    # the tile's points stretched through D: sample inside each tile box
    rng = np.random.default_rng(1)
    t = rng.random((12, 400, 3))
    x = sb.boxes[:, None, :, 0] + t * (sb.boxes[:, None, :, 1] - sb.boxes[:, None, :, 0])
    sv = np.linalg.svd(D.jacobian(x.reshape(-1, 3))[:, :3, :], compute_uv=False).reshape(12, 400, 3)
    assert np.all(sv[..., -1].min(1) >= sb.lower * (1 - 1e-12)) and np.all(sv[..., 0].max(1) <= sb.upper * (1 + 1e-12))
    # one tile per span here: the tile boxes are the spans, and a half box is bounded at least as tightly
    spans = scale_bounds(D)
    assert np.allclose(sb.boxes, spans.boxes) and np.allclose(sb.upper, spans.upper)
    half = sb.boxes.copy()
    half[:, 2, 1] = half[:, 2].mean(1)
    hb = scale_bounds(D, half)
    assert np.all(hb.upper <= sb.upper + 1e-12) and np.all(hb.lower >= sb.lower - 1e-12)


def test_bad_input_is_refused_with_the_fix():
    D = _test_map()
    with pytest.raises(SplineError, match="subdivide"):
        scale_bounds(D, subdivide=0)
    with pytest.raises(SplineError, match="domain"):
        scale_bounds(D, [[[0.0, 2.0], [0.0, 1.0], [0.0, 1.0]]])
    with pytest.raises(SplineError, match="shape"):
        scale_bounds(D, [[0.0, 1.0]])
    with pytest.raises(SplineError, match="needs a spline"):
        scale_bounds("map.npz")
