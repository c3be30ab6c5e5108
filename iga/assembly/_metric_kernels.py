"""Compiled metric kernels of :mod:`iga.assembly.compiled` (imported only when numba is installed and first needed).

The stiffness coefficient fields of the diffusion form at points
(:func:`metric_fields`), and fused with the geometry's derivatives on a grid
(:func:`geometry_metric3`, on the contractions of
:mod:`geometry.compiled._grid_kernels`).  Conductivity is
isotropic (a number per point) or a symmetric tensor (six components per
point, order (xx, yy, zz, xy, xz, yz)).
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange

from geometry.compiled._grid_kernels import contract21, direction0_row


@njit(cache=True, parallel=True, error_model="numpy")
def metric_fields(Du, Dv, Dw, kval, ktensor, fval, w, C, L, det):
    """Stiffness coefficients, source load and det J at M points.

    Du, Dv, Dw (M, 3): dx/du, dx/dv, dx/dw; kval, fval, w (M,): isotropic
    conductivity, source and quadrature weight; ``ktensor`` (M, 6) tensor
    conductivity components (xx, yy, zz, xy, xz, yz), or (0, 6) for the
    isotropic ``kval``.  With c_1 = x_v x x_w, c_2 = x_w x x_u, c_3 = x_u x x_v
    (the rows of det J * J^-1): C (6, M) gets w (c_r . K c_s) / |det J| in the
    pair order (0,0), (1,1), (2,2), (0,1), (0,2), (1,2); L (M,) gets
    f |det J| w and det (M,) gets det J (a zero determinant gives non-finite C,
    which the caller reports via ``det``).
    """
    iso = ktensor.shape[0] == 0
    for k in prange(Du.shape[0]):
        if iso:
            kk = kval[k]
            _metric_point(Du[k, 0], Du[k, 1], Du[k, 2], Dv[k, 0], Dv[k, 1], Dv[k, 2], Dw[k, 0], Dw[k, 1], Dw[k, 2],
                          True, kk, kk, kk, 0.0, 0.0, 0.0, fval[k], w[k], k, C, L, det)
        else:
            _metric_point(Du[k, 0], Du[k, 1], Du[k, 2], Dv[k, 0], Dv[k, 1], Dv[k, 2], Dw[k, 0], Dw[k, 1], Dw[k, 2],
                          False, ktensor[k, 0], ktensor[k, 1], ktensor[k, 2], ktensor[k, 3], ktensor[k, 4],
                          ktensor[k, 5], fval[k], w[k], k, C, L, det)


@njit(inline="always", error_model="numpy")
def _metric_point(u0, u1, u2, v0, v1, v2, w0, w1, w2, iso, k00, k11, k22, k01, k02, k12, fval, w, k, C, L, det):
    """C[:, k], L[k] and det[k] of :func:`metric_fields` from the derivatives x_u, x_v, x_w at one point.

    ``iso``: the conductivity is k00 (= k11 = k22) times the identity, which
    needs no tensor products.
    """
    a0, a1, a2 = v1 * w2 - v2 * w1, v2 * w0 - v0 * w2, v0 * w1 - v1 * w0
    b0, b1, b2 = w1 * u2 - w2 * u1, w2 * u0 - w0 * u2, w0 * u1 - w1 * u0
    e0, e1, e2 = u1 * v2 - u2 * v1, u2 * v0 - u0 * v2, u0 * v1 - u1 * v0
    dt = u0 * a0 + u1 * a1 + u2 * a2
    det[k] = dt
    adet = abs(dt)
    L[k] = fval * adet * w
    fac = w / adet
    if iso:  # K = k I: K c = k c, without the tensor products
        ka0, ka1, ka2 = k00 * a0, k00 * a1, k00 * a2
        kb0, kb1, kb2 = k00 * b0, k00 * b1, k00 * b2
        ke0, ke1, ke2 = k00 * e0, k00 * e1, k00 * e2
    else:
        ka0 = k00 * a0 + k01 * a1 + k02 * a2
        ka1 = k01 * a0 + k11 * a1 + k12 * a2
        ka2 = k02 * a0 + k12 * a1 + k22 * a2
        kb0 = k00 * b0 + k01 * b1 + k02 * b2
        kb1 = k01 * b0 + k11 * b1 + k12 * b2
        kb2 = k02 * b0 + k12 * b1 + k22 * b2
        ke0 = k00 * e0 + k01 * e1 + k02 * e2
        ke1 = k01 * e0 + k11 * e1 + k12 * e2
        ke2 = k02 * e0 + k12 * e1 + k22 * e2
    C[0, k] = fac * (a0 * ka0 + a1 * ka1 + a2 * ka2)
    C[1, k] = fac * (b0 * kb0 + b1 * kb1 + b2 * kb2)
    C[2, k] = fac * (e0 * ke0 + e1 * ke1 + e2 * ke2)
    C[3, k] = fac * (a0 * kb0 + a1 * kb1 + a2 * kb2)
    C[4, k] = fac * (a0 * ke0 + a1 * ke1 + a2 * ke2)
    C[5, k] = fac * (b0 * ke0 + b1 * ke1 + b2 * ke2)


@njit(cache=True, parallel=True, error_model="numpy")
def geometry_metric3(hom, rational, a, b, f0, B0, f1, B1, f2, B2, iso, K, fval, qw0, qw1, qw2, C, L, det):
    """:func:`grid_derivs3` and :func:`metric_fields` in one pass, for x = spline(xi) and constant k and f.

    hom (n0, n1, n2, m) holds the coordinates (m = 3) or the homogeneous
    coordinates with the weight last (m = 4, ``rational``); qw_k the Gauss
    weights per direction; K (6,) the constant conductivity tensor (xx, yy,
    zz, xy, xz, yz), ``iso`` when it is a multiple of the identity; fval a
    number.  C (6, n), L (n,) and det (n,) receive the fields of
    :func:`metric_fields` on the n = (b - a) nq1 nq2 points of grid rows
    a .. b - 1 (C order).  The derivatives of a grid row stay in a small buffer
    instead of a (4, n, m) array written and read back.
    """
    nq1, nq2, m = B1.shape[1], B2.shape[1], hom.shape[3]
    p0 = B0.shape[2] - 1
    lo = f0[a]
    U = contract21(hom, lo, f0[b - 1] + p0 + 1 - lo, B1, f1, B2, f2)
    Kn = nq2 * m
    k00, k11, k22, k01, k02, k12 = K[0], K[1], K[2], K[3], K[4], K[5]
    for item in prange((b - a) * nq1):
        # planes j inner: the items of one thread share q1, so the U rows they read stay in cache
        q1 = item // (b - a)
        j = item - q1 * (b - a)
        q0 = a + j
        s = f0[q0] - lo
        buf = np.empty((4, Kn))
        X, D0, D1, D2 = buf[0], buf[1], buf[2], buf[3]
        direction0_row(U, B0, q0, s, q1, X, D0, D1, D2, rational)  # the value only for the weight
        w01 = qw0[q0] * qw1[q1]
        base = (j * nq1 + q1) * nq2
        for q2 in range(nq2):
            o = q2 * m
            u0, u1, u2 = D0[o], D0[o + 1], D0[o + 2]
            v0, v1, v2 = D1[o], D1[o + 1], D1[o + 2]
            w0, w1, w2 = D2[o], D2[o + 1], D2[o + 2]
            if rational:  # x = H / w: dx = (dH - x dw) / w
                iw = 1.0 / X[o + 3]
                x0, x1, x2 = X[o] * iw, X[o + 1] * iw, X[o + 2] * iw
                du, dv, dw = D0[o + 3], D1[o + 3], D2[o + 3]
                u0, u1, u2 = (u0 - x0 * du) * iw, (u1 - x1 * du) * iw, (u2 - x2 * du) * iw
                v0, v1, v2 = (v0 - x0 * dv) * iw, (v1 - x1 * dv) * iw, (v2 - x2 * dv) * iw
                w0, w1, w2 = (w0 - x0 * dw) * iw, (w1 - x1 * dw) * iw, (w2 - x2 * dw) * iw
            _metric_point(u0, u1, u2, v0, v1, v2, w0, w1, w2, iso, k00, k11, k22, k01, k02, k12, fval,
                          w01 * qw2[q2], base + q2, C, L, det)


@njit(cache=True, parallel=True, error_model="numpy")
def elastic_metric(Du, Dv, Dw, lam, mu, w, start, G, LM, det):
    """The elastic kernels' fields at the M = P n points of a slab of P patches (n points each, C order).

    Du, Dv, Dw (M, 3): dx/du, dx/dv, dx/dw; lam, mu (M,): the Lame parameters
    (Pa); w (M,) the quadrature weights.  Point j of patch p gives, at grid
    position start + j of the fields (9, P, N) and (2, P, N):
    ``G[3 r + k, p] = c_r[k]`` (c_1 = x_v x x_w, c_2 = x_w x x_u, c_3 = x_u x x_v,
    the rows of det J * J^-1) and ``LM[:, p] = (lambda, mu) w / |det J|``;
    det (M,) gets det J (a zero determinant gives non-finite LM, which the
    caller reports via ``det``).
    """
    n = Du.shape[0] // G.shape[1]
    for k in prange(Du.shape[0]):
        p = k // n
        j = start + k - p * n
        u0, u1, u2 = Du[k, 0], Du[k, 1], Du[k, 2]
        v0, v1, v2 = Dv[k, 0], Dv[k, 1], Dv[k, 2]
        w0, w1, w2 = Dw[k, 0], Dw[k, 1], Dw[k, 2]
        a0, a1, a2 = v1 * w2 - v2 * w1, v2 * w0 - v0 * w2, v0 * w1 - v1 * w0
        b0, b1, b2 = w1 * u2 - w2 * u1, w2 * u0 - w0 * u2, w0 * u1 - w1 * u0
        e0, e1, e2 = u1 * v2 - u2 * v1, u2 * v0 - u0 * v2, u0 * v1 - u1 * v0
        dt = u0 * a0 + u1 * a1 + u2 * a2
        det[k] = dt
        fac = w[k] / abs(dt)
        G[0, p, j], G[1, p, j], G[2, p, j] = a0, a1, a2
        G[3, p, j], G[4, p, j], G[5, p, j] = b0, b1, b2
        G[6, p, j], G[7, p, j], G[8, p, j] = e0, e1, e2
        LM[0, p, j] = lam[k] * fac
        LM[1, p, j] = mu[k] * fac


@njit(cache=True, parallel=True, fastmath=True)
def elastic_block_fields(G, LM, a, b, start, F):
    """The parametric coefficient fields of block (a, b) of linear elasticity on a slab into F: on a diagonal
    block the six symmetric C_rs = (lf + mf) c_r[a] c_s[a] + mf c_r . c_s in the pair order (0,0), (1,1),
    (2,2), (0,1), (0,2), (1,2) (F (6, P, n)), off it the nine F_rs = lf c_r[a] c_s[b] + mf c_r[b] c_s[a] at
    index 3 r + s (F (9, P, n)), for the n grid points from ``start`` on.  G (9, P, N): the metric rows,
    ``G[3 r + k] = c_r[k]``; LM (2, P, N): lf = lambda w / |det J| and mf = mu w / |det J|
    (:mod:`iga.elasticity.forms`), on the whole grid (N points per patch, C order).  Straight-line code per
    point over contiguous runs: it vectorises."""
    P, n = F.shape[1], F.shape[2]
    chunk = 512
    for item in prange(P * ((n + chunk - 1) // chunk)):
        pi = item % P
        lo = (item // P) * chunk
        for q in range(lo, min(lo + chunk, n)):
            g = start + q
            lf, mf = LM[0, pi, g], LM[1, pi, g]
            c00, c01, c02 = G[0, pi, g], G[1, pi, g], G[2, pi, g]
            c10, c11, c12 = G[3, pi, g], G[4, pi, g], G[5, pi, g]
            c20, c21, c22 = G[6, pi, g], G[7, pi, g], G[8, pi, g]
            if a == b:
                ca0, ca1, ca2 = G[a, pi, g], G[3 + a, pi, g], G[6 + a, pi, g]  # c_r[a], r = 0, 1, 2
                lm = lf + mf
                F[0, pi, q] = lm * ca0 * ca0 + mf * (c00 * c00 + c01 * c01 + c02 * c02)
                F[1, pi, q] = lm * ca1 * ca1 + mf * (c10 * c10 + c11 * c11 + c12 * c12)
                F[2, pi, q] = lm * ca2 * ca2 + mf * (c20 * c20 + c21 * c21 + c22 * c22)
                F[3, pi, q] = lm * ca0 * ca1 + mf * (c00 * c10 + c01 * c11 + c02 * c12)
                F[4, pi, q] = lm * ca0 * ca2 + mf * (c00 * c20 + c01 * c21 + c02 * c22)
                F[5, pi, q] = lm * ca1 * ca2 + mf * (c10 * c20 + c11 * c21 + c12 * c22)
            else:
                for r in range(3):
                    ra, rb = G[3 * r + a, pi, g], G[3 * r + b, pi, g]
                    for s in range(3):
                        F[3 * r + s, pi, q] = lf * ra * G[3 * s + b, pi, g] + mf * rb * G[3 * s + a, pi, g]
