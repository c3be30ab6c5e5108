"""Compliance sensitivities of elastic solutions by Young's modulus (self-adjoint: no extra solve) and those of the
von Mises norm (one adjoint solve): against central differences of fresh solves, the scaling identity, and the
refusals."""

import numpy as np
import pytest

import tiling
from geometry import primitives as pr
from iga import ElasticityProblem, ProblemError
from iga.outputs import Compliance, HeatFlow, VonMisesNorm
from tiling import library


def _beam(E, **kw):
    """A twisted lattice beam of crosses clamped at one end, loaded at the other; E a channel of the map (Pa)."""
    D = pr.twisted(pr.box((0.04, 0.01, 0.01), degrees=(2, 2, 2)), 0.2, axis_point=(0.02, 0.005))
    ms = tiling.regular(D.with_channel("E", E), library.cross(0.4), (4, 1, 1))
    return ElasticityProblem(ms, youngs="E", poisson=0.3, **kw).dirichlet("umin", 0.0).traction("umax", [0, 0, -1e4])


def test_the_compliance_gradient_by_a_young_s_modulus_channel_is_its_finite_difference():
    rng = np.random.default_rng(0)
    E0 = 1e9 * (1 + rng.random((3, 3, 3)))
    s = _beam(E0).solve(solver="direct")
    g = s.gradient(Compliance(), wrt="channel:E")
    assert g.shape == E0.shape and np.all(g <= 0)  # stiffer anywhere: never more compliant
    d = rng.standard_normal(E0.shape) * 1e5
    fd = (Compliance().value(_beam(E0 + d).solve(solver="direct"))
          - Compliance().value(_beam(E0 - d).solve(solver="direct"))) / 2
    assert float(np.sum(g * d)) == pytest.approx(fd, rel=1e-6)
    # E scaled by (1 + p) everywhere scales the compliance by 1 / (1 + p): the tiles' sensitivities sum to -J
    tiles = s.gradient(Compliance(), wrt="tiles")
    assert tiles.shape == (4,)
    assert tiles.sum() == pytest.approx(-Compliance().value(s), rel=1e-10)
    patches = s.gradient(Compliance(), wrt="patches")
    assert patches.shape == (len(s.problem.model.patches),) and patches.sum() == pytest.approx(tiles.sum(), rel=1e-12)


def test_the_von_mises_norm_s_gradient_is_its_finite_difference():
    """dJ/du against differences of the output on moved displacements; dJ/dE per channel value and per tile
    (one adjoint solve) against fresh solves, with the beam's end clamped and, second, also pushed along x (a
    prescribed displacement that is not zero: the adjoint vanishes there, the gradient holds)."""
    rng = np.random.default_rng(5)
    E0 = 1e9 * (1 + rng.random((3, 3, 3)))
    out = VonMisesNorm(6)
    s = _beam(E0).solve(solver="direct", tol=1e-13)
    g = out.gradient(s)
    d, h, u = rng.standard_normal(g.shape), 1e-11, s.u.copy()  # (|u| <= 6e-5 m: a step of 1e-11 m is in the
    # quadratic regime of the difference, whose error falls 100x per decade of h)
    values = []
    for sign in (1, -1):
        s.u, s.output_values = u + sign * h * d, {}
        values.append(out.value(s))
    s.u, s.output_values = u, {}
    assert float(g @ d) == pytest.approx((values[0] - values[1]) / (2 * h), rel=1e-6)
    for pushed in (False, True):
        def solved(E, pushed=pushed):
            p = _beam(E)
            return (p.dirichlet("umax", 1e-5, components="x") if pushed else p).solve(solver="direct", tol=1e-13)

        s = solved(E0)
        dE = rng.standard_normal(E0.shape) * 1e6

        def central(h, dE=dE, solved=solved):
            return (out.value(solved(E0 + h * dE)) - out.value(solved(E0 - h * dE))) / (2 * h)

        # the clamped beam's stresses balance its load and hardly depend on E (E moved by 7e-4 of itself moves J
        # by 1.5e-6 of itself), so a central difference's round-off and truncation are both near 1e-6 of the
        # derivative; Richardson's extrapolation of two (error O(h^4)) is well below
        fd = (4 * central(0.5) - central(1.0)) / 3
        assert float(np.sum(s.gradient(out, wrt="channel:E") * dE)) == pytest.approx(fd, rel=1e-6)
        # the tiles' derivatives (a factor on E in each) sum to that of E scaled everywhere: zero for the clamped
        # beam (its stresses balance the load whatever E), not for the pushed one (its stresses scale with E)
        total = float(s.gradient(out, wrt="tiles").sum())
        assert total == pytest.approx((out.value(solved(E0 * 1.0001)) - out.value(solved(E0 * 0.9999))) / 2e-4,
                                      rel=1e-6, abs=1e-9 * out.value(s))


def test_elastic_sensitivities_refuse_what_they_do_not_cover():
    E0 = np.full((3, 3, 3), 1e9)
    s = _beam(E0).solve(solver="direct")
    with pytest.raises(ProblemError, match="Compliance"):
        s.gradient(HeatFlow("umax"), wrt="tiles")
    with pytest.raises(ProblemError, match="reads no channel 'k'"):
        s.gradient(Compliance(), wrt="channel:k")
    with pytest.raises(ProblemError, match="wrt must be"):
        s.gradient(Compliance(), wrt="wall")
    moved = _beam(E0).dirichlet("umax", 1e-4, components="x").solve(solver="direct")
    with pytest.raises(ProblemError, match="zero displacement"):
        moved.gradient(Compliance(), wrt="channel:E")
    warm = _beam(E0).thermal(10.0, 1e-5, 0.0).solve(solver="direct")
    with pytest.raises(ProblemError, match="thermal"):
        warm.gradient(Compliance(), wrt="tiles")
    with pytest.raises(ProblemError, match="thermal"):
        warm.gradient(VonMisesNorm(4), wrt="tiles")
    with pytest.raises(ProblemError, match="thermal"):
        VonMisesNorm(4).gradient(warm)


@pytest.mark.slow
def test_an_elastic_channel_design_is_stiffer_at_the_same_mean_modulus():
    """iga.optimize over the Young's modulus channel of the beam for least compliance, the volume mean of E (for
    E between two materials: the volume of each) kept; the result solved afresh."""
    import iga
    from iga.design import channel_volumes, design_map

    problem = _beam(np.full((3, 3, 3), 1.5e9))
    res = iga.optimize(problem, Compliance(), "channel:E", bounds=(1e9, 2e9), mean=1.5e9, maxiter=10)
    assert res.objective <= 0.95 * res.initial
    assert res.values.min() >= 1e9 * (1 - 1e-9) and res.values.max() <= 2e9 * (1 + 1e-9)
    D, placed = design_map(problem, "E")
    vol = channel_volumes(problem, D, placed)
    assert abs(vol @ res.values.reshape(-1) / vol.sum() - 1.5e9) <= 1e-6 * 1.5e9
    fresh = _beam(res.values).solve(solver="direct")
    assert Compliance().value(fresh) == pytest.approx(res.objective, rel=1e-8)
    with pytest.raises(ProblemError, match="VonMisesNorm"):
        iga.optimize(problem, HeatFlow("umax"), "channel:E", bounds=(1e9, 2e9))
    # the beam pushed along its axis as well: its stresses scale with E, so the grading lowers the smooth maximum
    pushed = _beam(np.full((3, 3, 3), 1.5e9)).dirichlet("umax", 1e-5, components="x")
    res = iga.optimize(pushed, VonMisesNorm(8), "channel:E", bounds=(1e9, 2e9), mean=1.5e9, maxiter=6)
    assert res.objective <= 0.97 * res.initial
    fresh = _beam(res.values).dirichlet("umax", 1e-5, components="x").solve(solver="direct")
    assert VonMisesNorm(8).value(fresh) == pytest.approx(res.objective, rel=1e-8)


def _moved(D, P):
    from geometry import BSpline

    return BSpline(D.degrees, D.knots, P, D.weights, channels=D.channels)


def _loaded(model):
    return ElasticityProblem(model, youngs="E", poisson=0.3).dirichlet("umin", 0.0).traction(
        "umax", [0, 2e3, -1e4]).body_force([0, 0, -2e4]).solve(solver="direct")


@pytest.mark.parametrize("output", [Compliance(), VonMisesNorm(6)], ids=str)
def test_the_shape_gradient_is_its_finite_difference(output):
    """wrt="map" on the twisted lattice beam with a graded modulus, a traction and a body force: the compliance
    (self-adjoint) and the von Mises norm (one adjoint solve)."""
    rng = np.random.default_rng(1)
    D = pr.twisted(pr.box((0.04, 0.01, 0.01), degrees=(2, 2, 2)), 0.2, axis_point=(0.02, 0.005))
    D = D.with_channel("E", 1e9 * (1 + rng.random(D.control_points.shape[:3])))

    def solve(D):
        return _loaded(tiling.regular(D, library.cross(0.4), (4, 1, 1)))

    g = solve(D).gradient(output, wrt="map")
    assert g.shape == D.control_points.shape[:3] + (3,)
    P0 = np.array(D.control_points)
    d = np.zeros_like(P0)
    d[..., :3] = rng.standard_normal(g.shape) * 2e-7
    fd = (output.value(solve(_moved(D, P0 + d))) - output.value(solve(_moved(D, P0 - d)))) / 2
    assert float(np.sum(g * d[..., :3])) == pytest.approx(fd, rel=1e-6)


@pytest.mark.parametrize("output", [Compliance(), VonMisesNorm(6)], ids=str)
def test_the_parameter_gradient_is_its_finite_difference(output):
    """wrt="parameters" of a field-graded lattice beam: the arm widths from a parameter spline, the modulus a
    channel of the map (its values drag with the moving points)."""
    from geometry import SplineFunction
    from geometry import knots as kn

    rng = np.random.default_rng(2)
    D = pr.twisted(pr.box((0.04, 0.01, 0.01), degrees=(2, 2, 2)), 0.2, axis_point=(0.02, 0.005))
    D = D.with_channel("E", 1e9 * (1 + rng.random(D.control_points.shape[:3])))
    U = kn.uniform_knots(2, 1)

    def solve(c):
        field = SplineFunction((2, 2, 2), [U, U, U], c)
        return _loaded(tiling.field_graded(D, library.face_graded_cross, (4, 1, 1), field))

    c0 = 0.35 + 0.05 * rng.random((3, 3, 3, 1))
    g = solve(c0).gradient(output, wrt="parameters")
    assert g.shape == (3, 3, 3)
    dc = rng.standard_normal(c0.shape) * 1e-5
    fd = (output.value(solve(c0 + dc)) - output.value(solve(c0 - dc))) / 2
    assert float(np.sum(g * dc[..., 0])) == pytest.approx(fd, rel=1e-6)


def test_elastic_shape_gradients_refuse_what_they_do_not_cover():
    E0 = np.full((3, 3, 3), 1e9)
    D = pr.twisted(pr.box((0.04, 0.01, 0.01), degrees=(2, 2, 2)), 0.2, axis_point=(0.02, 0.005))
    ms = tiling.regular(D.with_channel("E", E0), library.cross(0.4), (4, 1, 1))
    pressed = ElasticityProblem(ms, youngs="E", poisson=0.3).dirichlet("umin", 0.0).pressure("umax", 1e4)
    with pytest.raises(ProblemError, match="pressure"):
        pressed.solve(solver="direct").gradient(Compliance(), wrt="map")
    inside = ms.patches[-1].composed.evaluate(np.array([[0.5, 0.5, 0.5]]))[0, :3]  # a point of the last tile
    pointed = ElasticityProblem(ms, youngs="E", poisson=0.3).dirichlet("umin", 0.0).point_load(inside, [0, 0, -1.0])
    with pytest.raises(ProblemError, match="point load"):
        pointed.solve(solver="direct").gradient(Compliance(), wrt="map")
    with pytest.raises(ProblemError, match="thermal"):
        _beam(E0).thermal(10.0, 1e-5, 0.0).solve(solver="direct").gradient(VonMisesNorm(4), wrt="map")
    with pytest.raises(ProblemError, match="pressure"):
        pressed.solve(solver="direct").gradient(VonMisesNorm(4), wrt="map")


@pytest.mark.slow
def test_a_lattice_cantilever_graded_by_its_arm_widths_is_stiffer_at_the_same_volume():
    """iga.optimize(elastic problem, Compliance(), wrt="parameters"): the arm widths of a field-graded cantilever
    of crosses, the loaded end held (the same traction area, so the same force), at the start's solid volume."""
    import iga
    from geometry import SplineFunction
    from geometry import knots as kn
    from iga.outputs import Volume

    U = kn.uniform_knots(2, 1)
    D = pr.box((0.04, 0.01, 0.01), degrees=(1, 1, 1))

    def problem(c):
        field = SplineFunction((2, 2, 2), [U, U, U], np.asarray(c, float).reshape(3, 3, 3, 1))
        ms = tiling.field_graded(D, library.face_graded_cross, (4, 1, 1), field)
        return ElasticityProblem(ms, youngs=7e10, poisson=0.33).dirichlet("umin", 0.0).traction("umax", [0, 0, -1e5])

    start = problem(np.full((3, 3, 3), 0.35))
    res = iga.optimize(start, Compliance(), wrt="parameters", bounds=(0.15, 0.6), hold=("umax",), maxiter=6)
    assert res.objective <= 0.95 * res.initial
    assert np.all(res.values[-1] == 0.35)
    fresh = problem(res.values).solve()
    assert Compliance().value(fresh) == pytest.approx(res.objective, rel=1e-8)
    assert Volume().value(fresh) == pytest.approx(res.history[-1].mean, rel=1e-10)  # the steps record the volume
    # SLSQP stopped by its iteration limit keeps the volume constraint to its own progress, not to round-off
    assert Volume().value(fresh) == pytest.approx(Volume().value(start.solve()), rel=1e-4)
