"""Solution fields on the model's sample grids (:mod:`geometry.patches.sampling`): the temperature, heat flux and
conductivity of a heat solution; the displacement, stress, von Mises stress and material of an elastic one."""

from __future__ import annotations

import numpy as np

from geometry.patches.sampling import piece_basis

from iga.heat.coefficients import tensor_matrix
from iga.elasticity.forms import strain
from iga.errors import ProblemError
from iga.outputs import von_mises
from iga.discretisation.fields import grid_fields
from iga.discretisation.fields import field_spline, physical_gradient
from geometry.patches.chain import patch_geometry_points

__all__ = ["temperature_fields", "temperature_frames", "displacement_fields", "corrector_fields"]


def temperature_fields(solution):
    """The ``fields`` hook of :func:`geometry.patches.sampling.sample_model` for a solution: temperature, heat flux
    (W/m^2) and conductivity at the sample points."""
    return temperature_frames(solution.problem, solution.u[None], [""])


def temperature_frames(problem, U: np.ndarray, suffixes):
    """The ``fields`` hook for several temperature fields of ``problem`` at once (the frames of a transient
    solution): ``U`` (c, ndof) their coefficients, ``suffixes`` (c names) appended to ``temperature`` and
    ``heat_flux`` for each; the geometry is sampled once for all of them."""
    def hook(members, pax, x, D, chans, out):
        return _temperature_fields(problem, U, suffixes, members, pax, x, D, chans, out)

    return hook


def _temperature_fields(prob, U, suffixes, members, pax, x, D, chans, out: dict) -> np.ndarray:
    """Temperatures, heat fluxes and the conductivity (P, N[, 3]) of patches sharing a space, on a piece's grid,
    for the coefficient rows of ``U``.  The fields go into ``out``; returns the Jacobian determinants (P N,)
    computed on the way."""
    space = prob.spaces[members[0]]
    c = len(U)
    B = [piece_basis(d, a) for d, a in zip(space.dirs, pax)]  # per direction: (values, derivatives)
    blocks = np.stack([U[:, prob.offsets[i]:prob.offsets[i + 1]].reshape((c,) + space.shape) for i in members])
    T, grad, det = grid_fields(blocks, B, D, prob.weights[members[0]])
    P, N = x.shape[:2]

    def grad_at(pi, params):  # (n, c, 3): every field's physical gradient at parameters of patch pi
        coef = np.moveaxis(U[:, prob.offsets[pi]:prob.offsets[pi + 1]].reshape((c,) + space.shape), 0, -1)
        dxi = field_spline(space, coef, prob.weights[pi]).jacobian(params)
        J = patch_geometry_points(prob.model.patches[pi], params)[1]
        return np.stack([physical_gradient(J, dxi[:, a], f"patch {pi}", params) for a in range(c)], 1)

    grad = _limits(grad, members, pax, grad_at, prob)
    flat = {ch: np.reshape(v, -1) for ch, v in chans.items()}
    where = f"patches {members[0]}..{members[-1]}"
    for a, suffix in enumerate(suffixes):  # (a temperature-dependent conductivity: each field's own)
        K = prob.conductivity.values(x.reshape(-1, 3), flat, where, T[:, a])
        flux = -K[:, None] * grad[:, a] if K.ndim == 1 else -np.einsum("nij,nj->ni", tensor_matrix(K), grad[:, a])
        out[f"temperature{suffix}"] = T[:, a].reshape(P, N)
        out[f"heat_flux{suffix}"] = flux.reshape(P, N, 3)
    cond = K if K.ndim == 1 else tensor_matrix(K).reshape(-1, 9)
    out["conductivity"] = cond.reshape((P, N) + cond.shape[1:])
    return det


def displacement_fields(solution):
    """The ``fields`` hook for an :class:`iga.ElasticSolution`: displacement (m), stress (Pa, six components
    xx, yy, zz, xy, xz, yz), von Mises stress (Pa), Young's modulus and Poisson's ratio at the sample points (a
    cubic material: ``cubic_constants`` C11, C12, C44 in Pa)."""
    def hook(members, pax, x, D, chans, out):
        return _displacement_fields(solution, members, pax, x, D, chans, out)

    return hook


def _displacement_fields(solution, members, pax, x, D, chans, out: dict) -> np.ndarray:
    prob = solution.problem
    space, n = prob.spaces[members[0]], prob.ndof
    B = [piece_basis(d, a) for d, a in zip(space.dirs, pax)]
    P, N = x.shape[:2]
    o = prob.offsets
    U = np.stack([np.stack([solution.u[a * n + o[i] : a * n + o[i + 1]].reshape(space.shape) for a in range(3)])
                  for i in members])
    u, grad, det = grid_fields(U, B, D, prob.weights[members[0]])
    grad = _limits(grad, members, pax, lambda pi, p: solution.evaluate(pi, p)[1], prob)
    flat = {c: np.reshape(v, -1) for c, v in chans.items()}
    xs = x.reshape(-1, 3)
    where = f"patches {members[0]}..{members[-1]}"
    mod = prob.material.moduli(xs, flat, where)
    eps = strain(grad)
    if prob.thermal_strain is not None:
        params = np.stack(np.meshgrid(*pax, indexing="ij"), -1).reshape(-1, 3)
        th = np.concatenate([prob.thermal_strain(i, x[j], params, {c: v[j] for c, v in chans.items()})
                             for j, i in enumerate(members)])
        eps = eps - th[:, None, None] * np.eye(3)
    S = mod.stress(eps)
    voigt = np.stack([S[:, 0, 0], S[:, 1, 1], S[:, 2, 2], S[:, 0, 1], S[:, 0, 2], S[:, 1, 2]], 1)
    out.update({"displacement": u.reshape(P, N, 3), "stress": voigt.reshape(P, N, 6),
                "von_mises": von_mises(S)[1].reshape(P, N)})
    if prob.youngs is not None:  # isotropic
        out.update({"youngs_modulus": prob.youngs.values(xs, flat, where).reshape(P, N),
                    "poisson_ratio": prob.poisson.values(xs, flat, where).reshape(P, N)})
    else:  # cubic: C11, C12, C44
        c11 = mod.lam + 2 * mod.mu + mod.kappa
        out["cubic_constants"] = np.stack([c11, mod.lam, mod.mu], 1).reshape(P, N, 3)
    return det


def corrector_fields(prob, chi: np.ndarray):
    """The ``fields`` hook of the periodic cell problems (:mod:`iga.homogenisation.cells`): the correctors ``chi`` (ndof,
    3), one column per macroscopic gradient e_j (m), and the cell's heat flux for a unit gradient along x, y,
    z: ``cell_flux_x`` = -k (grad chi_x + e_x) .. (W/m^2 per K/m), and the conductivity."""
    def hook(members, pax, x, D, chans, out):
        space = prob.spaces[members[0]]
        B = [piece_basis(d, a) for d, a in zip(space.dirs, pax)]
        o = prob.offsets
        U = np.stack([np.stack([chi[o[i]:o[i + 1], j].reshape(space.shape) for j in range(3)]) for i in members])
        val, grad, det = grid_fields(U, B, D, prob.weights[members[0]])
        grad[~np.all(np.isfinite(grad), axis=(1, 2))] = np.nan  # a collapsed point: no gradient (not a zero)
        P, N = x.shape[:2]
        flat = {c: np.reshape(v, -1) for c, v in chans.items()}
        K = prob.conductivity.values(x.reshape(-1, 3), flat, f"patches {members[0]}..{members[-1]}")
        Km = K[:, None, None] * np.eye(3) if K.ndim == 1 else tensor_matrix(K)
        out["corrector"] = val.reshape(P, N, 3)
        for j, name in enumerate("xyz"):
            out[f"cell_flux_{name}"] = -np.einsum("nij,nj->ni", Km, grad[:, j] + np.eye(3)[j]).reshape(P, N, 3)
        out["conductivity"] = (K if K.ndim == 1 else K[:, 0]).reshape(P, N)
        return det

    return hook


#: how far (a fraction of the patch's parameter box) a sample on a collapsed edge or face is moved inwards to
#: take its gradient's limit
_INWARD = 1e-6


def _limits(grad: np.ndarray, members, pax, grad_at, prob) -> np.ndarray:
    """Gradients (P N, c, 3) with those at degenerate samples (a collapsed edge or face, where det J = 0 and the
    grid's gradient is not finite) replaced by their limit from inside: ``grad_at(patch, params (n, 3))`` at
    the sample moved towards the patch's centre by :data:`_INWARD` of its box.  Where that is singular too the
    gradient is NaN: written as not-a-number, never as a zero (the heat flux at a wedge's collapsed face is
    not 0)."""
    bad = ~np.all(np.isfinite(grad), axis=(1, 2))
    if not bad.any():
        return grad
    grid = np.stack(np.meshgrid(*pax, indexing="ij"), -1).reshape(-1, 3)
    N = len(grid)
    for j, pi in enumerate(members):
        rows = np.flatnonzero(bad[j * N:(j + 1) * N])
        if not len(rows):
            continue
        dom = np.array([[d.knots[0], d.knots[-1]] for d in prob.spaces[pi].dirs])
        inside = grid[rows] + _INWARD * (dom.mean(axis=1) - grid[rows])
        try:
            grad[j * N + rows] = grad_at(pi, inside)
        except ProblemError:  # singular there too: no limit to write
            grad[j * N + rows] = np.nan
    return grad
