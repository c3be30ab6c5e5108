"""Compiled kernels of :mod:`iga.assembly.compiled` (imported only when numba is installed and first needed).

Notation (3-D, one patch): ``C[c, q1, q2, q3]`` are the coefficient fields of a
form (weights, |J| and the material included), contracted term by term as
:class:`iga.assembly.terms.FormTerms` says (for diffusion the six symmetric
fields in the pair order (0,0), (1,1), (2,2), (0,1), (0,2), (1,2)).  Direction k has ``n_k`` basis
functions of degree ``p_k``, band width ``D_k = 2 p_k + 1`` and the window
tables of :class:`iga.discretisation.space.Space1D`: ``W[v, i, d, l]`` for the derivative
variants v = (0,0), (0,1), (1,0), (1,1) (v = 2 a + b), the window start
``s[i]`` (first quadrature index of i's window) and the non-zero range
``r[i, d] = [lo, hi)`` of the window points.
"""

from __future__ import annotations


import numpy as np

from geometry.cache import memo
from numba import njit, prange


@njit(cache=True, parallel=True)
def csr_structure3(lo1, c1, lo2, c2, lo3, c3, p1, p2, p3, indptr, indices):
    """Row pointers and column indices of the banded 3-D pattern (rows C order; columns sorted).

    Row (i1, i2, i3) holds the valid offsets d_k in [lo_k[i_k], lo_k[i_k] + c_k[i_k]),
    in the order d1, then d2, then d3; column j_k = i_k + d_k - p_k.
    """
    n1, n2, n3 = lo1.shape[0], lo2.shape[0], lo3.shape[0]
    indptr[0] = 0
    for i1 in range(n1):  # row counts, then a running sum (cheap next to the fill)
        for i2 in range(n2):
            for i3 in range(n3):
                row = (i1 * n2 + i2) * n3 + i3
                indptr[row + 1] = c1[i1] * c2[i2] * c3[i3]
    for row in range(n1 * n2 * n3):
        indptr[row + 1] += indptr[row]
    for i1 in prange(n1):
        for i2 in range(n2):
            for i3 in range(n3):
                pos = indptr[(i1 * n2 + i2) * n3 + i3]
                for d1 in range(lo1[i1], lo1[i1] + c1[i1]):
                    j1 = i1 + d1 - p1
                    for d2 in range(lo2[i2], lo2[i2] + c2[i2]):
                        j12 = (j1 * n2 + i2 + d2 - p2) * n3
                        for d3 in range(lo3[i3], lo3[i3] + c3[i3]):
                            indices[pos] = j12 + i3 + d3 - p3
                            pos += 1


@njit(inline="always")
def _weights1(b1, e1, l1, m1, t):
    """Direction-1 weights of the variants (1,1), (1,0), (0,1), (0,0) of the pair (l1, m1) at Gauss point t."""
    u0, u1 = b1[0, e1, l1, t], b1[1, e1, l1, t]
    return u1 * b1[1, e1, m1, t], u1 * b1[0, e1, m1, t], u0 * b1[1, e1, m1, t], u0 * b1[0, e1, m1, t]


@njit(inline="always")
def band_weights(W2, i2, d2, l):
    """Direction-2 weights of the variants (0,0), (0,1), (1,0), (1,1) at window point l of band entry (i2, d2)."""
    return W2[0, i2, d2, l], W2[1, i2, d2, l], W2[2, i2, d2, l], W2[3, i2, d2, l]


@njit(inline="always")
def _rows_of_element(ring, Yr, b1, pi, e1, f0, i2, p1, g1, K2):
    """Stage 1 of a kernel for direction-2 row i2: add the four direction-1 variant groups Yr (g1, 4, n2, K2)
    of element e1 into the ring rows of its p1 + 1 basis functions (first f0), slot i1 % (p1 + 1)."""
    R1 = p1 + 1
    for l1 in range(R1):
        slot = (f0 + l1) % R1
        m1 = 0
        while m1 < R1:
            nb = min(4, R1 - m1)
            da = ring[pi, slot, m1 - l1 + p1, i2]
            db = ring[pi, slot, min(m1 + 1, p1) - l1 + p1, i2]  # unused (nb < 2) rows are valid views
            dc = ring[pi, slot, min(m1 + 2, p1) - l1 + p1, i2]
            dd = ring[pi, slot, min(m1 + 3, p1) - l1 + p1, i2]
            for t in range(g1):
                Y0, Y1, Y2, Y3 = Yr[t, 0, i2], Yr[t, 1, i2], Yr[t, 2, i2], Yr[t, 3, i2]
                a0, a1, a2, a3 = _weights1(b1, e1, l1, m1, t)
                # weights of the other destinations (zero past nb: those rows are never written)
                x0, x1, x2, x3 = _weights1(b1, e1, l1, min(m1 + 1, p1), t)
                y0, y1, y2, y3 = _weights1(b1, e1, l1, min(m1 + 2, p1), t)
                z0, z1, z2, z3 = _weights1(b1, e1, l1, min(m1 + 3, p1), t)
                # nb is fixed for the sweep: LLVM unswitches the branches out of the k loop
                for k in range(K2):
                    v0, v1, v2, v3 = Y0[k], Y1[k], Y2[k], Y3[k]
                    da[k] += a0 * v0 + a1 * v1 + a2 * v2 + a3 * v3
                    if nb > 1:
                        db[k] += x0 * v0 + x1 * v1 + x2 * v2 + x3 * v3
                    if nb > 2:
                        dc[k] += y0 * v0 + y1 * v1 + y2 * v2 + y3 * v3
                    if nb > 3:
                        dd[k] += z0 * v0 + z1 * v1 + z2 * v2 + z3 * v3
            m1 += nb


@njit(inline="always")
def _flush_row(ring, out, cols, dest, indptr, pi, i1, i2, n2, n3, D3, lo1, c1, lo2, c2, lo3, c3):
    """Copy the complete ring rows (i1, i2, :) into CSR order (one sequential write per entry), clear the slot.

    ``dest[pi] = (base, scale, shift, column shift)``: entry k of row i goes to ``out[base + scale indptr[i] +
    shift (indptr[i + 1] - indptr[i]) + k]``; (pi nnz, 1, 0, -1) for data (P, nnz) flattened, (base, 3, b,
    b n + offset) for block b in the rows of a component-major vector operator (:mod:`iga.assembly._elastic_kernels`).
    A column shift s >= 0 also writes the entry's column j + s to ``cols`` at the same position."""
    slot = i1 % ring.shape[1]
    base, scale, shift, col_shift = dest[pi, 0], dest[pi, 1], dest[pi, 2], dest[pi, 3]
    p1, p3 = (ring.shape[2] - 1) // 2, (D3 - 1) // 2
    p2 = (ring.shape[4] // (n3 * D3) - 1) // 2
    for i3 in range(n3):
        row = (i1 * n2 + i2) * n3 + i3
        pos = base + scale * indptr[row] + shift * (indptr[row + 1] - indptr[row])
        for d1 in range(lo1[i1], lo1[i1] + c1[i1]):
            for d2 in range(lo2[i2], lo2[i2] + c2[i2]):
                k0 = (d2 * n3 + i3) * D3
                if col_shift >= 0:
                    j0 = ((i1 + d1 - p1) * n2 + i2 + d2 - p2) * n3 + i3 - p3 + col_shift
                    for d3 in range(lo3[i3], lo3[i3] + c3[i3]):
                        cols[pos] = j0 + d3
                        out[pos] = ring[pi, slot, d1, i2, k0 + d3]
                        pos += 1
                else:
                    for d3 in range(lo3[i3], lo3[i3] + c3[i3]):
                        out[pos] = ring[pi, slot, d1, i2, k0 + d3]
                        pos += 1
    for d1 in range(ring.shape[2]):
        for k in range(ring.shape[4]):
            ring[pi, slot, d1, i2, k] = 0.0


@njit(inline="always")
def _stage3(cl, wv, field, v3, b3, e3, f, Zf, t, q2, P3, G3, D3):
    """Stage 3 of :func:`form3_for`'s kernel on direction-3 element e3 (first function f) of Gauss row (t, q2):
    for each term j, sum_t3 d^a N_{f+l3} d^b N_{f+m3} F_c over the element's G3 points added to
    Zf[t, j, q2, i3 D3 + d3] for every local pair (l3, m3) (``cl`` (fields, G3): this row's coefficients on
    the element; ``wv`` (2, G3) scratch).  Term outermost: its field and orders are fixed while the pair and
    Gauss loops run with the caller's constant trip counts P3 and G3, which LLVM unrolls (inlined); the
    test side's product with the field is formed once per l3 (measured: as fast as the seven register
    accumulators of a kernel written for diffusion alone at p = 2, 5-10% slower at p = 3, and 30% faster
    than a run-time loop over the terms inside the pair loops)."""
    for j in range(field.shape[0]):
        c, v = field[j], v3[j]
        a, b = v >> 1, v & 1
        for t3 in range(G3):
            wv[0, t3] = cl[c, t3]
        for l3 in range(P3 + 1):
            k0 = (f + l3) * D3 - l3 + P3
            for t3 in range(G3):
                wv[1, t3] = b3[a, e3, l3, t3] * wv[0, t3]
            for m3 in range(P3 + 1):
                z = 0.0
                for t3 in range(G3):
                    z += wv[1, t3] * b3[b, e3, m3, t3]
                Zf[t, j, q2, k0 + m3] += z


@njit(inline="always")
def _sweep(y, Zf, t, q2, w, j, nb, K3):
    """y += sum of the nb (1 to 4) consecutive term rows Zf[t, j .. j + nb - 1, q2], row i weighted by w[i]:
    one pass over y (rows past nb are valid views, never read: nb is fixed for the sweep, so LLVM unswitches
    the branches out of the k loop)."""
    za, zb = Zf[t, j, q2], Zf[t, j + min(1, nb - 1), q2]
    zc, zd = Zf[t, j + min(2, nb - 1), q2], Zf[t, j + min(3, nb - 1), q2]
    wa, wb, wc, wd = w[0], w[1], w[2], w[3]
    for k in range(K3):
        acc = wa * za[k]
        if nb > 1:
            acc += wb * zb[k]
        if nb > 2:
            acc += wc * zc[k]
        if nb > 3:
            acc += wd * zd[k]
        y[k] += acc


@njit(cache=True, parallel=True, fastmath=True)
def form_stage2(Z, Y, W2, r2, s2, v2, groups, symmetric):
    """Stage 2 of :func:`form3_for`'s kernel for the g1 Gauss planes of one direction-1 element: the terms Z
    (g1, T, nq2, n3, D3) contracted along direction 2 (variant ``v2[j]`` of term j) into the four
    direction-1 variant groups Y (g1, 4, n2, D2, n3, D3) (group 0: (1,1), 1: (1,0), 2: (0,1), 3: (0,0), as
    :func:`stage1_flush` reads them); group g's terms are ``groups[g]:groups[g + 1]``, summed four at a time
    in one sweep (:func:`_sweep`).

    ``symmetric`` (:mod:`iga.assembly.terms`): group 1 is computed whole, groups 0 and 3 for d2 >= p2 only
    and mirrored under (i2, d2, i3, d3) -> (j2, 2 p2 - d2, j3, 2 p3 - d3), group 2 is group 1 transposed.
    Compiled once for every degree and term count.
    """
    g1, T, nq2, n3, D3 = Z.shape[0], Z.shape[1], Z.shape[2], Z.shape[3], Z.shape[4]
    n2, D2 = Y.shape[2], Y.shape[3]
    K3 = n3 * D3
    p2, P3 = (D2 - 1) // 2, (D3 - 1) // 2
    Zf = Z.reshape(g1, T, nq2, K3)
    Yf = Y.reshape(g1, Y.shape[1], n2, D2, K3)
    for item in prange(g1 * n2):  # sweeps run over the flattened (i3, d3) index: contiguous, they vectorise
        t = item // n2
        i2 = item - t * n2
        w = np.empty(4)
        for d2 in range(D2):
            whole = not symmetric or d2 >= p2
            for g in range(4):
                if not (whole or g == 1) or (symmetric and g == 2):  # symmetric: group 2 is mirrored below
                    continue
                y = Yf[t, g, i2, d2]
                for k in range(K3):
                    y[k] = 0.0
                for l in range(r2[i2, d2, 0], r2[i2, d2, 1]):
                    q2 = s2[i2] + l
                    for j in range(groups[g], groups[g + 1], 4):
                        nb = min(4, groups[g + 1] - j)
                        for i in range(nb):
                            w[i] = W2[v2[j + i], i2, d2, l]
                        _sweep(y, Zf, t, q2, w, j, nb, K3)
    if not symmetric:
        return
    for item in prange(g1 * n2):  # the mirrors: group 2 from group 1, groups 0 and 3 below the band's middle
        t = item // n2
        i2 = item - t * n2
        for d2 in range(D2):
            j2 = i2 + d2 - p2
            for i3 in range(n3):
                for d3 in range(D3):
                    j3 = i3 + d3 - P3
                    if 0 <= j2 < n2 and 0 <= j3 < n3:
                        Y[t, 2, i2, d2, i3, d3] = Y[t, 1, j2, 2 * p2 - d2, j3, 2 * P3 - d3]
                        if d2 < p2:
                            Y[t, 0, i2, d2, i3, d3] = Y[t, 0, j2, 2 * p2 - d2, j3, 2 * P3 - d3]
                            Y[t, 3, i2, d2, i3, d3] = Y[t, 3, j2, 2 * p2 - d2, j3, 2 * P3 - d3]
                    else:
                        Y[t, 2, i2, d2, i3, d3] = 0.0
                        if d2 < p2:
                            Y[t, 0, i2, d2, i3, d3] = 0.0
                            Y[t, 3, i2, d2, i3, d3] = 0.0


@njit(cache=True, parallel=True, fastmath=True)
def stage1_flush(ring, Y, b1, first1, pi, e1, out, cols, dest, indptr, lo1, c1, lo2, c2, lo3, c3):
    """Stage 1 of the slab kernels for direction-1 element e1 of patch pi: the four direction-1 variant groups
    Y (g1, 4, n2, D2, n3, D3) into the ring rows of its basis functions, then the rows no later element
    touches copied into ``out`` (and their columns into ``cols``) at the positions ``dest`` gives
    (:func:`_flush_row`).  Compiled once, shared by the
    scalar and the elastic kernels."""
    g1, n2, D2, n3, D3 = Y.shape[0], Y.shape[2], Y.shape[3], Y.shape[4], Y.shape[5]
    p1, E1, n1 = b1.shape[2] - 1, b1.shape[1], lo1.shape[0]
    K2 = D2 * n3 * D3
    Yr = Y.reshape(g1, 4, n2, K2)
    # stage 1: rows i1 = first1[e1] + l1, columns j1 = first1[e1] + m1, accumulated in the
    # banded ring buffer (row i1 in slot i1 % (p1 + 1)): contiguous, vectorisable sweeps.  Each
    # sweep reads the four Y rows of one Gauss plane once and adds them to up to four
    # destinations (m1 .. m1 + 3): with one destination per sweep, the re-reads of Y (300 KB
    # per i2 at p = 3) came from L2
    f0 = first1[e1]
    for i2 in prange(n2):
        _rows_of_element(ring, Yr, b1, pi, e1, f0, i2, p1, g1, K2)
    # rows that no later element touches are complete: copy them into CSR order (one
    # sequential write per entry) and clear their slots
    stop = first1[e1 + 1] if e1 + 1 < E1 else n1
    for i1 in range(f0, stop):
        for i2 in prange(n2):
            _flush_row(ring, out, cols, dest, indptr, pi, i1, i2, n2, n3, D3, lo1, c1, lo2, c2, lo3, c3)


@memo(64)  # one kernel per (p3, g3): a handful per process
def form3_for(p3: int, g3: int):
    """The form kernel ``form3`` for degree p3 and g3 Gauss points per element in direction 3.

    Both are compile-time constants of stage 3, so that LLVM unrolls its pair and Gauss loops
    (docs/performance.md); the terms are data (:class:`iga.assembly.terms.FormTerms`), so one kernel serves
    every form of every term count.  Stages 2 and 1 (:func:`form_stage2`, :func:`stage1_flush`) are compiled
    once for all degrees: a new (p3, g3) compiles stage 3 only, cached on disk like the other kernels (numba
    keys closures by their constants).
    """
    P3, G3 = int(p3), int(g3)

    @njit(cache=True, parallel=True, fastmath=True)
    def form3(C, field, variants, groups, symmetric, e0, b1, first1, W2, r2, s2, b3, first3, indptr, lo1, c1, lo2, c2,
              lo3, c3, ring, Z, Y, out, cols, dest):
        """Write sum_terms int F_c d^a N_i d^b N_j over a slab of direction-1 elements into the CSR data ``out``.

        C (fields, P, m g1, nq2, nq3): the coefficient fields on the Gauss planes of the m elements
        e0 .. e0 + m - 1 of direction 1, for P patches sharing one space; ``field`` (T,), ``variants`` (T, 3),
        ``groups`` (5,), ``symmetric``: the terms (:class:`iga.assembly.terms.FormTerms`); b1 (2, E1, p1 + 1, g1) local values
        and derivatives of direction 1 per element, ``first1[e]`` the index of the first basis function on
        element e (b3, first3 the same for direction 3); W2, r2, s2 the band tables of direction 2 (module
        notes).  Scratch, kept by the caller across slabs: ``ring`` (P, p1 + 1, 2 p1 + 1, n2, D2 n3 D3), zero
        on the first call and left zero after the last element; Z (g1, T, nq2, n3, D3) and
        Y (g1, 4, n2, D2, n3, D3).  ``out``, ``cols`` and ``dest``: the flat CSR data, its columns (written
        where asked) and where each patch's rows go in them (:func:`_flush_row`).

        Sum factorisation by slabs of direction-1 elements: for the g1 Gauss planes of element e1, contract
        direction 3 (Z, one row per term), then direction 2 (Y, four groups by the direction-1 variant), then
        direction 1 into the CSR rows of the p1 + 1 basis functions of e1.  Slabs run in order (rows of
        neighbouring slabs overlap); inside a slab the work is split over planes and rows.
        """
        nc, P, nq2, g1, E3 = C.shape[0], C.shape[1], C.shape[3], b1.shape[3], b3.shape[1]
        T, D3 = field.shape[0], Z.shape[4]
        n_el = C.shape[2] // g1
        Zf = Z.reshape(g1, T, nq2, Z.shape[3] * D3)
        v2, v3 = variants[:, 1].copy(), variants[:, 2].copy()
        for pi in range(P):
            for e1 in range(e0, e0 + n_el):
                for item in prange(g1 * nq2):
                    t = item // nq2
                    q2 = item - t * nq2
                    q1 = (e1 - e0) * g1 + t
                    cl = np.empty((nc, G3))
                    wv = np.empty((2, G3))
                    Zf[t, :, q2] = 0.0
                    for e3 in range(E3):
                        for t3 in range(G3):
                            for c in range(nc):
                                cl[c, t3] = C[c, pi, q1, q2, e3 * G3 + t3]
                        _stage3(cl, wv, field, v3, b3, e3, first3[e3], Zf, t, q2, P3, G3, D3)
                form_stage2(Z, Y, W2, r2, s2, v2, groups, symmetric)
                stage1_flush(ring, Y, b1, first1, pi, e1, out, cols, dest, indptr, lo1, c1, lo2, c2, lo3, c3)

    return form3


@njit(cache=True)
def compact_rows_cols(indptr, indices, data, new_index):
    """Keep the rows and columns i with ``new_index[i] >= 0`` of a CSR matrix, in place.

    Columns are renumbered to ``new_index`` (increasing on the kept ones, so
    sorted rows stay sorted).  Kept entries only move towards the front, so
    one forward pass overwrites ``indptr``, ``indices`` and ``data``; returns
    (rows, nnz) of the result, which occupies their leading parts.
    """
    n = indptr.shape[0] - 1
    pos = 0
    r = 0
    start = indptr[0]
    for row in range(n):
        end = indptr[row + 1]  # read before row r <= row is written
        if new_index[row] >= 0:
            indptr[r] = pos
            for k in range(start, end):
                c = new_index[indices[k]]
                if c >= 0:
                    indices[pos] = c
                    data[pos] = data[k]
                    pos += 1
            r += 1
        start = end
    indptr[r] = pos
    return r, pos


@njit(cache=True, parallel=True, fastmath=True)
def load3(L, e0, b1, first1, b2, e2lo, e2hi, first2, b3, first3, out):
    """Add sum_q N_i(q) L(q) over a slab of direction-1 elements to the load vectors ``out`` (P, n1, n2, n3).

    L (P, m g1, nq2, nq3): the source field (weights and |J| included) on the
    Gauss planes of elements e0 .. e0 + m - 1; b_k, first_k as in
    :func:`form3_for` (direction 2 too); ``e2lo[i2] .. e2hi[i2] - 1`` the
    direction-2 elements in the support of function i2.  Sum factorisation:
    direction 3 row by row, then direction 2 and 1 by rows i2 (one thread
    per row, so the accumulation into ``out`` needs no lock).
    """
    P, Q1, nq2 = L.shape[0], L.shape[1], L.shape[2]
    g1, p1 = b1.shape[3], b1.shape[2] - 1
    g2 = b2.shape[3]
    E3, g3, p3 = b3.shape[1], b3.shape[3], b3.shape[2] - 1
    n2, n3 = out.shape[2], out.shape[3]
    A = np.empty((Q1, nq2, n3))
    for pi in range(P):
        for row in prange(Q1 * nq2):
            q1 = row // nq2
            q2 = row - q1 * nq2
            a = A[q1, q2]
            for i3 in range(n3):
                a[i3] = 0.0
            for e3 in range(E3):
                f = first3[e3]
                for l3 in range(p3 + 1):
                    s = 0.0
                    for t3 in range(g3):
                        s += b3[0, e3, l3, t3] * L[pi, q1, q2, e3 * g3 + t3]
                    a[f + l3] += s
        for i2 in prange(n2):
            r = np.empty(n3)
            for q1 in range(Q1):
                e1 = e0 + q1 // g1
                t = q1 - (q1 // g1) * g1
                for i3 in range(n3):
                    r[i3] = 0.0
                for e2 in range(e2lo[i2], e2hi[i2]):
                    l2 = i2 - first2[e2]
                    for t2 in range(g2):
                        w = b2[0, e2, l2, t2]
                        a = A[q1, e2 * g2 + t2]
                        for i3 in range(n3):
                            r[i3] += w * a[i3]
                for l1 in range(p1 + 1):
                    w = b1[0, e1, l1, t]
                    o = out[pi, first1[e1] + l1, i2]
                    for i3 in range(n3):
                        o[i3] += w * r[i3]
