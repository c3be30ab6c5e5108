"""One-dimensional knot-vector algebra.

Everything here works on a single open (clamped) knot vector ``U`` of degree
``p`` with ``n = len(U) - p - 1`` basis functions, and returns *matrices* that
act on coefficient vectors.  The tensor-product spline class applies them
direction by direction, so every operation automatically acts on coordinates,
weights and channels at once.

Conventions
-----------
* Matrices map old coefficients to new ones: ``new = M @ old``.
* Refinement matrices are returned as ``scipy.sparse.csr_array``; small local
  operators (Bezier extraction, Bernstein elevation) as dense arrays.
* Degrees are at least 1.
"""

from __future__ import annotations

from math import comb

import numpy as np

from .cache import memo
import scipy.sparse as sp

from .cache import BoundedCache
from .errors import SplineError
from .errors import show
from .numbers import is_integer

__all__ = [
    "apply_along",
    "validate_knots",
    "breakpoints",
    "find_spans",
    "basis_functions",
    "basis_matrix",
    "greville",
    "insertion_matrix",
    "bezier_refinement",
    "extraction_operators",
    "bernstein_elevation",
    "elevation_matrix",
    "restriction",
    "bezier_to_bspline",
    "uniform_knots",
]


def apply_along(arr: np.ndarray, axis: int, M) -> np.ndarray:
    """Apply the matrix ``M`` (new, old), dense or sparse, along ``axis`` of the array ``arr``."""
    moved = np.moveaxis(arr, axis, 0)
    flat = moved.reshape(moved.shape[0], -1)
    out = M @ flat
    out = np.asarray(out).reshape((M.shape[0],) + moved.shape[1:])
    return np.moveaxis(out, 0, axis)


def uniform_knots(degree: int, n_elements: int, lo: float = 0.0, hi: float = 1.0) -> np.ndarray:
    """Open uniform knot vector of ``n_elements`` equal spans on ``[lo, hi]``."""
    inner = np.linspace(lo, hi, n_elements + 1)
    return np.concatenate([np.full(degree, lo), inner, np.full(degree, hi)])


_VALID = BoundedCache(1024)  # validated knot vectors (read-only arrays), keyed by bytes, degree and count


def validate_knots(knots, degree: int, n: int, direction: int = 0) -> np.ndarray:
    """Check that ``knots`` is a valid open knot vector for ``n`` coefficients.

    Returns the knot vector as a read-only float array (shared between splines
    with equal knot vectors).  Raises :class:`SplineError` naming
    ``direction`` and the offending value otherwise.
    """
    where = f"direction {direction}"
    if isinstance(knots, np.ndarray) and knots.dtype == float and knots.ndim == 1 and is_integer(degree):
        key = (knots.tobytes(), int(degree), int(n))
        hit = _VALID.lookup(key)
        if hit is not None:  # the same knot vector was validated before (e.g. thousands of composed tiles)
            return hit
    if not is_integer(degree) or degree < 1:
        raise SplineError(f"{where}: degree must be an integer >= 1, got {show(degree)}")
    try:
        U = np.asarray(knots, dtype=float)
    except (TypeError, ValueError) as exc:
        raise SplineError(f"{where}: knot vector is not numeric ({exc})") from None
    if U.ndim != 1:
        raise SplineError(f"{where}: knot vector must be one-dimensional, got shape {U.shape}")
    p = int(degree)
    if len(U) != n + p + 1:
        raise SplineError(
            f"{where}: knot vector has {len(U)} entries but degree {p} with {n} control points "
            f"needs n + p + 1 = {n + p + 1}; add or remove knots (or control points)"
        )
    if n < p + 1:
        raise SplineError(f"{where}: degree {p} needs at least {p + 1} control points, got {n}")
    bad = ~np.isfinite(U)
    if bad.any():
        raise SplineError(f"{where}: knot vector has non-finite value {show(U[bad][0])} at index {int(np.argmax(bad))}")
    dec = np.nonzero(np.diff(U) < 0)[0]
    if len(dec):
        i = int(dec[0])
        raise SplineError(f"{where}: knot vector decreases at index {i + 1} ({show(U[i])} -> {show(U[i + 1])}); sort it")
    if not (np.all(U[: p + 1] == U[0]) and np.all(U[-p - 1 :] == U[-1])):
        raise SplineError(
            f"{where}: knot vector is not open (clamped): the first and last {p + 1} knots must repeat "
            f"the end values, got {U[: p + 1].tolist()} ... {U[-p - 1 :].tolist()}"
        )
    if not U[-1] > U[0]:
        raise SplineError(f"{where}: knot vector spans an empty interval [{U[0]}, {U[-1]}]")
    vals, mults = np.unique(U, return_counts=True)
    inner = mults[1:-1]
    if np.any(inner > p + 1):
        k = int(np.argmax(inner > p + 1)) + 1
        raise SplineError(
            f"{where}: interior knot {show(vals[k])} has multiplicity {mults[k]} > degree + 1 = {p + 1}"
        )
    if mults[0] > p + 1 or mults[-1] > p + 1:
        raise SplineError(f"{where}: end knots may repeat at most degree + 1 = {p + 1} times")
    out = U.copy()
    return _VALID.get((out.tobytes(), p, int(n)), lambda: out)


def breakpoints(knots) -> tuple[np.ndarray, np.ndarray]:
    """Distinct knot values and their multiplicities."""
    return np.unique(np.asarray(knots, float), return_counts=True)


def find_spans(knots: np.ndarray, degree: int, x: np.ndarray, side: str = "right") -> np.ndarray:
    """Index ``i`` with ``U[i] <= x < U[i+1]`` (last non-empty span at the right end).

    ``side="left"``: ``U[i] < x <= U[i+1]`` instead, so that a point on an
    interior knot takes the span that ends there (the left-hand limit, e.g.
    one side of a discontinuity; first non-empty span at the left end).
    """
    n = len(knots) - degree - 1
    spans = np.searchsorted(knots, x, side=side) - 1
    return np.clip(spans, degree, n - 1)


def basis_functions(knots: np.ndarray, degree: int, x: np.ndarray, nder: int = 0, side: str = "right"):
    """Non-zero B-spline basis functions and derivatives at many points.

    Vectorised version of Algorithm A2.3 of Piegl & Tiller: loops run over the
    degree only, every statement acts on all points at once.

    Returns ``(spans, ders)`` with ``ders`` of shape ``(N, nder + 1, p + 1)``:
    ``ders[:, k, r]`` is the ``k``-th derivative of ``N_{span - p + r}``.
    ``side``: which limit at a knot (:func:`find_spans`).
    """
    U = knots
    p = degree
    x = np.asarray(x, dtype=float)
    N = x.shape[0]
    spans = find_spans(U, p, x, side)
    ndu = np.empty((p + 1, p + 1, N))
    left = np.empty((p + 1, N))
    right = np.empty((p + 1, N))
    ndu[0, 0] = 1.0
    for j in range(1, p + 1):
        left[j] = x - U[spans + 1 - j]
        right[j] = U[spans + j] - x
        saved = np.zeros(N)
        for r in range(j):
            ndu[j, r] = right[r + 1] + left[j - r]
            temp = ndu[r, j - 1] / ndu[j, r]
            ndu[r, j] = saved + right[r + 1] * temp
            saved = left[j - r] * temp
        ndu[j, j] = saved
    ders = np.zeros((nder + 1, p + 1, N))
    ders[0] = ndu[:, p]
    if nder > 0:
        a = np.zeros((2, p + 1, N))
        for r in range(p + 1):
            s1, s2 = 0, 1
            a[0, 0] = 1.0
            for k in range(1, min(nder, p) + 1):
                d = np.zeros(N)
                rk, pk = r - k, p - k
                if r >= k:
                    a[s2, 0] = a[s1, 0] / ndu[pk + 1, rk]
                    d = a[s2, 0] * ndu[rk, pk]
                j1 = 1 if rk >= -1 else -rk
                j2 = k - 1 if r - 1 <= pk else p - r
                for j in range(j1, j2 + 1):
                    a[s2, j] = (a[s1, j] - a[s1, j - 1]) / ndu[pk + 1, rk + j]
                    d = d + a[s2, j] * ndu[rk + j, pk]
                if r <= pk:
                    a[s2, k] = -a[s1, k - 1] / ndu[pk + 1, r]
                    d = d + a[s2, k] * ndu[r, pk]
                ders[k, r] = d
                s1, s2 = s2, s1
        fac = float(p)
        for k in range(1, nder + 1):
            ders[k] *= fac
            fac *= p - k
    return spans, np.transpose(ders, (2, 0, 1))


def basis_matrix(knots: np.ndarray, degree: int, x: np.ndarray, nder: int = 0, side: str = "right") -> sp.csr_array:
    """Sparse matrix ``B[i, j] = d^nder N_j(x_i)`` of shape ``(len(x), n)`` (``side``: :func:`find_spans`)."""
    x = np.asarray(x, float)
    spans, ders = basis_functions(knots, degree, x, nder, side)
    return _basis_csr(knots, degree, spans, ders[:, nder, :])


def basis_matrices(knots: np.ndarray, degree: int, x: np.ndarray, nder: int = 0,
                   side: str = "right") -> list[sp.csr_array]:
    """``[B_0, ..., B_nder]``, ``B_k[i, j] = d^k N_j(x_i)`` (each ``(len(x), n)``), from one evaluation of the
    non-zero basis functions (:func:`basis_functions` computes every order up to ``nder`` at once)."""
    x = np.asarray(x, float)
    spans, ders = basis_functions(knots, degree, x, nder, side)
    return [_basis_csr(knots, degree, spans, ders[:, k, :]) for k in range(nder + 1)]


def _basis_csr(knots, degree: int, spans: np.ndarray, values: np.ndarray) -> sp.csr_array:
    """CSR of the non-zero values (N, p + 1) at their spans: p + 1 entries per row, columns from span - p up."""
    cols = (spans[:, None] - degree + np.arange(degree + 1)).ravel()
    indptr = np.arange(0, (degree + 1) * len(spans) + 1, degree + 1)
    return sp.csr_array((values.ravel(), cols, indptr), shape=(len(spans), len(knots) - degree - 1))


def greville(knots: np.ndarray, degree: int) -> np.ndarray:
    """Greville abscissae (knot averages), one per basis function."""
    n = len(knots) - degree - 1
    idx = np.arange(n)[:, None] + 1 + np.arange(degree)
    return knots[idx].mean(axis=1)


def _boehm(U: np.ndarray, p: int, t: float):
    """Boehm's algorithm for ``t`` inserted once into ``U``: ``(new knots, k, mid, alpha)``: rows i <= k - p of
    the (n+1, n) insertion matrix copy old row i, rows ``mid`` blend ``alpha`` of old row i with ``1 - alpha``
    of old row i - 1, rows i >= k + 1 copy old row i - 1."""
    n = len(U) - p - 1
    k = find_spans(U, p, np.array([t]))[0]
    if t == U[-1]:  # a right-end value belongs to no span to the right
        k = n - 1
    mid = np.arange(max(k - p + 1, 0), k + 1)
    den = U[mid + p] - U[mid]
    alpha = np.where(den > 0, (t - U[mid]) / np.where(den > 0, den, 1.0), 0.0)
    return np.insert(U, k + 1, t), int(k), mid, alpha


def _insert_one(U: np.ndarray, p: int, t: float) -> tuple[np.ndarray, sp.csr_array]:
    """Knot vector with ``t`` inserted once and its (n+1, n) sparse matrix (:func:`_boehm`)."""
    n = len(U) - p - 1
    new, k, mid, alpha = _boehm(U, p, t)
    i = np.arange(n + 1)
    keep, shift = i[i <= k - p], i[i >= k + 1]
    r = np.concatenate([keep, mid, mid, shift])
    c = np.concatenate([keep, mid, mid - 1, shift - 1])
    v = np.concatenate([np.ones(len(keep)), alpha, 1.0 - alpha, np.ones(len(shift))])
    nz = v != 0
    return new, sp.csr_array((v[nz], (r[nz], c[nz])), shape=(n + 1, n))


#: insertion matrices of at most this many entries (rows x columns) are built dense, a row update per knot
#: (a face's space: tens of functions); larger ones as products of sparse one-knot matrices
_DENSE_INSERTION = 1 << 18


def insertion_matrix(knots: np.ndarray, degree: int, values) -> tuple[np.ndarray, sp.csr_array]:
    """Insert several knots (repeats allowed) into ``knots``.

    Returns ``(new_knots, R)`` with ``new_coefficients = R @ old_coefficients``.
    Raises :class:`SplineError` for values outside the open interval of the
    domain or that would raise a multiplicity above ``degree + 1``.
    """
    U = np.asarray(knots, float)
    p = degree
    vals = np.sort(np.atleast_1d(np.asarray(values, float)))
    if vals.size and (not np.all(np.isfinite(vals))):
        raise SplineError(f"knot values to insert must be finite, got {vals.tolist()}")
    n = len(U) - p - 1
    dense = (n + len(vals)) * n <= _DENSE_INSERTION
    # dense: each insertion blends p rows and shifts the rest (the same two products per entry as the sparse
    # product, so the same values); 5k face refinements of a T2 hierarchy took 22 s as sparse products
    R = np.eye(n) if dense else sp.identity(n, format="csr")
    for t in vals:
        if not (U[0] < t < U[-1]):
            raise SplineError(
                f"cannot insert knot {show(t)}: it must lie strictly inside the domain [{U[0]}, {U[-1]}]"
            )
        if np.count_nonzero(U == t) >= p + 1:
            raise SplineError(f"cannot insert knot {show(t)}: it already has multiplicity degree + 1 = {p + 1}")
        if dense:
            U, k, mid, alpha = _boehm(U, p, float(t))
            grown = np.empty((len(R) + 1, n))
            grown[: k - p + 1] = R[: k - p + 1]
            grown[mid] = alpha[:, None] * R[mid] + (1.0 - alpha)[:, None] * R[mid - 1]
            grown[k + 1 :] = R[k:]
            R = grown
        else:
            U, Ri = _insert_one(U, p, float(t))
            R = Ri @ R
    return U, sp.csr_array(R)


def bezier_refinement(knots: np.ndarray, degree: int):
    """Refine to Bezier form: every interior breakpoint gets multiplicity >= degree.

    Returns ``(bez_knots, R, first_rows, elements)`` where ``R`` maps the
    B-spline coefficients to the refined ones, ``first_rows[e]`` is the row of
    the first Bezier coefficient of element ``e`` (rows ``first_rows[e] ..
    first_rows[e] + p``) and ``elements`` is an ``(ne, 2)`` array of element
    intervals.
    """
    U = np.asarray(knots, float)
    p = degree
    vals, mults = breakpoints(U)
    missing = np.repeat(vals[1:-1], np.maximum(p - mults[1:-1], 0))
    Ub, R = insertion_matrix(U, p, missing)
    elements = np.stack([vals[:-1], vals[1:]], axis=1)
    spans = find_spans(Ub, p, elements[:, 0])
    return Ub, R, spans - p, elements


def extraction_operators(knots: np.ndarray, degree: int):
    """Bezier extraction operators of a 1-D B-spline space.

    Returns ``(C, first)``: ``C`` of shape ``(ne, p + 1, p + 1)`` and
    ``first[e]``, the index of the first B-spline function supported on element
    ``e``, such that the Bernstein coefficients on element ``e`` are
    ``C[e] @ coefficients[first[e] : first[e] + p + 1]``.  Both read-only: they
    are kept per knot vector and degree (bounded), as the tubes of a V-model,
    the composed tiles of a paving and the regularity proofs repeat a few spaces.
    """
    U = np.asarray(knots, float)
    return _EXTRACTION.get((U.tobytes(), int(degree)), lambda: _extraction(U, int(degree)))


def _extraction(U: np.ndarray, p: int):
    _, R, rows, elements = bezier_refinement(U, p)
    first = find_spans(U, p, elements[:, 0]) - p
    Rd = R.toarray()
    ridx = rows[:, None] + np.arange(p + 1)
    cidx = first[:, None] + np.arange(p + 1)
    C = Rd[ridx[:, :, None], cidx[:, None, :]]
    C.setflags(write=False)
    first.setflags(write=False)
    return C, first


_EXTRACTION = BoundedCache(256)


@memo(256)
def bernstein_elevation(p: int, t: int) -> np.ndarray:
    """Matrix ``E`` (p+t+1, p+1) raising Bernstein coefficients from degree p to p+t."""
    E = np.zeros((p + t + 1, p + 1))
    for i in range(p + t + 1):
        for j in range(max(0, i - t), min(p, i) + 1):
            E[i, j] = comb(p, j) * comb(t, i - j) / comb(p + t, i)
    E.setflags(write=False)
    return E


def bezier_to_bspline(knots: np.ndarray, degree: int) -> np.ndarray:
    """Left inverse of the stacked per-element Bezier extraction.

    Returns ``L`` of shape ``(n, ne * (p + 1))`` such that for every spline in
    the space, ``coefficients = L @ stacked_bernstein_coefficients``.  Used to
    bring products, elevated and composed pieces back to B-spline form; exact
    whenever the stacked data do lie in the space (they do by construction).
    Read-only: the composed pieces of a tile share their knot vectors, so the
    matrix (a pseudo-inverse) is kept for the last 128 (knots, degree) pairs
    whose matrix has at most 2^16 entries (0.5 MB; at degree 27 and 6
    elements it has 26,000), 64 MB at most.
    """
    U = np.ascontiguousarray(knots, float)
    n, elements = len(U) - degree - 1, len(np.unique(U)) - 1
    if n * elements * (degree + 1) <= 1 << 16:  # the matrix's entries
        return _bezier_to_bspline_cached(U.tobytes(), len(U), int(degree))
    return _bezier_to_bspline(U, int(degree))


@memo(128)
def _bezier_to_bspline_cached(key: bytes, n_knots: int, p: int) -> np.ndarray:
    return _bezier_to_bspline(np.frombuffer(key, float, n_knots), p)


def _bezier_to_bspline(U: np.ndarray, p: int) -> np.ndarray:
    _, R, rows, _ = bezier_refinement(U, p)
    Rd = R.toarray()
    stacked = Rd[(rows[:, None] + np.arange(p + 1)).ravel()]
    L = np.linalg.pinv(stacked, rcond=1e-13)
    L.setflags(write=False)
    return L


def elevation_matrix(knots: np.ndarray, degree: int, times: int) -> tuple[np.ndarray, np.ndarray]:
    """Raise the degree by ``times`` keeping continuity at every knot.

    Returns ``(new_knots, E)`` with ``new_coefficients = E @ old_coefficients``.
    """
    U = np.asarray(knots, float)
    p = degree
    if times == 0:
        return U, np.eye(len(U) - p - 1)
    vals, mults = breakpoints(U)
    new_mults = np.minimum(mults + times, p + times + 1)
    newU = np.repeat(vals, new_mults)
    _, R, rows, _ = bezier_refinement(U, p)
    Rd = R.toarray()
    bez = Rd[(rows[:, None] + np.arange(p + 1))]  # (ne, p+1, n)
    elevated = np.einsum("ij,ejk->eik", bernstein_elevation(p, times), bez)
    L = bezier_to_bspline(newU, p + times)
    return newU, L @ elevated.reshape(-1, bez.shape[-1])


def restriction(knots: np.ndarray, degree: int, a: float, b: float) -> tuple[np.ndarray, np.ndarray]:
    """Restrict a 1-D spline space to the sub-interval ``[a, b]``.

    Returns ``(sub_knots, S)`` with ``sub_coefficients = S @ coefficients``;
    the restricted spline equals the original on ``[a, b]``.
    """
    U = np.asarray(knots, float)
    p = degree
    if not (U[0] <= a < b <= U[-1]):
        raise SplineError(f"sub-interval [{a}, {b}] is not a non-empty part of the domain [{U[0]}, {U[-1]}]")
    ins = []
    for t in (a, b):
        if U[0] < t < U[-1]:
            ins += [t] * (p + 1 - int(np.count_nonzero(U == t)))
    U2, R = insertion_matrix(U, p, ins)
    lo = int(np.searchsorted(U2, a, side="left"))  # first of the p+1 copies of a
    hi = int(np.searchsorted(U2, b, side="right"))  # one past the last copy of b
    sub = U2[lo:hi]
    S = R.toarray()[lo : hi - p - 1]
    return sub, S
