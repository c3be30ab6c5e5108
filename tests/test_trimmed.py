"""Trimmed surfaces: validity of loops, exact composition with loops carried, tessellation areas, IGES 144."""

import numpy as np
import pytest
from numpy.polynomial.legendre import leggauss

from geometry import BSpline, SplineError, compose, primitives as pr
from geometry import knots as kn
from geometry.io.iges import write_iges
from geometry.shapes.trimmed import TrimmedSurface, reversed_curve
from helpers import read_own_iges as _read_own_iges


def _circle(cx, cy, r):
    """Exact NURBS circle (u, v) = (cx, cy) + r (cos, sin), counter-clockwise."""
    w = np.array([1, np.sqrt(0.5)] * 4 + [1])
    pts = np.array([[1, 0], [1, 1], [0, 1], [-1, 1], [-1, 0], [-1, -1], [0, -1], [1, -1], [1, 0]], float) * r
    U = np.r_[0, 0, 0, 0.25, 0.25, 0.5, 0.5, 0.75, 0.75, 1, 1, 1]
    return BSpline((2,), [U], np.c_[pts + [cx, cy], np.zeros(9)], w)


def _polygon(points):
    pts = np.array(list(points) + [points[0]], float)
    U = np.concatenate([[0.0], np.linspace(0, 1, len(pts)), [1.0]])
    return BSpline((1,), [U], np.c_[pts, np.zeros(len(pts))])


SQUARE = _polygon([(0, 0), (1, 0), (1, 1), (0, 1)])
# z = 0.15 u + 0.15 u^2 over the unit square (quadratic control net): area element sqrt(1 + (0.15 + 0.3 u)^2)
BENT = BSpline((2, 2), [kn.uniform_knots(2, 1)] * 2,
               np.array([[[x, y, 0.3 * x * x] for y in (0, 0.5, 1)] for x in (0, 0.5, 1)], float))


def _bent_area_disk(cx, cy, r, n=120):
    x, w = leggauss(n)
    rr, wr = 0.5 * r * (x + 1), 0.5 * r * w
    th, wt = np.pi * (x + 1), np.pi * w
    R, TH = np.meshgrid(rr, th, indexing="ij")
    u = cx + R * np.cos(TH)
    return float(np.sum(np.outer(wr, wt) * R * np.sqrt(1 + (0.15 + 0.3 * u) ** 2)))


def _bent_area_square():
    x, w = leggauss(40)
    u = 0.5 * (x + 1)
    return float(np.sum(0.5 * w * np.sqrt(1 + (0.15 + 0.3 * u) ** 2)))


@pytest.mark.parametrize("tol", [1e-2, 1e-3])
def test_planar_cap_area_equals_the_area_enclosed_by_its_loops(tol):
    flat = pr.box((1, 1, 1)).boundary("wmin")  # the unit square, z = 0
    cap = TrimmedSurface(flat, [SQUARE, _circle(0.5, 0.5, 0.25), _circle(0.15, 0.15, 0.08)])
    exact = 1 - np.pi * (0.25 ** 2 + 0.08 ** 2)
    perimeter = 4 + 2 * np.pi * (0.25 + 0.08)
    mesh = cap.tessellate(tol)
    assert abs(mesh.area - exact) <= tol * perimeter  # chords within tol of the loops: a band of width tol
    assert abs(mesh.area - exact) > 0  # (an inscribed polygon, not the exact disc)
    # every vertex lies in the kept region or on a loop
    uv = np.c_[mesh["u"], mesh["v"]]
    d = np.hypot(uv[:, 0] - 0.5, uv[:, 1] - 0.5)
    assert d.min() >= 0.25 - 1e-12


def test_curved_trimmed_area_converges_to_quadrature():
    holed = TrimmedSurface(BENT, [SQUARE, _circle(0.5, 0.5, 0.25)])
    disc = TrimmedSurface(BENT, [_circle(0.45, 0.5, 0.3)])
    for T, exact in ((holed, _bent_area_square() - _bent_area_disk(0.5, 0.5, 0.25)),
                     (disc, _bent_area_disk(0.45, 0.5, 0.3))):
        errs = [abs(T.tessellate(tol).area - exact) for tol in (1e-2, 1e-3)]
        assert errs[1] < 4e-3 * 1e-3 * 1e3 and errs[1] < errs[0]
        # every edge midpoint of the tessellation is within the tolerance of the surface (chord check)
        m = T.tessellate(1e-3)
        uv = np.c_[m["u"], m["v"]]
        f = m.faces.reshape(-1, 4)[:, 1:]
        a, b = f[:, 0], f[:, 1]
        mid = BENT.evaluate(0.5 * (uv[a] + uv[b]))[:, :3]
        assert np.linalg.norm(mid - 0.5 * (m.points[a] + m.points[b]), axis=1).max() <= 1e-3 * (1 + 1e-9)


def test_composition_is_exact_and_carries_the_loops():
    D = pr.box((2.0, 1.0, 1.0)).elevate_to((2, 2, 2))
    cp = D.control_points.copy()
    cp[..., 2] += 0.2 * np.sin(cp[..., 0]) * cp[..., 1]
    D = BSpline(D.degrees, D.knots, cp)
    inner = BSpline((1, 1), [kn.uniform_knots(1, 1)] * 2,
                    np.array([[[0.1, 0.1, 0.5], [0.1, 0.9, 0.5]], [[0.9, 0.1, 0.5], [0.9, 0.9, 0.5]]], float))
    T = TrimmedSurface(inner, [_circle(0.5, 0.5, 0.3)])
    C = T.compose(D)
    assert C.loops[0] is T.loops[0]
    rng = np.random.default_rng(0)
    t = rng.random(200)
    on_loop = T.loops[0].evaluate(t[:, None])[:, :2]
    # the composed surface on its loop = D(inner(loop)) composed as one curve (independently, exactly)
    curve = compose(D, compose(inner, T.loops[0]))
    assert np.abs(C.evaluate(on_loop)[:, :3] - curve.evaluate(t[:, None])[:, :3]).max() < 1e-12
    assert np.abs(C.boundary_curves()[0].evaluate(t[:, None])[:, :3] - curve.evaluate(t[:, None])[:, :3]).max() < 1e-12
    # and is the map of the inner surface at random parameters
    uv = rng.random((100, 2))
    assert np.abs(C.evaluate(uv)[:, :3] - D.evaluate(inner.evaluate(uv)[:, :3])[:, :3]).max() < 1e-12


def test_loop_orientation_is_normalised():
    flat = pr.box().boundary("wmin")
    T = TrimmedSurface(flat, [reversed_curve(SQUARE), reversed_curve(reversed_curve(_circle(0.5, 0.5, 0.2)))])
    assert np.allclose(T.tessellate(1e-3).area, TrimmedSurface(flat, [SQUARE, _circle(0.5, 0.5, 0.2)])
                       .tessellate(1e-3).area)
    assert T.contains(np.array([[0.05, 0.05], [0.5, 0.5]])).tolist() == [True, False]


def test_bad_loops_name_the_problem():
    flat = pr.box().boundary("wmin")
    open_loop = BSpline((1,), [np.r_[0, 0, 0.5, 1, 1]], np.array([[0.1, 0.1, 0], [0.9, 0.1, 0], [0.9, 0.9, 0]]))
    bowtie = _polygon([(0.1, 0.1), (0.9, 0.9), (0.9, 0.1), (0.1, 0.9)])
    cases = [([open_loop], "open"), ([bowtie], "intersects itself"),
             ([SQUARE, _circle(0.5, 0.5, 0.2), _circle(0.6, 0.5, 0.2)], "intersect each other"),
             ([_circle(0.5, 0.5, 0.2), _circle(0.9, 0.9, 0.05)], "outside loop 0"),
             ([_circle(0.9, 0.5, 0.3)], "leaves the surface's parameter domain"), ([], "non-empty"),
             ([flat], "non-empty list of B-spline curves")]
    for loops, match in cases:
        with pytest.raises(SplineError, match=match):
            TrimmedSurface(flat, loops)
    with pytest.raises(SplineError, match="2-variate"):
        TrimmedSurface(pr.box(), [SQUARE])
    with pytest.raises(SplineError, match="tolerance"):
        TrimmedSurface(flat, [SQUARE]).tessellate(0.0)


def test_trimmed_surfaces_in_iges(tmp_path):
    T = TrimmedSurface(BENT, [SQUARE, _circle(0.5, 0.5, 0.25)])
    path = write_iges(tmp_path / "t.igs", [T])
    entities = _read_own_iges(path)
    assert [int(e[0]) for e in entities] == [128, 126, 142, 126, 142, 144]
    # 144: surface pointer, outer given, one hole, the 142 pointers; each 142 points at the surface and its curve
    e144 = entities[-1]
    assert [int(v) for v in e144[1:]] == [1, 1, 1, 5, 9]
    assert [int(v) for v in entities[2][1:]] == [1, 1, 3, 0, 1]


def test_trimmed_iges_area_in_opencascade(tmp_path):
    gmsh = pytest.importorskip("gmsh")
    T = TrimmedSurface(BENT, [SQUARE, _circle(0.5, 0.5, 0.25)])
    path = write_iges(tmp_path / "t.igs", [T], units="mm")
    gmsh.initialize()
    try:
        gmsh.option.setNumber("General.Terminal", 0)
        gmsh.model.occ.importShapes(str(path))
        gmsh.model.occ.synchronize()
        (_, tag), = gmsh.model.getEntities(2)
        exact = _bent_area_square() - _bent_area_disk(0.5, 0.5, 0.25)
        assert gmsh.model.occ.getMass(2, tag) == pytest.approx(exact, rel=1e-6)
    finally:
        gmsh.finalize()


def test_a_tolerance_floating_point_cannot_meet_is_refused_at_once():
    disc = TrimmedSurface(BENT, [_circle(0.45, 0.5, 0.3)])
    with pytest.raises(SplineError, match=r"tolerance 1e-13 is below 1e-9 of the surface's size"):
        disc.tessellate(1e-13)
    with pytest.raises(SplineError, match=r"needs at least about [\d,]+ triangles \(estimated .*more than max_triangles = 50;"):
        disc.tessellate(1e-6, max_triangles=50)
    # the estimate is a lower bound (it passes 6,000 here); the fill itself stops when it would make more
    with pytest.raises(SplineError, match=r"needs more than 6,000 triangles \(filling the rings needs more"):
        disc.tessellate(1e-5, max_triangles=6000)
    assert disc.tessellate(1e-5, max_triangles=20000).n_cells > 6000


def test_a_loop_that_runs_back_along_itself_is_told_it_encloses_no_area():
    back = BSpline((1,), [np.array([0, 0, 0.5, 1, 1.0])], np.array([[0.2, 0.2, 0], [0.8, 0.8, 0], [0.2, 0.2, 0]]))
    with pytest.raises(SplineError, match=r"trimming loop 0 encloses no area \(it runs back along itself"):
        TrimmedSurface(pr.box().boundary("wmin"), [back])
