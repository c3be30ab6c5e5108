"""Compiled point inversion (imported only when numba is installed and first needed): the iterations of
:func:`geometry.maps.inversion.newton_inverse`, plain and damped, one point per work item.

Each point's iterates depend on that point alone in the vectorised loop too (the stopping and halving rules
are per point), so running them point by point gives the same iterates up to round-off: a 3 x 3 solve by
partial-pivoting elimination instead of LAPACK's, the Cox-de Boor basis of :mod:`geometry.compiled._fast_kernels`
instead of SciPy's.  A surface is evaluated as a trivariate of degree 0 in a third direction (knots [0, 1],
one layer of coefficients), whose derivative there is zero and whose parameter never moves.
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange

from geometry.numbers import TINY
from geometry.compiled._fast_kernels import span_basis, span_basis_d1, find_span


@njit(cache=True, inline="always", error_model="numpy")
def _value_jacobian(C, U, off, deg, rational, t, span, B, dB, Nm, L, R, acc, x, J):
    """x (3,) and J (3, 3) (column k: d/dt_k) of the first three components at parameters t (3,) inside the
    domain.  ``U``: the three knot vectors one after the other, direction k's at U[off[k]:off[k + 1]], of
    degree deg[k]; scratch: ``span`` (3,), ``B``, ``dB`` (3, p + 1) the basis values and derivatives,
    ``acc`` (4, 4) the value and the three derivatives of components 0-2 and the weight.  One loop over
    the directions, so each basis routine is inlined once: the kernel compiles in 13-16 s, where three
    copies of each took 33-41 s.  Inlined into the point loop (not called): 38 ms for 50k points against
    90-103 ms as a call."""
    m = C.shape[3]
    for k in range(3):
        Uk = U[off[k]:off[k + 1]]
        p = deg[k]
        i = find_span(Uk, p, C.shape[k], t[k])
        span[k] = i - p
        span_basis(Uk, p, i, t[k], B[k], L, R)
        span_basis_d1(Uk, p, i, t[k], dB[k], Nm, L, R)
    for j in range(4):
        for c in range(4):
            acc[j, c] = 0.0
    nc = 4 if rational else 3
    for a in range(deg[0] + 1):
        for b in range(deg[1] + 1):
            vv, dv, vd = B[0, a] * B[1, b], dB[0, a] * B[1, b], B[0, a] * dB[1, b]
            for e in range(deg[2] + 1):
                w, w0, w1, w2 = vv * B[2, e], dv * B[2, e], vd * B[2, e], vv * dB[2, e]
                for c in range(nc):
                    h = C[span[0] + a, span[1] + b, span[2] + e, m - 1 if c == 3 else c]
                    acc[0, c] += w * h
                    acc[1, c] += w0 * h
                    acc[2, c] += w1 * h
                    acc[3, c] += w2 * h
    for c in range(3):
        if rational:  # S = A / w: dS = (dA - S dw) / w
            x[c] = acc[0, c] / acc[0, 3]
            for k in range(3):
                J[c, k] = (acc[1 + k, c] - x[c] * acc[1 + k, 3]) / acc[0, 3]
        else:
            x[c] = acc[0, c]
            for k in range(3):
                J[c, k] = acc[1 + k, c]


@njit(cache=True, inline="always", error_model="numpy")
def _solve(A, g, d, step):
    """step (d,) = A^-1 g for the d x d matrix A (overwritten), by elimination with partial pivoting."""
    for j in range(d):
        step[j] = g[j]
    for j in range(d):
        piv = j
        for i in range(j + 1, d):
            if abs(A[i, j]) > abs(A[piv, j]):
                piv = i
        if piv != j:
            for k in range(d):
                A[j, k], A[piv, k] = A[piv, k], A[j, k]
            step[j], step[piv] = step[piv], step[j]
        for i in range(j + 1, d):
            f = A[i, j] / A[j, j]
            for k in range(j, d):
                A[i, k] -= f * A[j, k]
            step[i] -= f * step[j]
    for j in range(d - 1, -1, -1):
        s = step[j]
        for k in range(j + 1, d):
            s -= A[j, k] * step[k]
        step[j] = s / A[j, j]


@njit(cache=True, inline="always", error_model="numpy")
def _gauss_newton_step(J, r, t, lo, hi, d, projected, roundoff, A, Af, g, step):
    """:func:`geometry.maps.inversion._gauss_newton_step` for one point: the regularised normal equations, and with
    ``projected`` the parameters pinned at a bound the step would cross left out."""
    trace = 0.0
    for i in range(d):
        s = 0.0
        for c in range(3):
            s += J[c, i] * r[c]
        g[i] = s
        for k in range(d):
            s = 0.0
            for c in range(3):
                s += J[c, i] * J[c, k]
            A[i, k] = s
        trace += A[i, i]
    reg = roundoff * (trace + TINY)
    for i in range(d):
        A[i, i] += reg
    for i in range(d):
        for k in range(d):
            Af[i, k] = A[i, k]
    _solve(Af, g, d, step)
    if not projected:
        return
    pinned = 0
    for i in range(d):
        if (t[i] <= lo[i] and step[i] > 0) or (t[i] >= hi[i] and step[i] < 0):
            pinned |= 1 << i
    if pinned == 0 or pinned == (1 << d) - 1:
        return
    for i in range(d):
        fi = (pinned >> i) & 1 == 0
        for k in range(d):
            fk = (pinned >> k) & 1 == 0
            Af[i, k] = A[i, k] if (fi and fk) else (1.0 if (i == k and not fi) else 0.0)
        if not fi:
            g[i] = 0.0
    _solve(Af, g, d, step)


@njit(cache=True, parallel=True, error_model="numpy")
def invert_points(C, U, off, deg, rational, d, lo, hi, start, targets, tol, max_iter, damped, free_steps, halvings,
                  creep, roundoff, floor, params, dist):
    """Parameters ``params`` (N, 3) and distances ``dist`` (N,) of ``targets`` (N, 3) on the spline with
    homogeneous coefficients C (n0, n1, n2, m) and knots U, off, deg (:func:`_value_jacobian`), by the
    iterations of :func:`geometry.maps.inversion.newton_inverse` (``damped``:
    :func:`geometry.maps.inversion._damped_newton`) from ``start`` (N, 3); the first d parameters move, each
    clipped to [lo, hi]; ``floor`` (N,) the round-off of a residual norm (damped steps)."""
    pm = max(deg[0], max(deg[1], deg[2])) + 1
    for q in prange(start.shape[0]):
        span, B, dB = np.empty(3, np.int64), np.empty((3, pm)), np.zeros((3, pm))
        Nm, L, R = np.empty(pm), np.empty(pm), np.empty(pm)
        acc, x, J = np.empty((4, 4)), np.empty(3), np.empty((3, 3))
        A, Af, g, step = np.empty((3, 3)), np.empty((3, 3)), np.empty(3), np.empty(3)
        r, t, prev = np.empty(3), np.empty(3), np.empty(3)
        for i in range(3):
            t[i] = start[q, i]
            prev[i] = t[i]
        last = np.inf
        halved = 0
        k = 0
        final = False  # the iterate is final: evaluate it once more, for its distance
        while True:  # one evaluation site: iterations 0 .. max_iter - 1, then the final one
            _value_jacobian(C, U, off, deg, rational, t, span, B, dB, Nm, L, R, acc, x, J)
            for c in range(3):
                r[c] = x[c] - targets[q, c]
            norm = np.sqrt(r[0] * r[0] + r[1] * r[1] + r[2] * r[2])
            if final or k == max_iter:
                break
            k += 1
            held = False
            for i in range(d):
                if t[i] <= lo[i] or t[i] >= hi[i]:
                    held = True
            if damped:
                fl = floor[q]
                if norm > last + fl:  # uphill: halve the step; give up at the better point after a few halvings
                    gap = 0.0
                    for i in range(d):
                        t[i] = 0.5 * (prev[i] + t[i])
                        gap = max(gap, abs(t[i] - prev[i]))
                    halved += 1
                    if halved > halvings or gap <= tol:
                        for i in range(d):
                            t[i] = prev[i]
                        final = True
                    continue
                if k - 1 >= free_steps and (norm >= last - fl or (held and norm >= (1.0 - creep) * last)):
                    break  # idle: no better than its last iterate
                for i in range(d):
                    prev[i] = t[i]
                last, halved = norm, 0
            elif k - 1 >= free_steps - 1:
                if k - 1 >= free_steps and held and norm >= (1.0 - creep) * last:
                    break  # held at the domain's bound, creeping
                last = norm
            _gauss_newton_step(J, r, t, lo, hi, d, damped, roundoff, A, Af, g, step)
            moved = 0.0
            for i in range(d):
                new = min(max(t[i] - step[i], lo[i]), hi[i])
                moved = max(moved, abs(new - t[i]))
                t[i] = new
            if not moved > tol:
                final = True
        for c in range(3):
            params[q, c] = t[c]
        dist[q] = norm
