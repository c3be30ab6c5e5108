"""Outputs as objects: what a design is judged by, evaluable on a solution and, where it is differentiable in
the coefficients, with its gradient for the adjoint (:mod:`iga.sensitivity`).

Each output has ``value(solution) -> float`` and ``gradient(solution) -> (ndof,)`` (dJ/du, the partial
derivative in the solution's coefficients u; for an elastic solution (3 ndof,), component-major).  Units are
those of the solution: temperatures in C (or K, as the conditions were given), lengths in m.

* :class:`Volume` (m^3): the model's volume (no dependence on u).
* :class:`MeanTemperature` (C): int T dV / V, or over the faces of ``tag``: int T dA / A.
* :class:`TemperatureNorm` (C): (int |T|^p dV / V)^(1/p), or over the faces of ``tag``, a smooth maximum that
  tends to max |T| as p grows.
* :class:`HeatFlow` (W): the heat leaving through the faces of ``tag`` (value only).
* :class:`Compliance`: u . f, the work of the loads (heat: W K; elasticity: J).
* :class:`VonMisesNorm` (Pa): (int sigma_vm^p dV / V)^(1/p) of an elastic solution.
"""

from __future__ import annotations

import numpy as np

from geometry.errors import show
from geometry.grouping import ObjectIndex
from geometry.numbers import TINY, is_real

from iga.discretisation.faces import chunks
from iga.discretisation.fields import grid_fields
from iga.errors import ProblemError

__all__ = ["Output", "Volume", "MeanTemperature", "TemperatureNorm", "HeatFlow", "Compliance", "VonMisesNorm",
           "gauss_pass", "tag_faces", "von_mises"]


def gauss_pass(problem, fields: np.ndarray, fn, inverse: bool = False) -> None:
    """Call ``fn(chunk, space, vals (P nq, c), grads (P nq, c, 3), wv (P nq,), x (P nq, 3), chans)`` for every group
    of patches sharing a space and a tile spline, with the fields of coefficient vectors ``fields`` (c, ndof) at
    the Gauss points; ``wv`` the weights times |det J| (polynomial bases only).  ``inverse``: ``fn`` takes an
    eighth argument, J^-1 (P nq, 3, 3), [q, r, j] = d xi_r / d x_j (a load that tests physical gradients)."""
    same = ObjectIndex()
    groups: dict = {}
    for i, s in enumerate(problem.spaces):
        groups.setdefault((s.key(), same(problem.model.patches[i].spline)), []).append(i)
    c = len(fields)
    for members in groups.values():
        if problem.weights[members[0]] is not None:
            raise ProblemError(f"patch {members[0]} is analysed in the NURBS basis of its own weights; outputs' "
                               "gradients and sensitivities are computed in the polynomial basis only")
        space = problem.spaces[members[0]]
        tables = [np.swapaxes(d.B[:, :, :-1], 1, 2) for d in space.dirs]
        w = np.einsum("i,j,k->ijk", *[d.qw for d in space.dirs]).ravel()
        for chunk in chunks(members, c * space.nq_total):
            x, D, chans = problem.gauss_geometry.of(problem.model, chunk, space)
            U = np.stack([fields[:, problem.offsets[i]:problem.offsets[i + 1]].reshape((c,) + space.shape)
                          for i in chunk])
            vals, grads, det = grid_fields(U, tables, D)
            wv = np.broadcast_to(w, (len(chunk), len(w))).reshape(-1) * np.abs(det)
            extra = (np.linalg.inv(np.stack(D, -1).reshape(-1, 3, 3)),) if inverse else ()
            fn(chunk, space, vals, grads, wv, x.reshape(-1, 3), chans, *extra)


def _volume_load(solution, density) -> np.ndarray:
    """int density(T) N_i dV (ndof,) for ``density(T (N,)) -> (N,)`` of the solution's temperature at the Gauss
    points: the gradient of int g(T) dV with g' = density."""
    from iga.assembly.tensor import load_form

    prob = solution.problem
    out = np.zeros(prob.ndof)

    def add(chunk, space, vals, grads, wv, x, chans):
        L = (density(vals[:, 0]) * wv).reshape((len(chunk),) + space.qshape)
        loads = load_form(space, L)
        for j, pi in enumerate(chunk):
            out[prob.offsets[pi]:prob.offsets[pi + 1]] += loads[j].reshape(-1)

    gauss_pass(prob, solution.u[None], add)
    return out


def _exponent(p, what: str) -> float:
    """The exponent of a p-norm output: a number >= 1."""
    if not (is_real(p) and np.isfinite(p) and p >= 1):
        raise ProblemError(f"{what}: p must be a number >= 1, got {show(p)}")
    return float(p)


class Output:
    """An output J of a solution: :meth:`value`, and :meth:`gradient` dJ/du where it is differentiable."""

    name = "output"

    def value(self, solution) -> float:
        raise NotImplementedError

    def gradient(self, solution) -> np.ndarray:
        raise ProblemError(f"{self.name} has no gradient in the solution's coefficients here; its sensitivity "
                           "needs one (use MeanTemperature, TemperatureNorm or Compliance)")

    def __call__(self, solution) -> float:
        return self.value(solution)

    def __repr__(self) -> str:
        return self.name


def evaluated(output: Output, solution) -> float:
    """``output.value(solution)``, computed once per solution: kept in ``solution.output_values`` by the output's
    name (which names its parameters), since a design step asks for the objective, then for its gradient, whose
    adjoint load and explicit terms need the value again (each a pass over every Gauss point)."""
    done = solution.output_values
    if output.name not in done:
        done[output.name] = output.value(solution)
    return done[output.name]


def _heat(solution, what: str):
    if getattr(type(solution), "physics", None) != "heat":  # (Solution and its states declare it)
        raise ProblemError(f"{what} is an output of a heat solution (iga.Solution), got {show(solution)}")
    return solution


class Volume(Output):
    """The model's volume (m^3) by the problem's Gauss rule."""

    name = "Volume()"

    def value(self, solution) -> float:
        if hasattr(solution, "volume"):
            return float(solution.volume())
        return float(solution.integrate(lambda x, u, g: np.ones(len(x))))

    def gradient(self, solution) -> np.ndarray:
        return np.zeros(len(solution.u))


def tag_faces(solution, tag, what: str):
    """The face data of ``tag`` (a tag of the solution's model) and their area (m^2)."""
    prob = solution.problem
    fds = prob.faces(prob.faces_of(tag, what))
    return fds, float(sum(fd.dAw.sum() for fd in fds))


class MeanTemperature(Output):
    """The mean temperature: int T dV / V over the model, or int T dA / A over the faces of ``tag``."""

    def __init__(self, tag=None):
        self.tag = tag
        self.name = f"MeanTemperature({'' if tag is None else show(tag)})"

    def value(self, solution) -> float:
        s = _heat(solution, self.name)
        if self.tag is None:
            return float(s.mean_temperature())
        return float(self.gradient(s) @ s.u)

    def gradient(self, solution) -> np.ndarray:
        from iga.heat.forms import boundary_load

        s = _heat(solution, self.name)
        if self.tag is None:
            return _volume_load(s, np.ones_like) / s.volume()
        fds, area = tag_faces(s, self.tag, self.name)
        return boundary_load(fds, [fd.dAw for fd in fds], s.problem.ndof) / area


class TemperatureNorm(Output):
    """(int |T|^p dV / V)^(1/p) (C) over the model, or (int |T|^p dA / A)^(1/p) over the faces of ``tag``: a
    smooth maximum of |T| (``p`` >= 1; the larger, the closer to the maximum and the stiffer the gradient)."""

    def __init__(self, p: float = 8.0, tag=None):
        self.p, self.tag = _exponent(p, "TemperatureNorm"), tag
        self.name = f"TemperatureNorm({self.p:g}{'' if tag is None else ', ' + show(tag)})"

    def value(self, solution) -> float:
        s = _heat(solution, self.name)
        p = self.p
        if self.tag is None:
            return float((s.integrate(lambda x, T, g: np.abs(T) ** p) / s.volume()) ** (1 / p))
        fds, area = tag_faces(s, self.tag, self.name)
        return float((sum(float(np.sum(np.abs(fd.trace(s.u)) ** p * fd.dAw)) for fd in fds) / area) ** (1 / p))

    def gradient(self, solution) -> np.ndarray:
        from iga.heat.forms import boundary_load

        s = _heat(solution, self.name)
        p, J = self.p, evaluated(self, s)
        if not J > TINY:  # T = 0 everywhere: the norm has no direction to grow in
            return np.zeros(s.problem.ndof)
        if self.tag is None:
            return _volume_load(s, lambda T: np.abs(T) ** (p - 1) * np.sign(T)) * J ** (1 - p) / s.volume()
        fds, area = tag_faces(s, self.tag, self.name)
        dens = [np.abs(T) ** (p - 1) * np.sign(T) * fd.dAw for fd, T in ((fd, fd.trace(s.u)) for fd in fds)]
        return boundary_load(fds, dens, s.problem.ndof) * J ** (1 - p) / area


class HeatFlow(Output):
    """The heat leaving through the faces of ``tag`` (W, outward positive; :meth:`iga.Solution.flux`)."""

    def __init__(self, tag):
        self.tag = tag
        self.name = f"HeatFlow({show(tag)})"

    def value(self, solution) -> float:
        return float(_heat(solution, self.name).flux(self.tag))


class Compliance(Output):
    """u . f, the work of the loads on the solution (heat: sources, Neumann and Robin loads; elasticity: body
    forces, tractions, pressures and point loads): the design's overall stiffness (the smaller, the stiffer)."""

    name = "Compliance()"

    def _f(self, solution):
        f = solution._loads if hasattr(solution, "_loads") else solution._f
        if f is None:
            raise ProblemError("Compliance needs the load vector, which a distributed solve does not keep")
        return f

    def value(self, solution) -> float:
        return float(solution.u @ self._f(solution))

    def gradient(self, solution) -> np.ndarray:
        return np.array(self._f(solution), float)


def von_mises(S: np.ndarray) -> tuple:
    """(the deviator s of the stresses S (N, 3, 3), the von Mises stress sqrt(3/2 s : s) (N,)), in S's units."""
    dev = S - np.trace(S, axis1=1, axis2=2)[:, None, None] / 3 * np.eye(3)
    return dev, np.sqrt(1.5 * np.sum(dev * dev, axis=(1, 2)))


class VonMisesNorm(Output):
    """(int sigma_vm^p dV / V)^(1/p) (Pa) of an elastic solution: a smooth maximum of the von Mises stress.

    Its gradient in the displacement (:meth:`gradient`) is the load int tau : grad v dV with
    tau = J^(1-p) / V 3/2 sigma_vm^(p-2) C : s (s the stress deviator: d sigma_vm = 3/2 (C : s) : d eps / sigma_vm,
    and C : s = 2 mu s for an isotropic material), what
    the elastic adjoint solves with (:func:`iga.elasticity.adjoint.elastic_adjoint`); its sensitivities by the
    material and by the shape: :mod:`iga.elasticity.sensitivity`, :mod:`iga.elasticity.shape`."""

    def __init__(self, p: float = 8.0):
        self.p = _exponent(p, "VonMisesNorm")
        self.name = f"VonMisesNorm({self.p:g})"

    def _problem(self, solution):
        if getattr(type(solution), "physics", None) != "elasticity":
            raise ProblemError(f"{self.name} is an output of an elastic solution, got {show(solution)}")
        return solution.problem

    def value(self, solution) -> float:
        from iga.elasticity.forms import strain
        from iga.discretisation.fields import integrate_fields

        prob, p = self._problem(solution), self.p
        n, o = prob.ndof, prob.offsets

        def density(x, u, g, at):
            where = f"patches {at.patches[0]}..{at.patches[-1]}"
            mod = prob.material.moduli(x, at.chans, where)
            eps = strain(g)
            if prob.thermal_strain is not None:
                eps = eps - at.per_patch(prob.thermal_strain)[:, None, None] * np.eye(3)
            vm = von_mises(mod.stress(eps))[1]
            return np.stack([vm**p, np.ones_like(vm)], 1)

        total, vol = integrate_fields(prob, lambda i: np.stack([solution.u[a * n + o[i]:a * n + o[i + 1]].reshape(
            prob.spaces[i].shape) for a in range(3)]), 3, density, context=True)
        return float((total / vol) ** (1 / p))

    def gradient(self, solution) -> np.ndarray:
        """dJ/du (3 ndof,), component-major (class notes); a problem without thermal strain."""
        from iga.assembly.tensor import derivative_load_form
        from iga.elasticity.forms import moduli, strain

        prob, p = self._problem(solution), self.p
        if prob.thermal_strain is not None:
            raise ProblemError(f"{self.name}: the gradient of a thermal stress is not built; differentiate a problem "
                               "without .thermal(...)")
        n, o = prob.ndof, prob.offsets
        out = np.zeros(3 * n)
        J = evaluated(self, solution)
        if not J > TINY:  # no stress anywhere: the norm has no direction to grow in
            return out

        def add(chunk, space, vals, grads, wv, x, chans, Jinv):
            mod = moduli(prob, chunk, x, chans)
            dev, vm = von_mises(mod.stress(strain(grads)))
            # vm^(p - 2) s -> 0 where vm = 0 (p > 1), so those points add nothing
            scale = np.where(vm > 0, np.where(vm > 0, vm, 1.0) ** (p - 2), 0.0)
            # d vm / d eps = 3 / (2 vm) C : s (s the deviator; C : s = 2 mu s for an isotropic material)
            tau = (1.5 * scale * wv)[:, None, None] * mod.stress(dev)
            shape = (len(chunk),) + space.qshape
            for a in range(3):
                G = np.einsum("qj,qrj->rq", tau[:, a], Jinv)  # tau_aj d xi_r / d x_j: weights of d N / d xi_r
                terms = [(G[r].reshape(shape), tuple((int(k == r), None) for k in range(3))) for r in range(3)]
                loads = derivative_load_form(space, terms)
                for j, pi in enumerate(chunk):
                    out[a * n + o[pi]:a * n + o[pi + 1]] += loads[j].reshape(-1)

        gauss_pass(prob, solution.u.reshape(3, n), add, inverse=True)
        return out * J ** (1 - p) / Volume().value(solution)
