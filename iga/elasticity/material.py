"""Elastic materials: the moduli at points and the stress law they give.

An isotropic material (:class:`IsotropicMaterial`) has the Lame constants lambda and mu of Young's modulus E and
Poisson's ratio nu.  A material of cubic symmetry about the axes x, y, z (:class:`CubicMaterial`: a cross lattice's
homogenised stiffness, a cubic crystal) has three constants C11, C12, C44 (Voigt notation); with lambda = C12,
mu = C44 and the anisotropy kappa = C11 - C12 - 2 C44 its stress is

    sigma = lambda tr(eps) I + 2 mu eps + kappa diag(eps_xx, eps_yy, eps_zz),

the isotropic law plus kappa sum_a eps_aa e_a (x) e_a, which vanishes for an isotropic material.  It is
positive definite where mu > 0, C11 - C12 > 0 and C11 + 2 C12 > 0.  In the weak form the extra term couples
d_a N_i with d_a N_j in the diagonal block (a, a) alone (:func:`iga.elasticity.forms.block_terms`).

The constants of a :class:`CubicMaterial` are numbers, or functions of one channel of the map: an object with
``constants_at(p (N,)) -> (N, 3)`` (C11, C12, C44 in Pa) and ``slopes(p) -> (N, 3)`` (their derivatives by p),
such as :class:`iga.StiffnessTable` (the effective stiffness of a tile family tabulated over its
parameter): a graded lattice's macro model, differentiable by the channel's control values.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from geometry.errors import show

from iga.errors import ProblemError
from iga.heat.coefficients import ScalarField, is_number

__all__ = ["Moduli", "IsotropicMaterial", "CubicMaterial", "lame", "resolved"]


def lame(E: np.ndarray, nu: np.ndarray, where: str) -> tuple[np.ndarray, np.ndarray]:
    """Lame parameters (lambda, mu) in Pa from Young's modulus E (Pa, > 0) and Poisson's ratio nu in (-1, 0.5)."""
    E, nu = np.asarray(E, float), np.asarray(nu, float)
    if not np.all(E > 0):  # NaN fails too
        bad = E[~(E > 0)][0]
        raise ProblemError(f"Young's modulus must be a positive number of Pa, got {bad:g} on {where}")
    if not np.all((nu > -1.0) & (nu < 0.5)):
        bad = nu[~((nu > -1.0) & (nu < 0.5))][0]
        raise ProblemError(f"Poisson's ratio must lie in (-1, 0.5) (0.5 is incompressible, which this "
                           f"displacement formulation cannot take), got {bad:g} on {where}")
    return E * nu / ((1 + nu) * (1 - 2 * nu)), E / (2 * (1 + nu))


@dataclass
class Moduli:
    """Elastic constants at N points, each (N,) in Pa: the Lame constants ``lam``, ``mu`` and the cubic anisotropy
    ``kappa`` (None: isotropic); the stiffness C = lam I (x) I + 2 mu I_sym + kappa sum_a e_a e_a e_a e_a."""

    lam: np.ndarray
    mu: np.ndarray
    kappa: np.ndarray | None = None

    def stress(self, eps: np.ndarray) -> np.ndarray:
        """sigma = C : eps (N, 3, 3) for strains eps (N, 3, 3) (module notes)."""
        tr = np.trace(eps, axis1=1, axis2=2)
        sig = self.lam[:, None, None] * tr[:, None, None] * np.eye(3) + 2 * self.mu[:, None, None] * eps
        if self.kappa is not None:
            sig = sig + self.kappa[:, None, None] * (np.diagonal(eps, axis1=1, axis2=2)[:, :, None] * np.eye(3))
        return sig

    def product(self, a: np.ndarray, b: np.ndarray) -> np.ndarray:
        """a : C : b (N,) for strains a, b (N, 3, 3)."""
        out = self.lam * np.trace(a, axis1=1, axis2=2) * np.trace(b, axis1=1, axis2=2) + 2 * self.mu * np.sum(
            a * b, axis=(1, 2))
        if self.kappa is not None:
            out = out + self.kappa * np.sum(np.diagonal(a, axis1=1, axis2=2) * np.diagonal(b, axis1=1, axis2=2), 1)
        return out

    @property
    def dilatation(self) -> np.ndarray:
        """I : C : I / 3 = 3 lam + 2 mu + kappa (N,): the stress sigma = this x s I of an isotropic strain s I
        (a thermal strain's load per unit strain)."""
        out = 3 * self.lam + 2 * self.mu
        return out if self.kappa is None else out + self.kappa


class IsotropicMaterial:
    """An isotropic material: Young's modulus ``youngs`` (Pa, > 0) and Poisson's ratio ``poisson`` in (-1, 0.5),
    each a number, a channel name or a callable of x (:class:`iga.heat.coefficients.ScalarField`)."""

    kind = "isotropic"

    def __init__(self, youngs, poisson, model=None):
        self.youngs = youngs if isinstance(youngs, ScalarField) else \
            ScalarField(youngs, "Young's modulus", positive=True, model=model)
        self.poisson = poisson if isinstance(poisson, ScalarField) else \
            ScalarField(poisson, "Poisson's ratio", model=model)
        if self.poisson.constant is not None and not -1.0 < self.poisson.constant < 0.5:
            raise ProblemError(f"Poisson's ratio must lie in (-1, 0.5), got {show(self.poisson.constant)}")

    def fields(self) -> tuple:
        """The scalar fields the material reads."""
        return self.youngs, self.poisson

    def reads(self, channel: str) -> bool:
        """Whether any constant reads the channel ``channel``."""
        return any(f.kind == "channel" and f.spec == channel for f in self.fields())

    def moduli(self, x: np.ndarray, chans: dict, where: str) -> Moduli:
        """The moduli at points x (N, 3) with channel values ``chans`` {name: (N,)}."""
        return Moduli(*lame(self.youngs.values(x, chans, where), self.poisson.values(x, chans, where), where))

    def slopes(self, x: np.ndarray, chans: dict, where: str, channel: str) -> Moduli:
        """d(lam, mu)/dc (N,) each, by the value c of ``channel`` at the points (both constants may read it)."""
        E, nu = self.youngs.values(x, chans, where), self.poisson.values(x, chans, where)
        lam, mu = lame(E, nu, where)
        dlam, dmu = np.zeros_like(lam), np.zeros_like(mu)
        if self.youngs.kind == "channel" and self.youngs.spec == channel:  # both proportional to E
            dlam, dmu = dlam + lam / E, dmu + mu / E
        if self.poisson.kind == "channel" and self.poisson.spec == channel:
            dlam = dlam + E * (1 + 2 * nu**2) / ((1 + nu) * (1 - 2 * nu)) ** 2
            dmu = dmu - E / (2 * (1 + nu) ** 2)
        return Moduli(dlam, dmu)


class CubicMaterial:
    """A material of cubic symmetry about x, y, z (module notes): ``constants`` = (C11, C12, C44) in Pa (numbers),
    or an object with ``constants_at(p)`` and ``slopes(p)`` (N, 3) of the value p of the map's channel ``channel``
    (e.g. :meth:`iga.StiffnessTable.material`)."""

    kind = "cubic"

    def __init__(self, constants, channel: str | None = None, model=None):
        if isinstance(constants, (tuple, list)) and len(constants) == 3 and all(is_number(c) for c in constants):
            c = np.asarray(constants, float)
            if not np.all(np.isfinite(c)):
                raise ProblemError(f"CubicMaterial: the constants (C11, C12, C44) must be finite numbers of Pa, "
                                   f"got {show(constants)}")
            _check_definite(c[None], np.zeros((1, 3)), "CubicMaterial(constants)")
            if channel is not None:
                raise ProblemError(f"CubicMaterial: constant C11, C12, C44 read no channel; drop channel="
                                   f"{show(channel)} or give a table of the channel's value")
            self.table, self.constant, self.channel = None, c, None
            return
        if not (callable(getattr(constants, "constants_at", None)) and callable(getattr(constants, "slopes", None))):
            raise ProblemError(f"CubicMaterial: constants must be three numbers (C11, C12, C44) in Pa or a table of "
                               f"them over a channel (iga.stiffness_table(...)), got {show(constants)}")
        if not isinstance(channel, str):
            raise ProblemError(f"CubicMaterial: a table of constants needs the channel it reads (channel='t'), got "
                               f"{show(channel)}")
        if model is not None:
            ScalarField(channel, "the cubic material's parameter", model=model)  # (checks the channel exists)
        self.table, self.constant, self.channel = constants, None, channel

    def reads(self, channel: str) -> bool:
        return self.channel is not None and self.channel == channel

    def _constants(self, x, chans, where) -> np.ndarray:
        if self.table is None:
            return np.broadcast_to(self.constant, (len(x), 3))
        c = np.asarray(self.table.constants_at(np.asarray(chans[self.channel], float)), float)
        _check_definite(c, x, where)
        return c

    def moduli(self, x: np.ndarray, chans: dict, where: str) -> Moduli:
        c = self._constants(x, chans, where)
        return Moduli(np.ascontiguousarray(c[:, 1]), np.ascontiguousarray(c[:, 2]), c[:, 0] - c[:, 1] - 2 * c[:, 2])

    def slopes(self, x: np.ndarray, chans: dict, where: str, channel: str) -> Moduli:
        if not self.reads(channel):
            z = np.zeros(len(x))
            return Moduli(z, z, z)
        d = np.asarray(self.table.slopes(np.asarray(chans[self.channel], float)), float)
        return Moduli(np.ascontiguousarray(d[:, 1]), np.ascontiguousarray(d[:, 2]), d[:, 0] - d[:, 1] - 2 * d[:, 2])


def resolved(youngs, poisson, material, model):
    """The material of :class:`iga.ElasticityProblem`: an :class:`IsotropicMaterial` of ``youngs`` and ``poisson``,
    or ``material`` (its channels checked against the model's)."""
    if material is None:
        if youngs is None or poisson is None:
            raise ProblemError("ElasticityProblem needs youngs= and poisson= (an isotropic material) or material= "
                               "(iga.CubicMaterial)")
        return IsotropicMaterial(youngs, poisson, model=model)
    if youngs is not None or poisson is not None:
        raise ProblemError("ElasticityProblem takes youngs and poisson or a material, not both; drop one")
    if not isinstance(material, (IsotropicMaterial, CubicMaterial)):
        raise ProblemError(f"material must be an iga.CubicMaterial (or iga.IsotropicMaterial), got {show(material)}")
    if isinstance(material, IsotropicMaterial):  # (its channels checked against the model's)
        return IsotropicMaterial(material.youngs.spec, material.poisson.spec, model=model)
    if material.channel is not None:
        CubicMaterial(material.table, material.channel, model=model)  # (the channel must be the model's)
    return material


def _check_definite(c: np.ndarray, x: np.ndarray, where: str) -> None:
    """Refuse constants (N, 3) = (C11, C12, C44) whose stiffness is not positive definite (or not finite)."""
    ok = np.isfinite(c).all(1) & (c[:, 2] > 0) & (c[:, 0] - c[:, 1] > 0) & (c[:, 0] + 2 * c[:, 1] > 0)
    if not ok.all():
        i = int(np.argmin(ok))
        raise ProblemError(f"a cubic material needs C44 > 0, C11 - C12 > 0 and C11 + 2 C12 > 0 (a positive definite "
                           f"stiffness), got (C11, C12, C44) = {np.round(c[i], 6).tolist()} at x = "
                           f"{np.round(x[i], 6).tolist()} on {where}")
