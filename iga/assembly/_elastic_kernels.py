"""Compiled kernels of the elastic stiffness's lower blocks (imported only when numba is installed and first needed).

The six upper blocks (a <= b) of linear elasticity are forms of the one form kernel
(:func:`iga.assembly._assembly_kernels.form3_for`, :func:`iga.assembly.compiled.elastic_into`); their rows are
written, with their columns for component 0, straight into the component-major operator
(:class:`iga.assembly.vector_csr.VectorCSR`).  Here :func:`mirror_lower` copies the lower blocks from the upper
ones' transposes and the columns of components 1 and 2 from component 0's, at the positions
:func:`transpose_positions` finds on the banded tensor pattern.
"""

from __future__ import annotations



from numba import njit, prange



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
