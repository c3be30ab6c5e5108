"""Compiled bounds and monotonicity of spline sub-boxes (numba; imported only when available).

One pass per (box, child): the box's (d+1)^3 supporting coefficients are
carried to Bernstein form direction by direction (sum factorisation, 3 (d+1)^4
products), and the minimum, maximum and the signs of the differences along
each direction are read off without storing the coefficients.  The NumPy path
of :mod:`tiling.implicit.certify` computes the same from stored arrays.
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange


@njit(cache=True, parallel=True)
def judge_rows(G, boxes, children, f0, f1, f2, A0, A1, A2, band, low, high, mono):
    """Bounds (least and greatest Bernstein coefficient) and monotonicity bits of one child per row, written
    into low, high, mono (L,); the bits only where the bounds meet [-band, band] (else 0).

    G (n0, n1, n2): global coefficients; boxes (L, 3): box indices; children
    (L, 3): the child (m0, m1, m2) of each box; f_k (nb_k,): first supporting
    coefficient; A_k (nb_k, s, d+1, d+1): supporting coefficients ->
    Bernstein coefficients of child m of the box.  Bit 2k of mono: strictly
    increasing along +x_k; bit 2k + 1: strictly decreasing.
    """
    L = boxes.shape[0]
    d1 = A0.shape[2]
    chunks = min(L, 1024)  # work buffers allocated once per chunk, not per row
    for chunk in prange(chunks):
        T1 = np.empty((d1, d1, d1))
        T2 = np.empty((d1, d1, d1))
        C = np.empty((d1, d1, d1))
        for l in range(chunk * L // chunks, (chunk + 1) * L // chunks):
            _judge_one(G, boxes, children, f0, f1, f2, A0, A1, A2, band, low, high, mono, l, d1, T1, T2, C)


@njit(cache=True)
def _judge_one(G, boxes, children, f0, f1, f2, A0, A1, A2, band, low, high, mono, l, d1, T1, T2, C):
    """Row l (:func:`judge_rows`), with work buffers T1, T2, C of shape (d+1,) * 3."""
    m0, m1, m2 = children[l, 0], children[l, 1], children[l, 2]
    a, b, c = boxes[l, 0], boxes[l, 1], boxes[l, 2]
    for p in range(d1):
        for q in range(d1):
            for k in range(d1):
                t = 0.0
                for r in range(d1):
                    t += A2[c, m2, k, r] * G[f0[a] + p, f1[b] + q, f2[c] + r]
                T1[p, q, k] = t
    for p in range(d1):
        for j in range(d1):
            for k in range(d1):
                t = 0.0
                for q in range(d1):
                    t += A1[b, m1, j, q] * T1[p, q, k]
                T2[p, j, k] = t
    for i in range(d1):
        for j in range(d1):
            for k in range(d1):
                t = 0.0
                for p in range(d1):
                    t += A0[a, m0, i, p] * T2[p, j, k]
                C[i, j, k] = t
    low[l], high[l], mono[l] = _verdict(C, d1, band)


@njit(cache=True)
def _verdict(C, d1, band):
    """(least, greatest, monotonicity bits) of Bernstein coefficients C (d+1,) * 3; bits 0 unless the bounds
    meet [-band, band]."""
    lo, hi = C.min(), C.max()
    if lo > band or hi < -band:
        return lo, hi, 0
    bits = 0
    for axis in range(3):
        inc = True
        dec = True
        for i in range(d1 - (axis == 0)):
            for j in range(d1 - (axis == 1)):
                for k in range(d1 - (axis == 2)):
                    if axis == 0:
                        w = C[i + 1, j, k] - C[i, j, k]
                    elif axis == 1:
                        w = C[i, j + 1, k] - C[i, j, k]
                    else:
                        w = C[i, j, k + 1] - C[i, j, k]
                    inc &= w > 0
                    dec &= w < 0
        bits |= inc << (2 * axis) | dec << (2 * axis + 1)
    return lo, hi, bits
