"""Exact sensitivities of heat outputs by the adjoint: the derivative of an output J (:mod:`iga.outputs`) with
respect to the conductivity of each patch or tile, from one extra solve.

The discrete problem is R(u, p) = K(p) u - f = 0 on the free unknowns (interface constraints and Dirichlet
values eliminated as the solve eliminates them).  With the adjoint lambda, K lambda = dJ/du on the free
unknowns (the same reduced matrix: the heat forms are symmetric) and zero on the prescribed ones,

    dJ/dp = dJ/dp (explicit) - lambda . (dK/dp u - df/dp).

A factor (1 + p_e) on the conductivity of patch (or tile) e scales its diffusion matrix K_e, so
dJ/dp_e = - int_e grad lambda . k grad T dV, integrated by the problem's own Gauss rule: the derivative of
the discrete output, exact to round-off (a finite difference agrees to its own truncation error,
``tests/test_sensitivity.py``).  Robin, Neumann and source terms do not depend on the conductivity.
A conductivity given as a channel of the deformation map D is linear in D's control values k_c of that
channel: k(y) = sum_c R_c(y) k_c at the point's parameter y of D (R_c the NURBS basis where D has weights), so
dJ/dk_c = - int R_c(y) grad lambda . grad T dV (:func:`channel_sensitivity`).
"""

from __future__ import annotations

import numpy as np

from geometry.errors import show

from iga.adjoint import ChannelScatter, adjoint, design_map, map_basis, map_parameters, per_patch_or_tile
from iga.errors import ProblemError
from iga.heat.coefficients import TENSOR_PAIRS
from iga.outputs import Output, gauss_pass
from iga.parameter_sensitivity import parameter_sensitivity
from iga.shape_sensitivity import shape_sensitivity

__all__ = ["gradient", "adjoint", "conductivity_sensitivity", "channel_sensitivity", "design_map", "map_basis",
           "map_parameters"]


def gradient(solution, output: Output, wrt: str = "tiles", solver: str = "auto") -> np.ndarray:
    """The derivative of ``output`` (one of :mod:`iga.outputs`) on a steady heat ``solution`` by the adjoint:
    ``wrt="tiles"`` or ``"patches"``, per tile or patch for a factor (1 + p) on its conductivity
    (:func:`conductivity_sensitivity`); ``wrt="channel:NAME"``, per control value of the map's channel NAME, which
    the conductivity reads (:func:`channel_sensitivity`); ``wrt="map"``, per coordinate of the deformation map's
    control points, shaped (n1, n2, n3, 3) (:func:`iga.shape_sensitivity.shape_sensitivity`); ``wrt="parameters"``
    or ``"faces"``, per control value of a field-graded paving's parameter field or per value on its cell walls
    (:func:`iga.parameter_sensitivity.parameter_sensitivity`)."""
    if isinstance(wrt, str) and wrt.startswith("channel:"):
        return channel_sensitivity(solution, output, wrt.split(":", 1)[1], solver)
    if wrt == "map":
        return shape_sensitivity(solution, output, solver)
    if wrt in ("parameters", "faces"):
        return parameter_sensitivity(solution, output, wrt, solver)
    if wrt not in ("tiles", "patches"):
        raise ProblemError(f"wrt must be 'tiles', 'patches', 'channel:NAME', 'map', 'parameters' or 'faces', got "
                           f"{show(wrt)}")
    return conductivity_sensitivity(solution, output, per={"tiles": "tile", "patches": "patch"}[wrt], solver=solver)


def conductivity_sensitivity(solution, output: Output, per: str = "patch", solver: str = "auto") -> np.ndarray:
    """dJ/dp_e of ``output`` for a factor (1 + p_e) on the conductivity of every patch (``per="patch"``, (patches,))
    or every tile (``per="tile"``, (tiles,), a micro-structure's), at p = 0: one adjoint solve and one pass over the
    Gauss points (module notes).  Units: those of J per unit relative change of the conductivity."""
    if per not in ("patch", "tile"):
        raise ProblemError(f"per must be 'patch' or 'tile', got {show(per)}")
    prob = solution.problem
    if per == "tile" and not hasattr(prob.model, "tiles"):
        raise ProblemError("per='tile' needs a micro-structure (its patches know their tiles); use per='patch'")
    lam = adjoint(solution, output, solver)
    out = np.zeros(len(prob.model.patches))

    def add(chunk, space, vals, grads, wv, x, chans):
        where = f"patches {chunk[0]}..{chunk[-1]}"
        k = prob.conductivity.values(x, {c: np.reshape(v, -1) for c, v in chans.items()}, where)
        gT, gL = grads[:, 0], grads[:, 1]
        if k.ndim == 1:
            dens = k * np.sum(gT * gL, axis=1)
        else:  # the six tensor components (xx, yy, zz, xy, xz, yz)
            dens = sum(k[:, j] * (gL[:, r] * gT[:, s] + (gL[:, s] * gT[:, r] if r != s else 0.0))
                       for j, (r, s) in enumerate(TENSOR_PAIRS))
        out[np.asarray(chunk)] -= (dens * wv).reshape(len(chunk), -1).sum(1)

    gauss_pass(prob, np.stack([solution.u, lam]), add)
    return per_patch_or_tile(prob, out, per)


def channel_sensitivity(solution, output: Output, channel: str, solver: str = "auto"):
    """dJ/dk_c of ``output`` with respect to the control values of the channel ``channel`` of the deformation map
    (the heat problem's conductivity must be that channel): an array shaped like D's control grid (module
    notes); for a model of several maps (a V-rep union: its primitives and bridges) a tuple of such arrays, one
    per map in the order the patches first name them.  Units: those of J per W/(m K) of a control value."""
    prob = solution.problem
    k = prob.conductivity
    if k.scalar is None or k.scalar.kind != "channel" or k.scalar.spec != channel:
        raise ProblemError(f"channel_sensitivity: the conductivity is not the channel {show(channel)} of the map; "
                           "give the problem conductivity=" + repr(channel) + " (or differentiate the channel the "
                           "conductivity reads)")
    scatter = ChannelScatter(prob, channel)
    lam = adjoint(solution, output, solver)

    def add(chunk, space, vals, grads, wv, x, chans):
        scatter.add(chunk, space, -wv * np.sum(grads[:, 0] * grads[:, 1], axis=1))  # -grad T . grad lambda w|J|

    gauss_pass(prob, np.stack([solution.u, lam]), add)
    return scatter.result()
