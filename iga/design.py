"""Design by gradient: the control values of a material channel of the deformation map, optimised for an output.

:func:`optimize` takes a steady :class:`iga.HeatProblem` whose conductivity is a channel NAME of the deformation
map D (a graded material, e.g. aluminium near the heated face and steel away from it: Massarwi et al. 2018,
Fig. 18) and changes that channel's control values, within ``bounds``, to minimise an output of
:mod:`iga.outputs` (e.g. ``TemperatureNorm(8)``, a smooth maximum of the temperature), optionally at a fixed
volume mean of the channel (for a channel interpolated linearly between two materials, a fixed mean is a
fixed volume of each: the mass).  Every evaluation is an exact analysis of the same micro-structure with the
new map; the gradient is one adjoint solve (:func:`iga.sensitivity.channel_sensitivity`).  SciPy's SLSQP
(sequential quadratic programming, which takes bounds and the linear mean constraint directly) runs in
variables scaled to [0, 1]; the objective is scaled by its initial value.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from geometry.errors import show
from geometry.numbers import is_real

from iga.adjoint import design_map, map_basis, map_parameters
from iga.errors import ProblemError
from iga.optimiser import DesignResult, DesignStep, analysed, bounds_pair, check_design, redesigned, run_slsqp
from iga.outputs import Output, evaluated, gauss_pass
from iga.parameter_design import optimize_parameters
from iga.shape_design import optimize_shape

__all__ = ["optimize", "DesignResult", "DesignStep", "redesigned", "channel_volumes", "solid_fraction"]


def channel_volumes(problem, D, placed: bool) -> np.ndarray:
    """int R_c dV (m^3) of every control value c of D's channels over the model (D's basis at each Gauss point's
    parameter): the mean of a channel with control values k is volumes . k / volume."""
    patches = problem.model.patches
    out = np.zeros(int(np.prod(D.control_points.shape[:3])))

    def add(chunk, space, vals, grads, wv, x, chans):
        out[:] += map_basis(D, map_parameters(patches, chunk, space, D, placed)).T @ wv

    gauss_pass(problem, np.zeros((1, problem.ndof)), add)
    return out


def solid_fraction(problem, D, placed: bool, mean):
    """For a macro model whose cubic material is tabulated over a channel of D (a table with ``fraction(p)`` and
    ``fraction_slope(p)``, :class:`iga.StiffnessTable`): values -> (the mean solid volume fraction
    int phi(c(x)) dV / V, its gradient by the channel's control values (n,)), c(x) = R(x) . values at the Gauss
    points (D's basis there, gathered once)."""
    table = getattr(getattr(problem, "material", None), "table", None)
    if not (callable(getattr(table, "fraction", None)) and callable(getattr(table, "fraction_slope", None))):
        raise ProblemError("keep_fraction needs an elastic macro model whose cubic material is tabulated over the "
                           "channel (iga.stiffness_table(...).material(channel)): it knows the solid "
                           "volume fraction")
    if mean is not None:
        raise ProblemError(f"keep_fraction keeps the solid fraction; mean = {show(mean)} would constrain the "
                           "channel's mean too: drop one")
    patches, rows, weights = problem.model.patches, [], []

    def add(chunk, space, vals, grads, wv, x, chans):
        rows.append(map_basis(D, map_parameters(patches, chunk, space, D, placed)))
        weights.append(wv)

    gauss_pass(problem, np.zeros((1, problem.ndof)), add)
    B, w = sp.vstack(rows).tocsr(), np.concatenate(weights)
    V = float(w.sum())

    def fraction(values):
        c = B @ values
        return float(w @ table.fraction(c)) / V, B.T @ (w * table.fraction_slope(c)) / V

    return fraction


def _check(wrt, bounds, mean) -> None:
    """The arguments of a channel design (:func:`iga.optimiser.check_design` checks the rest)."""
    if not (isinstance(wrt, str) and wrt.startswith("channel:")):
        raise ProblemError(f"wrt must be 'channel:NAME' (the control values of the map's channel NAME, which the "
                           f"conductivity reads), 'map' (its control points) or 'parameters' (a field-graded "
                           f"paving's parameter field), got {show(wrt)}")
    if not bounds_pair(bounds, positive=True):
        raise ProblemError(f"bounds must be (low, high) of the channel with 0 < low < high, e.g. (54, 205) W/(m K) "
                           f"for steel to aluminium conductivities, or Young's moduli in Pa, got {show(bounds)}")
    if mean is not None and not (is_real(mean) and bounds[0] <= mean <= bounds[1]):
        raise ProblemError(f"mean = {show(mean)} cannot be met within bounds {show(tuple(bounds))}: a mean of the "
                           "channel lies between its bounds")


def optimize(problem, objective: Output, wrt: str = "channel:k", bounds=None, mean: float | None = None,
             maxiter: int = 30, tol: float = 1e-6, solver: str = "auto", hold=(), keep_volume: bool = True,
             keep_fraction: bool = False, axes: str = "xyz") -> DesignResult:
    """Minimise ``objective`` over the control values of the map's channel named in ``wrt`` (see the module), or
    over the map's control points (``wrt="map"``: :func:`iga.shape_design.optimize_shape`), or over the control
    values of a field-graded micro-structure's parameter field (``wrt="parameters"``:
    :func:`iga.parameter_design.optimize_parameters`).

    Parameters
    ----------
    problem : a steady :class:`iga.HeatProblem` whose conductivity is the channel (``conductivity="k"``), or
        an :class:`iga.ElasticityProblem` whose material reads it (``youngs="E"``, or a cubic material tabulated
        over it: a lattice's macro model, :meth:`iga.StiffnessTable.material`; objective
        ``Compliance()``, whose gradient needs no adjoint solve, or ``VonMisesNorm(p)``, one:
        :mod:`iga.elasticity.sensitivity`)
    objective : an output of :mod:`iga.outputs` with a gradient, e.g. ``TemperatureNorm(8)`` (C)
    wrt : ``"channel:NAME"``, ``"map"`` or ``"parameters"``
    bounds : (low, high) of every control value (W/(m K); default (54, 205), steel to aluminium; Pa for E); the initial
        values must lie within them.  For ``wrt="map"``: the largest move of a control point coordinate from its
        start (m); for ``wrt="parameters"``: (low, high) of the field's control values (required)
    mean : the volume mean of the channel to keep (W/(m K)); None: free
    maxiter, tol : SLSQP's iteration limit and tolerance (on the objective scaled by its initial value)
    solver : the linear solver of every analysis and adjoint
    hold : ``wrt="map"`` and ``"parameters"``: the map's faces (``"wmin"``, ...) whose control points (or the
        field's control values there) stay
    keep_volume : ``wrt="map"`` and ``"parameters"``: whether the solid volume is kept at its start
    axes : ``wrt="map"``: the coordinates of the control points that move (``"z"``: heights only)
    keep_fraction : a macro model's tabulated material (``wrt="channel:NAME"``): whether the mean solid volume
        fraction of its tile family over the model, int phi(c(x)) dV / V, is kept at its start (a lattice's
        mass; ``mean`` must then be None)

    Progress: one line per iteration on stderr where progress is on.
    """
    if wrt == "map":
        return optimize_shape(problem, objective, bounds, hold, keep_volume, maxiter, tol, solver, axes)
    if wrt == "parameters":
        return optimize_parameters(problem, objective, bounds, hold, keep_volume, maxiter, tol, solver)
    bounds = (54.0, 205.0) if bounds is None else bounds
    check_design(problem, objective, maxiter, elastic=True)
    _check(wrt, bounds, mean)
    name = wrt.split(":", 1)[1]
    elastic = hasattr(problem, "material")
    read = None if elastic else problem.conductivity.scalar
    if not (problem.material.reads(name) if elastic else read is not None and read.kind == "channel"
            and read.spec == name):
        raise ProblemError(f"wrt={wrt!r}: the {'material' if elastic else 'conductivity'} does not read the channel "
                           f"{show(name)}; the design changes the channel it reads")
    D, placed = design_map(problem, name)
    v0 = np.asarray(D.channel(name), float).reshape(-1)
    lo, hi = float(bounds[0]), float(bounds[1])
    if v0.min() < lo - 1e-9 * hi or v0.max() > hi + 1e-9 * hi:
        raise ProblemError(f"the channel {show(name)} starts at {v0.min():.4g} .. {v0.max():.4g}, outside bounds "
                           f"{show((lo, hi))}; widen the bounds or start from a design inside them")
    fraction = solid_fraction(problem, D, placed, mean) if keep_fraction else None
    vol = channel_volumes(problem, D, placed)
    total = float(vol.sum())

    def analyse(z):
        values = lo + np.clip(z, 0, 1) * (hi - lo)
        new = D.with_channel(name, values.reshape(D.control_points.shape[:3]))
        sol = analysed(problem.on(redesigned(problem.model, D, new, placed)), solver)
        measure, slope = (float(vol @ values / total), None) if fraction is None else fraction(values)
        return values, sol, evaluated(objective, sol), sol.gradient(objective, wrt, solver).reshape(-1) * (
            hi - lo), measure, None if slope is None else slope * (hi - lo)

    constraints = []
    if mean is not None:
        # vol . (lo + z (hi - lo)) / total = mean, i.e. vol . z / total = (mean - lo) / (hi - lo): linear, O(1)
        a, b = vol / total, (mean - lo) / (hi - lo)
        constraints = [{"type": "eq", "fun": lambda z: np.array([a @ z - b]), "jac": lambda z: a[None, :]}]
    z0 = (np.clip(v0, lo, hi) - lo) / (hi - lo)
    return run_slsqp(objective, analyse, z0, (0.0, 1.0), hi - lo, constraints, maxiter, tol,
                     "mean" if fraction is None else "solid fraction", D.control_points.shape[:3], keep_fraction)


