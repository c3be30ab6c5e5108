"""The pieces behind the implicit surfaces: edge restrictions as Bernstein pieces, their root brackets and
Newton iteration, and the batched connectivity checks of faces and cells."""

import numpy as np
import pytest
from scipy import ndimage

from geometry import SplineFunction
from geometry import knots as kn
from tiling.implicit.checks import cells_ok, faces_ok
from tiling.implicit.surface import EdgeSplines, _bracketed_newton


def _field(rng, knots_w):
    """A random scalar trivariate, cubic, with the knots ``knots_w`` along w (uniform along u and v)."""
    U = kn.uniform_knots(3, 3)
    n = len(knots_w) - 4
    return SplineFunction((3, 3, 3), [U, U, np.asarray(knots_w, float)], rng.uniform(-1, 1, (6, 6, n, 1)))


def _edges(rng, n, lo=0.0, hi=1.0):
    """n edges along w from w = lo to w = hi at random (u, v)."""
    a = np.c_[rng.uniform(0, 1, (n, 2)), np.full(n, lo)]
    b = a.copy()
    b[:, 2] = hi
    return a, b, np.full(n, 2)


def _crossing(f, rng, n):
    """Edges along w over the whole domain at random (u, v) where f changes sign: a, b, axes, f(a), f(b)."""
    a, b, ax = _edges(rng, n)
    E = EdgeSplines.of(f, a, b, ax)
    fa, fb = E(np.arange(n), a[:, 2]), E(np.arange(n), b[:, 2])
    keep = fa * fb < 0
    assert keep.sum() > n // 6
    return a[keep], b[keep], ax[keep], fa[keep], fb[keep]


def test_edge_pieces_equal_the_field_across_knots_and_on_them():
    rng = np.random.default_rng(3)
    f = _field(rng, [0, 0, 0, 0, 0.2, 0.5, 0.5, 0.7, 1, 1, 1, 1])  # a double knot at 0.5
    a, b, ax = _edges(rng, 400, 0.1, 0.9)  # each edge crosses the knots 0.2, 0.5 and 0.7
    E = EdgeSplines.of(f, a, b, ax)
    assert E.bern.shape[1] == 4 and np.all(np.isfinite(E.breaks))
    t = np.r_[rng.uniform(0.1, 0.9, 400), [0.2, 0.5, 0.7, 0.1]]
    rows = np.r_[np.arange(400), [0, 1, 2, 3]]
    x = a[rows].copy()
    x[:, 2] = t
    direct = f.evaluate(x, compiled=False)[:, 0]
    assert np.abs(E(rows, t) - direct).max() < 1e-13
    # derivatives along the edge against central differences of the direct evaluation
    h = 1e-6
    xp, xm = x.copy(), x.copy()
    xp[:, 2] += h
    xm[:, 2] -= h
    inside = np.abs(t[:, None] - np.array([0.2, 0.5, 0.7])).min(axis=1) > 1e-3  # (C1 at most at the knots)
    fd = (f.evaluate(xp, compiled=False)[:, 0] - f.evaluate(xm, compiled=False)[:, 0]) / (2 * h)
    assert np.abs(E(rows, t, derivative=True)[1] - fd)[inside].max() < 1e-6


def test_the_bracket_takes_the_first_piece_with_a_sign_change_and_a_root_on_a_knot():
    rng = np.random.default_rng(4)
    f = _field(rng, [0, 0, 0, 0, 0.25, 0.5, 0.75, 1, 1, 1, 1])
    a, b, ax, fa, fb = _crossing(f, rng, 300)
    piece, lo, hi, flo, fhi = EdgeSplines.of(f, a, b, ax).bracket(a[:, 2], b[:, 2], fa, fb)
    assert np.all(flo * fhi <= 0) and np.all(lo <= hi)
    # the bracket is one piece: no knot strictly inside, and it is the first piece with a sign change
    knots = np.array([0.25, 0.5, 0.75])
    assert not np.any((knots[None] > lo[:, None] + 1e-15) & (knots[None] < hi[:, None] - 1e-15))
    before = knots[None] <= lo[:, None] + 1e-15
    ends = np.c_[a[:, 2], np.where(before, knots[None], np.nan)]
    for r, e in enumerate(ends):  # f keeps its sign at every knot left of the bracket
        x = np.tile(a[r], (np.isfinite(e).sum(), 1))
        x[:, 2] = e[np.isfinite(e)]
        assert np.all(np.sign(f.evaluate(x, compiled=False)[:, 0]) == np.sign(fa[r]))
    # a field whose restriction vanishes exactly on the knot 0.5 of every edge: C0 there (multiplicity 3),
    # where the spline interpolates its coefficient 0
    U = kn.uniform_knots(3, 3)
    g = SplineFunction((3, 3, 3), [U, U, np.array([0, 0, 0, 0, 0.5, 0.5, 0.5, 1, 1, 1, 1.0])],
                       np.broadcast_to(np.array([-1, -0.7, -0.3, 0, 0.3, 0.7, 1]), (6, 6, 7))[..., None])
    n = len(a)
    E = EdgeSplines.of(g, a, b, ax)
    piece, lo, hi, flo, fhi = E.bracket(a[:, 2], b[:, 2], np.full(n, -1.0), np.full(n, 1.0))
    assert np.all(lo == 0.5) and np.all(hi == 0.5) and np.all(flo == 0) and np.all(fhi == 0)
    c, _ = _bracketed_newton(a, b, np.full(n, -1.0), np.full(n, 1.0), ax, E, 1e-12, 60)
    assert np.all(c[:, 2] == 0.5)


def test_newton_on_the_pieces_lands_on_the_exact_zero_set_inside_each_edge():
    rng = np.random.default_rng(5)
    f = _field(rng, [0, 0, 0, 0, 0.3, 0.3, 0.6, 1, 1, 1, 1])
    a, b, ax, fa, fb = _crossing(f, rng, 2000)
    E = EdgeSplines.of(f, a, b, ax)
    c, its = _bracketed_newton(a, b, fa, fb, ax, E, 1e-13, 60)
    assert its < 60
    assert np.all((c[:, 2] >= a[:, 2]) & (c[:, 2] <= b[:, 2])) and np.array_equal(c[:, :2], a[:, :2])
    assert np.abs(f.evaluate(c, compiled=False)[:, 0]).max() < 1e-12


def _face_reference(v, ij):
    i, j = ij
    return bool(v[i, j] > 0 and ndimage.label(v > 0)[1] == 1 and ndimage.label(v <= 0)[1] == 1)


def _cell_reference(v):
    if ndimage.label(v > 0)[1] != 1:
        return False
    label, n = ndimage.label(v <= 0)
    boundary = np.zeros(v.shape, bool)
    for k in range(3):
        np.moveaxis(boundary, k, 0)[[0, -1]] = True
    return set(range(1, n + 1)) <= set(label[boundary].tolist())


@pytest.mark.parametrize("seed", [0, 1])
def test_batched_face_and_cell_checks_agree_with_one_at_a_time(seed):
    rng = np.random.default_rng(seed)
    shapes2 = [(9, 9), (9, 17), (17, 9)]
    faces = [ndimage.gaussian_filter(rng.normal(size=shapes2[k % 3]), 1.5) + 0.05 for k in range(60)]
    centres = [(v.shape[0] // 2, v.shape[1] // 2) for v in faces]
    want = [_face_reference(v, c) for v, c in zip(faces, centres)]
    assert 0 < sum(want) < len(want)  # both outcomes occur
    assert faces_ok(faces, centres).tolist() == want
    shapes3 = [(9, 9, 9), (9, 17, 9), (17, 9, 9)]
    cells = [ndimage.gaussian_filter(rng.normal(size=shapes3[k % 3]), 1.2) + 0.1 for k in range(45)]
    # a pocket: an outside bubble in an inside cube (one inside component, not a valid cell)
    pocket = np.ones((9, 9, 9))
    pocket[4, 4, 4] = -1.0
    cells.append(pocket)
    want = [_cell_reference(v) for v in cells]
    assert not want[-1] and _cell_reference(np.ones((9, 9, 9)))
    assert 0 < sum(want) < len(want)
    assert cells_ok(cells).tolist() == want
