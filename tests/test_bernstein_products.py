"""The compiled Bernstein product (geometry.compiled._bernstein_kernels) and the high-degree composition built on it."""

import numpy as np
import pytest

from geometry import BSpline, bernstein as bz, compose_many, knots as kn

pytestmark = pytest.mark.all_threads  # the compiled kernels on every thread: a race would show

pytest.importorskip("numba", reason="the compiled product needs numba (test extra)")


@pytest.mark.parametrize("a_shape, b_shape, ndim", [
    ((40, 1, 10), (40, 3, 19), 1),
    ((6, 1, 10, 10), (6, 3, 19, 19), 2),  # the last product of a (27, 27) composition
    ((5, 3, 4), (4, 1, 3, 6), 2),  # batch axes broadcast: (4, 5)
    ((3, 2, 5, 4, 3), (3, 1, 2, 6, 4), 3),
])
def test_compiled_bernstein_product_equals_numpy_and_direct_evaluation(a_shape, b_shape, ndim):
    rng = np.random.default_rng(len(a_shape) + ndim)
    a, b = rng.standard_normal(a_shape), rng.standard_normal(b_shape)
    fast, ref = bz.multiply(a, b, ndim, compiled=True), bz.multiply(a, b, ndim, compiled=False)
    assert fast.shape == ref.shape
    assert np.abs(fast - ref).max() <= 1e-13 * np.abs(ref).max()
    # exact: the product's polynomial is the product of the factors' at random points (one batch entry)
    x = rng.random((30, ndim))
    batch, lead = fast.shape[:-ndim], (-1,) * (fast.ndim - ndim)  # the last batch entry

    def at_x(c):  # values at x of one batch entry of c
        return bz.evaluate(np.broadcast_to(c, batch + c.shape[c.ndim - ndim :])[lead][..., None], x, ndim)

    fa, fb, fp = at_x(a), at_x(b), at_x(fast)
    assert np.abs(fp - fa * fb).max() <= 1e-12 * np.abs(fa * fb).max()


def _map_and_surface(rng):
    """A tricubic map with 3 x 2 x 4 knot spans and a bicubic surface tile of 2 x 3 spans."""
    U = [kn.uniform_knots(3, n) for n in (3, 2, 4)]
    g = np.stack(np.meshgrid(*[kn.greville(u, 3) for u in U], indexing="ij"), -1)
    D = BSpline((3, 3, 3), U, g + 0.04 * rng.standard_normal(g.shape))
    s = np.stack(np.meshgrid(kn.greville(kn.uniform_knots(3, 2), 3), kn.greville(kn.uniform_knots(3, 3), 3),
                             indexing="ij"), -1)
    cp = np.concatenate([s, 0.5 + 0.2 * np.sin(3 * s[..., :1])], -1)
    return D, BSpline((3, 3), [kn.uniform_knots(3, 2), kn.uniform_knots(3, 3)], cp)


def test_compiled_products_compose_high_degree_surfaces_across_pieces_exactly(monkeypatch):
    # placements in different pieces of the map share one batch (per-placement pieces) and the (27, 27)
    # products run compiled: every composed surface equals D(A S + b) at random points, and the control
    # points equal the NumPy path's
    rng = np.random.default_rng(7)
    D, S = _map_and_surface(rng)
    P = []
    for e in [(0, 0, 0), (1, 1, 2), (2, 0, 3), (2, 1, 1), (0, 1, 3)]:
        lo = np.array([D.breakpoints(k)[e[k]] for k in range(3)])
        hi = np.array([D.breakpoints(k)[e[k] + 1] for k in range(3)])
        M = np.zeros((3, 4))
        M[:, :3] = np.diag(hi - lo) * rng.uniform(0.6, 0.95)
        M[:, 3] = lo + 0.02 * (hi - lo)
        P.append(M)
    fast = compose_many(D, S, np.array(P))
    assert fast[0].degrees == (27, 27)
    st = rng.random((200, 2))
    for C, M in zip(fast, P):
        y = S.evaluate(st)[:, :3] @ M[:, :3].T + M[:, 3]
        direct = D.evaluate(y)[:, :3]
        assert np.abs(C.evaluate(st)[:, :3] - direct).max() <= 1e-12 * np.abs(direct).max()
    monkeypatch.setattr(bz, "COMPILED_MACS", 1 << 62)  # every product in NumPy
    for C, R in zip(fast, compose_many(D, S, np.array(P))):
        assert np.abs(C.control_points - R.control_points).max() <= 1e-12 * np.abs(R.control_points).max()


def test_the_bezier_to_bspline_matrix_is_shared_and_read_only():
    U = kn.uniform_knots(27, 4)
    L = kn.bezier_to_bspline(U, 27)
    assert kn.bezier_to_bspline(U.copy(), 27) is L
    with pytest.raises(ValueError):
        L[0, 0] = 1.0
    # a left inverse of the stacked extraction: Bernstein pieces of a spline give back its coefficients
    c = np.random.default_rng(0).standard_normal(len(U) - 28)
    C, first = kn.extraction_operators(U, 27)
    stacked = np.concatenate([C[e] @ c[first[e] : first[e] + 28] for e in range(len(C))])
    assert np.abs(L @ stacked - c).max() < 1e-10 * np.abs(c).max()
