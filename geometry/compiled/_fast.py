"""Optional compiled kernel for scattered B-spline evaluation (numba, the ``fast`` extra).

SciPy's ``NdBSpline`` evaluates about 2e6 points/s on one core and holds the
GIL, so it cannot use a second core.  This kernel (Cox-de Boor basis, then
the (p + 1)^d tensor contraction per point, points split over threads with
``prange``) evaluates values, or values and first derivatives (for
Jacobians); higher derivatives stay with SciPy.  It is used
for large point sets when numba imports; otherwise nothing changes.  The
first use compiles it (cached on disk by numba), so small evaluations never
trigger it: see :data:`MIN_POINTS`.
"""

from __future__ import annotations

import importlib.util

import numpy as np

from geometry.cache import memo

from geometry import knots as kn
from geometry.compiled.lock import locked

#: below this many points the SciPy path is used (no compile, no thread start-up)
MIN_POINTS = 20_000

# numba is imported on first use only: importing it costs memory and time (docs/performance.md) that
# small analyses (the heat-sink demo) should not pay
AVAILABLE = importlib.util.find_spec("numba") is not None

_CHUNKS = 64  # work items of the kernel's parallel loop (must match _fast_kernels)


@memo(1)
def _kernel():
    """The compiled 3-D kernel (numba imported and the kernel loaded on first call)."""
    from geometry.compiled._fast_kernels import eval3

    return eval3


def readonly(a, dtype=float) -> np.ndarray:
    """A read-only, C-contiguous view (a copy only when needed) of a kernel input.

    Kernel inputs are always passed read-only, so that each kernel compiles
    one signature (numba types read-only and writable arrays apart).
    """
    out = np.ascontiguousarray(a, dtype=dtype).view()
    out.setflags(write=False)
    return out


def _grid_kernel():
    from geometry.compiled._grid_kernels import grid_derivs3

    return grid_derivs3


def applies(dim: int, n_points: int, min_points: int = MIN_POINTS) -> bool:
    """Whether :func:`evaluate` would run the compiled kernel for this many points."""
    return AVAILABLE and dim == 3 and n_points >= min_points


def evaluate(knots, degrees, coefficients: np.ndarray, x: np.ndarray, derivs: bool = False,
             min_points: int = MIN_POINTS) -> np.ndarray | None:
    """Values (N, m) of the spline with ``coefficients`` (n_1, ..., n_d, m) at ``x`` (N, d).

    ``derivs``: values and first derivatives instead, (4, N, m) (value,
    d/dx_0, d/dx_1, d/dx_2; at a knot the right-hand derivative, as SciPy's).
    Returns None when the kernel does not apply (numba missing, d != 3, or
    fewer than ``min_points`` points, :data:`MIN_POINTS` unless a caller that
    runs compiled kernels anyway asks for fewer) or when some point lies
    outside the domain or is not finite: the caller then checks the points
    (and raises, naming them) and uses SciPy.
    """
    if not applies(len(degrees), len(x), min_points) or np.ndim(x) != 2 or np.shape(x)[1] != 3:
        return None
    C = readonly(coefficients)
    X = readonly(x)
    out = np.empty((4 if derivs else 1, len(X), C.shape[-1]))
    bad = np.zeros(_CHUNKS, np.int64)
    U = [readonly(u) for u in knots]
    locked(_kernel())(X, U[0], int(degrees[0]), U[1], int(degrees[1]), U[2], int(degrees[2]), C, out, bad)
    if bad.any():
        return None
    return out if derivs else out[0]


def grid_tables(spline, axes, order=(0, 1, 2)) -> list:
    """Per direction: first non-zero basis index (nq,) and values/derivatives (2, nq, p + 1) at ``axes``.

    ``order``: the spline's directions in the order the tables are wanted
    (for coefficients transposed the same way).
    """
    out = []
    for k in order:
        U, p, ax = spline.knots[k], spline.degrees[k], axes[k]
        spans, ders = kn.basis_functions(U, p, np.clip(ax, U[0], U[-1]), 1)
        out.append((readonly(spans - p, np.int64), readonly(np.moveaxis(ders, 1, 0))))
    return out


def grid_derivs(hom: np.ndarray, rows: slice, tables) -> np.ndarray:
    """Value and derivatives (4, n, m) of a 3-D spline with coefficients ``hom`` on grid rows ``rows``.

    ``tables`` from :func:`grid_tables`; n = rows x nq1 x nq2 points in C order.
    """
    (f0, B0), (f1, B1), (f2, B2) = tables
    m = hom.shape[-1]
    out = np.empty((4, rows.stop - rows.start, len(f1), len(f2), m))
    locked(_grid_kernel())(readonly(hom), rows.start, rows.stop, f0, B0, f1, B1, f2, B2, out)
    return out.reshape(4, -1, m)
