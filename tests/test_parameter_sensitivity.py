"""Parameter sensitivities of field-graded pavings (wrt="parameters", wrt="faces"): the adjoint derivative of heat
outputs with respect to the parameter field's control values equals central finite differences of fresh
analyses of re-paved models; the refusals name the input and the fix."""

import numpy as np
import pytest

import iga
import tiling
from geometry import SplineFunction
from geometry import knots as kn
from geometry import primitives as pr
from iga import HeatProblem, ProblemError
from iga.outputs import Compliance, MeanTemperature, TemperatureNorm, Volume
from iga.parameter_sensitivity import tile_derivatives
from tiling import library

U2 = kn.uniform_knots(2, 1)


def _map(channel=True):
    D = pr.twisted(pr.box((0.02, 0.02, 0.02), degrees=(2, 2, 2)), 0.3, axis_point=(0.01, 0.01))
    rng = np.random.default_rng(3)
    return D.with_channel("k", 100 + 50 * rng.random(D.control_points.shape[:3])) if channel else D


def _spline(c):
    return SplineFunction((2, 2, 2), [U2, U2, U2], c)


def _conditions(p):
    return p.dirichlet("umin", 20.0).neumann("wmin", 5e4).robin("umax | vmax", 50.0, 20.0)


def _fd_check(analyse, c0, outputs, wrt="parameters", h=1e-5, rtol=1e-6, seed=0):
    """Each output's gradient at c0 along one random direction against the central difference of the output
    (the three analyses shared by the outputs); returns the gradients."""
    sol = analyse(c0)
    d = np.random.default_rng(seed).standard_normal(np.shape(c0))
    plus, minus = analyse(c0 + h * d), analyse(c0 - h * d)
    out = []
    for output in outputs:
        g = sol.gradient(output, wrt=wrt)
        assert np.all(np.isfinite(g))
        fd = (output.value(plus) - output.value(minus)) / (2 * h)
        an = float(np.sum(np.reshape(g, np.shape(d)) * d))
        assert abs(an - fd) <= rtol * abs(fd), (output, an, fd)
        out.append(g)
    return out


@pytest.mark.slow
def test_a_parameter_spline_s_gradient_is_its_finite_difference():
    """A curved map, a conductivity channel of the map (its values drag with the moving points), Dirichlet,
    Neumann and Robin faces: every output's gradient by the parameter spline's 27 control values."""
    D = _map()

    def analyse(c):
        ms = tiling.field_graded(D, library.face_graded_cross, (2, 2, 2), _spline(c))
        return _conditions(HeatProblem(ms, conductivity="k")).solve(tol=1e-13)

    c0 = 0.3 + 0.05 * np.random.default_rng(1).random((3, 3, 3, 1))
    outputs = [MeanTemperature(), TemperatureNorm(8), MeanTemperature("wmin"), Volume(), Compliance()]
    for g in _fd_check(analyse, c0, outputs):
        assert g.shape == (3, 3, 3)


@pytest.mark.slow
def test_a_channel_field_of_a_rational_map():
    """The field a channel of a rational map (an exact annulus sector: NURBS basis at the wall centres), per
    control value of the channel."""
    D0 = pr.annulus(0.01, 0.02, 0.01, np.pi / 2, elements=(2, 1, 1))
    assert D0.is_rational
    shape = D0.control_points.shape[:3]
    D0 = D0.with_channel("k", np.full(shape, 150.0))

    def analyse(t):
        D = D0.with_channel("t", t)
        ms = tiling.field_graded(D, library.face_graded_cross, (1, 2, 2), "t")
        return HeatProblem(ms, conductivity="k").neumann("wmin", 2e3).robin("wmax", 30.0, 20.0).solve(tol=1e-13)

    t0 = 0.3 + 0.1 * np.random.default_rng(2).random(shape)
    g, = _fd_check(analyse, t0, [TemperatureNorm(8)])
    assert g.shape == shape


def test_a_heat_sink_graded_by_its_pins_widths():
    """The heat-sink family (library.face_graded_heat_sink): T2 at its default, every side's pins as wide as the
    field on that wall, neighbours glued by identities only (field_graded refuses any other), its derivative
    shared by all cells as the per-tile extrapolation gives it, and every output's gradient by the parameter
    spline's control values equal to the central difference of fresh analyses."""
    base = library.heat_sink_t2().patches[0]
    assert np.abs(library.face_graded_heat_sink().patches[0].control_points - base.control_points).max() < 1e-15
    D = _map()

    def paved(c):
        return tiling.field_graded(D, library.face_graded_heat_sink, (2, 2, 1), _spline(c))

    c0 = 0.3 + 0.1 * np.random.default_rng(6).random((3, 3, 3, 1))
    ms = paved(c0)
    assert all(i.kind == "identity" for i in ms.interfaces) and len(ms.interfaces) == 4
    for t, tile in enumerate(ms.tiles):
        P, width = tile.patches[0].control_points, ms.grading.values(t)
        # the top layer's slot edge next to the pins (column 2 of 6) on each side: 0.5 - half-gap = the width
        for face, edge in (("umin", P[0, 2, 4, 1]), ("umax", P[5, 2, 4, 1]), ("vmin", P[2, 0, 4, 0]),
                           ("vmax", P[2, 5, 4, 0])):
            assert abs(edge - width[face]) < 1e-15, (t, face)

    def plain(**values):
        return library.face_graded_heat_sink(**values)

    shared = tile_derivatives(ms.grading, ms.tiles[1], 1)
    extrapolated = tile_derivatives(tiling.field_graded(D, plain, (2, 2, 1), _spline(c0)).grading, ms.tiles[1], 1)
    for face in shared:
        assert np.abs(shared[face][0] - extrapolated[face][0]).max() <= 1e-9
    assert not np.any(shared["wmin"][0]) and not np.any(shared["wmax"][0])  # the bottom and top shape nothing

    def analyse(c):
        return _conditions(HeatProblem(paved(c), conductivity="k")).solve(tol=1e-13)

    _fd_check(analyse, c0, [TemperatureNorm(8), MeanTemperature("wmin"), Volume()])
    with pytest.raises(tiling.TilingError, match=r"umax must be in \(0, 0\.5\)"):
        library.face_graded_heat_sink(umax=0.5)


def test_a_hierarchical_sink_s_graded_leaves():
    """tiling.leaf_graded: the two-level sink whose 16 leaves are face_graded_heat_sink members, on a curved map
    with a conductivity channel: the same interfaces and tags as the T2 sink, one value on every wall two leaves
    share (and their faces glued as identities), the leaves' pins as wide as the field says, the parameter
    gradient of the hottest point and of a face mean equal to central differences (branch faces in the model)."""
    D = _map()
    T2 = library.heat_sink_t2()

    def paved(c):
        return tiling.leaf_graded(D, T2, (2, 2), 2, library.face_graded_heat_sink, _spline(c))

    c0 = 0.3 + 0.1 * np.random.default_rng(7).random((3, 3, 3, 1))
    ms, ref = paved(c0), tiling.hierarchical(D, T2, (2, 2), 2)
    glued = [{(i.kind, frozenset([i.a, i.b])) for i in m.interfaces} for m in (ms, ref)]
    assert glued[0] == glued[1] and len(glued[0]) == len(ref.interfaces)
    assert {k: sorted(v) for k, v in ms.tags.items()} == {k: sorted(v) for k, v in ref.tags.items()}
    g = ms.grading
    leaves = g.graded_tiles()
    assert leaves == [t for t in range(len(ms.tiles)) if ms.tiles[t] is not T2] and len(leaves) == 16
    assert len(g.site_centres) == 6 * 16 - sum(i.kind == "identity" and ms.patches[i.a[0]].level == 1
                                              for i in ms.interfaces)  # a shared wall: one site
    for t in leaves:
        P, width = ms.tiles[t].patches[0].control_points, g.values(t)
        assert abs(P[0, 2, 4, 1] - width["umin"]) < 1e-15 and abs(P[2, 5, 4, 0] - width["vmax"]) < 1e-15

    def analyse(c):
        return (HeatProblem(paved(c), conductivity="k").neumann("branch-in", 2e4).robin("exterior", 3000.0, 0.0)
                .solve(tol=1e-13))

    _fd_check(analyse, c0, [TemperatureNorm(8), MeanTemperature("wmax")])
    # the design re-paves the hierarchy with the moved field at every step, at the same solid volume
    problem = HeatProblem(paved(c0), conductivity="k").neumann("branch-in", 2e4).robin("exterior", 3000.0, 0.0)
    result = iga.optimize(problem, TemperatureNorm(8), wrt="parameters", bounds=(0.2, 0.49), maxiter=3, tol=1e-12)
    assert result.objective < result.initial and result.solution.problem.model.tiles_per_level() == [4, 16]
    assert Volume().value(result.solution) == pytest.approx(result.history[0].mean, rel=1e-6)
    with pytest.raises(tiling.TilingError, match="branch-in face"):
        tiling.leaf_graded(D, T2, (2, 2), 2, library.face_graded_cross, 0.3)  # seven patches, no branch-in


def _squared(**values):
    """A family whose control points are not affine in its values (the widths their squares' images)."""
    return library.face_graded_cross(**{f: 0.1 + v * v for f, v in values.items()})


def test_a_family_that_is_not_affine_and_a_number_field():
    D = _map(channel=False)

    def analyse(c):
        ms = tiling.field_graded(D, _squared, (2, 1, 1), _spline(c))
        return _conditions(HeatProblem(ms, conductivity=150.0)).solve(tol=1e-13)

    c0 = 0.45 + 0.05 * np.random.default_rng(4).random((3, 3, 3, 1))
    _fd_check(analyse, c0, [MeanTemperature()])

    def constant(v):
        ms = tiling.field_graded(D, library.face_graded_cross, (2, 1, 1), float(v))
        return _conditions(HeatProblem(ms, conductivity=150.0)).solve(tol=1e-13)

    g, = _fd_check(constant, np.array(0.3), [TemperatureNorm(4)])
    assert g.shape == ()


def test_wall_values_and_the_affine_family_s_shared_derivative():
    """wrt="faces" shaped like the wall values; the parameter gradient is their chain through the spline's basis
    (a sum when the field is constant); the affine family's one derivative equals the per-tile extrapolation."""
    D = _map(channel=False)
    ms = tiling.field_graded(D, library.face_graded_cross, (2, 2, 1), 0.3)
    sol = _conditions(HeatProblem(ms, conductivity=150.0)).solve()
    walls = sol.gradient(MeanTemperature(), wrt="faces")
    assert [w.shape for w in walls] == [f.shape for f in ms.grading.faces]
    total = sol.gradient(MeanTemperature(), wrt="parameters")
    assert abs(float(total) - sum(float(w.sum()) for w in walls)) <= 1e-12 * abs(float(total))

    def plain(**values):
        return library.face_graded_cross(**values)

    general = tiling.field_graded(D, plain, (2, 2, 1), 0.3)
    t = 3
    shared = tile_derivatives(ms.grading, ms.tiles[t], t)
    extrapolated = tile_derivatives(general.grading, general.tiles[t], t)
    for face in shared:
        for a, b in zip(shared[face], extrapolated[face]):
            assert np.abs(a - b).max() <= 1e-9


def test_refusals_name_the_input_and_the_fix():
    D = _map(channel=False)
    regular = _conditions(HeatProblem(tiling.regular(D, library.cross(), (1, 1, 1)), conductivity=1.0)).solve()
    with pytest.raises(ProblemError, match="field_graded"):
        regular.gradient(MeanTemperature(), wrt="parameters")
    ms = tiling.field_graded(D, library.face_graded_cross, (2, 1, 1), lambda s: 0.2 + 0.1 * s[:, 0])
    sol = _conditions(HeatProblem(ms, conductivity=1.0)).solve()
    with pytest.raises(ProblemError, match="wrt='faces'"):
        sol.gradient(MeanTemperature(), wrt="parameters")
    assert len(sol.gradient(MeanTemperature(), wrt="faces")) == 3  # the wall values of a callable field do work
    edge = _conditions(HeatProblem(tiling.field_graded(D, library.face_graded_cross, (1, 1, 1), 0.9995),
                                   conductivity=1.0)).solve()
    with pytest.raises(ProblemError, match="range"):
        edge.gradient(MeanTemperature(), wrt="parameters")

    def changing(**values):  # a tile that gains a patch when its umin value moves
        t = library.face_graded_cross(**values)
        return t if values["umin"] == 0.3 else library.cube()

    odd = _conditions(HeatProblem(tiling.field_graded(D, changing, (1, 1, 1), 0.3), conductivity=1.0)).solve()
    with pytest.raises(ProblemError, match="structure"):
        odd.gradient(MeanTemperature(), wrt="faces")
    D2 = _map().with_channel("s", np.ones((3, 3, 3)))
    src = HeatProblem(tiling.field_graded(D2, library.face_graded_cross, (1, 1, 1), 0.3), conductivity=1.0,
                      source="s").dirichlet("umin", 0.0).solve()
    with pytest.raises(ProblemError, match="source"):
        src.gradient(MeanTemperature(), wrt="parameters")
    with pytest.raises(ProblemError, match="'faces'"):
        sol.gradient(MeanTemperature(), wrt="wall")


@pytest.mark.slow
def test_a_graded_lattice_designed_by_its_field_is_cooler_at_the_same_volume():
    """iga.optimize(wrt="parameters"): the arm widths of a 2 x 2 x 1 lattice of face-graded crosses, heated through
    its held bottom face and cooled on its top, at the start's solid volume; the result re-analysed afresh."""

    D = pr.box((0.04, 0.04, 0.01), degrees=(1, 1, 1))
    field = _spline(np.full((3, 3, 3, 1), 0.35))
    ms = tiling.field_graded(D, library.face_graded_cross, (2, 2, 1), field)
    prob = HeatProblem(ms, conductivity=205.0).neumann("wmin", 2e4).robin("wmax", 3000.0, 0.0)
    objective = TemperatureNorm(8)
    res = iga.optimize(prob, objective, wrt="parameters", bounds=(0.15, 0.6), hold=("wmin",), maxiter=8)
    assert res.values.shape == (3, 3, 3)
    assert np.all(res.values[:, :, 0] == 0.35)  # the heated face's widths held: the same power comes in
    assert res.values.min() >= 0.15 and res.values.max() <= 0.6
    assert res.objective <= 0.8 * res.initial
    start, end = Volume().value(prob.solve()), Volume().value(res.solution)
    assert abs(end - start) <= 1e-6 * start
    fresh = HeatProblem(tiling.field_graded(D, library.face_graded_cross, (2, 2, 1), _spline(res.values[..., None])),
                        conductivity=205.0).neumann("wmin", 2e4).robin("wmax", 3000.0, 0.0).solve()
    assert abs(objective.value(fresh) - res.objective) <= 1e-8 * res.objective
    with pytest.raises(ProblemError, match="bounds"):
        iga.optimize(prob, objective, wrt="parameters")
    constant = HeatProblem(tiling.field_graded(D, library.face_graded_cross, (1, 1, 1), 0.3), conductivity=205.0)
    with pytest.raises(ProblemError, match="one number"):
        iga.optimize(constant.neumann("wmin", 2e4).robin("wmax", 3000.0, 0.0), objective, wrt="parameters",
                     bounds=(0.15, 0.6), hold=("wmin",))
    # bounds the family refuses are refused before any analysis, naming the family and its range
    pins = HeatProblem(tiling.field_graded(D, library.face_graded_heat_sink, (2, 2, 1), _spline(np.full((3, 3, 3, 1),
                       0.4))), conductivity=205.0).neumann("wmin", 2e4).robin("wmax", 3000.0, 0.0)
    for bounds in ((0.15, 0.6), (0.15, 0.4999), (0.0, 0.45)):
        with pytest.raises(ProblemError, match=r"face_graded_heat_sink .* must be in \(0, 0\.5\).*narrow the bounds"):
            iga.optimize(pins, objective, wrt="parameters", bounds=bounds, maxiter=2)


def _slotted(umin=0.3, umax=0.3, vmin=0.3, vmax=0.3, wmin=0.3, wmax=0.3):
    """The heat-sink tile T1 (a slot along u opening towards its top) with the slot's width scaled by the top
    face's value: the slot walls are faces at an interior discontinuity plane."""
    from geometry import BSpline

    T = library.heat_sink_t1().patches[0]
    cp = np.array(T.control_points)
    half = np.array([0.0, 0.0, 0.0, 0.03, 0.05]) * (wmax / 0.3)
    for k, g in enumerate(half):  # the six u coordinates of each layer: two quadratic pieces either side of 0.5
        cp[:, :, k, 0] = np.array([0.0, (0.5 - g) / 2, 0.5 - g, 0.5 + g, (1.5 + g) / 2, 1.0])[:, None]
    return tiling.Tile([BSpline(T.degrees, T.knots, cp)], name="slotted")


def test_the_slot_walls_of_a_tile_move_with_its_parameter():
    """Robin cooling on every free face, the slot walls (faces at the tiles' discontinuity planes) included: the
    face terms take the limit of the tile's basis from the wall's side."""
    D = _map(channel=False)

    def analyse(c):
        ms = tiling.field_graded(D, _slotted, (2, 1, 1), _spline(c))
        assert any("u=0.5" in f for _, f in ms.tags["boundary"])
        return HeatProblem(ms, conductivity=150.0).neumann("wmin", 5e4).robin("boundary - wmin", 80.0,
                                                                                20.0).solve(tol=1e-13)

    c0 = 0.3 + 0.05 * np.random.default_rng(5).random((3, 3, 3, 1))
    _fd_check(analyse, c0, [MeanTemperature(), MeanTemperature("wmax")])
