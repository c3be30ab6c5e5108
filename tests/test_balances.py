"""The balances the toolkit reports compare two independently computed quantities, and they can fail.

Heat: the energy identity int K grad T . grad T dV + int_Robin h T^2 dA = T . f + r . T_D, the left side from
the temperature field at the Gauss points, the right from the assembled loads and the consistent reactions.
Elasticity: the virtual work int sigma : eps(u) dV (from the stresses) against the work of the loads and of the
supports; the strain energy has the thermal strain removed.  Each is shown to move when the solution is wrong.
"""

import copy

import numpy as np
import pytest

import tiling
from geometry import primitives as pr
from iga import ElasticityProblem, HeatProblem
from tiling import library as L


def _perturbed(solution, size, seed=0):
    """A copy of ``solution`` whose coefficients are off by ``size`` times their span, at random."""
    wrong = copy.copy(solution)
    rng = np.random.default_rng(seed)
    wrong.u = solution.u + size * float(np.ptp(solution.u)) * rng.standard_normal(len(solution.u))
    return wrong


def test_the_heat_energy_identity_holds_on_a_hierarchy_and_fails_for_a_wrong_temperature():
    ms = tiling.hierarchical(pr.box((2.0, 1.0, 1.0)), L.heat_sink_t2(), (2, 1), 2, scale=0.5)
    s = (HeatProblem(ms, conductivity=lambda x: 1 + x[:, 0], source=3.0).dirichlet("wmin", 50.0)
         .robin("boundary - wmin - wmax", 10.0, 20.0).neumann("wmax", -5.0).solve())
    b = s.energy_balance()
    assert b.internal > 0 and b.relative_error < 1e-12, b
    wrong = _perturbed(s, 1e-4).energy_balance()
    assert wrong.relative_error > 1e-6, wrong  # a temperature off by 1e-4 of its span shows
    # a wrong conductivity in post-processing (the field's energy no longer the assembled one's) shows too
    other = copy.copy(s)
    other.problem = copy.copy(s.problem)
    other.problem.conductivity = HeatProblem(ms, conductivity=lambda x: 1 + 1.01 * x[:, 0]).conductivity
    assert other.energy_balance().relative_error > 1e-4


def test_prescribed_displacement_work_equals_twice_the_strain_energy_of_a_stretched_bar():
    # a bar of length 2 and section 1 x 1 stretched by delta: F = E A delta / L, U = F delta / 2 (nu = 0)
    E, delta = 200e9, 1e-4
    bar = pr.box((2.0, 1.0, 1.0), degrees=(2, 2, 2), elements=(2, 1, 1))
    s = (ElasticityProblem(bar, E, 0.0).dirichlet("umin", 0.0, "x").dirichlet("umax", delta, "x")
         .dirichlet("vmin", 0.0, "y").dirichlet("wmin", 0.0, "z").solve())
    F = E * 1.0 * delta / 2.0
    assert s.strain_energy() == pytest.approx(0.5 * F * delta, rel=1e-10)
    w = s.info["work"]
    assert w["external_J"] == pytest.approx(F * delta, rel=1e-10)  # all of it the supports' work r . u_D
    assert w["relative_error"] < 1e-12
    assert _perturbed(s, 1e-3).work_balance().relative_error > 1e-6


def test_a_free_thermal_expansion_stores_no_energy_and_a_wrong_one_is_told():
    E, alpha, dT = 70e9, 2.3e-5, 50.0
    ms = tiling.regular(pr.box((2.0, 1.0, 1.0)), L.cross(), (2, 1, 1))
    s = ElasticityProblem(ms, E, 0.3).thermal(dT, alpha, 0.0).hold_rigid().solve()
    volume = HeatProblem(ms).dirichlet("boundary", 0.0).solve().volume()
    scale = E * (alpha * dT) ** 2 * volume  # the energy the thermal strain would store if it were held
    assert s.strain_energy() <= 1e-12 * scale  # (1/2 u'Ku reported 8.63 J here)
    assert s.info["work"]["relative_error"] < 1e-9
    assert _perturbed(s, 1e-3).work_balance().relative_error > 1e-6


def test_loaded_lattice_work_balance_moves_with_a_wrong_displacement():
    ms = tiling.regular(pr.box((2.0, 1.0, 1.0)), L.cross(), (2, 2, 1))
    s = ElasticityProblem(ms, 1e9, 0.3).dirichlet("umin", 0.0).traction("umax", [0.0, 0.0, -1e5]).solve()
    assert s.info["work"]["relative_error"] < 1e-9 and s.info["work"]["internal_J"] > 0
    assert s.info["work"]["internal_J"] == pytest.approx(2 * s.strain_energy(), rel=1e-10)
    assert _perturbed(s, 1e-4).work_balance().relative_error > 1e-6
