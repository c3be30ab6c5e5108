"""Exact sensitivities of an elastic solution's compliance or von Mises norm with respect to its Young's modulus:
per patch or tile (a factor (1 + p_e) on E there) or per control value of the map's channel that E reads.

The compliance J = u . f of K(p) u = f with loads and supports that do not depend on p (homogeneous supports,
no thermal strain) is self-adjoint: its adjoint is u itself, so dJ/dp = -u . dK/dp u needs no extra solve.
With C = E C_1(nu) (both Lame constants are proportional to E), dK/dE is K / E pointwise:

    dJ/dp_e = - int_e eps(u) : C : eps(u) dV,      dJ/dE_c = - int R_c(y) eps(u) : C : eps(u) / E dV,

with R_c the map's basis (NURBS where it has weights) at each Gauss point's parameter y: one pass over the
Gauss points, the derivative of the discrete compliance (``tests/test_elastic_sensitivity.py`` compares it with
central differences of fresh solves).  The von Mises norm J = (int sigma_vm^p dV / V)^(1/p)
(:class:`iga.outputs.VonMisesNorm`) depends on E through the stress too (sigma_vm scales with E at a fixed
strain) and needs one adjoint solve, K lambda = dJ/du (:func:`iga.elasticity.adjoint.elastic_adjoint`):

    dJ/dp_e = int_e (J^(1-p) / V sigma_vm^p - eps(lambda) : C : eps(u)) dV,   and / E with R_c per channel value.

Prescribed displacements may be non-zero there (lambda vanishes on them).  Refused with
:class:`iga.errors.ProblemError`: other outputs, prescribed displacements other than zero for the compliance,
thermal strains (their load depends on E), and a Young's modulus that is not the channel asked for.
"""

from __future__ import annotations

import numpy as np

from geometry.errors import show

from iga.adjoint import ChannelScatter, per_patch_or_tile
from iga.elasticity.adjoint import elastic_adjoint
from iga.elasticity.forms import strain
from iga.elasticity.shape import self_adjoint, strain_and_stress
from iga.errors import ProblemError
from iga.outputs import Output, VonMisesNorm, Volume, evaluated, gauss_pass, von_mises

__all__ = ["elastic_sensitivity"]


def elastic_sensitivity(solution, output: Output, wrt: str = "tiles", solver: str = "auto") -> np.ndarray:
    """dJ/dp of the compliance or the von Mises norm of an elastic ``solution`` (module notes): ``wrt="tiles"``
    (tiles,) or ``"patches"`` (patches,) for a factor on E, in the output's units per unit relative change;
    ``wrt="channel:NAME"`` per control value of the map's channel NAME that E reads, shaped like the map's control
    grid (a tuple of them for a model of several maps), per Pa.  ``solver``: the von Mises norm's adjoint solve."""
    solution.problem.gauss_geometry.keep(solution.problem)  # the value, the adjoint load and this pass
    stress = isinstance(output, VonMisesNorm)
    if stress:
        if solution.problem.thermal_strain is not None:
            raise ProblemError("elastic sensitivities: a thermal strain's load depends on E (its terms are not "
                               "built); differentiate a problem without .thermal(...)")
    else:
        self_adjoint(solution, output, "elastic sensitivities", "sensitivity by Young's modulus")
    prob = solution.problem
    channel = None
    if isinstance(wrt, str) and wrt.startswith("channel:"):
        channel = wrt.split(":", 1)[1]
        if prob.youngs.kind != "channel" or prob.youngs.spec != channel:
            raise ProblemError(f"wrt={wrt!r}: Young's modulus is {show(prob.youngs.spec)}, not the channel "
                               f"{show(channel)}; the derivative is by the channel E reads")
        scatter = ChannelScatter(prob, channel)
    elif wrt in ("tiles", "patches"):
        if wrt == "tiles" and not hasattr(prob.model, "tiles"):
            raise ProblemError("wrt='tiles' needs a micro-structure (its patches know their tiles); use 'patches'")
        out = np.zeros(len(prob.model.patches))
    else:
        raise ProblemError(f"wrt must be 'tiles', 'patches' or 'channel:NAME' for an elastic solution, got "
                           f"{show(wrt)}")

    n = prob.ndof
    fields = solution.u.reshape(3, n)
    if stress:  # the adjoint, and the explicit term's factor J^(1-p) / V
        p = output.p
        factor = evaluated(output, solution) ** (1 - p) / Volume().value(solution)
        fields = np.vstack([fields, elastic_adjoint(solution, output, solver).reshape(3, n)])

    def add(chunk, space, vals, grads, wv, x, chans):
        E, eps, sig = strain_and_stress(prob, chunk, grads[:, :3], x, chans)
        if stress:  # J^(1-p) / V sigma_vm^p - eps(lambda) : C : eps(u)
            vm = von_mises(sig)[1]
            dens = (factor * vm**p - np.sum(sig * strain(grads[:, 3:]), axis=(1, 2))) * wv
        else:
            dens = -np.sum(sig * eps, axis=(1, 2)) * wv  # - eps : C : eps
        if channel is None:
            out[np.asarray(chunk)] += dens.reshape(len(chunk), -1).sum(1)
        else:
            scatter.add(chunk, space, dens / E)

    gauss_pass(prob, fields, add)
    if channel is not None:
        return scatter.result()
    return per_patch_or_tile(prob, out, {"tiles": "tile", "patches": "patch"}[wrt])
