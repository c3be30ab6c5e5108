"""Offsets to a stated tolerance and the two-level composite chain of Elber 2017, Fig. 8 (strip, offset, ruled
volume, stitches), measured at 10^4 random points."""

import numpy as np
import pytest

from geometry import SplineError, check_regular, primitives
from geometry.shapes import examples as shapes
from geometry.shapes.offset import exact_offset, offset
from geometry.shapes.sweep import section_error
from tiling import TilingError, library
from tiling.composite import stitched_strip
from tiling.export import watertightness

DUCK_SKIN = shapes.duck().boundary("vmax").swap(0, 1)  # u along the body (5 spans), v across
STRIP = [[0.05, 0.95], [0.4, 0.6]]


def _random_params(S, n=10_000, seed=0):
    rng = np.random.default_rng(seed)
    dom = S.domain
    return dom[:, 0] + rng.random((n, 2)) * (dom[:, 1] - dom[:, 0])


@pytest.mark.parametrize("tol", [1e-3, 1e-5])
def test_offset_is_within_its_tolerance_of_the_exact_offset(tol):
    strip = DUCK_SKIN.extract(np.array(STRIP))
    o = offset(strip, 0.02, tol)
    x = _random_params(strip)
    err = np.linalg.norm(o.surface.evaluate(x)[:, :3] - exact_offset(strip, 0.02, x), axis=1)
    assert err.max() <= tol and o.error <= tol
    assert err.max() <= 1.2 * o.error  # the reported figure is what is measured, not a loose guess
    # and it is an offset: the distance to the surface along its normal is the thickness
    n = np.cross(*np.moveaxis(strip.jacobian(x)[:, :3, :], 2, 0))
    n /= np.linalg.norm(n, axis=1)[:, None]
    along = np.einsum("ni,ni->n", o.surface.evaluate(x)[:, :3] - strip.evaluate(x)[:, :3], n)
    assert np.abs(along - 0.02).max() <= tol


def test_offset_of_a_cylinder_is_the_coaxial_cylinder():
    cyl = primitives.annulus()  # exact NURBS: its inner and outer faces are cylinders
    faces = [cyl.boundary(f) for f in ("umin", "umax", "vmin", "vmax", "wmin", "wmax")]
    radii = [np.ptp(np.hypot(*F.evaluate(_random_params(F, 50))[:, :2].T)) for F in faces]
    side = faces[int(np.argmin(radii))]  # the lateral face: constant radius
    o = offset(side, 0.1, 1e-6)
    x = _random_params(side, 2000)
    r_in = np.hypot(*side.evaluate(x)[:, :2].T)
    r_out = np.hypot(*o.surface.evaluate(x)[:, :2].T)
    assert np.abs(np.abs(r_out - r_in) - 0.1).max() <= 1e-6 and o.error <= 1e-6
    with pytest.raises(SplineError, match="raise the tolerance"):  # refused, not ground on for minutes
        offset(side, 0.1, 1e-15)


@pytest.mark.slow
@pytest.mark.long
def test_fig8_chain_strip_offset_ruled_volume_and_round_stitches():
    tol = 1e-5
    out = stitched_strip(DUCK_SKIN, STRIP, 0.02, library.stitch(), (20, 2, 1), radius=0.003, tolerance=tol)
    assert out.offset.error <= tol
    assert check_regular(out.volume, max_depth=6).regular
    # the ruled volume is exact between the strip (w = 0) and the offset (w = 1)
    x = _random_params(out.strip, 2000)
    for w, S in ((0.0, out.strip), (1.0, out.offset.surface)):
        assert np.abs(out.volume.evaluate(np.column_stack([x, np.full(len(x), w)]))[:, :3]
                      - S.evaluate(x)[:, :3]).max() < 1e-10
    rep = out.stitches.struts
    assert len(rep.sweeps) == 2 and rep.error <= tol  # each row of 20 stitches continues into one fibre
    rng = np.random.default_rng(4)
    for s in rep.sweeps:
        lo, hi = s.axis.domain[0]
        err = section_error(s.surface, s.axis, s.radius, rng.random(5000), lo + rng.random(5000) * (hi - lo))
        assert err.max() <= tol
    report = watertightness(out.stitches)
    assert report["closed"] and report["manifold"] and report["euler_characteristic"] == 2 * len(rep.sweeps)


def test_bad_offsets_and_strips_are_refused():
    S = primitives.box().boundary("wmax")
    with pytest.raises(SplineError, match="non-zero length"):
        offset(S, 0.0)
    with pytest.raises(SplineError, match="positive length"):
        offset(S, 0.1, tolerance=-1.0)
    with pytest.raises(SplineError, match="BSpline surface"):
        offset(primitives.box(), 0.1)
    for bad in ("0.02", float("nan"), 0.0):  # a string once reached abs() and crashed with a TypeError
        with pytest.raises(TilingError, match="non-zero length"):
            stitched_strip(DUCK_SKIN, STRIP, bad, library.stitch(), (2, 1, 1))
    with pytest.raises(TilingError, match="curve tiles"):
        stitched_strip(DUCK_SKIN, STRIP, 0.02, library.cross(), (2, 1, 1))
