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

from functools import lru_cache
from itertools import product as iproduct
from math import comb

import numpy as np

from .knots import bernstein_elevation

__all__ = ["binomials", "multiply", "power", "elevate", "derivative", "split_matrices", "evaluate"]


@lru_cache(maxsize=512)
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


def multiply(a: np.ndarray, b: np.ndarray, ndim: int) -> np.ndarray:
    """Exact product of Bernstein polynomials (batched, broadcasting batch axes).

    ``a``: (..., p_1+1, ..., p_d+1), ``b``: (..., q_1+1, ..., q_d+1) ->
    (..., p_1+q_1+1, ..., p_d+q_d+1).
    """
    pa = a.shape[a.ndim - ndim :]
    pb = b.shape[b.ndim - ndim :]
    if int(np.prod(pa)) > int(np.prod(pb)):  # loop over the smaller factor
        a, b, pa, pb = b, a, pb, pa
    batch = np.broadcast_shapes(a.shape[: a.ndim - ndim], b.shape[: b.ndim - ndim])
    sa = _scale(a, ndim)
    sb = np.broadcast_to(_scale(b, ndim), batch + tuple(pb))
    out = np.zeros(batch + tuple(x + y - 1 for x, y in zip(pa, pb)))
    lead = (slice(None),) * len(batch)
    for idx in iproduct(*(range(n) for n in pa)):
        coef = sa[(Ellipsis,) + idx]
        if np.ndim(coef):
            coef = coef.reshape(coef.shape + (1,) * ndim)
        sl = lead + tuple(slice(i, i + n) for i, n in zip(idx, pb))
        out[sl] += coef * sb
    return _scale(out, ndim, inverse=True)


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


@lru_cache(maxsize=256)
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


def combos(shape) -> list[tuple[int, ...]]:
    """All multi-indices of an array shape (small helper for the compose loops)."""
    return list(iproduct(*(range(n) for n in shape)))
