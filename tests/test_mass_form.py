"""The mass (zero-order) form, M_ij = int c N_i N_j dV: one term of the sum-factorised vocabulary
(iga.assembly.tensor.banded_form), checked against independent integrals of the same fields."""

import numpy as np
import pytest

from geometry import primitives as pr
from iga import HeatProblem
from iga.discretisation.fields import integrate_fields

pytestmark = pytest.mark.all_threads  # the compiled kernels on every thread: a race would show


def _field_integral(problem, coefficients, fn):
    """int fn(x, u) dV of the field with ``coefficients`` (ndof,) by the problem's Gauss rule (the solution's
    evaluation path, not the assembly's)."""
    return integrate_fields(problem, lambda i: coefficients[problem.offsets[i]:problem.offsets[i + 1]].reshape(
        (1,) + problem.spaces[i].shape), 1, lambda x, v, g: fn(x, v[:, 0]))


@pytest.mark.slow
@pytest.mark.parametrize("name, model, volume", [
    ("twisted box", pr.twisted(pr.box((2.0, 1.0, 0.5), degrees=(2, 2, 2)), 0.6, axis_point=(1.0, 0.5)), None),
    ("NURBS annulus", pr.annulus(0.5, 1.0, 0.3, np.pi / 2), 0.3 * np.pi / 4 * (1.0 - 0.25)),
    ("paved crosses", "crosses", None),
])
def test_the_mass_form_integrates_products_of_fields_exactly(name, model, volume):
    rng = np.random.default_rng(7)
    rho_c = 3.5e6  # J/(m^3 K), steel
    if isinstance(model, str):  # a micro-structure: placed, composed patches in groups sharing a tile spline
        import tiling
        from tiling import library as L

        model = tiling.regular(pr.twisted(pr.box(degrees=(2, 2, 2)), 0.4, axis_point=(0.5, 0.5)), L.cross(),
                               (2, 2, 1))
    prob = HeatProblem(model, degree_elevation=1, refine=1)
    M = prob.mass(rho_c)
    assert abs(M - M.T).max() <= 1e-12 * abs(M).max()  # symmetric
    ones = np.ones(prob.ndof)
    # partition of unity: the whole model's heat capacity (the exact NURBS annulus's analytic volume; the
    # twisted box's by the solution's Gauss rule)
    volume = _field_integral(prob, ones, lambda x, a: a) if volume is None else volume
    assert ones @ M @ ones == pytest.approx(rho_c * volume, rel=1e-10)
    u, v = rng.standard_normal(prob.ndof), rng.standard_normal(prob.ndof)
    assert u @ M @ u == pytest.approx(_field_integral(prob, u, lambda x, a: rho_c * a * a), rel=1e-10)
    assert u @ M @ v == pytest.approx(0.5 * (_field_integral(prob, u + v, lambda x, a: rho_c * a * a)
                                             - _field_integral(prob, u, lambda x, a: rho_c * a * a)
                                             - _field_integral(prob, v, lambda x, a: rho_c * a * a)), rel=1e-9)
    assert np.linalg.eigvalsh(M.toarray()).min() > 0  # positive definite


def test_a_graded_capacity_weights_the_mass_where_it_is():
    # c = 1 + x on the box [0, 2] x [0, 1] x [0, 0.5]: int c dV = 0.5 * (2 + 2) = 2
    prob = HeatProblem(pr.box((2.0, 1.0, 0.5), degrees=(2, 2, 2)), refine=1)
    M = prob.mass(lambda x: 1.0 + x[:, 0])
    ones = np.ones(prob.ndof)
    assert ones @ M @ ones == pytest.approx(2.0, rel=1e-12)
    with pytest.raises(Exception, match="heat capacity"):
        prob.mass(-1.0)
