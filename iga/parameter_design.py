"""Grading by gradient: the parameter field of a field-graded micro-structure (:func:`tiling.field_graded`: e.g.
the arm widths of :func:`tiling.library.face_graded_cross` on every cell wall) optimised for an output of a
steady heat analysis, or for the compliance of an elastic one (:mod:`iga.elasticity.shape`).

:func:`optimize_parameters` (``iga.optimize(problem, objective, wrt="parameters", bounds=(low, high))``) changes
the field's control values (a parameter spline's coefficients or a channel of the map) within ``bounds`` (a
B-spline lies in the hull of its control values, so the field on every wall stays within them: choose them
inside the family's range), except those on the faces named in ``hold`` (a clamped field's values on a face
of the map are its control values there alone: holding the heated face keeps the tiles' area there, and so
the power a flux brings in), optionally keeping the solid volume of the micro-structure at its start (a
nonlinear equality whose gradient is :class:`iga.outputs.Volume`'s).  Every evaluation re-paves the map with
the family at the new field (the exact tiles of their wall values) and analyses it; the gradient is one
adjoint solve (:mod:`iga.parameter_sensitivity`).  SLSQP runs in variables scaled to [0, 1].
"""

from __future__ import annotations

import numpy as np

import tiling
from geometry import SplineFunction
from geometry.errors import show
from geometry.numbers import is_real

from iga.adjoint import shape_map
from iga.errors import ProblemError
from iga.optimiser import analysed, bounds_pair, check_design, free_mask, run_slsqp
from iga.outputs import Output, Volume, evaluated
from iga.parameter_sensitivity import STEP, parameter_sensitivity

__all__ = ["optimize_parameters"]


def _field_values(grading, D) -> np.ndarray:
    """The field's control values: a parameter spline's coefficients (n1, n2, n3), the map channel's control values
    (n1, n2, n3), or the one number (a 0-d array)."""
    field = grading.field
    if isinstance(field, SplineFunction):
        return np.array(field.coefficients[..., 0], float)
    if isinstance(field, str):
        return np.array(D.channel(field), float)
    if is_real(field):
        return np.array(float(field))
    raise ProblemError("wrt='parameters': the field is a callable, which has no control values to optimise; give "
                       "it as a parameter spline (geometry.SplineFunction) or a channel of the map")


def _with_values(grading, D, values: np.ndarray):
    """(map, field) of the design with the field's control values ``values``."""
    field = grading.field
    if isinstance(field, SplineFunction):
        return D, SplineFunction(field.degrees, field.knots, values.reshape(field.coefficients.shape), field.weights)
    if isinstance(field, str):
        return D.with_channel(field, values.reshape(D.control_points.shape[:3])), field
    return D, float(values)


def _family_takes(family, lo: float, hi: float) -> None:
    """Refuse bounds whose ends (less and more a derivative's step, :data:`iga.parameter_sensitivity.STEP`) the
    family refuses as wall values, before any analysis: SLSQP would reach them mid-run."""
    faces = ("umin", "umax", "vmin", "vmax", "wmin", "wmax")
    name = family.__name__ if hasattr(family, "__name__") else show(family)  # (a function, or another callable)
    for v in (lo - STEP * max(1.0, abs(lo)), hi + STEP * max(1.0, abs(hi))):
        try:
            family(**{f: v for f in faces})
        except tiling.TilingError as exc:
            raise ProblemError(f"wrt='parameters': bounds {show((lo, hi))} reach outside the range of the family "
                               f"{name} (with a derivative's step of {STEP:g} beyond them): {exc}; narrow the "
                               "bounds") from None


def optimize_parameters(problem, objective: Output, bounds, hold=(), keep_volume: bool = True, maxiter: int = 30,
                        tol: float = 1e-6, solver: str = "auto"):
    """Minimise ``objective`` over the control values of the model's parameter field (module notes); returns an
    :class:`iga.optimiser.DesignResult` whose ``values`` are the final control values (shaped like the field's)
    and whose steps record the solid volume (m^3)."""
    check_design(problem, objective, maxiter, elastic=True)
    grading = getattr(problem.model, "grading", None)
    if grading is None:
        raise ProblemError("wrt='parameters' designs the parameter field of a field-graded micro-structure "
                           "(tiling.field_graded, tiling.leaf_graded); this model has none")
    if not bounds_pair(bounds):
        raise ProblemError(f"wrt='parameters': bounds must be (low, high) of the field's control values, low < high "
                           f"(inside the family's range, e.g. (0.15, 0.6) arm widths), got {show(bounds)}")
    D, _ = shape_map(problem)
    v0 = _field_values(grading, D)
    lo, hi = float(bounds[0]), float(bounds[1])
    if v0.min() < lo or v0.max() > hi:
        raise ProblemError(f"the parameter field starts at {v0.min():.4g} .. {v0.max():.4g}, outside bounds "
                           f"{show((lo, hi))}; widen the bounds or start from a field inside them")
    _family_takes(grading.family, lo, hi)
    free = free_mask(v0.shape, hold) if v0.ndim == 3 else np.ones(v0.shape, bool)
    if hold and v0.ndim != 3:
        raise ProblemError("hold: the field is one number (every wall alike); give a parameter spline or a channel "
                           "to hold some walls")
    if not free.any():
        raise ProblemError(f"hold = {show(list(hold))} holds every control value of the field: nothing can move")
    volume, model = Volume(), problem.model

    def analyse(z):
        values = v0.copy()
        values[free] = lo + np.clip(z, 0, 1) * (hi - lo)
        new, field = _with_values(grading, D, values)
        ms = grading.rebuild(new, field, model.name)
        sol = analysed(problem.on(ms), solver)
        g = np.asarray(parameter_sensitivity(sol, objective, "parameters", solver))[free] * (hi - lo)
        gV = np.asarray(parameter_sensitivity(sol, volume, "parameters", solver))[free] * (hi - lo)
        return values, sol, evaluated(objective, sol), g, evaluated(volume, sol), gV

    z0 = (v0[free] - lo) / (hi - lo)
    return run_slsqp(objective, analyse, z0, (0.0, 1.0), hi - lo, [], maxiter, tol, "volume", v0.shape,
                     keep_measure=keep_volume)
