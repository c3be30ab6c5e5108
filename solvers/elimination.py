"""Linear constraints on unknowns solved by elimination: ``C x = rhs`` turned into ``x = T z + x0``.

The analysis uses it where constraints act on unknowns that are already reduced: the Dirichlet data of DOFs that
are combinations of others, and the continuity conditions that branch rows of one DOF class imply between
masters.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from scipy.linalg import qr, solve_triangular
from scipy.sparse.csgraph import connected_components

from geometry.numbers import TINY

#: the toolkit's rank threshold (relative to the largest pivot of a block) and round-off floor of O(1) entries:
#: the values of ``geometry.tolerances.RANK`` and ``ROUNDOFF``, which the solvers package does not import
RANK, ROUNDOFF = 1e-10, 1e-14

__all__ = ["elimination", "induced_elimination"]


def induced_elimination(C: sp.spmatrix, rhs: np.ndarray, tol: float = RANK):
    """:func:`elimination` without the kept columns: ``(T, x0, touched)``."""
    return elimination(C, rhs, tol)[:3]


def elimination(C: sp.spmatrix, rhs: np.ndarray, tol: float = RANK):
    """Solve the linear constraints ``C x = rhs`` on free unknowns by elimination.

    Dirichlet DOFs that are *slaves* (child branch-in DOFs on a Dirichlet face,
    e.g. the bottom edge of a slot inside a parent's branch-out face) fix a
    combination of their masters, not one master: ``P[row] u = g``.  These rows
    are split into independent blocks (connected components of the columns they
    share, SciPy's csgraph); per block a column-pivoted QR finds the rank ``r``
    and expresses ``r`` pivot columns through the others.

    Returns ``(T, x0, touched, keep)``: every ``x`` with ``C x = rhs`` (in the least-squares
    sense when the rows conflict) is ``x = T z + x0``; ``T`` is sparse (n x nz)
    with unit columns for the untouched unknowns; ``touched`` are the columns C involves; ``keep`` (n,) whether
    each unknown stays one (a column of T), in order.
    """
    C = sp.csr_matrix(C)
    n = C.shape[1]
    C.data[np.abs(C.data) < ROUNDOFF] = 0.0
    C.eliminate_zeros()
    rows = np.nonzero(np.diff(C.indptr))[0]
    touched = np.unique(C.indices)
    x0 = np.zeros(n)
    if not len(touched):
        return sp.identity(n, format="csc"), x0, touched, np.ones(n, bool)
    Ct = C[rows][:, touched].tocsc()
    # columns linked through a shared row belong to one block
    link = (abs(Ct.T) @ abs(Ct)).tocsr()
    nb, label = connected_components(link, directed=False)
    keep = np.ones(n, bool)  # columns that stay unknowns
    t_rows, t_cols, t_vals = [], [], []  # entries of T for eliminated columns: x_piv = sum_j t x_j
    for b in range(nb):
        cols_b = np.nonzero(label == b)[0]
        sub = Ct[:, cols_b]
        rows_b = np.unique(sub.indices)
        A = sub[rows_b].toarray()
        y = rhs[rows[rows_b]]
        Q, R, perm = qr(A, mode="economic", pivoting=True)
        d = np.abs(np.diag(R))
        r = int(np.sum(d > tol * max(d[0], TINY))) if len(d) else 0
        if r == 0:
            continue
        piv, rest = perm[:r], perm[r:]
        # A[:, piv] x_piv + A[:, rest] x_rest = y  ->  x_piv = R11^-1 (Q1^T y - R12 x_rest)
        R11, R12 = R[:r, :r], R[:r, r:]
        base = solve_triangular(R11, Q[:, :r].T @ y)
        coup = -solve_triangular(R11, R12) if len(rest) else np.zeros((r, 0))
        gp, gr = touched[cols_b[piv]], touched[cols_b[rest]]
        x0[gp] = base
        keep[gp] = False
        ii, jj = np.nonzero(np.abs(coup) > 0.1 * ROUNDOFF)
        t_rows.append(gp[ii]); t_cols.append(gr[jj]); t_vals.append(coup[ii, jj])
    col_of = np.full(n, -1)
    col_of[keep] = np.arange(int(keep.sum()))
    kept = np.nonzero(keep)[0]
    r_all = np.concatenate([kept] + t_rows)
    c_all = np.concatenate([col_of[kept]] + [col_of[c] for c in t_cols])
    v_all = np.concatenate([np.ones(len(kept))] + t_vals)
    T = sp.csc_matrix((v_all, (r_all, c_all)), shape=(n, int(keep.sum())))
    return T, x0, touched, keep
