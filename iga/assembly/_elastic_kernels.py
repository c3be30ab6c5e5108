"""Compiled kernel of the elastic stiffness blocks (imported only when numba is installed and first needed).

The same slab-wise sum factorisation as :func:`iga.assembly._assembly_kernels.stiffness3`
(direction 3, then 2, then 1 into a banded ring buffer, rows written into the
CSR data once complete; stage 1 and the copy-out are shared, and like stage 2
compiled once for all degrees), for one block (a, b) of linear elasticity
(:mod:`iga.elasticity.forms`):

    F^{ab}_rs = lf c_r[a] c_s[b] + mf c_r[b] c_s[a] + delta_ab mf c_r . c_s,

formed on the fly from the metric rows ``c`` (nine fields) and the weighted
Lame fields lf = lambda w / |det J|, mf = mu w / |det J|: no per-block
coefficient field is ever stored.  A diagonal block is symmetric: its six
coefficients take the scalar kernel's stages 3 and 2 (half the direction-2
band, mirrored).  An off-diagonal block has nine (r, s) terms and no mirror.
The rows are written, with their columns, straight into the component-major
operator (:class:`iga.assembly.vector_csr.VectorCSR`); :func:`mirror_lower` copies the
lower blocks from the upper ones.
"""

from __future__ import annotations


import numpy as np

from geometry.cache import memo
from numba import njit, prange

from iga.assembly._assembly_kernels import band_weights, heat_stage2, stage1_flush, symmetric_stage3


@njit(cache=True, parallel=True, fastmath=True)
def elastic_stage2(Z, Y, W2, r2, s2):
    """Stage 2 of :func:`elastic3` for the g1 Gauss planes of one direction-1 element: Z (g1, 9, nq2, n3, D3)
    contracted along direction 2 into the four direction-1 variant groups Y (g1, 4, n2, D2, n3, D3).
    Compiled once for every degree, as :func:`iga.assembly._assembly_kernels.heat_stage2`."""
    g1, nq2, n3, D3 = Z.shape[0], Z.shape[2], Z.shape[3], Z.shape[4]
    n2, D2 = Y.shape[2], Y.shape[3]
    K3 = n3 * D3
    Zf = Z.reshape(g1, 9, nq2, K3)
    Yf = Y.reshape(g1, 4, n2, D2, K3)
    # stage 2: groups by the direction-1 variant; (r, s) has direction-2 variant (r == 1, s == 1):
    # Y0 (1,1) = F00; Y1 (1,0) = F01, F02; Y2 (0,1) = F10, F20; Y3 (0,0) = F11, F12, F21, F22
    for item in prange(g1 * n2):
        t = item // n2
        i2 = item - t * n2
        for d2 in range(D2):
            y0, y1, y2, y3 = Yf[t, 0, i2, d2], Yf[t, 1, i2, d2], Yf[t, 2, i2, d2], Yf[t, 3, i2, d2]
            for k in range(K3):
                y0[k] = 0.0
                y1[k] = 0.0
                y2[k] = 0.0
                y3[k] = 0.0
            for l in range(r2[i2, d2, 0], r2[i2, d2, 1]):
                q2 = s2[i2] + l
                w00, w01, w10, w11 = band_weights(W2, i2, d2, l)
                f00, f01, f02 = Zf[t, 0, q2], Zf[t, 1, q2], Zf[t, 2, q2]
                f10, f11, f12 = Zf[t, 3, q2], Zf[t, 4, q2], Zf[t, 5, q2]
                f20, f21, f22 = Zf[t, 6, q2], Zf[t, 7, q2], Zf[t, 8, q2]
                for k in range(K3):
                    y0[k] += w00 * f00[k]
                    y1[k] += w01 * f01[k] + w00 * f02[k]
                    y2[k] += w10 * f10[k] + w00 * f20[k]
                    y3[k] += w11 * f11[k] + w10 * f12[k] + w01 * f21[k] + w00 * f22[k]


@njit(inline="always")
def _general_stage3(F, b3, e3, f, Z, t, q2, P3, G3):
    """Stage 3 of ``elastic3`` for an off-diagonal block on direction-3 element e3 (first function f) of Gauss
    row (t, q2): the nine terms F (9, G3), slot 3 r + s, contracted with their direction-3 variants
    (r == 2, s == 2) into Z[t, :, q2].  Inlined, so the caller's constant P3 and G3 fix the trip counts."""
    for l3 in range(P3 + 1):
        i3 = f + l3
        for m3 in range(P3 + 1):
            d3 = m3 - l3 + P3
            z00 = z01 = z02 = z10 = z11 = z12 = z20 = z21 = z22 = 0.0  # z_rs
            for t3 in range(G3):
                u0 = b3[0, e3, l3, t3]
                u1 = b3[1, e3, l3, t3]
                v0 = b3[0, e3, m3, t3]
                v1 = b3[1, e3, m3, t3]
                w00 = u0 * v0  # direction-3 variants (0,0), (0,1), (1,0), (1,1)
                w01 = u0 * v1
                w10 = u1 * v0
                z00 += w00 * F[0, t3]
                z01 += w00 * F[1, t3]
                z02 += w01 * F[2, t3]
                z10 += w00 * F[3, t3]
                z11 += w00 * F[4, t3]
                z12 += w01 * F[5, t3]
                z20 += w10 * F[6, t3]
                z21 += w10 * F[7, t3]
                z22 += u1 * v1 * F[8, t3]
            Z[t, 0, q2, i3, d3] += z00
            Z[t, 1, q2, i3, d3] += z01
            Z[t, 2, q2, i3, d3] += z02
            Z[t, 3, q2, i3, d3] += z10
            Z[t, 4, q2, i3, d3] += z11
            Z[t, 5, q2, i3, d3] += z12
            Z[t, 6, q2, i3, d3] += z20
            Z[t, 7, q2, i3, d3] += z21
            Z[t, 8, q2, i3, d3] += z22


_PAIR_R = np.array([0, 1, 2, 0, 0, 1])  # the scalar kernel's pair order (0,0), (1,1), (2,2), (0,1), (0,2), (1,2)
_PAIR_S = np.array([0, 1, 2, 1, 2, 2])


@njit(inline="always")
def _coefficients(G, LM, a, b, pi, q1, q2, q3, F, t3):
    """The parametric coefficients of block (a, b) at one Gauss point into column t3 of F: on a diagonal block
    the six symmetric ones C_rs = (lf + mf) c_r[a] c_s[a] + mf c_r . c_s in the scalar kernel's pair order,
    off it the nine F_rs = lf c_r[a] c_s[b] + mf c_r[b] c_s[a] (slot 3 r + s)."""
    lf, mf = LM[0, pi, q1, q2, q3], LM[1, pi, q1, q2, q3]
    if a == b:
        for j in range(6):
            r, s = _PAIR_R[j], _PAIR_S[j]
            dot = (G[3 * r, pi, q1, q2, q3] * G[3 * s, pi, q1, q2, q3]
                   + G[3 * r + 1, pi, q1, q2, q3] * G[3 * s + 1, pi, q1, q2, q3]
                   + G[3 * r + 2, pi, q1, q2, q3] * G[3 * s + 2, pi, q1, q2, q3])
            F[j, t3] = (lf + mf) * G[3 * r + a, pi, q1, q2, q3] * G[3 * s + a, pi, q1, q2, q3] + mf * dot
    else:
        for r in range(3):
            ra, rb = G[3 * r + a, pi, q1, q2, q3], G[3 * r + b, pi, q1, q2, q3]
            for s in range(3):
                F[3 * r + s, t3] = lf * ra * G[3 * s + b, pi, q1, q2, q3] + mf * rb * G[3 * s + a, pi, q1, q2, q3]


@memo(16)  # one kernel per (p3, g3), as stiffness3_for
def elastic3_for(p3: int, g3: int):
    """The block kernel ``elastic3`` for degree p3 and g3 Gauss points per element in direction 3."""
    P3, G3 = int(p3), int(g3)

    @njit(cache=True, parallel=True, fastmath=True)
    def elastic3(G, LM, a, b, e0, b1, first1, W2, r2, s2, b3, first3, indptr, lo1, c1, lo2, c2, lo3, c3,
                 ring, Z7, Z9, Y, out, cols, dest):
        """Write block (a, b) of the elastic stiffness over a slab of direction-1 elements into ``out``.

        G (9, P, m g1, nq2, nq3): the metric rows, ``G[3 r + k] = c_r[k]``;
        LM (2, P, m g1, nq2, nq3): lf and mf (module notes); the other
        arguments as :func:`iga.assembly._assembly_kernels.stiffness3`, with two stage-3
        scratches: Z7 (g1, 7, nq2, n3, D3) for a diagonal block, whose symmetric
        coefficients take the scalar kernel's stages 3 and 2 (half of the
        direction-2 band mirrored), and Z9 (g1, 9, nq2, n3, D3) for the nine
        terms of an off-diagonal one.  Row i is the test function (component a),
        column j the trial (b); ``dest`` places the rows in ``out`` and their
        columns in ``cols`` (for a component-major operator: base a 3 nnz +
        3 nnz_before, scale 3, shift b, column shift b n + offset).
        """
        P, nq2, g1, E3 = G.shape[1], G.shape[3], b1.shape[3], b3.shape[1]
        n_el = G.shape[2] // g1
        K3 = Z9.shape[3] * Z9.shape[4]
        Z7f, Z9f = Z7.reshape(g1, 7, nq2, K3), Z9.reshape(g1, 9, nq2, K3)
        for pi in range(P):
            for e1 in range(e0, e0 + n_el):
                for item in prange(g1 * nq2):
                    t = item // nq2
                    q2 = item - t * nq2
                    q1 = (e1 - e0) * g1 + t
                    F = np.empty((9, G3))
                    if a == b:
                        Z7f[t, :, q2] = 0.0
                    else:
                        Z9f[t, :, q2] = 0.0
                    for e3 in range(E3):
                        f = first3[e3]
                        for t3 in range(G3):
                            _coefficients(G, LM, a, b, pi, q1, q2, e3 * G3 + t3, F, t3)
                        if a == b:
                            symmetric_stage3(F, b3, e3, f, Z7, t, q2, P3, G3)
                        else:
                            _general_stage3(F, b3, e3, f, Z9, t, q2, P3, G3)
                if a == b:
                    heat_stage2(Z7, Y, W2, r2, s2)
                else:
                    elastic_stage2(Z9, Y, W2, r2, s2)
                stage1_flush(ring, Y, b1, first1, pi, e1, out, cols, dest, indptr, lo1, c1, lo2, c2, lo3, c3)

    return elastic3


@njit(cache=True, parallel=True)
def mirror_lower(indptr, indices, transpose, before, nnz_total, data, cols):
    """Blocks (1, 0), (2, 0), (2, 1) of component-major operators as the transposes of (0, 1), (0, 2), (1, 2),
    in place, for the patches whose scalar non-zeros start at ``before[m]`` (layout of
    :class:`iga.assembly.vector_csr.VectorCSR`); ``transpose[k]`` the position of entry (j, i) for entry k = (i, j) of
    the scalar pattern (indptr, indices).  Row by row of the upper blocks, scattering into the lower ones
    (gathering row by row of the lower blocks measured 2x slower).  The columns of the rows of components 1 and
    2, lower blocks included, are those of component 0's row (block b of every row reads columns j + b n +
    offset): copied a row at a time, in order, from the columns the kernel wrote for component 0."""
    n = indptr.shape[0] - 1
    for m in range(before.shape[0]):
        nb = before[m]
        for i in prange(n):
            s, li = indptr[i], indptr[i + 1] - indptr[i]
            for k in range(s, s + li):
                j = indices[k]
                sj = indptr[j]
                lj = indptr[j + 1] - sj
                t = transpose[k] - sj
                for a in range(2):
                    for b in range(a + 1, 3):
                        data[b * 3 * nnz_total + 3 * (nb + sj) + a * lj + t] = \
                            data[a * 3 * nnz_total + 3 * (nb + s) + b * li + k - s]
            row = 3 * (nb + s)
            for a in range(1, 3):
                shift = a * 3 * nnz_total
                for k in range(row, row + 3 * li):
                    cols[shift + k] = cols[k]


@njit(cache=True, parallel=True)
def transpose_positions(indptr, lo1, c1, lo2, c2, lo3, c3, p1, p2, p3, out):
    """``out[e]``: the CSR position of entry (j, i) for entry e = (i, j) of the banded tensor pattern (rows C
    order, offsets d1, d2, d3 nested): its band offsets are the mirrored ones, d_k -> 2 p_k - d_k, so the
    transpose of data on this symmetric pattern is ``data[out]``."""
    n1, n2, n3 = lo1.shape[0], lo2.shape[0], lo3.shape[0]
    for i1 in prange(n1):
        for i2 in range(n2):
            for i3 in range(n3):
                pos = indptr[(i1 * n2 + i2) * n3 + i3]
                for d1 in range(lo1[i1], lo1[i1] + c1[i1]):
                    j1 = i1 + d1 - p1
                    for d2 in range(lo2[i2], lo2[i2] + c2[i2]):
                        j2 = i2 + d2 - p2
                        head = (2 * p1 - d1 - lo1[j1]) * c2[j2] + 2 * p2 - d2 - lo2[j2]
                        for d3 in range(lo3[i3], lo3[i3] + c3[i3]):
                            j3 = i3 + d3 - p3
                            out[pos] = indptr[(j1 * n2 + j2) * n3 + j3] + head * c3[j3] + 2 * p3 - d3 - lo3[j3]
                            pos += 1
