"""Exact functional composition ``outer(inner(.))`` (003 Section 2, Eqs. 4-7).

The outer map ``D`` (a curve, surface or trivariate; usually the trivariate
deformation map) is taken one Bezier piece at a time.  On a piece with
parameter box ``[lo, hi]`` and degrees ``(n_1, ..., n_D)`` the inner spline's
first ``D`` coordinates, normalised ``s = (t - lo) / (hi - lo)``, are
polynomials (or rational functions ``X / W``) of the inner parameters, and

    D(s) = sum_I Q_I prod_k C(n_k, i_k) X_k^{i_k} (W - X_k)^{n_k - i_k} / W^{n_k}

is again a (rational) polynomial of degree ``(n_1 + ... + n_D) * m`` per inner
direction (Eq. 7).  Everything is computed with exact Bernstein products
(:func:`geometry.bernstein.multiply`): first the powers of each normalised
coordinate, then the products ``H_I`` of all but the last outer direction,
which are shared by every outer coordinate and channel, then one product per
last-direction index.  All of it is batched over the inner spline's Bezier
elements and over placements (:func:`compose_many`).

Channels: the outer map's channels are composed like its coordinates; the
inner spline's own channels are carried along unaltered (re-expressed in the
result basis).  Result channels = outer.channels + inner.channels.

Axis-aligned boxes: when a placed inner patch is a box whose every outer
parameter is an affine function of one inner parameter (a regular paving of
box-shaped tile patches), ``outer(inner)`` is the outer map restricted to a
sub-box.  It is computed by blossoming (no products) and keeps the outer
degrees, permuted to the inner parameter order: exact, and far lower than
Eq. (7).  Patches with channels or weights of their own take the general path.

Degrees: Eq. (7) of 003 for polynomial and rational input alike.  One
exception, forced by the mathematics: a *rational* outer map with an inner
spline that carries its own channels needs one extra factor ``W`` (or one
extra inner degree ``m``) so that the carried channel shares the result's
denominator; the result degree is then ``(n_1 + ... + n_D + 1) * m``.
"""

from __future__ import annotations

from math import comb

import numpy as np

from . import bernstein as bz
from . import knots as kn
from .bspline import BSpline
from .errors import SplineError
from .products import from_bezier_elements

__all__ = ["compose", "compose_many", "map_points", "result_degrees"]


def result_degrees(outer_degrees, inner_degrees) -> tuple[int, ...]:
    """Degrees of ``outer(inner)`` by Eq. (7) of 003: ``sum(outer_degrees) * m_k``."""
    n = sum(outer_degrees)
    return tuple(n * m for m in inner_degrees)


# --------------------------------------------------------------------------- core
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
    """Compose one outer Bezier piece with a batch of inner Bernstein pieces.

    Q: (n_1+1, ..., n_D+1, Co) homogeneous outer coefficients (weights last if rational).
    S: list of D arrays (B, m_1+1, ...): homogeneous numerators X_k of the
       normalised inner coordinates.
    W: (B, m_1+1, ...) inner weight (ones for a polynomial inner).
    Returns (B, Co, P_1+1, ...) Bernstein coefficients of
    ``sum_I Q_I prod_k b_{k, i_k}`` with ``b_{k,i} = C(n_k, i) X_k^i (W - X_k)^(n_k - i)``.

    The products ``H_I`` of the factors of all but the last outer direction
    are formed once and shared by every component (coordinates, channels,
    weight); the last direction costs one product per index, with all
    components as matrix rows.  (A de Casteljau pyramid with polynomial
    arithmetic needs fewer flops but measured slower: its products are
    memory-bound.)
    """
    D = Q.ndim - 1
    degs = Q.shape[:D]
    factors = [_bernstein_factors(S[k], W, degs[k] - 1, ndim) for k in range(D)]
    H = factors[0]
    for k in range(1, D - 1):
        H = [bz.multiply(h, f, ndim) for h in H for f in factors[k]]
    H = np.stack(H, axis=1)  # (B, prod(n_1+1 .. n_{D-1}+1), bern...)
    Qr = Q.reshape(-1, degs[-1], Q.shape[-1])  # (I, n_D + 1, Co)
    out = None
    for k, fk in enumerate(factors[-1]):
        M = np.einsum("ic,bi...->bc...", Qr[:, k, :], H)  # (B, Co, bern...)
        term = bz.multiply(M, fk[:, None], ndim)
        out = term if out is None else out + term
    return out


def _inner_bezier(inner: BSpline):
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


def _compose_batch(outer_piece_hom, outer_rational, lo, hi, inner: BSpline, A, b, inner_bezier):
    """Compose ``inner`` placed by ``p -> A p + b`` into one outer Bezier piece.

    ``A``: (B, D, 3), ``b``: (B, D) placements already restricted to the
    outer's D parameter directions; ``inner_bezier`` = :func:`_inner_bezier`
    of ``inner``.  Returns (degrees, knots, list of B homogeneous coefficient
    arrays, rational).
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
    Ascaled = A / h[None, :, None]
    bscaled = (b - lo[None, :]) / h[None, :]
    S = np.einsum("bkj,e...j->bke...", Ascaled, Xh) + bscaled[:, :, None].reshape(bscaled.shape + (1,) * (d + 1)) * Wi[None, None]
    Bn = S.shape[0]
    flatS = [S[:, k].reshape((Bn * S.shape[2],) + S.shape[3:]) for k in range(S.shape[1])]
    Wb = np.broadcast_to(Wi[None], (Bn,) + Wi.shape).reshape((-1,) + Wi.shape[1:])
    res = _compose_pieces(outer_piece_hom, flatS, Wb, d)  # (B*E, Co, P+1...)
    ntot = sum(s - 1 for s in outer_piece_hom.shape[:-1])  # >= 2: outer degrees are >= 1
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
    coefs = [from_bezier_elements(hom[i], knots, degrees) for i in range(Bn)] if np.prod(ne) > 1 else [
        hom[i].reshape(hom.shape[1 + d :]) for i in range(Bn)
    ]
    return degrees, knots, coefs, rational


def _outer_pieces(outer: BSpline):
    """Outer Bezier pieces (homogeneous) and breakpoints per direction."""
    patches, boxes = outer.bezier_patches(homogeneous=True)
    return patches, [outer.breakpoints(k) for k in range(outer.dim)]


def _locate(boxlo, boxhi, breaks, tol):
    """Span index per direction for parameter boxes, or -1 where a box crosses a knot line."""
    idx = []
    for k, bp in enumerate(breaks):
        i_lo = np.searchsorted(bp, boxlo[:, k] + tol[k], side="right") - 1
        i_hi = np.searchsorted(bp, boxhi[:, k] - tol[k], side="left") - 1
        i_lo = np.clip(i_lo, 0, len(bp) - 2)
        i_hi = np.clip(i_hi, 0, len(bp) - 2)
        idx.append(np.where(i_lo == i_hi, i_lo, -1))
    return np.stack(idx, axis=1)


def _check_pair(outer, inner):
    if not isinstance(outer, BSpline) or not isinstance(inner, BSpline):
        raise SplineError("compose() takes two geometry.BSpline objects")
    if outer.dim not in (2, 3):
        raise SplineError(f"the outer map must be a surface or a trivariate, got a {outer.dim}-variate spline")
    if outer.dim == 2 and inner.dim == 3:
        raise SplineError("a trivariate cannot be composed into a surface; use a trivariate outer map")
    clash = set(outer.channels) & set(inner.channels)
    if clash:
        raise SplineError(f"outer and inner both define channel(s) {sorted(clash)}; rename one of them")


def _finish(outer, inner, degrees, knots, hom, rational):
    # exact result of validated inputs: skip re-validation (it dominated large pavings)
    knots = [kn.validate_knots(U, p, n, k) for k, (U, p, n) in enumerate(zip(knots, degrees, hom.shape[:-1]))]
    return BSpline._trusted(degrees, knots, hom, rational, channels=outer.channels + inner.channels)


def compose_many(outer: BSpline, inner: BSpline, placements, name: str = "inner") -> list[BSpline]:
    """Compose ``inner`` placed by each affine map into ``outer``, exactly.

    Parameters
    ----------
    outer : trivariate (or surface) BSpline, the deformation map D.
    inner : BSpline whose coordinates live in the unit cube (the tile patch).
    placements : array (P, 3, 4): ``[A | b]`` mapping tile coordinates ``p``
        to outer parameters ``A p + b`` (only the first ``outer.dim`` rows are
        used for a surface outer map).

    Every placed patch must lie inside one knot span of ``outer`` (pave per
    span); otherwise :class:`SplineError` names the placement and knot line.
    Placements falling into the same Bezier piece of ``outer`` are composed in
    one vectorised batch.
    """
    _check_pair(outer, inner)
    P = np.asarray(placements, float)
    if P.ndim != 3 or P.shape[1:] != (3, 4) or not np.all(np.isfinite(P)):
        raise SplineError(f"placements must be a finite array of shape (P, 3, 4), got {P.shape}")
    Do = outer.dim
    A, b = P[:, :Do, :3], P[:, :Do, 3]
    pts = inner.points.reshape(-1, 3)
    placed = np.einsum("pkj,nj->pnk", A, pts) + b[:, None, :]
    lo, hi = placed.min(axis=1), placed.max(axis=1)
    dom = outer.domain
    span = dom[:, 1] - dom[:, 0]
    tol = 1e-10 * span
    outside = np.any((lo < dom[:, 0] - tol) | (hi > dom[:, 1] + tol), axis=1)
    if outside.any():
        i = int(np.argmax(outside))
        raise SplineError(
            f"{name} placement {i} reaches parameters {lo[i].tolist()}..{hi[i].tolist()} outside the outer "
            f"domain {dom.tolist()}; scale the placements into the domain"
        )
    patches, breaks = _outer_pieces(outer)
    where = _locate(lo, hi, breaks, tol)
    crossing = np.any(where < 0, axis=1)
    if crossing.any():
        i = int(np.argmax(crossing))
        k = int(np.argmax(where[i] < 0))
        bp = breaks[k]
        line = bp[(bp > lo[i, k] + tol[k]) & (bp < hi[i, k] - tol[k])][0]
        raise SplineError(
            f"{name} placement {i} crosses the outer map's knot line {'uvw'[k]} = {line:g} "
            f"(its control points span {lo[i, k]:g}..{hi[i, k]:g}); pave per knot span so no tile crosses a knot line"
            + (" or use compose() which splits curves" if inner.dim == 1 else "")
        )
    results = [None] * len(P)
    keys = np.ravel_multi_index(where.T, tuple(len(bp) - 1 for bp in breaks))
    perm, alpha, beta = _axis_aligned(inner, placed, Do)
    for key in np.unique(keys[perm[:, 0] >= 0]):  # boxes: the outer map restricted, no products
        e = np.unravel_index(key, tuple(len(bp) - 1 for bp in breaks))
        elo = np.array([breaks[k][e[k]] for k in range(Do)])
        ehi = np.array([breaks[k][e[k] + 1] for k in range(Do)])
        sel = np.nonzero((keys == key) & (perm[:, 0] >= 0))[0]
        for sigma in np.unique(perm[sel], axis=0):
            sub = sel[np.all(perm[sel] == sigma, axis=1)]
            for i, spline in zip(sub, _restrict_batch(outer, patches[e], elo, ehi, inner, sigma, alpha[sub],
                                                         beta[sub])):
                results[i] = spline
    todo = np.nonzero(perm[:, 0] < 0)[0]
    if not len(todo):
        return results
    keys_all = keys
    keys = np.full(len(P), -1)
    keys[todo] = keys_all[todo]
    inner_bezier = _inner_bezier(inner)
    # Work in chunks of placements whose result coefficients fill about 1 MiB:
    # the batched products are memory-bound, and cache-sized chunks measured
    # 1.6x faster than one big batch (benchmarks/composition.py).
    size = np.prod([sum(outer.degrees) * m + 1 for m in inner.degrees]) * inner_bezier[0].shape[0]
    chunk = int(np.clip((1 << 20) // (8 * outer.homogeneous.shape[-1] * size), 1, 256))
    for key in np.unique(keys[todo]):  # one batch per occupied outer Bezier piece
        sel_all = np.nonzero(keys == key)[0]
        e = np.unravel_index(key, tuple(len(bp) - 1 for bp in breaks))
        Q = patches[e]
        elo = np.array([breaks[k][e[k]] for k in range(Do)])
        ehi = np.array([breaks[k][e[k] + 1] for k in range(Do)])
        for c0 in range(0, len(sel_all), chunk):
            sel = sel_all[c0 : c0 + chunk]
            degrees, knots, coefs, rational = _compose_batch(
                Q, outer.is_rational, elo, ehi, inner, A[sel], b[sel], inner_bezier
            )
            for j, i in enumerate(sel):
                results[i] = _finish(outer, inner, degrees, knots, coefs[j], rational)
    return results


def _axis_aligned(inner: BSpline, placed: np.ndarray, Do: int):
    """Which placed inner patches are axis-aligned boxes in the outer parameters.

    A placed patch qualifies when each outer parameter k is an affine function
    ``alpha_k + beta_k xi_j`` of a single inner parameter j = sigma[k] (its
    control points are then alpha + beta * Greville abscissae), the inner spline
    is polynomial, has no channels and ``inner.dim == Do``.  Returns sigma
    (P, Do) (-1 rows where not aligned), alpha and beta (P, Do).
    """
    nP = placed.shape[0]
    perm = np.full((nP, Do), -1)
    alpha = np.zeros((nP, Do))
    beta = np.zeros((nP, Do))
    if inner.dim != Do or inner.is_rational or inner.channels:
        return perm, alpha, beta
    shape = inner.shape
    idx = np.indices(shape).reshape(inner.dim, -1)
    Y = placed  # (P, n, Do)
    scale = np.abs(Y).max(axis=1).max(axis=1) + 1.0
    match = np.zeros((nP, Do, inner.dim), bool)
    fits = {}
    for j in range(inner.dim):
        g = kn.greville(inner.knots[j], inner.degrees[j])
        last = np.ravel_multi_index(tuple(shape[k] - 1 if k == j else 0 for k in range(inner.dim)), shape)
        bj = (Y[:, last] - Y[:, 0]) / (g[-1] - g[0])  # (P, Do)
        aj = Y[:, 0] - bj * g[0]
        pred = aj[:, None, :] + bj[:, None, :] * g[idx[j]][None, :, None]
        ok = np.abs(Y - pred).max(axis=1) <= 1e-13 * scale[:, None]
        match[:, :, j] = ok & (np.abs(bj) > 1e-12 * scale[:, None])
        fits[j] = (aj, bj)
    unique = match.sum(axis=2) == 1
    sigma = np.argmax(match, axis=2)
    good = np.all(unique, axis=1) & np.array([len(set(r)) == Do for r in sigma])
    perm[good] = sigma[good]
    for k in range(Do):
        for j in range(inner.dim):
            rows = good & (sigma[:, k] == j)
            alpha[rows, k] = fits[j][0][rows, k]
            beta[rows, k] = fits[j][1][rows, k]
    return perm, alpha, beta


def _restrict_batch(outer, Q, elo, ehi, inner, sigma, alpha, beta):
    """Outer Bezier piece ``Q`` restricted to the boxes ``alpha + beta * inner domain`` (exact).

    outer(alpha_k + beta_k xi_sigma[k]) has the outer degrees, so the result is
    the piece re-expanded on each sub-box (blossoming), axes permuted to the
    inner parameter order.  Returns one BSpline per placement.
    """
    Do = len(sigma)
    dom = inner.domain
    h = ehi - elo
    R = np.broadcast_to(Q[None], (len(alpha),) + Q.shape)  # (B, n_1+1, ..., C)
    for k in range(Do):
        a, b = dom[sigma[k]]
        t0 = (alpha[:, k] + beta[:, k] * a - elo[k]) / h[k]
        t1 = (alpha[:, k] + beta[:, k] * b - elo[k]) / h[k]
        M = bz.subinterval_matrices(Q.shape[k] - 1, t0, t1)  # (B, n+1, n+1)
        X = np.moveaxis(R, k + 1, 1)
        Y = np.matmul(M, X.reshape(X.shape[0], X.shape[1], -1)).reshape(X.shape)  # batched BLAS
        R = np.moveaxis(Y, 1, k + 1)
    inv = np.argsort(sigma)  # result axis j <- outer axis inv[j]
    R = np.transpose(R, (0,) + tuple(1 + int(k) for k in inv) + (Do + 1,))
    degrees = tuple(Q.shape[int(k)] - 1 for k in inv)
    knots = [np.repeat(dom[j], p + 1) for j, p in enumerate(degrees)]
    return [_finish(outer, inner, degrees, knots, np.ascontiguousarray(r), outer.is_rational) for r in R]


def _affine_identity():
    """The identity placement (1, 3, 4): inner coordinates are the outer parameters."""
    M = np.zeros((1, 3, 4))
    M[0, :3, :3] = np.eye(3)
    return M


def compose(outer: BSpline, inner: BSpline) -> BSpline:
    """Exact composition ``outer(inner(.))``.

    ``inner``'s first ``outer.dim`` coordinates are parameters of ``outer``.
    Curves, surfaces and trivariates go into a trivariate; curves and surfaces
    into a surface (using the inner x, y).  A curve crossing knot lines of a
    B-spline outer map is split at the crossings and the composed pieces are
    joined into one B-spline (C0 at the joints); a surface or trivariate that
    crosses a knot line raises :class:`SplineError`.
    """
    _check_pair(outer, inner)
    try:
        return compose_many(outer, inner, _affine_identity())[0]
    except SplineError as exc:
        if inner.dim != 1 or "crosses the outer map's knot line" not in str(exc):
            raise
    return _compose_curve_split(outer, inner)


def _crossings(curve: BSpline, k: int, value: float) -> np.ndarray:
    """Curve parameters where coordinate ``k`` equals ``value`` (roots per Bezier segment)."""
    patches, boxes = curve.bezier_patches(homogeneous=True)
    roots = []
    for e in range(patches.shape[0]):  # per curve segment (few), roots of a small polynomial
        a, t0, t1 = patches[e], boxes[e, 0, 0], boxes[e, 0, 1]
        p = a.shape[0] - 1
        num = a[:, k] - value * (a[:, -1] if curve.is_rational else 1.0)
        # Bernstein -> power basis in the local variable s
        pw = np.zeros(p + 1)
        for i in range(p + 1):
            for j in range(i, p + 1):
                pw[j] += num[i] * comb(p, i) * comb(p - i, j - i) * (-1) ** (j - i)
        r = np.roots(pw[::-1]) if np.any(pw[1:]) else np.array([])
        r = r[np.abs(r.imag) < 1e-9].real
        r = r[(r > 1e-12) & (r < 1 - 1e-12)]
        roots += list(t0 + r * (t1 - t0))
    return np.array(roots)


def _compose_curve_split(outer: BSpline, curve: BSpline) -> BSpline:
    breaks = [outer.breakpoints(k) for k in range(outer.dim)]
    params = []
    for k in range(outer.dim):
        for v in breaks[k][1:-1]:
            params += list(_crossings(curve, k, v))
    lo, hi = curve.domain[0]
    cuts = np.unique(np.round(np.asarray(params, float), 14))
    cuts = cuts[(cuts > lo) & (cuts < hi)]
    edges = np.r_[lo, cuts, hi]
    pieces = [curve.extract([[a, b]]) for a, b in zip(edges[:-1], edges[1:])]
    composed = []
    for i, piece in enumerate(pieces):
        try:
            composed.append(compose_many(outer, piece, _affine_identity(), name=f"curve piece {i}")[0])
        except SplineError as exc:
            raise SplineError(f"curve piece {i} on [{edges[i]:g}, {edges[i + 1]:g}] still crosses a knot line: {exc}") from None
    P = max(c.degrees[0] for c in composed)
    composed = [c.elevate(0, P - c.degrees[0]) for c in composed]
    rational = any(c.is_rational for c in composed)
    homs, knots = [], [np.full(P + 1, lo)]
    for i, c in enumerate(composed):
        h = c.homogeneous if (c.is_rational or not rational) else np.concatenate([c.homogeneous, np.ones((c.shape[0], 1))], 1)
        homs.append(h if i == 0 else h[1:])
        inner_knots = c.knots[0][P + 1 : -P - 1]
        a, b = edges[i], edges[i + 1]
        knots.append(a + (inner_knots - c.knots[0][0]) * (b - a) / (c.knots[0][-1] - c.knots[0][0]))
        knots.append(np.full(P, b) if i < len(composed) - 1 else np.full(P + 1, hi))
    if rational:
        # scale each piece's homogeneous coefficients so the shared joint has one weight
        scaled = [homs[0]]
        for i in range(1, len(homs)):
            prev_w = scaled[-1][-1, -1]
            first = composed[i].homogeneous[0] if composed[i].is_rational else np.r_[composed[i].control_points[0], 1.0]
            scaled.append(homs[i] * (prev_w / first[-1]))
        homs = scaled
    hom = np.concatenate(homs, axis=0)
    U = np.concatenate(knots)
    return BSpline._from_hom((P,), [U], hom, rational, channels=composed[0].channels)


def map_points(outer: BSpline, points) -> np.ndarray:
    """Approximate mode for polygonal tiles (003 Eq. 3): map vertices through ``outer``.

    ``points``: (N, 3) tile vertices already placed in ``outer``'s parameter
    domain (or (N, 2) for a surface outer map).  Returns (N, 3 + channels) mapped
    vertices.  Unlike :func:`compose` this is *not* exact between vertices:
    edges and faces of the polygons stay straight in Euclidean space and
    continuity is not preserved; refine the mesh to reduce the error.
    """
    pts = np.asarray(points, float)
    if pts.ndim != 2 or pts.shape[1] < outer.dim:
        raise SplineError(f"points must have shape (N, {outer.dim}) or (N, 3), got {pts.shape}")
    return outer.evaluate(pts[:, : outer.dim])
