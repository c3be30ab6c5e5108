"""Exact shape sensitivities of heat outputs: the derivative of an output J with respect to the control points of
the deformation map D, by one adjoint solve.

Every patch of a micro-structure is x = D(A T(xi) + b) (a single spline: x = D(xi)), polynomial or rational in
D's control points P_c, so moving P_c by delta e_d moves every material point by the velocity
V = R_c(y) e_d, with R_c D's basis function (NURBS where D has weights) at the point's parameter y in D. The
interface constraints and the Dirichlet projection of a constant are parametric, untouched by the move; the
coefficient vector u is a function of the parameters only. The material derivative of the discrete residual
R(u, P) = K(P) u - f(P) and of J(u, P) gives, with the adjoint lambda of :func:`iga.adjoint.adjoint`,

    dJ/dP = dJ/dP (explicit) - lambda . (dK/dP u - df/dP),

and each term is an integral whose shape derivative is classical (e.g. Haslinger & Makinen 2003, Ch. 3):

* diffusion, int grad lambda . K grad u dV: grad lambda . (div V K - grad V K - K grad V^T) grad u dV
  (grad V_ij = dV_i/dx_j; the conductivity is a number or channels of D: material, it moves with the points);
* source, Neumann and Robin terms, int s dV and int s dA: s div V dV and s div_G V dA, with the surface
  divergence div_G V = div V - n . (grad V n);
* the outputs' own integrals (:mod:`iga.outputs`: volume and face means, p-norms, the volume, the compliance
  u . f) the same way.

With V = R_c e_d, div V = d_d R_c and grad V = e_d (grad R_c)^T, every term is Q(x) : (e_d grad R_c^T) for a
3 x 3 field Q on the Gauss points, and grad_x R_c = D'(y)^-T grad_y R_c (x = D(y)): so dJ/dP_{c,d} =
sum_q sum_k (Q D'^-T)_{dk} d_k R_c(y_q) w_q, one scatter per parametric direction k of D.  The result is
the derivative of the discrete output (exact to round-off: ``tests/test_shape_sensitivity.py`` compares it
with finite differences of fresh analyses of moved maps).

Refused with :class:`iga.errors.ProblemError`: coefficients given as callables of x (their values would move
with x: dk/dx . V terms not built), Dirichlet values other than numbers, radiation and k(T) (nonlinear),
several maps (V-rep primitives), patches analysed in their own NURBS basis.
"""

from __future__ import annotations

import numpy as np

from geometry.errors import show
from geometry.faces import FACE_AXIS, parse_slot_face

from iga.elasticity.shape import elastic_densities
from iga.errors import ProblemError
from iga.heat.conditions import face_values
from iga.outputs import (Compliance, MeanTemperature, Output, TemperatureNorm, Volume, evaluated, gauss_pass,
                         tag_faces)
from iga.adjoint import adjoint, map_basis_values, map_parameters, shape_map

__all__ = ["shape_sensitivity", "shape_densities", "face_parameters", "face_plane", "steady_heat"]


def shape_sensitivity(solution, output: Output, solver: str = "auto") -> np.ndarray:
    """dJ/dP of ``output`` with respect to the coordinates of the deformation map's control points, shaped like
    them: (n1, n2, n3, 3) (module notes).  Units: those of J per metre."""
    steady_heat(solution, "wrt='map'")
    D, placed = shape_map(solution.problem)
    grad = np.zeros((int(np.prod(D.control_points.shape[:3])), 3))
    patches = solution.problem.model.patches

    def volume(chunk, space, Qw, dk):
        _scatter(grad, D, map_parameters(patches, chunk, space, D, placed), Qw)

    def faces(fds, Qw):
        y = np.concatenate(face_parameters(solution.problem, fds, D, placed))
        for a in range(0, len(y), _SCATTER_POINTS):
            _scatter(grad, D, y[a:a + _SCATTER_POINTS], Qw[a:a + _SCATTER_POINTS])

    shape_densities(solution, output, volume, faces, solver, "wrt='map'")
    return grad.reshape(D.control_points.shape[:3] + (3,))


def steady_heat(solution, what: str) -> None:
    """Refuse what is neither a steady heat solution nor an elastic one (the derivatives here are of those)."""
    if getattr(type(solution), "physics", None) == "elasticity":
        return
    if getattr(type(solution), "physics", None) != "heat" or not getattr(type(solution), "steady", False):
        raise ProblemError(f"{what} differentiates a steady heat solution (iga.Solution) or an elastic one, got "
                           f"{show(solution)}")


def shape_densities(solution, output: Output, volume, faces, solver: str = "auto", what: str = "wrt='map'") -> None:
    """The shape derivative of ``output`` as densities against the velocity gradient: dJ = sum_q Q_q : grad V_q
    over the Gauss points of the volume and of the Neumann, Robin and output faces, for any velocity V that
    carries the material (module notes); one adjoint solve.  ``volume(chunk, space, Qw (P nq, 3, 3), dk (P nq,))``
    per group of patches of :func:`iga.outputs.gauss_pass` (``dk``: the weighted derivative of the integrand by
    an isotropic conductivity value at the point, for velocities that do not carry a conductivity field);
    ``faces(face data, Qw (N, 3, 3))`` once, all faces' points concatenated in their order.  An elastic
    solution's compliance: :func:`iga.elasticity.shape.elastic_densities` (``dk`` by Young's modulus)."""
    steady_heat(solution, what)
    if getattr(type(solution), "physics", None) == "elasticity":  # the compliance's densities
        return elastic_densities(solution, output, volume, faces, what, solver)
    prob = solution.problem
    _check_material(prob, what)
    explicit = _explicit_terms(output, solution, what)
    # the volume does not depend on the temperature: its adjoint is zero (no solve)
    lam = np.zeros(prob.ndof) if isinstance(output, Volume) else adjoint(solution, output, solver)
    u_load = solution.u if isinstance(output, Compliance) else None  # u . f: f's shape terms with u for lambda
    conductivity_at = _conductivity_matrix(prob)
    source = prob.source

    def add(chunk, space, vals, grads, wv, x, chans):
        where = f"patches {chunk[0]}..{chunk[-1]}"
        flat = {c: np.reshape(v, -1) for c, v in chans.items()}
        gT, gL, T, L = grads[:, 0], grads[:, 1], vals[:, 0], vals[:, 1]
        K = conductivity_at(x, flat, where)  # (N, 3, 3)
        KgT, KgL = np.einsum("qij,qj->qi", K, gT), np.einsum("qij,qj->qi", K, gL)
        s = np.sum(gL * KgT, axis=1)
        # - lambda . dK/dP u (diffusion) + lambda . df/dP (source) + explicit volume terms
        Q = np.einsum("qi,qj->qij", gL, KgT) + np.einsum("qi,qj->qij", gT, KgL)
        scalar = -s + source.values(x, flat, where) * (L if u_load is None else L + T)
        if explicit.volume is not None:
            scalar = scalar + explicit.volume(T)
        Q += scalar[:, None, None] * np.eye(3)
        volume(chunk, space, Q * wv[:, None, None], -np.sum(gL * gT, axis=1) * wv)

    gauss_pass(prob, np.stack([solution.u, lam]), add)
    fds, psis = [], []
    for f, psi in _face_densities(prob, solution, lam, u_load, explicit):
        fds += f
        psis += psi
    if fds:  # every face at once
        normal = np.concatenate([fd.normal for fd in fds])
        dens = np.concatenate([p * fd.dAw for fd, p in zip(fds, psis)])
        faces(fds, dens[:, None, None] * (np.eye(3) - np.einsum("qi,qj->qij", normal, normal)))


def _check_material(prob, what: str) -> None:
    """Refuse what the shape derivative here does not cover (module notes)."""
    k = prob.conductivity
    if k.of_temperature is not None or k.table is not None or any(c.kind == "radiation" for c in prob.conditions):
        raise ProblemError(f"{what} is for linear heat problems: a temperature-dependent conductivity or radiation "
                           "makes the problem nonlinear")
    if k.callable is not None or (k.scalar is not None and k.scalar.kind == "callable"):
        raise ProblemError(f"{what} needs a conductivity that moves with the material (a number or channels of "
                           "the map); a callable of x would change under the move (its gradient term is not built)")
    if prob.source.kind == "callable":
        raise ProblemError(f"{what} needs a source that moves with the material (a number or a channel of the map),"
                           " not a callable of x")
    for c in prob.conditions:
        if c.kind == "dirichlet" and c.value.kind != "number":
            raise ProblemError(f"{what}: the Dirichlet value on {show(c.tag)} must be a number (the projection "
                               "of a field would move with the faces)")
        if c.kind in ("neumann", "robin") and (c.value.kind == "callable" or (c.h is not None and
                                                                            c.h.kind == "callable")):
            raise ProblemError(f"{what}: the {c.kind} data on {show(c.tag)} must be numbers or channels of the "
                               "map (material), not callables of x")
        if c.timed is not None:
            raise ProblemError(f"{what} is for steady problems; the condition on {show(c.tag)} changes in time")


def _conductivity_matrix(prob):
    """``K(x, chans, where) -> (N, 3, 3)``: the conductivity tensor at points (isotropic: k I)."""
    from iga.heat.coefficients import TENSOR_PAIRS

    k = prob.conductivity

    def tensor(x, chans, where):
        n = len(x)
        if k.scalar is not None:
            return k.scalar.values(x, chans, where)[:, None, None] * np.eye(3)
        comps = np.broadcast_to(k.K6, (n, 6)) if k.K6 is not None else \
            np.stack([np.asarray(chans[c], float) for c in k.channels], axis=1)
        out = np.empty((n, 3, 3))
        for j, (r, s) in enumerate(TENSOR_PAIRS):
            out[:, r, s] = out[:, s, r] = comps[:, j]
        return out

    return tensor


class _Explicit:
    """The output's own shape terms: ``volume(T) -> (N,)`` the density of its div V term per unit volume, and
    ``faces`` [(face data, density(T) per face)] of its div_G V terms; either None."""

    def __init__(self, volume=None, faces=None):
        self.volume, self.faces = volume, faces


def _explicit_terms(output: Output, solution, what: str) -> _Explicit:
    """The explicit shape terms of the outputs of :mod:`iga.outputs` (module notes)."""
    if isinstance(output, Volume):
        return _Explicit(volume=np.ones_like)
    if isinstance(output, Compliance):  # u . f: the loads' own shape terms, with u beside the adjoint
        return _Explicit()
    if isinstance(output, (MeanTemperature, TemperatureNorm)):
        p = output.p if isinstance(output, TemperatureNorm) else 1.0
        J = evaluated(output, solution)
        if isinstance(output, TemperatureNorm):
            def density(T, measure):
                return J ** (1 - p) * (np.abs(T) ** p - J ** p) / (p * measure)
        else:
            def density(T, measure):
                return (T - J) / measure
        if output.tag is None:
            V = solution.volume()
            return _Explicit(volume=lambda T: density(T, V))
        fds, area = tag_faces(solution, output.tag, output.name)
        return _Explicit(faces=[(fd, density(fd.trace(solution.u), area)) for fd in fds])
    raise ProblemError(f"{what} knows the shape terms of Volume, MeanTemperature, TemperatureNorm and "
                       f"Compliance; got {show(output)}")


def _face_densities(prob, solution, lam, compliance, explicit: _Explicit):
    """[(faces, [psi per face])]: the densities psi of the div_G V terms on Neumann and Robin faces (+ q lambda,
    - h (u - T_inf) lambda), of a compliance (``compliance`` its u: + q u, + h T_inf u) and of the output's own
    face terms."""
    by_kind = prob.faces_by_kind()
    out = []
    for kind in ("neumann", "robin"):
        tags: dict = {}
        for key, c in by_kind[kind].items():
            tags.setdefault(c.tag, []).append(key)
        for tag, keys in tags.items():
            c, fds = by_kind[kind][keys[0]], prob.faces(keys)
            value = face_values(c.value, fds, tag)  # q (Neumann) or T_inf (Robin)
            h = face_values(c.h, fds, tag) if kind == "robin" else [None] * len(fds)
            dens = []
            for fd, v, hf in zip(fds, value, h):
                lam_f = fd.trace(lam)
                if kind == "neumann":
                    d = v * (lam_f if compliance is None else lam_f + fd.trace(compliance))
                else:
                    u_f = fd.trace(solution.u)
                    d = -hf * (u_f - v) * lam_f + (0.0 if compliance is None else hf * v * u_f)
                dens.append(d)
            out.append((fds, dens))
    if explicit.faces:
        out.append(([fd for fd, _ in explicit.faces], [d for _, d in explicit.faces]))
    return out


def face_parameters(prob, faces, D, placed: bool) -> list[np.ndarray]:
    """The parameters y (N_f, 3) in D of the Gauss points of each face data of ``faces`` (in their own point
    order): the face's parametric grid of the patch's analysis space, through the tile (the side's limit at a
    slot plane; evaluated once per tile spline, face and space) and the patch's placement."""
    grids: dict = {}
    out = []
    for fd in faces:
        patch, space = prob.model.patches[fd.patch], prob.spaces[fd.patch]
        key = (id(patch.spline), fd.face, space.key())
        if key not in grids:
            grids[key] = _face_grid(patch.spline, fd.face, space, placed)
        S = grids[key]
        y = S @ patch.placement[:, :3].T + patch.placement[:, 3] if placed and patch.placement is not None else S
        out.append(np.clip(y, D.domain[:, 0], D.domain[:, 1]))
    return out


def face_plane(spline, face: str) -> tuple:
    """(direction k, parameter at, side) of a face of ``spline``: a boundary face (side 0) or a slot face at an
    interior discontinuity plane (side -1: the piece below it, +1: above)."""
    slot = parse_slot_face(face)
    if slot is None:
        k, side = FACE_AXIS[face]
        return k, spline.knots[k][-1] if side else spline.knots[k][0], 0
    return slot


def _face_grid(spline, face: str, space, placed: bool) -> np.ndarray:
    """The face's Gauss grid (N, 3) of ``space`` on the tile ``spline``: its parameters, or (placed) the tile's
    points there (at a slot plane, the limit from the face's side)."""
    k, at, sgn = face_plane(spline, face)
    if sgn:
        box = spline.domain.copy()
        box[k] = [box[k, 0], at] if sgn < 0 else [at, box[k, 1]]
        spline = spline.extract(box)
    axes = [d.qpts for d in space.dirs]
    axes[k] = np.array([at])
    grid = np.stack(np.meshgrid(*axes, indexing="ij"), -1).reshape(-1, 3)
    return spline.evaluate(grid)[:, :3] if placed else grid


#: points per scatter of the face terms (bounded temporaries: 27 basis functions of D a point, 3 derivatives)
_SCATTER_POINTS = 1 << 16


def _scatter(grad: np.ndarray, D, y: np.ndarray, Q: np.ndarray) -> None:
    """grad (control points, 3) += sum_q (Q_q D'(y_q)^-T)_{dk} d_k R_c(y_q): the weighted fields Q (N, 3, 3) of a
    pass (module notes) at D's parameters y (N, 3)."""
    Dy = D.jacobian(y)[:, :3, :]  # dx/dy (N, 3, 3)
    Z = np.einsum("qdj,qkj->qdk", Q, np.linalg.inv(Dy))  # Q D'^-T: (Q D'^-T)_{dk} = sum_j Q_dj (D'^-1)_kj
    idx, _, dR = map_basis_values(D, y, derivatives=True)
    flat = idx.ravel()
    for d in range(3):
        val = sum(dR[k] * Z[:, d, k][:, None] for k in range(3))
        grad[:, d] += np.bincount(flat, weights=val.ravel(), minlength=len(grad))
