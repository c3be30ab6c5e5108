"""Compliance sensitivities of elastic solutions by Young's modulus (self-adjoint: no extra solve): against central
differences of fresh solves, the scaling identity, and the refusals."""

import numpy as np
import pytest

import tiling
from geometry import primitives as pr
from iga import ElasticityProblem, ProblemError
from iga.outputs import Compliance, VonMisesNorm
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
    assert s.gradient(Compliance(), wrt="patches").sum() == pytest.approx(tiles.sum(), rel=1e-12)


def test_elastic_sensitivities_refuse_what_they_do_not_cover():
    E0 = np.full((3, 3, 3), 1e9)
    s = _beam(E0).solve(solver="direct")
    with pytest.raises(ProblemError, match="Compliance"):
        s.gradient(VonMisesNorm(4), wrt="channel:E")
    with pytest.raises(ProblemError, match="not the channel 'k'"):
        s.gradient(Compliance(), wrt="channel:k")
    with pytest.raises(ProblemError, match="wrt must be"):
        s.gradient(Compliance(), wrt="map")
    moved = _beam(E0).dirichlet("umax", 1e-4, components="x").solve(solver="direct")
    with pytest.raises(ProblemError, match="zero displacement"):
        moved.gradient(Compliance(), wrt="channel:E")
    warm = _beam(E0).thermal(10.0, 1e-5, 0.0).solve(solver="direct")
    with pytest.raises(ProblemError, match="thermal"):
        warm.gradient(Compliance(), wrt="tiles")


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
    with pytest.raises(ProblemError, match="Compliance"):
        iga.optimize(problem, VonMisesNorm(4), "channel:E", bounds=(1e9, 2e9))
