"""The Bernstein core of exact composition (Elber 2017, Eqs. 4-7; Massarwi et al. 2018, Eq. 3).

On one Bezier piece of the outer map with parameter box ``[lo, hi]`` and
degrees ``(n_1, ..., n_D)``, the inner spline's first ``D`` coordinates,
normalised ``s = (t - lo) / (hi - lo)``, are polynomials (or rational
functions ``X / W``) of the inner parameters, and

    D(s) = sum_I Q_I prod_k C(n_k, i_k) X_k^{i_k} (W - X_k)^{n_k - i_k} / W^{n_k}

is again a (rational) polynomial of degree ``(n_1 + ... + n_D) * m`` per
inner direction (Elber 2017, Eq. 7), computed with exact Bernstein products
(:func:`geometry.bernstein.multiply`), batched over the inner spline's Bezier
elements and over placements.
"""

from __future__ import annotations

from math import comb

import numpy as np

from geometry import bernstein as bz
from geometry import knots as kn
from geometry.bspline import BSpline
from geometry.composition.products import from_bezier_elements

__all__ = ["compose_batch", "inner_bezier"]


def _bernstein_factors(X, W, n, ndim):
    """``[C(n,k) X^k (W - X)^(n-k)]_k`` in Bernstein form (degree n*m), batched.

    ``X``, ``W``: (B, m_1+1, ...), homogeneous numerator and weight of one
    normalised coordinate.  Powers are computed once and reused for every k.
    """
    xcache, ycache = {}, {}
    Y = W - X
    out = []
    for k in range(n + 1):
        if k == 0:
            f = bz.power(Y, n, ndim, ycache)
        elif k == n:
            f = bz.power(X, n, ndim, xcache)
        else:
            f = bz.multiply(bz.power(X, k, ndim, xcache), bz.power(Y, n - k, ndim, ycache), ndim)
        out.append(comb(n, k) * f)
    return out


def _compose_pieces(Q, S, W, ndim):
    """Compose outer Bezier pieces with a batch of inner Bernstein pieces.

    Q: (G, n_1+1, ..., n_D+1, Co) homogeneous outer coefficients (weights last if rational), one piece per
       group of B / G consecutive batch rows (a placement's inner elements share its outer piece).
    S: list of D arrays (B, m_1+1, ...): homogeneous numerators X_k of the
       normalised inner coordinates.
    W: (B, m_1+1, ...) inner weight (ones for a polynomial inner).
    Returns (B, Co, P_1+1, ...) Bernstein coefficients of
    ``sum_I Q_I prod_k b_{k, i_k}`` with ``b_{k,i} = C(n_k, i) X_k^i (W - X_k)^(n_k - i)``.

    The products ``H_I`` of the factors of all but the last outer direction
    are formed once and shared by every component (coordinates, channels,
    weight); they do not depend on the outer piece, so placements in
    different pieces share them (only the contraction with Q is per piece).
    The last direction is summed by de Casteljau's pyramid on the contracted
    polynomials, with all components as matrix rows: a third of the
    multiplications of one product per index by the full-degree factors for
    a trivariate tile (in NumPy the pyramid measured no faster, its products
    being memory-bound; with the compiled product, 1.5x faster:
    docs/performance.md).
    """
    D = Q.ndim - 2
    degs = Q.shape[1 : D + 1]
    G = Q.shape[0]
    factors = [_bernstein_factors(S[k], W, degs[k] - 1, ndim) for k in range(D - 1)]
    H = factors[0]
    for k in range(1, D - 1):
        H = [bz.multiply(h, f, ndim) for h in H for f in factors[k]]
    H = np.stack(H, axis=1)  # (B, prod(n_1+1 .. n_{D-1}+1), bern...)
    bern = H.shape[2:]
    H = H.reshape(G, -1, H.shape[1], int(np.prod(bern)))  # (G, B / G, I, bern flat)
    Qt = np.moveaxis(Q.reshape(G, -1, degs[-1], Q.shape[-1]), 1, -1)  # (G, n_D + 1, Co, I)
    # the contraction with each placement's piece: b_k = sum_I Q_Ik H_I, (B, Co, bern...) per index k of
    # the last direction (one batched matmul each)
    b = [np.matmul(Qt[:, None, k], H).reshape((-1, Q.shape[-1]) + bern) for k in range(degs[-1])]
    # the last direction by de Casteljau's pyramid: b_k <- (W - X) b_k + X b_(k+1) leaves
    # sum_k C(n, k) X^k (W - X)^(n - k) b_k; n (n + 1) products by factors of the inner degree only,
    # against n + 1 by the factors of degree n m (a third of the multiplications at n = 3, m = 2)
    X = S[-1][:, None]
    Y = W[:, None] - X
    while len(b) > 1:
        b = [bz.multiply(b[k], Y, ndim) + bz.multiply(b[k + 1], X, ndim) for k in range(len(b) - 1)]
    return b[0]


def inner_bezier(inner: BSpline):
    """Inner Bezier elements (E, m_1+1, ..., C_hom) and their per-direction element counts."""
    patches, _ = inner.bezier_patches(homogeneous=True)
    d = inner.dim
    ne = patches.shape[:d]
    return patches.reshape((-1,) + patches.shape[d:]), ne


def _result_knots(inner: BSpline, degrees):
    """Result knot vectors: inner breakpoints, continuity of the inner kept."""
    out = []
    for k in range(inner.dim):
        vals, mults = kn.breakpoints(inner.knots[k])
        m = inner.degrees[k]
        P = degrees[k]
        cont = m - mults
        new = P - cont
        new[0] = new[-1] = P + 1
        out.append(np.repeat(vals, np.clip(new, 1, P + 1)))
    return out


def compose_batch(outer_piece_hom, outer_rational, lo, hi, inner: BSpline, A, b, inner_bezier):
    """Compose ``inner`` placed by ``p -> A p + b`` into the outer Bezier piece of each placement.

    ``outer_piece_hom``: (B, n_1+1, ..., n_D+1, Co) the homogeneous outer piece of each placement, ``lo``,
    ``hi`` (B, D) its parameter box; ``A``: (B, D, 3), ``b``: (B, D) placements already restricted to the
    outer's D parameter directions; ``inner_bezier`` = :func:`inner_bezier` of ``inner``.  Returns
    (degrees, knots, list of B homogeneous coefficient arrays, rational).
    """
    d = inner.dim
    E, ne = inner_bezier  # (E, m+1..., Ch)
    n_ch_in = len(inner.channels)
    rin = inner.is_rational
    if rin:
        Xh, Wi = E[..., :3], E[..., -1]
        Ci = E[..., 3:-1]
    else:
        Xh, Wi = E[..., :3], np.ones(E.shape[:-1])
        Ci = E[..., 3:]
    h = hi - lo
    # normalised homogeneous coordinates per (placement, element): (B, E, m+1...)
    Ascaled = A / h[:, :, None]
    bscaled = (b - lo) / h
    S = np.einsum("bkj,e...j->bke...", Ascaled, Xh) + bscaled[:, :, None].reshape(bscaled.shape + (1,) * (d + 1)) * Wi[None, None]
    Bn = S.shape[0]
    flatS = [S[:, k].reshape((Bn * S.shape[2],) + S.shape[3:]) for k in range(S.shape[1])]
    Wb = np.broadcast_to(Wi[None], (Bn,) + Wi.shape).reshape((-1,) + Wi.shape[1:])
    res = _compose_pieces(outer_piece_hom, flatS, Wb, d)  # (B*E, Co, P+1...)
    ntot = sum(s - 1 for s in outer_piece_hom.shape[1:-1])  # >= 2: outer degrees are >= 1
    comps = [res]  # a rational outer map's weight is already res's last component
    if rin and not outer_rational:
        comps.append(bz.power(Wb, ntot, d, {})[:, None])  # denominator W^ntot
    if n_ch_in:
        Cb = np.broadcast_to(Ci[None], (Bn,) + Ci.shape).reshape((-1,) + Ci.shape[1:])
        Cb = np.moveaxis(Cb, -1, 1)  # (B*E, c, m+1...)
        if outer_rational:
            # carried channel needs the result denominator: numerators * W, channel * N_w
            num = res[:, :-1]
            Nw = res[:, -1:]
            if rin:
                num = bz.multiply(num, Wb[:, None], d)
                Nw2 = bz.multiply(Nw, Wb[:, None], d)
                ch = bz.multiply(Cb, Nw, d)  # (W c) * N_w, degree (ntot+1) m
            else:
                num = bz.elevate(num, list(inner.degrees), d)
                Nw2 = bz.elevate(Nw, list(inner.degrees), d)
                ch = bz.multiply(Cb, Nw, d)
            comps = [num, ch, Nw2]
        else:
            if rin:  # (W c) * W^(ntot-1) over W^ntot
                ch = bz.multiply(Cb, bz.power(Wb, ntot - 1, d, {})[:, None], d)
            else:
                ch = bz.elevate(Cb, [(ntot - 1) * m for m in inner.degrees], d)
            comps = [res, ch] + comps[1:]
    hom = np.concatenate(comps, axis=1)  # (B*E, Ctot, P+1...)
    rational = outer_rational or rin
    bern_shape = hom.shape[2:]
    hom = np.moveaxis(hom, 1, -1).reshape((Bn,) + tuple(ne) + bern_shape + (hom.shape[1],))
    degrees = tuple(s - 1 for s in hom.shape[1 + d : 1 + 2 * d])
    knots = _result_knots(inner, degrees)
    if np.prod(ne) > 1:  # all placements at once: their coefficients side by side as extra components
        C = hom.shape[-1]
        side = np.moveaxis(hom, 0, -2).reshape(hom.shape[1:-1] + (Bn * C,))
        arr = from_bezier_elements(side, knots, degrees)
        coefs = list(np.moveaxis(arr.reshape(arr.shape[:-1] + (Bn, C)), -2, 0))
    else:
        coefs = [hom[i].reshape(hom.shape[1 + d :]) for i in range(Bn)]
    return degrees, knots, coefs, rational


