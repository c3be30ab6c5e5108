"""Compiled kernels of :mod:`geometry.compiled._fast` (imported only when numba is installed and first needed)."""

from __future__ import annotations

import numpy as np
from numba import njit, prange


@njit(cache=True, inline="always", error_model="numpy")
def find_span(U, p, n, t):
    """Knot span index i with U[i] <= t < U[i + 1] (t = U[-1] -> last span); A2.1 of The NURBS Book."""
    if t >= U[n]:
        return n - 1
    if t <= U[p]:
        return p
    lo, hi = p, n
    mid = (lo + hi) // 2
    while t < U[mid] or t >= U[mid + 1]:
        if t < U[mid]:
            hi = mid
        else:
            lo = mid
        mid = (lo + hi) // 2
    return mid

@njit(cache=True, inline="always", error_model="numpy")
def span_basis(U, p, i, t, N, left, right):
    """Non-zero basis values N[0..p] at t in span i (A2.2)."""
    N[0] = 1.0
    for j in range(1, p + 1):
        left[j] = t - U[i + 1 - j]
        right[j] = U[i + j] - t
        saved = 0.0
        for r in range(j):
            tmp = N[r] / (right[r + 1] + left[j - r])
            N[r] = saved + right[r + 1] * tmp
            saved = left[j - r] * tmp
        N[j] = saved

@njit(cache=True, inline="always", error_model="numpy")
def span_basis_d1(U, p, i, t, dN, Nm, left, right):
    """First derivatives dN[0..p] of the non-zero basis functions at t in span i (NURBS Book Eq. 2.7).

    N'_{k,p} = p N_{k,p-1} / (U[k+p] - U[k]) - p N_{k+1,p-1} / (U[k+p+1] - U[k+1]); both
    denominators contain the non-empty span i wherever their N is non-zero.
    """
    if p == 0:
        dN[0] = 0.0
        return
    span_basis(U, p - 1, i, t, Nm, left, right)  # Nm[j] = N_{i-p+1+j, p-1}, j = 0..p-1
    for a in range(p + 1):
        k = i - p + a
        d = 0.0
        if a >= 1:
            d += Nm[a - 1] / (U[k + p] - U[k])
        if a <= p - 1:
            d -= Nm[a] / (U[k + p + 1] - U[k + 1])
        dN[a] = p * d


@njit(cache=True, parallel=True, error_model="numpy")
def eval3(x, U0, p0, U1, p1, U2, p2, C, out, bad):
    """Values (out (1, N, m)) or values and first derivatives (out (4, N, m): value, d/dx0, d/dx1, d/dx2).

    Points outside the domain or not finite are counted in ``bad`` (per work item) and skipped.
    """
    npts = x.shape[0]
    m = C.shape[3]
    nd = out.shape[0]
    n0, n1, n2 = C.shape[0], C.shape[1], C.shape[2]
    pm = max(p0, max(p1, p2)) + 1
    chunks = bad.shape[0]
    for ch in prange(chunks):
        a0 = ch * npts // chunks
        a1 = (ch + 1) * npts // chunks
        B0 = np.empty(pm)
        B1 = np.empty(pm)
        B2 = np.empty(pm)
        dB0 = np.zeros(pm)
        dB1 = np.zeros(pm)
        dB2 = np.zeros(pm)
        Nm = np.empty(pm)
        L = np.empty(pm)
        R = np.empty(pm)
        acc = np.empty((nd, m))
        for k in range(a0, a1):
            t0, t1, t2 = x[k, 0], x[k, 1], x[k, 2]
            # outside the domain or NaN (comparisons with NaN are false): flag, the caller re-checks
            if not (U0[0] <= t0 <= U0[-1] and U1[0] <= t1 <= U1[-1] and U2[0] <= t2 <= U2[-1]):
                bad[ch] += 1
                continue
            i0 = find_span(U0, p0, n0, t0)
            i1 = find_span(U1, p1, n1, t1)
            i2 = find_span(U2, p2, n2, t2)
            span_basis(U0, p0, i0, t0, B0, L, R)
            span_basis(U1, p1, i1, t1, B1, L, R)
            span_basis(U2, p2, i2, t2, B2, L, R)
            for j in range(nd):
                for c in range(m):
                    acc[j, c] = 0.0
            if nd == 1:
                for a in range(p0 + 1):
                    ia = i0 - p0 + a
                    for b in range(p1 + 1):
                        wab = B0[a] * B1[b]
                        ib = i1 - p1 + b
                        for e in range(p2 + 1):
                            w = wab * B2[e]
                            ie = i2 - p2 + e
                            for c in range(m):
                                acc[0, c] += w * C[ia, ib, ie, c]
            else:
                span_basis_d1(U0, p0, i0, t0, dB0, Nm, L, R)
                span_basis_d1(U1, p1, i1, t1, dB1, Nm, L, R)
                span_basis_d1(U2, p2, i2, t2, dB2, Nm, L, R)
                for a in range(p0 + 1):
                    ia = i0 - p0 + a
                    for b in range(p1 + 1):
                        ib = i1 - p1 + b
                        vv, dv, vd = B0[a] * B1[b], dB0[a] * B1[b], B0[a] * dB1[b]
                        for e in range(p2 + 1):
                            ie = i2 - p2 + e
                            w, w0, w1, w2 = vv * B2[e], dv * B2[e], vd * B2[e], vv * dB2[e]
                            for c in range(m):
                                h = C[ia, ib, ie, c]
                                acc[0, c] += w * h
                                acc[1, c] += w0 * h
                                acc[2, c] += w1 * h
                                acc[3, c] += w2 * h
            for j in range(nd):
                for c in range(m):
                    out[j, k, c] = acc[j, c]
