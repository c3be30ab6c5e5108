"""Bounds and monotonicity of a tensor-product spline on sub-boxes of its knot spans, from Bernstein coefficients.

Every knot span of a trivariate scalar spline F is split into ``per_span``
parts per direction; on each sub-box F is one polynomial, whose Bernstein
coefficients are convex combinations of the B-spline coefficients that
support the box.  Their least and greatest bound F on the closed box (the
convex hull property), and the signs of their differences along x_k bound
dF/dx_k: all positive, F rises strictly along +x_k on the box.  A box can be
split further (``split`` children per direction, by the same change of
basis) where the bounds are too loose.  The certificate of random implicit
structures (:mod:`tiling.implicit.certify`) reads these verdicts.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.special import comb

from geometry.compiled import _fast
from geometry import knots as kn

__all__ = ["BoxGrid", "box_grid", "judge", "judge_children", "classify", "sign_at", "BAND"]

_CHUNK = 4_000_000  # Bernstein coefficients per chunk of boxes (32 MB of float64), NumPy path
BAND = 0.02  # monotonicity bits are computed only where the bounds meet [-BAND, BAND]


@dataclass
class BoxGrid:
    """The sub-boxes of the global field, per direction k: ``first[k]`` (nb_k,) index of the first supporting
    coefficient, ``ops[k]`` (nb_k, d + 1, d + 1) supporting coefficients -> Bernstein coefficients,
    ``per_cell[k]`` boxes per cell."""

    degree: int
    first: list
    ops: list
    per_cell: tuple

    @property
    def shape(self) -> tuple:
        return tuple(len(f) for f in self.first)

    def window(self, k: int, n: int) -> np.ndarray:
        """(nb_k, n) indicator of the coefficients supporting each box along direction k."""
        W = np.zeros((len(self.first[k]), n))
        rows = np.repeat(np.arange(len(self.first[k])), self.degree + 1)
        W[rows, (self.first[k][:, None] + np.arange(self.degree + 1)).ravel()] = 1.0
        return W


def _span_operators(U, d, per_span):
    """First supporting index (nb,) and B-spline -> Bernstein operators (nb, d + 1, d + 1) of every sub-interval."""
    breaks = np.unique(U)
    h = np.repeat(np.diff(breaks) / per_span, per_span)
    lo = np.repeat(breaks[:-1], per_span) + h * np.tile(np.arange(per_span), len(breaks) - 1)
    t = 0.5 - 0.5 * np.cos(np.pi * (2 * np.arange(d + 1) + 1) / (2 * d + 2))  # Chebyshev nodes: inside, distinct
    spans, ders = kn.basis_functions(U, d, (lo[:, None] + h[:, None] * t).ravel())
    first = spans.reshape(-1, d + 1)[:, 0] - d
    i = np.arange(d + 1)
    bern = comb(d, i) * t[:, None] ** i * (1 - t[:, None]) ** (d - i)  # (points, Bernstein index)
    return first, np.linalg.solve(bern, ders[:, 0, :].reshape(-1, d + 1, d + 1))


def box_grid(knots, degree: int, counts, per_span: int) -> BoxGrid:
    """Sub-boxes of a field of ``degree`` on the global ``knots`` (one vector per direction): ``per_span`` per span."""
    ops = [_span_operators(np.asarray(U, float), degree, per_span) for U in knots]
    return BoxGrid(degree, [o[0] for o in ops], [o[1] for o in ops],
                   tuple(len(o[0]) // c for o, c in zip(ops, counts)))


def _judge(C):
    """Bounds and monotonicity bits of boxes from their Bernstein coefficients C (..., d+1, d+1, d+1)."""
    flat = C.reshape(-1, C.shape[-1] ** 3)  # reductions over one contiguous axis: several times faster
    lo, hi = flat.min(axis=1), flat.max(axis=1)
    mono = np.zeros(len(flat), np.uint8)
    for k in range(3):
        diff = np.diff(C, axis=C.ndim - 3 + k).reshape(len(flat), -1)
        mono |= (diff.min(axis=1) > 0).astype(np.uint8) << 2 * k
        mono |= (diff.max(axis=1) < 0).astype(np.uint8) << 2 * k + 1
    return lo.reshape(C.shape[:-3]), hi.reshape(C.shape[:-3]), mono.reshape(C.shape[:-3])


def sign_at(low, high, level=0.0) -> np.ndarray:
    """+1 where F > level on the whole box (``low`` > level), -1 where F < level (``high`` < level), else 0 (int8)."""
    return np.where(low > level, 1, np.where(high < level, -1, 0)).astype(np.int8)


def judge(G: np.ndarray, grid: BoxGrid, boxes: np.ndarray, split: int = 1):
    """Bounds of F (least and greatest Bernstein coefficient) and monotonicity bits (uint8) of all the
    children of ``boxes`` (L, 3), each box split in ``split`` parts per direction: (low, high, mono), each
    (L, s, s, s).  :func:`judge_children` for one child per row."""
    m = np.stack(np.unravel_index(np.arange(split ** 3), (split,) * 3), 1)
    L = len(boxes)
    shape = (L,) + (split,) * 3
    out = judge_children(G, grid, np.repeat(np.asarray(boxes, np.int64), split ** 3, axis=0), np.tile(m, (L, 1)),
                         split)
    return tuple(a.reshape(shape) for a in out)


def judge_children(G: np.ndarray, grid: BoxGrid, boxes: np.ndarray, children: np.ndarray, split: int):
    """Bounds of F and monotonicity bits of child ``children[l]`` (of ``split`` per direction) of box
    ``boxes[l]``, row by row: (low, high, mono), each (L,).

    Bit 2k: F strictly increasing along +x_k on the child; bit 2k + 1:
    strictly decreasing; the bits are set only on children whose bounds meet
    [-BAND, BAND] (the only ones whose monotonicity the certificate asks).
    Compiled when numba is installed, else NumPy in chunks of ``_CHUNK``
    coefficients.
    """
    sub = _subdivision(grid.degree, split)
    A = [np.ascontiguousarray(np.einsum("mij,bjp->bmip", sub, op)) for op in grid.ops]  # (nb_k, s, d+1, d+1)
    boxes = np.ascontiguousarray(boxes, dtype=np.int64)
    children = np.ascontiguousarray(children, dtype=np.int64)
    L = len(boxes)
    low, high, mono = np.empty(L), np.empty(L), np.empty(L, np.uint8)
    if _fast.AVAILABLE:
        from geometry.compiled.lock import locked

        from tiling.implicit._certify_kernels import judge_rows

        locked(judge_rows)(np.ascontiguousarray(G, dtype=float), boxes, children, *grid.first, *A, BAND, low, high,
                           mono)
        return low, high, mono
    d1 = grid.degree + 1
    step = max(1, _CHUNK // d1 ** 3)
    for i in range(0, L, step):
        b, m = boxes[i:i + step], children[i:i + step]
        win = [grid.first[k][b[:, k]][:, None] + np.arange(d1) for k in range(3)]
        local = G[win[0][:, :, None, None], win[1][:, None, :, None], win[2][:, None, None, :]]
        C = np.einsum("lip,ljq,lkr,lpqr->lijk", *(A[k][b[:, k], m[:, k]] for k in range(3)), local, optimize=True)
        low[i:i + step], high[i:i + step], mono[i:i + step] = _judge(C)
    mono[(low > BAND) | (high < -BAND)] = 0  # as the compiled path: bits only where they are used
    return low, high, mono


def classify(G: np.ndarray, grid: BoxGrid):
    """Bounds and monotonicity bits (:func:`judge`) of every box of the grid, each of the grid's shape."""
    boxes = np.stack(np.unravel_index(np.arange(int(np.prod(grid.shape))), grid.shape), 1)
    return tuple(a.reshape(grid.shape) for a in judge(G, grid, boxes))


def _subdivision(d, s):
    """Bernstein coefficients on [m/s, (m+1)/s] from those on [0, 1]: (s, d + 1, d + 1)."""
    i = np.arange(d + 1)
    t = 0.5 - 0.5 * np.cos(np.pi * (2 * i + 1) / (2 * d + 2))

    def basis(x):
        return comb(d, i) * x[:, None] ** i * (1 - x[:, None]) ** (d - i)
    return np.stack([np.linalg.solve(basis(t), basis((m + t) / s)) for m in range(s)])
