"""Compiled kernel of :func:`geometry.bernstein.multiply` (imported only when numba is installed and first needed).

The product of two tensor-product Bernstein polynomials is the full
convolution of their binomially scaled coefficients, unscaled by the
binomials of the result (module notes of :mod:`geometry.bernstein`).  For the
high degrees of composition (Elber 2017, Fig. 4: factors of degree (9, 9) to
(18, 18), results of (27, 27)) the direct loops with the last axis innermost
do a third of the multiplications of the banded-Toeplitz matrix product,
write no Toeplitz matrix and scale on the fly.  Serial on purpose: composition
interleaves these products with BLAS calls, whose idle threads spin for a
while after each call, and a parallel kernel run between them measured 4x
slower than alone.
"""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True, nogil=True)
def product3(a, b, wa, wb, wo, out):
    """``out[s, i, j]`` = the Bernstein product of ``a[s, i]`` and ``b[s, j]`` over three Bernstein axes.

    a (B, Ca, p1, p2, p3), b (B, Cb, q1, q2, q3): coefficients; wa (p1, p2, p3), wb (q1, q2, q3): their
    binomial scalings, wo (r1, r2, r3) the inverse scaling of the result, r_k = p_k + q_k - 1; out
    (B, Ca, Cb, r1, r2, r3), zero on entry.  Fewer Bernstein axes are passed as leading axes of length 1.
    """
    B, Ca, Cb = a.shape[0], a.shape[1], b.shape[1]
    p1, p2, p3 = a.shape[2], a.shape[3], a.shape[4]
    q1, q2, q3 = b.shape[2], b.shape[3], b.shape[4]
    r1, r2, r3 = out.shape[3], out.shape[4], out.shape[5]
    bs = np.empty((q1, q2, q3))
    for s in range(B):
        for j in range(Cb):
            for l1 in range(q1):
                for l2 in range(q2):
                    for l3 in range(q3):
                        bs[l1, l2, l3] = b[s, j, l1, l2, l3] * wb[l1, l2, l3]
            for i in range(Ca):
                o = out[s, i, j]
                for k1 in range(p1):
                    for l1 in range(q1):
                        for k2 in range(p2):
                            for l2 in range(q2):
                                row = o[k1 + l1, k2 + l2]
                                bb = bs[l1, l2]
                                for k3 in range(p3):
                                    x = a[s, i, k1, k2, k3] * wa[k1, k2, k3]
                                    for l3 in range(q3):
                                        row[k3 + l3] += x * bb[l3]
                for m1 in range(r1):
                    for m2 in range(r2):
                        for m3 in range(r3):
                            o[m1, m2, m3] *= wo[m1, m2, m3]
