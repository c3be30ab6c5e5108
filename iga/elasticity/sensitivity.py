"""Exact sensitivities of an elastic solution's compliance or von Mises norm with respect to its material: per
patch or tile (a factor (1 + p_e) on the whole stiffness C there) or per control value of a map's channel that
the material reads (Young's modulus, Poisson's ratio, or a cubic material tabulated over the channel:
:mod:`iga.elasticity.material`).

The compliance J = u . f of K(p) u = f with loads and supports that do not depend on p (homogeneous supports,
no thermal strain) is self-adjoint: its adjoint is u itself, so dJ/dp = -u . dK/dp u needs no extra solve:

    dJ/dp_e = - int_e eps(u) : C : eps(u) dV,      dJ/dc = - int R_c(y) eps(u) : C' : eps(u) dV,

with C' the derivative of the stiffness by the channel's value at the point (C / E for Young's modulus) and R_c
the map's basis (NURBS where it has weights) at each Gauss point's parameter y: one pass over the Gauss points,
the derivative of the discrete compliance (``tests/test_elastic_sensitivity.py`` compares it with central
differences of fresh solves).  The von Mises norm J = (int sigma_vm^p dV / V)^(1/p)
(:class:`iga.outputs.VonMisesNorm`) depends on the material through the stress too (d sigma_vm = 3/2 s : dC :
eps / sigma_vm at a fixed strain, s the deviator) and needs one adjoint solve, K lambda = dJ/du
(:func:`iga.elasticity.adjoint.elastic_adjoint`):

    dJ/dc = int R_c (J^(1-p) / V 3/2 sigma_vm^(p-2) s : C' : eps(u) - eps(lambda) : C' : eps(u)) dV,

and per tile with C for C' (the first term is then J^(1-p) / V sigma_vm^p).  Prescribed displacements may be
non-zero there (lambda vanishes on them).  Refused with :class:`iga.errors.ProblemError`: other outputs,
prescribed displacements other than zero for the compliance, thermal strains (their load depends on the
material), and a channel the material does not read.
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
    (tiles,) or ``"patches"`` (patches,) for a factor on the stiffness, in the output's units per unit relative
    change; ``wrt="channel:NAME"`` per control value of the map's channel NAME that the material reads, shaped like
    the map's control grid (a tuple of them for a model of several maps), per unit of the channel.  ``solver``: the von Mises norm's adjoint solve."""
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
        if not prob.material.reads(channel):
            raise ProblemError(f"wrt={wrt!r}: the material reads no channel {show(channel)} ({_reads(prob)}); the "
                               "derivative is by a channel the material reads")
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
        _, eps, sig = strain_and_stress(prob, chunk, grads[:, :3], x, chans)
        if channel is None:  # d(C : eps) by a factor (1 + p_e) on the whole stiffness
            dsig = sig
        else:
            flat = {c: np.reshape(v, -1) for c, v in chans.items()}
            dsig = prob.material.slopes(x, flat, f"patches {chunk[0]}..{chunk[-1]}", channel).stress(eps)
        if stress:  # J^(1-p) / V 3/2 sigma_vm^(p-2) s : dC : eps - eps(lambda) : dC : eps(u)
            dev, vm = von_mises(sig)
            scale = np.where(vm > 0, np.where(vm > 0, vm, 1.0) ** (p - 2), 0.0)
            dens = (1.5 * factor * scale * np.sum(dev * dsig, axis=(1, 2))
                    - np.sum(dsig * strain(grads[:, 3:]), axis=(1, 2))) * wv
        else:
            dens = -np.sum(dsig * eps, axis=(1, 2)) * wv  # - eps : dC : eps
        if channel is None:
            out[np.asarray(chunk)] += dens.reshape(len(chunk), -1).sum(1)
        else:
            scatter.add(chunk, space, dens)

    gauss_pass(prob, fields, add)
    if channel is not None:
        return scatter.result()
    return per_patch_or_tile(prob, out, {"tiles": "tile", "patches": "patch"}[wrt])


def _reads(prob) -> str:
    """What the material's constants are, for messages."""
    m = prob.material
    if m.kind == "isotropic":
        return f"Young's modulus {show(m.youngs.spec)}, Poisson's ratio {show(m.poisson.spec)}"
    return f"a cubic material of the channel {show(m.channel)}" if m.channel else "a cubic material of numbers"
