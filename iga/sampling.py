"""The temperature on the model's sample grids (:mod:`geometry.sampling`): values, heat flux, conductivity."""

from __future__ import annotations

import numpy as np

from geometry.chain import gradient_and_det
from geometry.sampling import piece_basis

from .coefficients import tensor_matrix

__all__ = ["temperature_fields"]


def temperature_fields(solution):
    """The ``fields`` hook of :func:`geometry.sampling.sample_model` for a solution: temperature, heat flux
    (W/m^2) and conductivity at the sample points."""
    def hook(members, pax, x, D, chans, out):
        return _temperature_fields(solution, members, pax, x, D, chans, out)

    return hook


def _temperature_fields(solution, members, pax, x, D, chans, out: dict) -> np.ndarray:
    """Temperature, heat flux and conductivity (P, N[, c]) of patches sharing a space, on a piece's grid.

    The fields go into ``out``; returns the Jacobian determinants (P N,) computed on the way.
    """
    prob = solution.problem
    space = prob.spaces[members[0]]
    B = [piece_basis(d, a) for d, a in zip(space.dirs, pax)]  # per direction: (values, derivatives)
    U = np.stack([solution.u[prob.offsets[i] : prob.offsets[i + 1]].reshape(space.shape) for i in members])
    T = np.einsum("pabc,ia,jb,kc->pijk", U, B[0][0], B[1][0], B[2][0], optimize=True).reshape(len(members), -1)
    dxi = np.stack([np.einsum("pabc,ia,jb,kc->pijk", U, *(B[d][int(d == k)] for d in range(3)), optimize=True)
                    .reshape(len(members), -1) for k in range(3)], axis=-1)
    P, N = T.shape
    grad, det = gradient_and_det(D, dxi.reshape(-1, 3))
    grad[~np.all(np.isfinite(grad), axis=1)] = 0.0  # degenerate points (collapsed edges): no gradient
    flat = {c: np.reshape(v, -1) for c, v in chans.items()}
    K = prob.conductivity.values(x.reshape(-1, 3), flat, f"patches {members[0]}..{members[-1]}")
    flux = -K[:, None] * grad if K.ndim == 1 else -np.einsum("nij,nj->ni", tensor_matrix(K), grad)
    cond = K if K.ndim == 1 else tensor_matrix(K).reshape(-1, 9)
    out.update({"temperature": T, "heat_flux": flux.reshape(P, N, 3),
                "conductivity": cond.reshape((P, N) + cond.shape[1:])})
    return det
