"""The weak form of steady heat conduction as named pieces (Massarwi et al. 2018, Eq. 9).

Find T = T_D on Dirichlet faces such that for all v vanishing there

    a(T, v) = int_Omega K grad T . grad v dV  +  sum_Robin int_F h T v dA
    l(v)    = int_Omega f v dV  +  sum_Neumann int_F q v dA  +  sum_Robin int_F h T_inf v dA

Each piece is one function here:

* :func:`diffusion` -- the coefficient fields of ``int K grad T . grad v`` at
  Gauss points (K a number or a symmetric tensor per point) and, from the same
  Jacobians, the source density of ``int f v``; the sum-factorised kernels
  (:mod:`iga.assembly.tensor`, compiled: :mod:`iga.assembly.compiled`) contract them,
  chosen by :class:`iga.heat.volume.VolumeAssembler`;
* :func:`boundary_mass` -- ``int_F c T v dA`` over faces (Robin h, and the
  L2 projection of Dirichlet data with c = 1);
* :func:`boundary_load` and :func:`boundary_load_columns` -- ``int_F g v dA``
  (Neumann flux, Robin h T_inf, Dirichlet data), summed or one column per face.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from iga.assembly.tensor import banded_form, banded_to_csr_data, load_form, pattern
from iga.heat.coefficients import TENSOR_PAIRS
from iga.discretisation.faces import cross
from iga.discretisation.rational import nurbs_scale

__all__ = ["diffusion", "boundary_mass", "boundary_load", "boundary_load_columns"]


def diffusion(D, K, f, w):
    """Stiffness coefficient fields C (6, M), source density L (M,) and det J (M,) at M Gauss points.

    D: [dx/du, dx/dv, dx/dw], each of M points x 3 (any leading shape); K (M,)
    isotropic conductivity or (M, 6) tensor components (xx, yy, zz, xy, xz, yz);
    f (M,) source; w (M,) quadrature weights.  With c_1 = x_v x x_w,
    c_2 = x_w x x_u, c_3 = x_u x x_v (the rows of det J * J^-1), the integrand
    K grad N_i . grad N_j |det J| = sum_rs C_rs d_r N_i d_s N_j with
    C_rs = w (c_r . K c_s) / |det J|, in the pair order (0,0), (1,1), (2,2),
    (0,1), (0,2), (1,2); L = f |det J| w.  A zero determinant gives
    non-finite C, which the caller reports from ``det``.  The compiled twin is
    :func:`iga.assembly.compiled.metric_fields`.
    """
    Du, Dv, Dw = (np.moveaxis(d.reshape(-1, 3), 1, 0) for d in D)  # (3, M) component-major views
    c = (cross(Dv, Dw, 0), cross(Dw, Du, 0), cross(Du, Dv, 0))
    det = Du[0] * c[0][0] + Du[1] * c[0][1] + Du[2] * c[0][2]
    adet = np.abs(det)
    L = f * adet * w
    K = np.asarray(K, float)
    with np.errstate(divide="ignore", invalid="ignore"):  # zero det: reported by the caller
        fac = (K if K.ndim == 1 else 1.0) * w / adet
    if K.ndim == 2:  # K c_s, one product per direction s
        Kc = [np.stack([sum(K[:, _index(i, j)] * cs[j] for j in range(3)) for i in range(3)]) for cs in c]
    else:
        Kc = c
    C = np.empty((6, len(det)))
    for j, (r, t) in enumerate(TENSOR_PAIRS):
        out = C[j]
        np.multiply(c[r][0], Kc[t][0], out=out)
        out += c[r][1] * Kc[t][1]
        out += c[r][2] * Kc[t][2]
        out *= fac
    return C, L, det


def _index(i: int, j: int) -> int:
    """Position of the symmetric tensor entry (i, j) in the (xx, yy, zz, xy, xz, yz) order."""
    return TENSOR_PAIRS.index((min(i, j), max(i, j)))


def _by_space(fds) -> dict:
    """Indices of face data grouped by face space (by space object first: a batch of faces shares one, so
    the key is computed once per object, not per face)."""
    by_object: dict = {}
    for i, fd in enumerate(fds):
        by_object.setdefault(id(fd.space), (fd.space, []))[1].append(i)
    out: dict = {}
    for space, idx in by_object.values():
        out.setdefault(space.key(), []).extend(idx)
    return {k: sorted(v) for k, v in out.items()}


def _kept(fds, values, patches):
    """The faces (and their values) of the patches in ``patches`` (all when None): one MPI rank's share."""
    if patches is None:
        return fds, values
    keep = [i for i, fd in enumerate(fds) if fd.patch in patches]
    return [fds[i] for i in keep], [values[i] for i in keep]


def boundary_mass(fds, coeffs, ndof: int, patches=None) -> sp.csr_matrix:
    """Global sparse sum over faces of int_F c N_i N_j dA; ``coeffs[f]`` is c * dA * w at face f's Gauss points.

    ``patches``: only the faces of these patches (a set), default all.
    """
    fds, coeffs = _kept(fds, coeffs, patches)
    rows, cols, vals = [], [], []
    for idx in _by_space(fds).values():
        space = fds[idx[0]].space
        F = np.stack([coeffs[i] * fds[i].basis_scale(2) for i in idx]).reshape((len(idx),) + space.qshape)
        data = banded_to_csr_data(space, banded_form(space, [(F, ((0, 0), (0, 0)))]))
        pat = pattern(space)
        for row, i in enumerate(idx):  # the NURBS basis (iga.discretisation.rational): w_i w_j
            if fds[i].w_dofs is not None:
                data[row] *= nurbs_scale(pat, fds[i].w_dofs)
        dofs = np.stack([fds[i].dofs for i in idx])
        local_rows = np.repeat(np.arange(pat.n), np.diff(pat.indptr))
        rows.append(dofs[:, local_rows].ravel())
        cols.append(dofs[:, pat.indices].ravel())
        vals.append(data.ravel())
    if not rows:
        return sp.csr_matrix((ndof, ndof))
    return sp.csr_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))), shape=(ndof, ndof))


def boundary_load_columns(fds, values, ndof: int) -> sp.csc_matrix:
    """Sparse (ndof, n_faces): column f holds int_F g N_i dA; ``values[f]`` is g * dA * w at face f's Gauss points."""
    rows, cols, vals = [np.zeros(0, np.int64)], [np.zeros(0, np.int64)], [np.zeros(0)]
    for idx in _by_space(fds).values():
        space = fds[idx[0]].space
        L = load_form(space, np.stack([values[i] * fds[i].basis_scale() for i in idx]).reshape((len(idx),) +
                                                                                              space.qshape))
        L = L.reshape(len(idx), -1)
        for row, i in enumerate(idx):
            if fds[i].w_dofs is not None:
                L[row] *= fds[i].w_dofs
        rows.append(np.stack([fds[i].dofs for i in idx]).ravel())
        cols.append(np.repeat(idx, space.ndof))
        vals.append(L.reshape(-1))
    return sp.csc_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))),
                         shape=(ndof, len(fds)))


def boundary_load(fds, values, ndof: int, patches=None) -> np.ndarray:
    """Global vector: sum over faces of int_F g N_i dA (see :func:`boundary_load_columns`); ``patches`` as in
    :func:`boundary_mass`."""
    fds, values = _kept(fds, values, patches)
    return np.asarray(boundary_load_columns(fds, values, ndof).sum(axis=1)).ravel()
