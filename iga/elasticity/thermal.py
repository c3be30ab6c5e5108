"""Thermal strain of the thermo-elastic coupling: alpha (T - T_ref), with T from a heat solution on the same
model (evaluated on each patch's own temperature spline at the elastic Gauss points), a number or a callable."""

from __future__ import annotations

import numpy as np

from geometry.errors import show

from iga.heat.coefficients import ScalarField, is_number
from iga.errors import ProblemError

__all__ = ["thermal_strain"]


def thermal_strain(problem, temperature, expansion, reference=0.0):
    """The callable ``(patch, x (m, 3), params (m, 3), chans) -> (m,)`` of alpha (T - T_ref) for
    :class:`iga.elasticity.volume.ElasticVolume`."""
    alpha = ScalarField(expansion, "thermal expansion coefficient", model=problem.model)
    if not is_number(reference) or not np.isfinite(reference):
        raise ProblemError(f"the reference temperature must be a finite number, got {show(reference)}")
    ref = float(reference)
    if hasattr(temperature, "temperature_spline") and hasattr(temperature, "problem"):
        heat = temperature
        if not _same_model(heat.problem.model, problem.model):
            raise ProblemError("the heat solution was computed on another model (its patches are not this elastic "
                               "problem's, patch for patch); solve the heat problem on the model of the elastic problem")

        def T_at(pi, x, params, chans):
            return heat.temperature_spline(pi).evaluate(params)[:, 0]
    else:
        T = ScalarField(temperature, "temperature", model=problem.model)

        def T_at(pi, x, params, chans):
            return T.values(x, chans, f"patch {pi}")

    def strain(pi, x, params, chans):
        return alpha.values(x, chans, f"patch {pi}") * (T_at(pi, x, params, chans) - ref)

    return strain


def _same_model(a, b) -> bool:
    """Whether two analysis models hold the same patches, patch for patch: the same tile spline, placement and
    map (a model normalised twice from one Microstructure is still the same model)."""
    def same_spline(s, t) -> bool:
        return s is t or (s is not None and t is not None and np.array_equal(s.control_points, t.control_points)
                          and np.array_equal(s.weights, t.weights) and all(
                              np.array_equal(U, V) for U, V in zip(s.knots, t.knots)))

    return a is b or (len(a.patches) == len(b.patches) and all(
        same_spline(p.spline, q.spline) and same_spline(p.outer, q.outer)
        and np.array_equal(p.placement, q.placement) for p, q in zip(a.patches, b.patches)))
