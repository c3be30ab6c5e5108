"""Batched tensor-product Bernstein (Bezier) polynomial algebra.

A Bernstein array holds the coefficients of one or many tensor-product
polynomials on the unit box: its *last* ``ndim`` axes are the Bernstein
indices (sizes ``p_k + 1``), every leading axis is a batch axis (placements,
elements, components...).  All functions here are exact linear/bilinear maps on
those coefficients, vectorised over the batch axes.

The product uses the classical identity

    B_i^p(t) B_j^q(t) = C(p,i) C(q,j) / C(p+q,i+j) * B_{i+j}^{p+q}(t),

i.e. a convolution of binomially scaled coefficients, computed with one
slice-add per coefficient of the smaller factor (no dense Kronecker matrices).
"""

from __future__ import annotations

from itertools import product as iproduct
from math import comb

import numpy as np

from .cache import memo

from geometry.compiled import _fast
from geometry.compiled.lock import locked
from .knots import bernstein_elevation

#: multiplications from which a product runs in the compiled kernel (where numba is installed): below, the
#: NumPy path costs less than the kernel's call and the numba import
COMPILED_MACS = 1 << 16

__all__ = ["binomials", "multiply", "power", "elevate", "derivative", "split_matrices", "evaluate"]


@memo(512)
def binomials(p: int) -> np.ndarray:
    """``[C(p, 0), ..., C(p, p)]`` as floats (read-only)."""
    b = np.array([comb(p, i) for i in range(p + 1)], dtype=float)
    b.setflags(write=False)
    return b


def _scale(a: np.ndarray, ndim: int, inverse: bool = False) -> np.ndarray:
    """Multiply (or divide) each Bernstein axis by its binomial coefficients."""
    out = a
    for k in range(ndim):
        axis = a.ndim - ndim + k
        b = binomials(a.shape[axis] - 1)
        shape = [1] * a.ndim
        shape[axis] = -1
        out = out / b.reshape(shape) if inverse else out * b.reshape(shape)
    return out


def multiply(a: np.ndarray, b: np.ndarray, ndim: int, compiled: bool | None = None) -> np.ndarray:
    """Exact product of Bernstein polynomials (batched, broadcasting batch axes).

    ``a``: (..., p_1+1, ..., p_d+1), ``b``: (..., q_1+1, ..., q_d+1) ->
    (..., p_1+q_1+1, ..., p_d+q_d+1).

    ``compiled``: in the direct loops of :func:`geometry.compiled._bernstein_kernels.product3`
    (numba, d <= 3); by default when numba is installed and the product takes
    at least :data:`COMPILED_MACS` multiplications (so that small analyses
    never import numba).  Otherwise in NumPy: the convolution of binomially
    scaled coefficients is computed as one batched matrix product with a
    banded Toeplitz matrix of the smaller factor along the last axis (BLAS),
    then block shift-adds over the other axes.
    Batch axes along which only the larger factor varies (e.g. coordinate
    components multiplied by one scalar factor) become matrix rows, so the
    scalar factor is never copied per component.
    """
    pa = tuple(a.shape[a.ndim - ndim :])
    pb = tuple(b.shape[b.ndim - ndim :])
    if int(np.prod(pa)) > int(np.prod(pb)):  # the smaller factor becomes the Toeplitz kernel
        a, b, pa, pb = b, a, pb, pa
    ba, bb = a.shape[: a.ndim - ndim], b.shape[: b.ndim - ndim]
    batch = np.broadcast_shapes(ba, bb)
    ba = (1,) * (len(batch) - len(ba)) + tuple(ba)
    # split batch axes into a "shared" prefix and a suffix where the kernel is constant
    n_shared = len(batch)
    while n_shared > 0 and ba[n_shared - 1] == 1:
        n_shared -= 1
    shared, rows = batch[:n_shared], batch[n_shared:]
    B = int(np.prod(shared, dtype=int))
    C = int(np.prod(rows, dtype=int))
    r = tuple(x + y - 1 for x, y in zip(pa, pb))
    if compiled is None:
        compiled = ndim <= 3 and B * C * int(np.prod(pa)) * int(np.prod(pb)) >= COMPILED_MACS and _fast.AVAILABLE
    if compiled:
        sa = np.broadcast_to(a.reshape(ba + pa), shared + (1,) * len(rows) + pa).reshape((B, 1) + pa)
        sb = np.broadcast_to(b, batch + pb).reshape((B, C) + pb)
        return _product_compiled(sa, sb).reshape(batch + r)
    sa = np.broadcast_to(_scale(a, ndim).reshape(ba + pa), shared + (1,) * len(rows) + pa).reshape((B, 1) + pa)
    sb = np.broadcast_to(_scale(b, ndim), batch + pb).reshape((B, C) + pb)
    out = _convolve(sa, sb).reshape(batch + r)
    return _scale(out, ndim, inverse=True)


def _convolve(a: np.ndarray, b: np.ndarray, max_bytes: int = 64 << 20) -> np.ndarray:
    """Batched full convolution: a (B, Ca, pa...), b (B, Cb, pb...) -> (B, Ca * Cb, pa+pb-1...).

    The factor with the longer last axis is written as a banded Toeplitz matrix
    along that axis (it costs ``r_L / p_L`` times the direct flop count, so the
    longer factor is the cheaper choice); the other factor multiplies it in one
    batched ``matmul``; the remaining axes are handled by block shift-adds over
    the smaller set of leading indices.
    """
    swap = a.shape[-1] < b.shape[-1]
    t, o = (b, a) if swap else (a, b)  # t: Toeplitz factor, o: row factor
    B = a.shape[0]
    Ct, pt = t.shape[1], t.shape[2:]
    Co, po = o.shape[1], o.shape[2:]
    r = tuple(x + y - 1 for x, y in zip(pt, po))
    pL, qL, rL = pt[-1], po[-1], r[-1]
    It = Ct * int(np.prod(pt[:-1], dtype=int))
    Jo = Co * int(np.prod(po[:-1], dtype=int))
    nd = len(r) - 1
    out = np.zeros((B, Ct, Co) + r)
    step = max(1, int(max_bytes // max(1, 8 * It * Jo * rL)))
    jj = np.arange(qL)
    loop_t = int(np.prod(pt[:-1], dtype=int)) <= int(np.prod(po[:-1], dtype=int))
    for s0 in range(0, B, step):
        s1 = min(B, s0 + step)
        n = s1 - s0
        tI = t[s0:s1].reshape(n, It, pL)
        # banded Toeplitz laid out (n, qL, It, rL): T[:, j, :, j + i] = t[..., i]
        T = np.zeros((n, qL, It, rL))
        for i in range(pL):
            T[:, jj, :, jj + i] = tI[:, :, i]
        # one wide GEMM per batch entry: (Jo, qL) @ (qL, It * rL)
        Y = np.matmul(o[s0:s1].reshape(n, Jo, qL), T.reshape(n, qL, It * rL))
        Y = Y.reshape((n, Co) + tuple(po[:-1]) + (Ct,) + tuple(pt[:-1]) + (rL,))
        blk = out[s0:s1]
        if loop_t:  # shift-add over the Toeplitz factor's leading indices
            for idx in iproduct(*(range(m) for m in pt[:-1])):
                src = Y[(slice(None),) * (2 + nd + 1) + idx]  # (n, Co, po_head..., Ct, rL)
                src = np.moveaxis(src, 2 + nd, 1)  # (n, Ct, Co, po_head..., rL)
                sl = (slice(None),) * 3 + tuple(slice(i, i + m) for i, m in zip(idx, po[:-1])) + (slice(None),)
                blk[sl] += src
        else:  # ... or over the row factor's leading indices
            for idx in iproduct(*(range(m) for m in po[:-1])):
                src = Y[(slice(None), slice(None)) + idx]  # (n, Co, Ct, pt_head..., rL)
                src = np.swapaxes(src, 1, 2)
                sl = (slice(None),) * 3 + tuple(slice(i, i + m) for i, m in zip(idx, pt[:-1])) + (slice(None),)
                blk[sl] += src
    out = out.reshape((B, Ct * Co) + r) if not swap else np.swapaxes(out, 1, 2).reshape((B, Ct * Co) + r)
    return out


@memo(256)
def _weights(shape: tuple, inverse: bool) -> np.ndarray:
    """The binomial scaling (or its inverse) of a Bernstein array of ``shape`` (read-only, as a tensor)."""
    w = np.ones(shape)
    for k, n in enumerate(shape):
        b = binomials(n - 1)
        w = w * (1.0 / b if inverse else b).reshape((1,) * k + (-1,) + (1,) * (len(shape) - k - 1))
    w.setflags(write=False)
    return w


def _product_compiled(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Bernstein products a (B, Ca, pa...) x b (B, Cb, pb...) -> (B, Ca, Cb, r...) in the compiled kernel."""
    from geometry.compiled._bernstein_kernels import product3

    swap = a.shape[-1] > b.shape[-1]  # the longer last axis innermost: the loop the compiler vectorises
    if swap:
        a, b = b, a
    B, Ca, Cb = a.shape[0], a.shape[1], b.shape[1]
    pad = (1,) * (5 - a.ndim)
    pa, pb = pad + a.shape[2:], pad + b.shape[2:]
    r = tuple(x + y - 1 for x, y in zip(pa, pb))
    out = np.zeros((B, Ca, Cb) + r)
    locked(product3)(_fast.readonly(np.reshape(a, (B, Ca) + pa)), _fast.readonly(np.reshape(b, (B, Cb) + pb)),
                     _weights(pa, False), _weights(pb, False), _weights(r, True), out)
    return np.swapaxes(out, 1, 2) if swap else out


def power(a: np.ndarray, k: int, ndim: int, cache: dict | None = None) -> np.ndarray:
    """``a**k`` in Bernstein form (k >= 0), reusing ``cache[j] = a**j`` when given."""
    if cache is None:
        cache = {}
    if k == 0:
        return np.ones(a.shape[: a.ndim - ndim] + (1,) * ndim)
    if k == 1:
        return a
    if k not in cache:
        h = k // 2
        cache[k] = multiply(power(a, h, ndim, cache), power(a, k - h, ndim, cache), ndim)
    return cache[k]


def elevate(a: np.ndarray, times, ndim: int) -> np.ndarray:
    """Degree elevation of every Bernstein axis by ``times`` (int or per axis)."""
    times = [times] * ndim if np.isscalar(times) else list(times)
    out = a
    for k in range(ndim):
        if times[k]:
            axis = a.ndim - ndim + k
            E = bernstein_elevation(out.shape[axis] - 1, int(times[k]))
            out = np.moveaxis(np.tensordot(E, np.moveaxis(out, axis, 0), axes=(1, 0)), 0, axis)
    return out


def derivative(a: np.ndarray, axis_k: int, ndim: int, length: float = 1.0) -> np.ndarray:
    """Bernstein coefficients of the derivative along Bernstein axis ``axis_k``.

    ``length`` is the parameter length of the interval the unit Bernstein
    variable is mapped onto (derivative w.r.t. the real parameter).
    """
    axis = a.ndim - ndim + axis_k
    p = a.shape[axis] - 1
    if p == 0:
        shape = list(a.shape)
        return np.zeros(shape)
    return (p / length) * np.diff(a, axis=axis)


@memo(256)
def split_matrices(p: int, t: float = 0.5) -> tuple[np.ndarray, np.ndarray]:
    """de Casteljau subdivision matrices (left, right) at ``t`` for degree ``p``."""
    I = np.eye(p + 1)
    left = np.zeros((p + 1, p + 1))
    right = np.zeros((p + 1, p + 1))
    cur = I.copy()
    for r in range(p + 1):
        left[r] = cur[0]
        right[p - r] = cur[-1]
        cur = (1 - t) * cur[:-1] + t * cur[1:]
    left.setflags(write=False)
    right.setflags(write=False)
    return left, right


def subinterval_matrices(p: int, t0, t1) -> np.ndarray:
    """Bernstein coefficients of a degree-``p`` polynomial restricted to [t0, t1] (batched).

    Returns M (B, p + 1, p + 1) with ``new = M @ old`` for each pair
    (t0[b], t1[b]); t0 > t1 reverses the direction.  Entry (i, r) is the
    coefficient of the blossom b(t0^(p-i), t1^i) on control point r:
    sum_j B^i_j(t1) B^(p-i)_(r-j)(t0).
    """
    t0 = np.atleast_1d(np.asarray(t0, float))
    t1 = np.atleast_1d(np.asarray(t1, float))

    def bern(m, t):  # (B, m + 1): B^m_j(t)
        j = np.arange(m + 1)
        return binomials(m)[None, :] * t[:, None] ** j * (1 - t[:, None]) ** (m - j)

    M = np.zeros((len(t0), p + 1, p + 1))
    for i in range(p + 1):
        b1, b0 = bern(i, t1), bern(p - i, t0)
        for j in range(i + 1):
            M[:, i, j : j + p - i + 1] += b1[:, j : j + 1] * b0
    return M


def evaluate(a: np.ndarray, x: np.ndarray, ndim: int) -> np.ndarray:
    """Evaluate an un-batched Bernstein array (p_1+1, ..., p_d+1, C) at points ``x`` (N, d) in [0,1]^d."""
    out = a
    for k in range(ndim):
        p = a.shape[k] - 1
        t = x[:, k][:, None]
        B = binomials(p) * t ** np.arange(p + 1) * (1 - t) ** (p - np.arange(p + 1))
        if k == 0:
            out = np.tensordot(B, out, axes=(1, 0))  # (N, ...)
        else:
            out = np.einsum("nj,nj...->n...", B, out)
    return out
