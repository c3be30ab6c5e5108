"""Spline kernel: evaluation, refinement, elevation, extraction, restriction, validation."""

import numpy as np
import pytest
import scipy.sparse as sp
from hypothesis import given, settings, strategies as st

from geometry import BSpline, SplineError, SplineFunction, knots as kn
from helpers import random_points, random_spline, rel_err

dims = st.integers(1, 3)
seeds = st.integers(0, 2**32 - 1)
FAST = settings(max_examples=25, deadline=None)


@FAST
@given(seed=seeds, dim=dims, rational=st.booleans())
def test_partition_of_unity(seed, dim, rational):
    rng = np.random.default_rng(seed)
    s = random_spline(rng, dim)
    # a spline whose coefficients are all 1 is the constant 1 (sum of basis functions)
    one = SplineFunction(s.degrees, s.knots, np.ones(s.shape + (1,)), s.weights if rational else None)
    x = random_points(rng, s, 500)
    assert np.abs(one(x) - 1.0).max() < 1e-13


def test_basis_functions_match_scipy_single_basis():
    from scipy.interpolate import BSpline as SciB

    rng = np.random.default_rng(0)
    for p in range(1, 6):
        U = np.r_[np.zeros(p + 1), [0.2, 0.5, 0.5, 0.7], np.ones(p + 1)]
        n = len(U) - p - 1
        x = rng.random(300)
        B = kn.basis_matrix(U, p, x).toarray()
        D = kn.basis_matrix(U, p, x, nder=2).toarray()
        for j in range(n):
            c = np.zeros(n); c[j] = 1
            ref = SciB(U, c, p)
            assert np.abs(B[:, j] - ref(x)).max() < 1e-13
            if p >= 2:
                assert np.abs(D[:, j] - ref(x, 2)).max() < 1e-9 * max(1, np.abs(ref(x, 2)).max())


@FAST
@given(seed=seeds, dim=dims, rational=st.booleans())
def test_derivatives_against_finite_differences(seed, dim, rational):
    rng = np.random.default_rng(seed)
    s = random_spline(rng, dim, rational=rational, channels=("k",), max_p=4)
    h = 1e-6
    x = 0.1 + 0.8 * rng.random((50, dim))
    D = s.derivatives(x, 2)
    for k in range(dim):
        e = np.zeros(dim); e[k] = h
        fd = (s(x + e) - s(x - e)) / (2 * h)
        a = tuple(int(i == k) for i in range(dim))
        # away from knots the spline is smooth; skip points whose stencil straddles a knot
        near = np.any(np.abs(x[:, k][:, None] - s.knots[k][None, :]) < 2 * h, axis=1)
        assert np.abs(D[a][~near] - fd[~near]).max() < 1e-5 * max(1, np.abs(fd).max())
        fd2 = (s(x + e) - 2 * s(x) + s(x - e)) / h**2
        a2 = tuple(2 * int(i == k) for i in range(dim))
        assert np.abs(D[a2][~near] - fd2[~near]).max() < 2e-2 * max(1, np.abs(fd2).max())
    if dim >= 2:  # mixed second derivative
        e0, e1 = np.eye(dim)[0] * 1e-4, np.eye(dim)[1] * 1e-4
        fdm = (s(x + e0 + e1) - s(x + e0 - e1) - s(x - e0 + e1) + s(x - e0 - e1)) / (4e-8)
        a = (1, 1) + (0,) * (dim - 2)
        near = np.any(np.abs(x[:, :2, None] - np.stack([np.pad(s.knots[0], (0, 40), constant_values=9)[:40], np.pad(s.knots[1], (0, 40), constant_values=9)[:40]])[None]) < 2e-4, axis=(1, 2))
        assert np.abs(D[a][~near] - fdm[~near]).max() < 1e-3 * max(1, np.abs(fdm).max())


@pytest.mark.slow
@pytest.mark.parametrize("dim", [1, 2, 3])
@pytest.mark.parametrize("rational", [False, True])
@pytest.mark.parametrize("p", [1, 2, 3, 4, 5])
def test_knot_insertion_elevation_extraction_exact(dim, rational, p):
    rng = np.random.default_rng(100 * dim + 10 * p + rational)
    degrees = tuple([p] + list(rng.integers(1, 6, dim - 1)))
    s = random_spline(rng, dim, degrees=degrees, rational=rational, channels=("k", "rho"), n_inner_max=2)
    x = random_points(rng, s, 1000)
    ref = s(x)
    # knot insertion: several knots, with repeats, and the matrix is exact
    vals = np.r_[rng.uniform(0.01, 0.99, 2), 0.5, 0.5]
    s2, R = s.insert_knots(0, vals)
    assert rel_err(s2(x), ref) < 1e-12
    assert sp.issparse(R) and R.shape == (s2.shape[0], s.shape[0])
    moved = np.moveaxis(s.homogeneous, 0, 0).reshape(s.shape[0], -1)
    assert np.abs(R @ moved - s2.homogeneous.reshape(s2.shape[0], -1)).max() == 0.0
    # degree elevation in every direction
    s3 = s
    for k in range(dim):
        s3 = s3.elevate(k, 1 + k % 2)
    assert s3.degrees == tuple(pk + 1 + k % 2 for k, pk in enumerate(s.degrees))
    assert rel_err(s3(x), ref) < 1e-12
    # Bezier extraction: evaluate each element's Bernstein patch at its own points
    from geometry import bernstein

    patches, boxes = s.bezier_patches()
    bp = [s.breakpoints(k) for k in range(dim)]
    e = np.stack([np.clip(np.searchsorted(bp[k], x[:, k], "right") - 1, 0, len(bp[k]) - 2) for k in range(dim)], 1)
    lo = np.stack([bp[k][e[:, k]] for k in range(dim)], 1)
    hi = np.stack([bp[k][e[:, k] + 1] for k in range(dim)], 1)
    local = (x - lo) / (hi - lo)
    hp, _ = s.bezier_patches(homogeneous=True)
    vals_b = np.empty_like(ref)
    for i in range(len(x)):  # test-side reference loop (small N), not library code
        h = bernstein.evaluate(hp[tuple(e[i])], local[i : i + 1], dim)[0]
        vals_b[i] = h[:-1] / h[-1] if rational else h
    assert rel_err(vals_b, ref) < 1e-12
    assert patches.shape[:dim] == s.n_elements and boxes.shape == s.n_elements + (dim, 2)


@pytest.mark.parametrize("dim", [1, 2, 3])
def test_extraction_operators_reproduce_bezier_coefficients(dim):
    rng = np.random.default_rng(dim)
    s = random_spline(rng, dim, rational=False)
    patches, _ = s.bezier_patches()
    C, first = s.extraction_operators(0)
    cp = s.control_points
    for e in range(C.shape[0]):
        local = np.tensordot(C[e], cp[first[e] : first[e] + s.degrees[0] + 1], axes=(1, 0))
        sl = (e,) + (0,) * (dim - 1)  # first element in other directions
        # compare after extracting the other directions the same way
        other = local
        for k in range(1, dim):
            Ck, fk = s.extraction_operators(k)
            other = np.moveaxis(np.tensordot(Ck[0], np.moveaxis(other, k, 0)[fk[0] : fk[0] + s.degrees[k] + 1], axes=(1, 0)), 0, k)
        assert np.abs(other - patches[sl]).max() < 1e-13


@FAST
@given(seed=seeds, dim=dims, rational=st.booleans())
def test_split_extract_reverse_permute(seed, dim, rational):
    rng = np.random.default_rng(seed)
    s = random_spline(rng, dim, rational=rational, channels=("k",))
    x = random_points(rng, s, 300)
    t = float(rng.uniform(0.2, 0.8))
    left, right = s.split(0, t)
    xl = x.copy(); xl[:, 0] *= t
    assert rel_err(left(xl), s(xl)) < 1e-12
    lo = rng.uniform(0, 0.9, dim)
    box = np.stack([lo, lo + rng.uniform(0.05, 1.0 - lo)], axis=1)
    sub = s.extract(box)
    xs = box[:, 0] + x * (box[:, 1] - box[:, 0])
    assert rel_err(sub(xs), s(xs)) < 1e-12
    r = s.reverse(0)
    xr = x.copy(); xr[:, 0] = 1 - xr[:, 0]
    assert rel_err(r(xr), s(x)) < 1e-13
    perm = list(rng.permutation(dim))
    q = s.permute(perm)
    # permute: q(y) = s(x) where y[j] = x[perm[j]]
    assert rel_err(q(x[:, perm]), s(x)) < 1e-13


def test_boundary_faces_and_edges_keep_channels():
    rng = np.random.default_rng(5)
    s = random_spline(rng, 3, rational=True, channels=("k",))
    x = rng.random((200, 2))
    for name, (k, side) in {"umin": (0, 0), "umax": (0, 1), "vmin": (1, 0), "vmax": (1, 1), "wmin": (2, 0), "wmax": (2, 1)}.items():
        f = s.boundary(name)
        assert f.dim == 2 and f.channels == ("k",)
        full = np.insert(x, k, float(side), axis=1)
        assert rel_err(f(x), s(full)) < 1e-13
    edge = s.boundary("umin").boundary("vmax")
    t = rng.random((50, 1))
    assert rel_err(edge(t), s(np.column_stack([np.zeros(50), t, np.ones(50)]))) < 1e-13


def test_affine_map_and_channels():
    rng = np.random.default_rng(6)
    s = random_spline(rng, 3, rational=True, channels=("k",))
    A = rng.normal(size=(3, 3)); b = rng.normal(size=3)
    x = random_points(rng, s, 200)
    t = s.affine(A, b)
    assert rel_err(t(x)[:, :3], s(x)[:, :3] @ A.T + b) < 1e-12
    assert np.array_equal(t(x)[:, 3], s(x)[:, 3])
    s2 = s.with_channel("rho", 7.0)
    assert s2.channels == ("k", "rho") and np.allclose(s2(x)[:, 4], 7.0)
    assert s2.without_channels("k").channels == ("rho",)
    with pytest.raises(SplineError, match="unknown channel 'q'"):
        s.channel("q")


def test_grid_evaluation_matches_scattered():
    rng = np.random.default_rng(7)
    s = random_spline(rng, 3, rational=True, channels=("k",))
    axes = [np.sort(rng.random(n)) for n in (5, 6, 7)]
    G = s.evaluate_grid(axes)
    X = np.stack(np.meshgrid(*axes, indexing="ij"), -1).reshape(-1, 3)
    assert rel_err(G.reshape(-1, 4), s(X)) < 1e-13


def test_refine_bisects_spans_and_returns_matrices():
    rng = np.random.default_rng(8)
    s = random_spline(rng, 2, degrees=(2, 3))
    r, Rs = s.refine(2)
    assert r.n_elements == tuple(4 * n for n in s.n_elements)
    x = random_points(rng, s, 100)
    assert rel_err(r(x), s(x)) < 1e-12
    assert Rs[0].shape == (r.shape[0], s.shape[0])


# ----------------------------------------------------------------- validation
U2 = [0, 0, 0, 1, 1, 1]


@pytest.mark.parametrize(
    "kwargs, match",
    [
        (dict(degrees=(2,), knots=[[0, 0, 0, 1, 1]], cp=np.zeros((3, 3))), "needs n \\+ p \\+ 1"),
        (dict(degrees=(2,), knots=[[0, 0, 0, 0.7, 0.5, 1, 1, 1]], cp=np.zeros((5, 3))), "decreases at index 4"),
        (dict(degrees=(2,), knots=[[0, 0, 0.1, 0.5, 1, 1, 1]], cp=np.zeros((4, 3))), "not open"),
        (dict(degrees=(1,), knots=[[0, 0, 0.5, 0.5, 0.5, 1, 1]], cp=np.zeros((5, 3))), "multiplicity 3 > degree \\+ 1 = 2"),
        (dict(degrees=(2,), knots=[[0, 0, 0, np.nan, 1, 1, 1]], cp=np.zeros((4, 3))), "non-finite"),
        (dict(degrees=(2,), knots=[U2], cp=np.zeros((3, 3)), w=[1, -1, 1]), "weight at \\(1,\\) must be finite and positive"),
        (dict(degrees=(2,), knots=[U2], cp=[[0, 0, 0], [np.inf, 0, 0], [1, 1, 1]]), "control point \\(1,\\) component 0 is not finite"),
        (dict(degrees=(2,), knots=[U2], cp=np.zeros((3, 2))), "shape \\(n_1, ..., n_d, 3\\)"),
        (dict(degrees=(0,), knots=[[0, 1]], cp=np.zeros((1, 3))), "degree must be an integer >= 1"),
        (dict(degrees=(2, 2), knots=[U2], cp=np.zeros((3, 3))), "2 degrees given"),
    ],
)
def test_invalid_input_raises_spline_error(kwargs, match):
    with pytest.raises(SplineError, match=match):
        BSpline(kwargs["degrees"], kwargs["knots"], kwargs["cp"], kwargs.get("w"))


def test_invalid_operations_raise_spline_error():
    s = BSpline((2,), [U2], np.zeros((3, 3)))
    with pytest.raises(SplineError, match="outside the domain"):
        s([[1.5]])
    with pytest.raises(SplineError, match="strictly inside"):
        s.insert_knots(0, [1.0])
    with pytest.raises(SplineError, match="multiplicity degree \\+ 1"):
        s.insert_knots(0, [0.5, 0.5, 0.5, 0.5])
    with pytest.raises(SplineError, match="direction must be"):
        s.elevate(1)
    with pytest.raises(SplineError, match="unknown boundary|curve's boundary"):
        s.boundary("umin")
    with pytest.raises(SplineError, match="channel names must be unique"):
        BSpline((2,), [U2], np.zeros((3, 5)), channels=("k", "k"))


@pytest.mark.parametrize("seed", range(4))
def test_compiled_scattered_evaluation_matches_scipy(seed):
    pytest.importorskip("numba", reason="the compiled kernel needs numba (the test extra installs it)")
    from geometry.compiled import _fast
    rng = np.random.default_rng(seed)
    s = random_spline(rng, 3, rational=seed % 2 == 1, channels=("k",) * (seed % 2), max_p=4)
    n = _fast.MIN_POINTS + 7
    x = rng.random((n, 3))
    x[:8] = [[0, 0, 0], [1, 1, 1], [1, 0, 1], [0, 1, 0]] + [list(rng.random(3)) for _ in range(4)]
    # knots themselves (span boundaries, multiple knots included)
    for k in range(3):
        inner = np.unique(s.knots[k])
        x[8 : 8 + len(inner), k] = inner
    fast = _fast.evaluate(s.knots, s.degrees, s.homogeneous, x)
    ref = s._hom_eval(s._check_params(x), (0, 0, 0))  # SciPy's NdBSpline
    assert fast is not None and fast.shape == ref.shape
    assert np.abs(fast - ref).max() <= 1e-13 * max(1.0, np.abs(ref).max())
    assert _fast.evaluate(s.knots, s.degrees, s.homogeneous, x[:100]) is None  # small sets stay with SciPy
    # values and first derivatives in one pass (right-hand derivatives at knots, as SciPy's)
    eye = [(1, 0, 0), (0, 1, 0), (0, 0, 1)]
    D = s._derivs(s._check_params(x), [(0, 0, 0)] + eye)  # SciPy's NdBSpline, quotient rule when rational
    vals, J = s.value_and_jacobian(x)
    scale = max(1.0, max(np.abs(D[a]).max() for a in eye))
    assert np.abs(vals - D[(0, 0, 0)]).max() <= 1e-13 * max(1.0, np.abs(D[(0, 0, 0)]).max())
    assert np.abs(J - np.stack([D[a] for a in eye], -1)).max() <= 1e-12 * scale
    assert np.abs(s.jacobian(x) - np.stack([D[a] for a in eye], -1)).max() <= 1e-12 * scale
    # the derivatives one array per direction, all columns or the first three (a map's geometry), from the kernel
    # for any number of points when asked (compiled=True), or from SciPy (compiled=False)
    for compiled, rows in ((None, slice(None)), (True, slice(0, 50)), (False, slice(0, 50))):
        v3, d3 = s.value_and_derivatives(x[rows], compiled=compiled, columns=3)
        assert len(d3) == 3 and all(d.shape == (len(v3), 3) for d in d3)
        assert np.abs(v3 - vals[rows]).max() <= 1e-13 * max(1.0, np.abs(vals).max())
        assert max(np.abs(d - J[rows][:, :3, k]).max() for k, d in enumerate(d3)) <= 1e-12 * scale
    assert [d.shape[1] for d in s.value_and_derivatives(x[:50], compiled=True)[1]] == [J.shape[1]] * 3
    # small sets stay with SciPy and agree
    v2, J2 = s.value_and_jacobian(x[:100])
    assert np.abs(v2 - vals[:100]).max() <= 1e-13 * max(1.0, np.abs(vals).max())
    assert np.abs(J2 - J[:100]).max() <= 1e-12 * scale
    # bad points in a large set: the kernel declines and the usual checks name them
    for bad, msg in ((np.nan, "non-finite"), (1.5, "outside the domain")):
        y = x.copy()
        y[11, seed % 3] = bad
        with pytest.raises(SplineError, match=msg):
            s.evaluate(y)
        with pytest.raises(SplineError, match=msg):
            s.jacobian(y)
