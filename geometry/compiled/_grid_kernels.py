"""Compiled grid evaluation of 3-D tensor-product splines (numba; imported only when needed).

Values and first derivatives on a tensor grid of parameters by sum
factorisation: directions 2 and 1 contracted on the coefficient rows a slab
of direction 0 touches (:func:`contract21`), then direction 0 row by row
(:func:`direction0_row`); :func:`grid_derivs3` writes them out.  The metric
kernels of the analysis (``iga.assembly._metric_kernels``) reuse the two stages.
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange


@njit(cache=True, parallel=True)
def contract21(hom, lo, R, B1, f1, B2, f2):
    """Directions 2 and 1 of a 3-D spline contracted on the coefficient rows lo .. lo + R - 1 of direction 0.

    Returns U (3, R, nq1, nq2 m): (value, value), (derivative, value) and
    (value, derivative) in directions (1, 2); arguments as in
    :func:`grid_derivs3`.
    """
    m = hom.shape[3]
    n1 = hom.shape[1]
    p1, p2 = B1.shape[2] - 1, B2.shape[2] - 1
    nq1, nq2 = B1.shape[1], B2.shape[1]
    T = np.empty((2, R, n1, nq2, m))  # direction 2 contracted (value, derivative)
    for item in prange(R * n1):
        r = item // n1
        i1 = item - r * n1
        for q2 in range(nq2):
            s = f2[q2]
            for c in range(m):
                t0 = 0.0
                t1 = 0.0
                for l in range(p2 + 1):
                    h = hom[lo + r, i1, s + l, c]
                    t0 += B2[0, q2, l] * h
                    t1 += B2[1, q2, l] * h
                T[0, r, i1, q2, c] = t0
                T[1, r, i1, q2, c] = t1
    # then direction 1: the innermost loops run over the contiguous (q2, component) rows, so they vectorise
    K = nq2 * m
    U = np.empty((3, R, nq1, K))
    Tf = T.reshape(2, R, n1, K)
    for item in prange(R * nq1):
        r = item // nq1
        q1 = item - r * nq1
        s = f1[q1]
        U0, U1, U2 = U[0, r, q1], U[1, r, q1], U[2, r, q1]
        for k in range(K):
            U0[k] = 0.0
            U1[k] = 0.0
            U2[k] = 0.0
        for l in range(p1 + 1):
            v = B1[0, q1, l]
            dv = B1[1, q1, l]
            T0, T1 = Tf[0, r, s + l], Tf[1, r, s + l]
            for k in range(K):
                U0[k] += v * T0[k]
                U1[k] += dv * T0[k]
                U2[k] += v * T1[k]
    return U


@njit(inline="always")
def direction0_row(U, B0, q0, s, q1, X, D0, D1, D2, value):
    """Direction 0 contracted at grid coordinate q0 for grid row q1: the rows X (if ``value``), D0, D1, D2 (K,).

    U (3, R, nq1, K) from :func:`contract21`; ``s`` the first coefficient row
    of q0's basis functions relative to U's first row.
    """
    K = D0.shape[0]
    for k in range(K):
        D0[k] = 0.0
        D1[k] = 0.0
        D2[k] = 0.0
    if value:
        for k in range(K):
            X[k] = 0.0
    for l in range(B0.shape[2]):
        v = B0[0, q0, l]
        dv = B0[1, q0, l]
        V0, V1, V2 = U[0, s + l, q1], U[1, s + l, q1], U[2, s + l, q1]
        if value:  # one sweep for all four rows
            for k in range(K):
                X[k] += v * V0[k]
                D0[k] += dv * V0[k]
                D1[k] += v * V1[k]
                D2[k] += v * V2[k]
        else:
            for k in range(K):
                D0[k] += dv * V0[k]
                D1[k] += v * V1[k]
                D2[k] += v * V2[k]


@njit(cache=True, parallel=True)
def grid_derivs3(hom, a, b, f0, B0, f1, B1, f2, B2, out):
    """Values and first derivatives of a 3-D tensor spline on the rows a..b-1 of a grid.

    hom (n0, n1, n2, m): coefficients (homogeneous for NURBS); per direction k,
    ``f_k[q]`` the first non-zero basis function at grid coordinate q and
    ``B_k[v, q, l]`` its ``l``-th non-zero function (v = 0) or derivative
    (v = 1).  out (4, b - a, nq1, nq2, m) receives the value and the
    derivatives along directions 0, 1 and 2.  Sum factorisation: direction 2,
    then 1 (on the coefficient rows the slab touches), then 0.
    """
    nq1, nq2, m = B1.shape[1], B2.shape[1], hom.shape[3]
    p0 = B0.shape[2] - 1
    lo = f0[a]
    U = contract21(hom, lo, f0[b - 1] + p0 + 1 - lo, B1, f1, B2, f2)
    K = nq2 * m
    outf = out.reshape(4, b - a, nq1, K)
    for item in prange((b - a) * nq1):
        # planes j inner: the items of one thread share q1, so the U rows they read (about 130 KB)
        # stay in cache; with q1 inner the rows were re-read from memory for every plane
        q1 = item // (b - a)
        j = item - q1 * (b - a)
        q0 = a + j
        s = f0[q0] - lo
        direction0_row(U, B0, q0, s, q1, outf[0, j, q1], outf[1, j, q1], outf[2, j, q1], outf[3, j, q1], True)
