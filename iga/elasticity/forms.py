"""Coefficient fields of small-strain linear elasticity on the Gauss grid (Elber 2017, Section 3).

With the displacement ``u = sum_j N_j u_j`` (three components per basis
function) the bilinear form int sigma(u) : eps(v) dV couples component a of
test function N_i with component b of trial function N_j by

    K^{ab}_{ij} = int lambda d_a N_i d_b N_j + mu d_b N_i d_a N_j + mu delta_ab grad N_i . grad N_j dV.

In the parameters, d_a N = sum_r c_r[a] d_r N / det J with c_1 = x_v x x_w,
c_2 = x_w x x_u, c_3 = x_u x x_v (the rows of det J * J^-1, as in
:func:`iga.heat.forms.diffusion`), so K^{ab} = sum_rs int F^{ab}_rs d_r N_i d_s N_j with

    F^{ab}_rs = w / |det J| (lambda c_r[a] c_s[b] + mu c_r[b] c_s[a] + mu delta_ab c_r . c_s),

nine parametric terms per block (symmetric in (r, s) on the diagonal blocks,
F^{ba}_rs = F^{ab}_sr off it).  A cubic material (:mod:`iga.elasticity.material`) adds
kappa d_a N_i d_a N_j to the diagonal blocks.  A thermal strain alpha (T - T_ref) I adds the
load int beta div v dV with beta = (3 lambda + 2 mu + kappa) alpha (T - T_ref):
component a of N_i receives sum_r int beta sign(det J) w c_r[a] d_r N_i.
"""

from __future__ import annotations

import numpy as np

from iga.discretisation.faces import cross
from iga.elasticity.material import Moduli, lame

__all__ = ["lame", "moduli", "strain", "metric_rows", "block_terms", "divergence_terms"]


def strain(grads: np.ndarray) -> np.ndarray:
    """The small strain sym(grad u) (N, 3, 3) of displacement gradients (N, 3, 3), [q, i, j] = d u_i / d x_j."""
    return 0.5 * (grads + np.transpose(grads, (0, 2, 1)))


def moduli(prob, chunk, x, chans) -> Moduli:
    """The problem's :class:`iga.elasticity.material.Moduli` at Gauss points x (N, 3) of the patches ``chunk``,
    the channels there."""
    flat = {c: np.reshape(v, -1) for c, v in chans.items()}
    return prob.material.moduli(x, flat, f"patches {chunk[0]}..{chunk[-1]}")


def metric_rows(D) -> tuple[list, np.ndarray]:
    """(c, det): the rows c_r (3, M) of det J * J^-1 and det J (M,) from the derivatives [x_u, x_v, x_w]."""
    Du, Dv, Dw = (np.moveaxis(d.reshape(-1, 3), 1, 0) for d in D)
    c = [cross(Dv, Dw, 0), cross(Dw, Du, 0), cross(Du, Dv, 0)]
    return c, Du[0] * c[0][0] + Du[1] * c[0][1] + Du[2] * c[0][2]


def _variants(r: int, s: int | None) -> tuple:
    return tuple((int(k == r), int(k == s)) if s is not None else (int(k == r), None) for k in range(3))


def block_terms(c, fac, lam, mu, a: int, b: int, shape, kappa=None) -> list:
    """The banded-form terms [(F (P,) + qshape, derivative orders)] of block (a, b); ``fac`` = w / |det J| (1
    when lam, mu and kappa already carry it): what the NumPy assembly sums (:mod:`iga.elasticity.volume`).
    ``kappa``: a cubic material's anisotropy (:mod:`iga.elasticity.material`), which adds kappa c_r[a] c_s[a] to
    the diagonal block (a, a): the same products as lambda's there.

    Off the diagonal all nine.  On a diagonal block F is symmetric, so only the half H = F_rr / 2 + F_rs
    (r < s) is returned, six terms, and the block is H + H^T (as :func:`iga.assembly.tensor.stiffness_data`)."""
    if kappa is not None and a == b:
        lam = lam + kappa
    lca = [lam * c[r][a] for r in range(3)]  # products shared by the terms
    mcb = [mu * c[r][b] for r in range(3)]
    out = []
    for r in range(3):
        for s in range(3):
            if a == b and s < r:
                continue
            F = lca[r] * c[s][b] + mcb[r] * c[s][a]
            if a == b:
                F += mu * (c[r][0] * c[s][0] + c[r][1] * c[s][1] + c[r][2] * c[s][2])
                if s == r:
                    F *= 0.5
            if not (np.isscalar(fac) and fac == 1.0):
                F = fac * F
            out.append((F.reshape(shape), _variants(r, s)))
    return out


def divergence_terms(c, weight, a: int, shape) -> list:
    """Load terms [(G (P,) + qshape, orders)] of int g d_a v dV for the field ``weight`` = g sign(det J) w."""
    return [((weight * c[r][a]).reshape(shape), _variants(r, None)) for r in range(3)]
