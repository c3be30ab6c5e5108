"""Lower-order approximation (Massarwi et al. 2018, Section 6.3): measured deviation, shared sides, analysis."""

import numpy as np
import pytest

import tiling
from geometry import BSpline, MultiPatch, SplineError, compose, primitives as pr
from geometry.composition.reduction import reduce_degree, reduce_model
from iga import HeatProblem
from tiling import library as L


def _curved_map():
    D = pr.box((1.0, 1.0, 2.0)).elevate_to((1, 1, 2))
    cp = D.control_points.copy()
    cp[..., 0] += 0.3 * np.sin(cp[..., 2])
    cp[..., 1] += 0.1 * cp[..., 2] ** 2
    return BSpline(D.degrees, D.knots, cp)


@pytest.fixture(scope="module")
def model():
    ms = tiling.regular(_curved_map(), L.bent_cross(), (1, 1, 2))
    ms.compose_all()
    return ms


@pytest.mark.parametrize("q", [2, 3])
def test_reported_deviation_is_the_measured_one(model, q):
    V = model.patches[0].composed
    assert V.degrees == (12, 12, 8)
    R, dev = reduce_degree(V, q, check=17)
    assert R.degrees == (q, q, q) and np.prod(R.shape) < np.prod(V.shape)
    x = np.random.default_rng(q).random((10_000, 3))
    measured = np.linalg.norm(V.evaluate(x)[:, :3] - R.evaluate(x)[:, :3], axis=1).max()
    assert 0.85 * dev <= measured <= 1.02 * dev
    # the approximation interpolates the corners exactly
    c = np.array([[0, 0, 0], [1, 1, 1], [0, 1, 0.5]], float)
    c = V.domain[:, 0] + c * (V.domain[:, 1] - V.domain[:, 0])
    assert np.abs(V.evaluate(c[:2]) - R.evaluate(c[:2])).max() < 1e-13


def test_patches_of_low_degree_are_reproduced():
    rng = np.random.default_rng(0)
    for q in (2, 3):
        b = pr.box((1.0, 2.0, 1.0)).elevate_to((q, q, q))
        cp = b.control_points + 0.05 * rng.uniform(-1, 1, b.control_points.shape)
        b = BSpline(b.degrees, b.knots, cp)
        R, dev = reduce_degree(b, q)
        assert dev < 1e-12
        x = rng.random((500, 3))
        assert np.abs(R.evaluate(x) - b.evaluate(x)).max() < 1e-12


def face_dof_grid(s: BSpline, face):
    return s.boundary(face).control_points[..., :3]


def test_shared_sides_stay_identical(model):
    for q in (2, 3):
        red, report = reduce_model(model, q)
        checked = 0
        for itf in model.interfaces:
            (pa, fa), (pb, fb) = itf.a, itf.b
            A, Bg = face_dof_grid(red[pa], fa), face_dof_grid(red[pb], fb)
            if itf.flip[0]:
                Bg = Bg[::-1]
            if itf.flip[1]:
                Bg = Bg[:, ::-1]
            if itf.swap:
                Bg = np.swapaxes(Bg, 0, 1)
            assert np.abs(A - Bg).max() < 1e-12
            checked += 1
        assert checked == len(model.interfaces) > 0
        assert report["degrees_before"] == [(12, 12, 8)] and report["control_points"][1] < report["control_points"][0]
        assert len(MultiPatch.from_splines(red).interfaces) == len(model.interfaces)


def test_the_reduced_model_is_a_heat_model_as_accurate_as_the_exact_one(model):
    """A manufactured temperature (defined everywhere) solved on the exact and on the reduced geometry."""
    T = lambda x: np.sin(x[:, 0]) * np.cos(x[:, 1]) * np.exp(0.5 * x[:, 2])  # noqa: E731
    f = lambda x: 1.75 * T(x)  # noqa: E731  (-lap T)
    exact = HeatProblem(model, source=f, degree_elevation=1).dirichlet("boundary", T).solve(tol=1e-12).l2_error(T)
    errs = []
    for q in (2, 3):
        red, _ = reduce_model(model, q)
        p = HeatProblem(MultiPatch.from_splines(red), source=f, degree_elevation=3 - q + 1)
        errs.append(p.dirichlet("boundary", T).solve(tol=1e-12).l2_error(T))
    assert 0 < exact < 1e-3 and max(errs) < 2 * exact


def test_reduction_bad_input():
    with pytest.raises(SplineError, match="2 or 3"):
        reduce_degree(pr.box(), 4)
    with pytest.raises(SplineError, match="trivariate"):
        reduce_degree(pr.box().boundary("umin"), 2)
    with pytest.raises(SplineError, match="check"):
        reduce_degree(pr.box(), 2, check=1)
    assert compose  # (imported for the module's users)


def _t2_sink():
    """The vertical T2 sink with its patches at the degree Eq. 7 gives them, 12: its box map is affine, so the
    composition keeps the tiles' degree 2 (geometry/composition/affine.py); elevated, the same functions with the
    same continuity, as a curved map would leave them (the reduction then has work to do)."""
    ms = tiling.hierarchical(pr.box((0.06, 0.06, 0.03), degrees=(2, 2, 2)), L.heat_sink_t2(), (2, 2), levels=2)
    for P, V in zip(ms.patches, ms.compose_all()):
        assert V.degrees == (2, 2, 2)
        P.set_composed(V.elevate_to((12, 12, 12)))
    return ms


def test_discontinuities_survive_the_reduction():
    """The slots of a partial discontinuity (knots of full multiplicity) stay slots: each piece is fitted to its
    own one-sided polynomial and the reduced patch keeps the knot of multiplicity q + 1."""
    V = _t2_sink().patches[0].composed  # degree 12; u = 0.5 and v = 0.5 are C^-1, w = 0.4 is C0
    rng = np.random.default_rng(3)
    for q in (2, 3):
        R, dev = reduce_degree(V, q)
        for k, mult in ((0, q + 1), (1, q + 1), (2, q)):
            vals, counts = np.unique(R.knots[k], return_counts=True)
            assert counts[1:-1].tolist() == [mult] and vals[1] == pytest.approx(0.5 if k < 2 else 0.4)
        assert dev < 1e-12  # the map is affine and the tile quadratic: the reduction is exact
        for side in (-1, 1):  # both one-sided limits at the discontinuity, at random (v, w) above the base
            x = np.column_stack([np.full(200, 0.5 + side * 1e-13), rng.random(200), 0.4 + 0.6 * rng.random(200)])
            assert np.abs(V.evaluate(x)[:, :3] - R.evaluate(x)[:, :3]).max() < 1e-12


@pytest.mark.slow
def test_a_reduced_hierarchy_keeps_its_topology_and_tags_and_solves_as_the_original():
    from geometry import reduced_model

    ms = _t2_sink()
    red, report = reduced_model(ms, 2)
    assert [i.kind for i in red.interfaces] == [i.kind for i in ms.interfaces] and red.tags == ms.tags
    assert red.face_regions == ms.face_regions and report["branch_gap"] < 1e-12
    sols = [HeatProblem(m, 50.0).neumann("branch-in", 1000.0).robin("exterior", 5.0, 30.0).solve(tol=1e-12)
            for m in (ms, red)]
    # same geometry, same spaces (the tile's degree 2 on the same knots): the same temperatures
    assert sols[1].mean_temperature() == pytest.approx(sols[0].mean_temperature(), rel=1e-10)
    assert sols[1].flux("exterior") == pytest.approx(sols[0].flux("exterior"), rel=1e-9)
    assert sols[1].info["components"]["count"] == 1 and sols[1].info["balance"]["relative_error"] < 1e-10
    # a curved map: the reduction is an approximation; its branch sides are reported apart by what it moved
    from iga.app.maps import circular_heat_sink_map

    sink = tiling.hierarchical(circular_heat_sink_map(), L.heat_sink_t1(), (4, 1), levels=2)
    red, report = reduced_model(sink, 3)
    assert 0 < report["branch_gap"] <= 2 * report["deviation"] < 1e-5
    t = [HeatProblem(m, 50.0).neumann("branch-in", 1000.0).robin("exterior", 5.0, 30.0).solve().mean_temperature()
         for m in (sink, red)]
    assert abs(t[1] - t[0]) < 1e-3 * abs(t[0])
