"""NURBS analysis on patches whose geometry is their own rational spline.

Isogeometric analysis on a NURBS patch uses the NURBS basis R_i = w_i N_i / W (W = sum_j w_j N_j, the
geometry's weight function), which holds every affine field of x: the exact annulus then reproduces a linear
temperature and a free thermal expansion is stress free, to round-off.  A patch qualifies when its analysis
space is its geometry's own space refined or elevated (the spline is rational and no deformation map is
composed over it): W then lies in the analysis space, with coefficients ``w`` there.

The unknowns are the NURBS control values d (T = sum d_i w_i N_i / W, a partition of unity), and every
tensor-product table and pattern is the polynomial space's: the forms are assembled in the basis N_i / W
and scaled by w_i per basis function (:func:`nurbs_scale`).  For a form sum_rs C_rs d_r v d_s u (v, u of the
basis), with d_r (N / W) = d_r N / W - N g_r and g_r = d_r W / W^2 (parameter derivatives):

    sum_rs C_rs d_r N_i d_s N_j / W^2  +  sum_r F_r (d_r N_i N_j + N_i d_r N_j)  +  F_0 N_i N_j,
    F_r = -sum_s C_rs g_s / W,   F_0 = sum_rs C_rs g_r g_s,

first- and zero-order terms of the same sum-factorised vocabulary (:func:`iga.assembly.tensor.banded_form`); loads
and face forms take 1 / W per basis function.  Composed rational patches (a polynomial tile in a NURBS map)
keep the tile's polynomial basis: their image's weight is W_D(A T + b), and the tile's basis divided by it
does not hold the affine fields unless the tile space is elevated to the composed degree, so the
Remark 2 basis is kept there: a field affine in the map's parameters is exact, an affine field of x
converges (a free thermal expansion of a cross lattice in the exact annulus: 0.11, 0.057, 0.029 E alpha dT
of von Mises stress at refine 0, 1, 2; ``benchmarks/nurbs_quadrature.py``).
"""

from __future__ import annotations

import numpy as np

from geometry import SplineFunction
from geometry import knots as kn
from geometry.patches.chain import grid_values_derivs
from iga.assembly.terms import SYMMETRIC_PAIRS

__all__ = ["own_rational", "rational_quadrature_extra", "weight_coefficients", "weight_grid", "weight_fields",
           "rational_form", "rational_diffusion_fields", "rational_load_terms", "stiffness_half_terms",
           "rational_load", "nurbs_scale"]


def own_rational(patch) -> bool:
    """Whether the patch is analysed in the NURBS basis: a rational spline that is its own geometry."""
    return bool(patch.spline.is_rational) and getattr(patch, "outer", None) is None


def rational_quadrature_extra(spline, space) -> int:
    """Gauss points per element and direction added to p + 1 on a patch analysed in the NURBS basis on
    ``space``.  Its integrands are rational, which no Gauss rule integrates exactly, and the error falls with
    the variation of W over an element: measured on the exact quarter annulus (a linear temperature, degrees
    2 and 3), one more point per halving of delta = max over elements of (max W / min W - 1) keeps the error
    of the patch test below 1e-10 down to delta = 0.01, where p + 1 points suffice (``python
    benchmarks/nurbs_quadrature.py`` prints the table): ceil(log2(delta / 0.01)) points, at most 8."""
    ends = [np.unique(d.knots) for d in space.dirs]
    axes = [np.append((b[:-1, None] + np.diff(b)[:, None] * np.linspace(0.0, 1.0, 5)[None, :-1]).ravel(), b[-1])
            for b in ends]  # 4 intervals per element, ends shared
    W = grid_values_derivs(_weight_function(spline), axes)[0][:, 0].reshape([len(a) for a in axes])
    win = np.lib.stride_tricks.sliding_window_view(W, (5, 5, 5))[::4, ::4, ::4]
    delta = float((win.max(axis=(3, 4, 5)) / win.min(axis=(3, 4, 5))).max()) - 1.0
    if delta <= 0.01:
        return 0
    return int(min(8, np.ceil(np.log2(delta / 0.01))))


def _weight_function(spline) -> SplineFunction:
    return SplineFunction(spline.degrees, spline.knots, np.asarray(spline.weights, float)[..., None])


def weight_coefficients(spline, space) -> np.ndarray | None:
    """The coefficients (space.shape) of the spline's weight function W in the analysis ``space``, or None
    where the space does not hold W (a degree or knots below the geometry's): found by interpolation at the
    space's Greville points (exact when W lies in the space) and checked at the element midpoints."""
    Wf = _weight_function(spline)
    for d, p, U in zip(space.dirs, spline.degrees, spline.knots):
        inner = np.unique(U)[1:-1]
        if d.degree < p or not np.all(np.isin(inner, d.knots)):
            return None
    gre = [kn.greville(d.knots, d.degree) for d in space.dirs]
    vals = Wf.evaluate(np.stack(np.meshgrid(*gre, indexing="ij"), -1).reshape(-1, 3))[:, 0].reshape(space.shape)
    c = vals
    for k, (d, g) in enumerate(zip(space.dirs, gre)):
        B = kn.basis_matrix(d.knots, d.degree, g).toarray()
        c = np.moveaxis(np.tensordot(np.linalg.solve(B, np.eye(len(g))), np.moveaxis(c, k, 0), axes=(1, 0)), 0, k)
    mids = [0.5 * (np.unique(d.knots)[:-1] + np.unique(d.knots)[1:]) for d in space.dirs]
    S = SplineFunction([d.degree for d in space.dirs], [d.knots for d in space.dirs], c[..., None])
    pts = np.stack(np.meshgrid(*mids, indexing="ij"), -1).reshape(-1, 3)
    if np.abs(S.evaluate(pts)[:, 0] - Wf.evaluate(pts)[:, 0]).max() > 1e-10 * float(np.abs(vals).max()):
        return None
    return c


def weight_grid(spline, axes) -> tuple[np.ndarray, list]:
    """W (N,) and its parameter derivatives [(N,)] * 3 on the tensor grid ``axes`` (C order)."""
    H, dH = grid_values_derivs(_weight_function(spline), axes)
    return H[:, 0], [d[:, 0] for d in dH]


def weight_fields(spline, space, P: int) -> tuple[np.ndarray, list]:
    """W and its parameter derivatives on ``space``'s Gauss grid, each broadcast to (P,) + qshape for a batch of
    P patches sharing the spline: the fields :func:`rational_form` and :func:`rational_load_terms` take."""
    shape = (P,) + space.qshape
    W, dW = weight_grid(spline, space.qaxes)
    return np.broadcast_to(W.reshape(space.qshape), shape), [np.broadcast_to(v.reshape(space.qshape), shape)
                                                              for v in dW]


def _sides(variants):
    """The derivative direction on the test (i) and trial (j) side of a first-order term's orders, or None."""
    r = next((k for k, (a, _) in enumerate(variants) if a), None)
    s = next((k for k, (_, b) in enumerate(variants) if b), None)
    return r, s


def _orders(d: int, r, s) -> tuple:
    return tuple((int(k == r), int(k == s)) for k in range(d))


def rational_form(terms, W: np.ndarray, dW: list) -> list:
    """The terms [(F, orders)] of a form in the basis N (at most one first derivative per side) rewritten for
    the basis N / W (module notes), for :func:`iga.assembly.tensor.banded_form`; W and dW on the terms' Gauss grid
    (each of the terms' field shape).  Linear in the terms and commuting with the transpose, so a half form
    H (K = H + H^T) maps to the half of the rewritten form."""
    if not terms:
        return []
    d = len(terms[0][1])
    g = [x / W**2 for x in dW]
    out = []
    for F, variants in terms:
        r, s = _sides(variants)
        out.append((F / W**2, _orders(d, r, s)))
        if r is not None:
            out.append((-F * g[r] / W, _orders(d, None, s)))
        if s is not None:
            out.append((-F * g[s] / W, _orders(d, r, None)))
        if r is not None and s is not None:
            out.append((F * g[r] * g[s], _orders(d, None, None)))
    return out


def rational_diffusion_fields(C: np.ndarray, W: np.ndarray, dW) -> np.ndarray:
    """The ten fields of :data:`iga.assembly.terms.RATIONAL_DIFFUSION` from the six diffusion fields C (6, ...)
    (C_rs in :data:`iga.assembly.terms.SYMMETRIC_PAIRS` order) and W, dW (broadcasting against C[0]): C_rs / W^2,
    F_r = -sum_s C_rs g_s / W and F_0 = sum_rs C_rs g_r g_s with g_r = d_r W / W^2 (module notes).  The form
    :func:`rational_form` gives for the diffusion terms, gathered into one field per order, a first-order term
    and its transpose sharing theirs: so the form is declared symmetric and the kernel contracts half of it."""
    full = {}
    for c, (r, s) in enumerate(SYMMETRIC_PAIRS):
        full[r, s] = full[s, r] = C[c]
    g = [d / W**2 for d in dW]
    out = np.empty((10,) + np.shape(C[0]))
    out[:6] = C / W**2
    for r in range(3):
        out[6 + r] = -sum(full[r, s] * g[s] for s in range(3)) / W
    out[9] = sum(full[r, s] * g[r] * g[s] for r in range(3) for s in range(3))
    return out


def rational_load_terms(terms, W: np.ndarray, dW: list) -> list:
    """Load terms [(G, ((a_k, None),) * d)] (a value or one first derivative of the test function) rewritten
    for the basis N / W, for :func:`iga.assembly.tensor.derivative_load_form`."""
    out = []
    for G, variants in terms:
        d = len(variants)
        r = next((k for k, (a, _) in enumerate(variants) if a), None)
        out.append((G / W, tuple((int(k == r), None) for k in range(d))))
        if r is not None:
            out.append((-G * dW[r] / W**2, tuple((0, None) for _ in range(d))))
    return out


def stiffness_half_terms(C: dict, d: int = 3) -> list:
    """The half terms H (K = H + H^T) of sum_rs C_rs d_r N_i d_s N_j for symmetric C given by ``C[(r, s)]``,
    r <= s (:func:`iga.assembly.tensor.stiffness_data`'s split)."""
    return [((0.5 if r == s else 1.0) * F, _orders(d, r, s)) for (r, s), F in C.items()]


def rational_load(L: np.ndarray, W: np.ndarray) -> np.ndarray:
    """A value load's density for the basis N / W: L / W."""
    return L / W.reshape(L.shape)


def nurbs_scale(pat, w: np.ndarray) -> np.ndarray:
    """Per CSR entry of ``pat`` (a space's pattern), w_i w_j: a form in the basis N / W becomes the form in the
    NURBS basis R = w N / W, whose unknowns are the NURBS control values (R sums to one, so fluxes summed
    from reactions and the Dirichlet data keep their meaning)."""
    rows = np.repeat(np.arange(pat.n), np.diff(pat.indptr))
    return w[rows] * w[pat.indices]
