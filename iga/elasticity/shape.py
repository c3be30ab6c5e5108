"""The shape derivative of an elastic solution's compliance or von Mises norm, as densities against the velocity
gradient: what ``wrt="map"`` (:mod:`iga.shape_sensitivity`) and ``wrt="parameters"``
(:mod:`iga.parameter_sensitivity`) contract with their velocities.

The compliance J = l(u) of a(u, v) = l(v) is self-adjoint, so dJ = 2 l'(u) - a'(u, u) for a move V of the
material points, and with grad u -> grad u - grad u grad V, dx -> div V dx, dA -> div_G V dA (material
coefficients: numbers or channels of the map, which move with the points):

    a'(u, u) = int eps : C : eps div V - 2 sigma : (grad u grad V) dV,
    l'(u)   = int f . u div V dV + int t . u div_G V dA,

i.e. dJ = sum_q Q_q : grad V_q with Q = 2 grad u^T sigma + (2 f . u - eps : C : eps) I in the volume and
Q = 2 (t . u) (I - n n) on traction faces.  The von Mises norm J = (I / V)^(1/p), I = int sigma_vm^p dV, takes
one adjoint solve, a(v, lambda) = J'(u) v (:func:`iga.elasticity.adjoint.elastic_adjoint`), and
dJ = J'_explicit + l'(lambda) - a'(u, lambda), where d sigma_vm = 3/2 (C : s) : d eps / sigma_vm (s the
deviator; C : s = 2 mu s for an isotropic material) at fixed u gives the explicit part: with c = J^(1-p) / V,

    Q = grad lambda^T sigma(u) + grad u^T sigma(lambda) - 3/2 c sigma_vm^(p-2) grad u^T (C : s)
        + (c / p (sigma_vm^p - J^p) - eps(u) : C : eps(lambda) + f . lambda) I,

and (t . lambda) (I - n n) on traction faces (the compliance's formulas with 2 u for lambda, and no explicit
part but the loads').  The material is isotropic or cubic (:mod:`iga.elasticity.material`); where a moved point
reads a channel of the map elsewhere (``wrt="parameters"``), the integrand's derivative by that channel (C') is
handed on as ``dk``.  ``tests/test_elastic_sensitivity.py`` and ``tests/test_cubic_material.py`` compare both with
central differences of fresh solves.  Refused: other outputs, pressures (their direction moves with the face), point loads (they stay where
they are while the material moves), callables of x, thermal strains and prescribed displacements other than zero.
"""

from __future__ import annotations

import numpy as np

from geometry.errors import show

from iga.elasticity.forms import moduli, strain
from iga.errors import ProblemError
from iga.elasticity.adjoint import elastic_adjoint
from iga.outputs import Compliance, Volume, VonMisesNorm, evaluated, gauss_pass, von_mises

__all__ = ["elastic_densities", "strain_and_stress", "self_adjoint", "drag_channel"]


def self_adjoint(solution, output, what: str, subject: str = "shape derivative") -> None:
    """Refuse what makes the compliance's adjoint other than the solution itself: another output, and what
    :func:`held_at_zero` refuses."""
    if not isinstance(output, Compliance):
        raise ProblemError(f"{what}: the elastic {subject} is of Compliance() (self-adjoint: no extra solve), got "
                           f"{show(output)}")
    held_at_zero(solution, what)


def held_at_zero(solution, what: str) -> None:
    """Refuse a thermal strain (its load depends on the material and the shape), prescribed displacements other
    than zero (their work is not in u . f, and they would move with the boundary) and a distributed solve (no
    prescribed values kept)."""
    if solution.problem.thermal_strain is not None:
        raise ProblemError(f"{what}: the thermal strain's terms are not built; differentiate a problem without "
                           ".thermal(...)")
    if solution._prescribed is None or np.any(np.asarray(solution._prescribed) != 0):
        raise ProblemError(f"{what} needs supports that hold at zero displacement (and a serial solve)")


def _check(solution, output, what: str) -> None:
    """:func:`self_adjoint` (the von Mises norm: :func:`held_at_zero`), and the loads and materials whose shape
    terms are built."""
    if isinstance(output, VonMisesNorm):
        held_at_zero(solution, what)
    else:
        self_adjoint(solution, output, what)
    prob = solution.problem
    if prob.point_loads:
        raise ProblemError(f"{what}: a point load stays where it is while the material moves (its term is not "
                           "built); use a traction")
    for load in prob.loads:
        if load.kind != "traction" or load.value.kind != "vector":
            raise ProblemError(f"{what}: the {load.kind} on {show(load.tag)} must be a traction of three numbers (a "
                               "pressure's direction moves with the face; a callable of x would move)")
    if prob.body is not None and prob.body.kind != "vector":
        raise ProblemError(f"{what}: the body force must be three numbers, not a callable of x")
    for field in (prob.youngs, prob.poisson) if prob.material.kind == "isotropic" else ():
        if field.kind == "callable":
            raise ProblemError(f"{what}: {field.what} must be a number or a channel of the map (material), not a "
                               "callable of x")


def strain_and_stress(prob, chunk, grads, x, chans) -> tuple:
    """(the :class:`iga.elasticity.material.Moduli`, eps (N, 3, 3), sigma = C : eps (N, 3, 3)) at Gauss points of
    the patches ``chunk`` from the displacement gradients ``grads`` (N, 3, 3), the points x and the channels
    there (no thermal strain)."""
    mod = moduli(prob, chunk, x, chans)
    eps = strain(grads)
    return mod, eps, mod.stress(eps)


def drag_channel(prob) -> str | None:
    """The channel whose value at a point sets the stiffness's scale or shape there (an isotropic material's
    Young's modulus, a cubic material's table parameter), or None: what a point moved within the map drags."""
    m = prob.material
    if m.kind == "isotropic":
        return m.youngs.spec if m.youngs.kind == "channel" else None
    return m.channel


def _slopes(prob, chunk, x, chans):
    """dC/dc (:class:`iga.elasticity.material.Moduli`) by the value c of :func:`drag_channel` at the Gauss points
    x of ``chunk``, or None when the material reads no channel."""
    channel = drag_channel(prob)
    if channel is None:
        return None
    flat = {c: np.reshape(v, -1) for c, v in chans.items()}
    return prob.material.slopes(x, flat, f"patches {chunk[0]}..{chunk[-1]}", channel)


def elastic_densities(solution, output, volume, faces, what: str, solver: str = "auto") -> None:
    """The shape densities of the compliance or the von Mises norm (module notes; the volume's, div V, for
    :class:`Volume`) handed to ``volume(chunk, space, Qw, dk)`` per group of patches (``dk``: the weighted
    derivative of the integrand by the value of :func:`drag_channel` at the point) and to ``faces(face data, Qw)`` once, as
    :func:`iga.shape_sensitivity.shape_densities` does for heat; ``solver``: the von Mises norm's adjoint."""
    prob = solution.problem
    prob.gauss_geometry.keep(prob)
    n = prob.ndof
    if isinstance(output, Volume):  # geometry alone: dV' = div V dV
        gauss_pass(prob, np.zeros((1, n)), lambda chunk, space, vals, grads, wv, x, chans: volume(
            chunk, space, wv[:, None, None] * np.eye(3), np.zeros_like(wv)))
        return
    _check(solution, output, what)
    body = None if prob.body is None else np.asarray(prob.body.spec, float)
    stress = isinstance(output, VonMisesNorm)
    # the field that tests the loads' shape terms: 2 u for the compliance (self-adjoint), the adjoint lambda
    tested = elastic_adjoint(solution, output, solver) if stress else 2 * solution.u
    if stress:
        p, J = output.p, evaluated(output, solution)
        c = J ** (1 - p) / Volume().value(solution)

    def add(chunk, space, vals, grads, wv, x, chans):
        gu, gl = grads[:, :3], grads[:, 3:]  # (u's, and the adjoint's for the von Mises norm)
        if not stress:
            _, eps, sig = strain_and_stress(prob, chunk, gu, x, chans)
            slopes = _slopes(prob, chunk, x, chans)
            energy2 = np.sum(sig * eps, axis=(1, 2))  # eps : C : eps
            Q = 2 * np.einsum("qik,qij->qkj", gu, sig)
            scalar = -energy2 + (0.0 if body is None else 2 * vals[:, :3] @ body)
            dk = np.zeros_like(wv) if slopes is None else -slopes.product(eps, eps) * wv  # - eps : C' : eps
            volume(chunk, space, (Q + scalar[:, None, None] * np.eye(3)) * wv[:, None, None], dk)
            return
        mod, eps, sig = strain_and_stress(prob, chunk, gu, x, chans)
        slopes, eps_l = _slopes(prob, chunk, x, chans), strain(gl)
        sig_l = mod.stress(eps_l)
        dev, vm = von_mises(sig)
        cross = np.sum(sig_l * eps, axis=(1, 2))  # eps(u) : C : eps(lambda)
        scale = np.where(vm > 0, np.where(vm > 0, vm, 1.0) ** (p - 2), 0.0)  # vm^(p-2) s -> 0 where vm = 0
        # d sigma_vm = 3/2 (C : s) : d eps / sigma_vm (C : s = 2 mu s for an isotropic material)
        Q = (np.einsum("qik,qij->qkj", gl, sig) + np.einsum("qik,qij->qkj", gu, sig_l)
             - (1.5 * c * scale)[:, None, None] * np.einsum("qik,qij->qkj", gu, mod.stress(dev)))
        scalar = c / p * (vm**p - J**p) - cross + (0.0 if body is None else vals[:, 3:] @ body)
        if slopes is None:
            dk = np.zeros_like(wv)
        else:  # the integrand's derivative by the dragged channel: 3/2 c sigma_vm^(p-2) s : C' : eps - eps_l : C' : eps
            dsig = slopes.stress(eps)
            dk = (1.5 * c * scale * np.sum(dev * dsig, axis=(1, 2)) - np.sum(eps_l * dsig, axis=(1, 2))) * wv
        volume(chunk, space, (Q + scalar[:, None, None] * np.eye(3)) * wv[:, None, None], dk)

    # the compliance's volume terms need u alone (2 u's gradients would be u's twice over)
    fields = np.vstack([solution.u.reshape(3, n), tested.reshape(3, n)]) if stress else solution.u.reshape(3, n)
    gauss_pass(prob, fields, add)
    fds, dens = [], []
    for load in prob.loads:
        t = np.asarray(load.value.spec, float)
        for fd in prob.faces(sorted(set(prob.tag_faces(load.tag)))):
            w = np.stack([fd.trace(tested[a * n:(a + 1) * n]) for a in range(3)], axis=1)
            fds.append(fd)
            dens.append((w @ t) * fd.dAw)
    if fds:
        normal = np.concatenate([fd.normal for fd in fds])
        d = np.concatenate(dens)
        faces(fds, d[:, None, None] * (np.eye(3) - np.einsum("qi,qj->qij", normal, normal)))
