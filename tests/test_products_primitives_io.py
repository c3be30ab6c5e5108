"""Exact products, primitives, save/load, command line."""

import subprocess
import sys
from math import pi

import numpy as np
import pytest
from commands import iga_command
from hypothesis import given, settings, strategies as st

import geometry
from geometry import BSpline, SplineError, SplineFunction, bernstein, multiply, primitives as pr
from helpers import random_points, random_spline, rel_err


@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), dim=st.integers(1, 3), rf=st.booleans(), rg=st.booleans(), vec=st.booleans())
def test_bspline_products_equal_pointwise_products(seed, dim, rf, rg, vec):
    rng = np.random.default_rng(seed)
    f = random_spline(rng, dim, rational=rf, max_p=3, n_inner_max=2)
    g = random_spline(rng, dim, rational=rg, max_p=3, n_inner_max=2)
    F = SplineFunction(f.degrees, f.knots, f.coefficients[..., :1], f.weights)  # scalar
    G = SplineFunction(g.degrees, g.knots, g.coefficients if vec else g.coefficients[..., :1], g.weights)
    h = multiply(F, G)
    x = random_points(rng, f, 1000)
    assert h.degrees == tuple(a + b for a, b in zip(f.degrees, g.degrees))
    assert rel_err(h(x), F(x) * G(x)) < 1e-12


def test_bezier_products_equal_pointwise_products():
    rng = np.random.default_rng(3)
    a = rng.normal(size=(4, 3, 4))  # batch 4, degrees (2, 3)
    b = rng.normal(size=(4, 5, 2))  # batch 4, degrees (4, 1)
    c = bernstein.multiply(a, b, 2)
    assert c.shape == (4, 7, 5)
    x = rng.random((300, 2))
    for i in range(4):
        va = bernstein.evaluate(a[i][..., None], x, 2)[:, 0]
        vb = bernstein.evaluate(b[i][..., None], x, 2)[:, 0]
        vc = bernstein.evaluate(c[i][..., None], x, 2)[:, 0]
        assert np.abs(vc - va * vb).max() < 1e-12 * max(1, np.abs(va * vb).max())


def test_product_continuity_is_the_minimum_of_the_factors():
    U = np.array([0, 0, 0, 0, 0.3, 0.3, 0.6, 1, 1, 1, 1.0])  # cubic: C1 at 0.3, C2 at 0.6
    V = np.array([0, 0, 0, 0.5, 1, 1, 1.0])  # quadratic: C1 at 0.5
    f = SplineFunction((3,), [U], np.ones((7, 1)))
    g = SplineFunction((2,), [V], np.ones((4, 1)))
    h = multiply(f, g)
    vals, mults = np.unique(h.knots[0], return_counts=True)
    assert dict(zip(vals.tolist(), mults.tolist())) == {0.0: 6, 0.3: 4, 0.5: 4, 0.6: 3, 1.0: 6}


def test_product_rejects_mismatched_factors():
    f = SplineFunction((1,), [[0, 0, 1, 1]], np.ones((2, 2)))
    g = SplineFunction((1,), [[0, 0, 2, 2]], np.ones((2, 1)))
    with pytest.raises(SplineError, match="share the parameter domain"):
        multiply(f, g)
    h = SplineFunction((1,), [[0, 0, 1, 1]], np.ones((2, 3)))
    with pytest.raises(SplineError, match="cannot multiply 2 components by 3"):
        multiply(f, h)


def test_annulus_exact_and_polynomial():
    rng = np.random.default_rng(1)
    x = rng.random((2000, 3))
    a = pr.annulus(0.5, 1.0, 2.0, angle=1.5 * pi, elements=(2, 3, 1), channels={"k": 205.0})
    v = a(x)
    r_expect = 0.5 + 0.5 * x[:, 1]
    assert np.abs(np.hypot(v[:, 0], v[:, 1]) - r_expect).max() < 1e-14
    assert np.allclose(v[:, 3], 205.0)
    p = pr.annulus(0.5, 1.0, 2.0, angle=1.5 * pi, exact=False)
    assert not p.is_rational
    err = np.abs(np.hypot(*p(x)[:, :2].T) - r_expect).max()
    assert 1e-5 < err < 3e-4  # the documented cubic-arc error, not exact


def test_tapered_is_exact_and_twisted_keeps_z():
    rng = np.random.default_rng(2)
    x = rng.random((1000, 3))
    a = pr.annulus(0.5, 1.0, 1.0)
    t = pr.tapered(a, 0.5)
    r = np.hypot(*t(x)[:, :2].T)
    assert np.abs(r - (0.5 + 0.5 * x[:, 1]) * (1 - 0.5 * x[:, 2])).max() < 1e-14
    tw = pr.twisted(pr.annulus(0.5, 1.0, 1.0, exact=False), 0.7)
    assert np.abs(tw(x)[:, 2] - x[:, 2]).max() < 1e-14
    top = tw.evaluate(np.array([[0.0, 0.0, 1.0]]))[0]
    assert abs(np.arctan2(top[1], top[0]) - 0.7) < 1e-12


def test_volume_constructors():
    rng = np.random.default_rng(4)
    x = rng.random((500, 3))
    b = pr.box((2, 3, 4), (1, 1, 1), degrees=(2, 3, 1), elements=(2, 1, 3), channels={"k": 1.0})
    assert rel_err(b(x)[:, :3], 1 + x * [2, 3, 4]) < 1e-14
    # Boolean sum of the six faces of a curved polynomial volume reproduces it
    c = pr.annulus(0.5, 1.0, 1.0, exact=False, elements=(2, 1, 1)).elevate(1, 1).elevate(2, 2)
    faces = {n: c.boundary(n) for n in geometry.FACE_NAMES}
    assert rel_err(pr.coons_volume(faces)(x), c(x)) < 1e-12
    bad = dict(faces, umax=faces["umax"].translate([0, 0, 0.1]))
    with pytest.raises(SplineError, match="do not agree on their shared edge"):
        pr.coons_volume(bad)
    # extrusion, ruled volume, skinning, revolution
    base = pr.annulus(0.5, 1.0, 1.0).boundary("wmin")
    e = pr.extrude(base, [0, 0, 3])
    assert np.abs(e(x)[:, 2] - 3 * x[:, 2]).max() < 1e-14
    ruled = pr.ruled(base, base.scale([2, 2, 1]).translate([0, 0, 1]))
    assert np.abs(np.hypot(*ruled(x)[:, :2].T) - (0.5 + 0.5 * x[:, 1]) * (1 + x[:, 2])).max() < 1e-13
    sk = pr.skin([base, base.translate([0, 0, 1]), base.translate([0, 0, 2]), base.translate([0, 0, 3])])
    assert sk.degrees[2] == 3 and np.abs(sk(x)[:, 2] - 3 * x[:, 2]).max() < 1e-13
    prof = BSpline((1, 1), [[0, 0, 1, 1]] * 2, np.array([[[0.5, 0, 0], [0.5, 0, 1]], [[1, 0, 0], [1, 0, 1]]]))
    rv = pr.revolve(prof, pi)
    v = rv(x)
    assert np.abs(np.hypot(v[:, 0], v[:, 1]) - (0.5 + 0.5 * x[:, 1])).max() < 1e-14
    with pytest.raises(SplineError, match="xz half-plane"):
        pr.revolve(prof.translate([0, 1, 0]))


def test_save_load_round_trip_exact(tmp_path):
    rng = np.random.default_rng(9)
    items = [random_spline(rng, d, rational=bool(d % 2), channels=("k",) * (d > 1)) for d in (1, 2, 3)]
    geometry.save_all(tmp_path / "s.npz", items)
    back = geometry.load_all(tmp_path / "s.npz")
    for a, b in zip(items, back):
        assert a.degrees == b.degrees and a.channels == b.channels
        assert all(np.array_equal(u, v) for u, v in zip(a.knots, b.knots))
        assert np.array_equal(a.control_points, b.control_points)
        assert (a.weights is None and b.weights is None) or np.array_equal(a.weights, b.weights)
    assert not list(tmp_path.glob(".s.npz*")), "temporary file left behind"


def test_save_load_errors(tmp_path):
    s = pr.box()
    with pytest.raises(SplineError, match="does not exist; create it first"):
        geometry.save(tmp_path / "missing" / "x.npz", s)
    with pytest.raises(SplineError, match="does not exist"):
        geometry.load(tmp_path / "nothing.npz")
    (tmp_path / "junk.npz").write_bytes(b"not a zip")
    with pytest.raises(SplineError, match="not an .npz archive"):
        geometry.load(tmp_path / "junk.npz")
    np.savez(tmp_path / "other.npz", a=np.zeros(3))
    with pytest.raises(SplineError, match="not an iga-toolkit spline file"):
        geometry.load(tmp_path / "other.npz")


@pytest.mark.slow
def test_cli_help_and_info(tmp_path):
    out = subprocess.run([sys.executable, "-m", "iga", "--help"], capture_output=True, text=True)
    assert out.returncode == 0
    for word in ("demo", "run", "info"):
        assert word in out.stdout
    geometry.save(tmp_path / "b.npz", pr.box(channels={"k": 3.0}))
    out = iga_command("info", tmp_path / "b.npz")
    assert out.returncode == 0 and "channels=['k']" in out.stdout
    out = iga_command("info", tmp_path / "none.npz")
    assert out.returncode == 1 and "does not exist" in out.stderr and "Traceback" not in out.stderr


def test_point_inversion_recovers_parameters_and_reuses_its_start_grid_while_the_spline_lives():
    import gc

    from geometry.maps import inversion

    rng = np.random.default_rng(7)
    D = pr.twisted(pr.box((1.0, 2.0, 1.0), degrees=(2, 2, 2), elements=(3, 2, 2)), 0.6, axis_point=(0.5, 1.0))
    t = rng.uniform(D.domain[:, 0], D.domain[:, 1], (50, 3))
    x = D.evaluate(t)[:, :3]
    first = inversion.invert(D, x)
    assert first.inside.all() and np.abs(first.params - t).max() < 1e-9  # a regular map: the parameters
    assert D in inversion._STARTS
    again = inversion.invert(D, x[::-1])  # the kept start grid gives the same answers
    assert np.array_equal(again.params, first.params[::-1])
    # the compiled Newton evaluations (numba, where installed) find the same parameters as SciPy's
    many = rng.uniform(D.domain[:, 0], D.domain[:, 1], (3000, 3))
    xm = D.evaluate(many)[:, :3]
    fast, slow = inversion.invert(D, xm, compiled=True), inversion.invert(D, xm, compiled=False)
    assert np.abs(fast.params - slow.params).max() < 1e-12 and np.abs(fast.params - many).max() < 1e-9
    # a point off a surface: the nearest point, its distance, and not "inside"
    S = D.boundary("wmax")
    off = S.evaluate(np.array([[0.3, 0.4]]))[:, :3] + np.array([[0.0, 0.0, 0.25]])
    r = inversion.invert(S, off)
    assert not r.inside[0] and 0 < r.distance[0] <= 0.25 + 1e-12
    n_before = len(inversion._STARTS)
    del D, S, first, again, r
    gc.collect()
    assert len(inversion._STARTS) <= n_before - 2  # entries die with their splines


def test_element_boxes_hold_every_element_and_outside_points_stop_inverting_once_they_stall():
    from geometry.maps import inversion
    from geometry.shapes.examples import cylinder

    rng = np.random.default_rng(4)
    D = cylinder(1.0, 4.0, 0)
    for S in (D, pr.annulus(1.0, 2.0, 1.0).refine(2)[0]):  # polynomial, and rational with 64 elements
        boxes = S.element_boxes()
        bps = [S.breakpoints(k) for k in range(3)]
        assert len(boxes) == int(np.prod(S.n_elements))
        for e, idx in enumerate(np.ndindex(*S.n_elements)):  # C order, as documented
            lo, hi = [bps[k][idx[k]] for k in range(3)], [bps[k][idx[k] + 1] for k in range(3)]
            x = S.evaluate(rng.uniform(lo, hi, (300, 3)))[:, :3]
            assert np.all(x >= boxes[e, :, 0] - 1e-12) and np.all(x <= boxes[e, :, 1] + 1e-12)
        assert np.all(boxes[:, :, 1] - boxes[:, :, 0] <= np.ptp(S.points.reshape(-1, 3), axis=0) + 1e-12)
    # points around the cylinder: the inside ones found exactly; the outside ones, whose clipped iterates
    # only crept along the boundary for all 40 iterations, stop within a few
    lo, hi = D.bounding_box().T
    pts = rng.uniform(lo - 0.5, hi + 0.5, (2000, 3))
    t_in = rng.uniform(D.domain[:, 0], D.domain[:, 1], (300, 3))
    pts[:300] = D.evaluate(t_in)[:, :3]
    calls = []
    newton = inversion.newton_inverse

    def counting(fn, *args, **kwargs):
        return newton(lambda t: calls.append(len(t)) or fn(t), *args, **kwargs)

    inversion.newton_inverse = counting
    try:
        r = inversion.invert(D, pts)
    finally:
        inversion.newton_inverse = newton
    assert r.inside[:300].all() and np.abs(D.evaluate(r.params[:300])[:, :3] - pts[:300]).max() < 1e-10
    assert sum(calls) < 6 * len(pts)  # 11.6 evaluations per point when they crept for all 40 iterations


@pytest.mark.parametrize("allow_zeros,depth", [(False, 9), (True, 6)])
def test_regularity_proofs_together_equal_the_proofs_alone(allow_zeros, depth):
    from geometry.maps.regularity import check_regular, check_regular_many
    from helpers import random_spline as rs

    rng = np.random.default_rng(11)
    box = pr.box(degrees=(2, 2, 2), elements=(2, 3, 2))
    splines = [pr.twisted(box, a, axis_point=(0.5, 0.5)) for a in (0.2, 1.1, 2.9)]  # regular, then strongly twisted
    splines += [rs(rng, 3, degrees=(2, 2, 2), channels=("k",) * (i % 2)) for i in range(6)]  # folds, some channels
    splines += [pr.annulus(1.0, 2.0, 1.0), rs(rng, 3, degrees=(2, 1, 3), rational=True), splines[0]]
    alone = [check_regular(s, depth, allow_zeros) for s in splines]
    together = check_regular_many(splines, depth, allow_zeros)
    assert {r.status for r in alone} >= {"regular", "singular"}  # both verdicts occur in the set
    for a, b in zip(alone, together):
        assert (a.status, a.orientation, a.depth, a.message) == (b.status, b.orientation, b.depth, b.message)
        assert np.allclose(a.jacobian_bounds, b.jacobian_bounds, rtol=1e-12, atol=0)  # (products batched: rounding)
        order = lambda B: B[np.lexsort(B.reshape(len(B), B.shape[1] * B.shape[2]).T)]  # noqa: E731
        assert np.array_equal(order(a.boxes), order(b.boxes))


def test_concatenated_ranges_equal_the_loop_of_aranges():
    from geometry.ranges import concatenated_ranges

    rng = np.random.default_rng(9)
    for _ in range(20):
        starts, counts = rng.integers(-50, 50, 30), rng.integers(0, 6, 30)
        loop = np.concatenate([np.arange(s, s + c) for s, c in zip(starts, counts)] + [np.zeros(0, np.int64)])
        assert np.array_equal(concatenated_ranges(starts, counts), loop)
    assert np.array_equal(concatenated_ranges(7, [2, 1]), [7, 8, 7])
    assert concatenated_ranges([], []).shape == (0,)
