"""Exact sensitivities of an elastic solution's compliance with respect to its Young's modulus: per patch or tile
(a factor (1 + p_e) on E there) or per control value of the map's channel that E reads.

The compliance J = u . f of K(p) u = f with loads and supports that do not depend on p (homogeneous supports,
no thermal strain) is self-adjoint: its adjoint is u itself, so dJ/dp = -u . dK/dp u needs no extra solve.
With C = E C_1(nu) (both Lame constants are proportional to E), dK/dE is K / E pointwise:

    dJ/dp_e = - int_e eps(u) : C : eps(u) dV,      dJ/dE_c = - int R_c(y) eps(u) : C : eps(u) / E dV,

with R_c the map's basis (NURBS where it has weights) at each Gauss point's parameter y: one pass over the
Gauss points, the derivative of the discrete compliance (``tests/test_elastic_sensitivity.py`` compares it with
central differences of fresh solves).  Refused with :class:`iga.errors.ProblemError`: other outputs (their
adjoint is not built), prescribed displacements other than zero, thermal strains (their load depends on E),
and a Young's modulus that is not the channel asked for.
"""

from __future__ import annotations

import numpy as np

from geometry.errors import show

from iga.adjoint import design_map, map_basis, map_parameters
from iga.elasticity.shape import strain_and_stress
from iga.errors import ProblemError
from iga.outputs import Compliance, Output, gauss_pass

__all__ = ["elastic_sensitivity"]


def elastic_sensitivity(solution, output: Output, wrt: str = "tiles") -> np.ndarray:
    """dJ/dp of the compliance of an elastic ``solution`` (module notes): ``wrt="tiles"`` (tiles,) or
    ``"patches"`` (patches,) for a factor on E, in J per unit relative change; ``wrt="channel:NAME"`` per control
    value of the map's channel NAME that E reads, shaped like the map's control grid, in J per Pa."""
    if not isinstance(output, Compliance):
        raise ProblemError(f"elastic sensitivities are of Compliance() (self-adjoint: no extra solve); "
                           f"{show(output)} has no elastic adjoint here")
    prob = solution.problem
    if prob.thermal_strain is not None:
        raise ProblemError("elastic sensitivities: the thermal strain's load depends on Young's modulus (its "
                           "term is not built); differentiate a problem without .thermal(...)")
    prescribed = solution._prescribed
    if prescribed is None:
        raise ProblemError("elastic sensitivities need the solve's prescribed values, which a distributed solve "
                           "does not keep")
    if np.any(np.asarray(prescribed) != 0):
        raise ProblemError("elastic sensitivities of the compliance need supports that hold at zero displacement "
                           "(a prescribed non-zero displacement does work the loads' u . f does not count)")
    channel = None
    if isinstance(wrt, str) and wrt.startswith("channel:"):
        channel = wrt.split(":", 1)[1]
        if prob.youngs.kind != "channel" or prob.youngs.spec != channel:
            raise ProblemError(f"wrt={wrt!r}: Young's modulus is {show(prob.youngs.spec)}, not the channel "
                               f"{show(channel)}; the derivative is by the channel E reads")
        D, placed = design_map(prob, channel)
        out = np.zeros(int(np.prod(D.control_points.shape[:3])))
    elif wrt in ("tiles", "patches"):
        if wrt == "tiles" and not hasattr(prob.model, "tiles"):
            raise ProblemError("wrt='tiles' needs a micro-structure (its patches know their tiles); use 'patches'")
        out = np.zeros(len(prob.model.patches))
    else:
        raise ProblemError(f"wrt must be 'tiles', 'patches' or 'channel:NAME' for an elastic solution, got "
                           f"{show(wrt)}")
    n = prob.ndof
    patches = prob.model.patches

    def add(chunk, space, vals, grads, wv, x, chans):
        E, eps, sig = strain_and_stress(prob, chunk, grads, x, chans)
        energy2 = np.sum(sig * eps, axis=(1, 2)) * wv  # eps : C : eps
        if channel is None:
            out[np.asarray(chunk)] -= energy2.reshape(len(chunk), -1).sum(1)
        else:
            out[:] -= map_basis(D, map_parameters(patches, chunk, space, D, placed)).T @ (energy2 / E)

    gauss_pass(prob, solution.u.reshape(3, n), add)
    if channel is not None:
        return out.reshape(D.control_points.shape[:3])
    if wrt == "patches":
        return out
    tiles = np.array([p.tile for p in patches])
    return np.bincount(tiles, weights=out, minlength=len(prob.model.tiles))
