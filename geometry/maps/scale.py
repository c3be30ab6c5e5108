"""Bounds on the local scale of a map, from its first fundamental form as exact spline products.

A tile paved into the domain of a map D is stretched by D's Jacobian J: a unit
parameter length along direction ``a`` becomes ``|J a|``.  Elber 2017 (Section 4) notes that
one "can only establish bounds on the different scale factors, by computing the field of
the first fundamental form of the deforming trivariate, as spline functions, and bound
their range".  This module does exactly that, per Bezier piece:

* ``G = J^T J`` (entries ``dD/du_i . dD/du_j``) is a polynomial on every knot span,
  formed exactly in Bernstein form with products of the derivative polynomials
  (for a NURBS map, the polynomial numerator ``N = w^4 G`` over ``w^4``, both of degree
  4p, whose ratio is a convex combination of the ratios of their coefficients);
* ``G(x)`` is a convex combination of its Bernstein coefficient matrices ``G_k``, and
  the largest eigenvalue is convex (the smallest concave) on symmetric matrices, so

      min_k lambda_min(G_k)  <=  lambda(G(x))  <=  max_k lambda_max(G_k);

* the singular values of J (the scale factors) are the square roots of G's eigenvalues,
  and the stretch of parametric direction ``i`` is ``sqrt(G_ii)``, bounded by the range
  of G_ii's coefficients.

The bounds are guaranteed; they tighten as O(h^2) when each span is cut into
``subdivide``^d sub-boxes (de Casteljau restriction, exact).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from geometry import bernstein as bz
from geometry.errors import SplineError, show
from geometry.spline import SplineFunction
from geometry.numbers import is_integer
from geometry.resources import check_memory

__all__ = ["ScaleBounds", "scale_bounds"]

_CHUNK = 1 << 24  # floats of coefficient matrices formed at once (128 MiB)


@dataclass
class ScaleBounds:
    """Guaranteed bounds on how much a map stretches each box of its parameter domain.

    boxes : (K, d, 2) parameter boxes (knot spans, or the boxes asked for)
    lower, upper : (K,) lower bound of the smallest and upper bound of the largest
        singular value of the Jacobian over each box (model units per parameter unit)
    axis_lower, axis_upper : (K, d) bounds on the stretch |dD/du_i| of each parametric direction
    tiles : (K,) the placed tile of each box, when the boxes are a micro-structure's tiles
    """

    boxes: np.ndarray
    lower: np.ndarray
    upper: np.ndarray
    axis_lower: np.ndarray
    axis_upper: np.ndarray
    tiles: np.ndarray | None = None

    @property
    def distortion(self) -> np.ndarray:
        """(K,) upper bound of the ratio of the largest to the smallest scale factor on each box
        (1 for a similarity; inf where the lower bound is 0)."""
        with np.errstate(divide="ignore"):
            return np.where(self.lower > 0, self.upper / np.where(self.lower > 0, self.lower, 1.0), np.inf)

    def summary(self) -> list[str]:
        """Lines for people: the range of the scale factors and the worst boxes."""
        d = self.boxes.shape[1]
        names = "uvw"[:d]
        axis = ", ".join(f"|dD/d{n}| {lo:.4g} .. {hi:.4g}" for n, lo, hi in
                         zip(names, self.axis_lower.min(0), self.axis_upper.max(0)))
        worst = int(np.argmax(self.distortion))
        box = " x ".join(f"[{a:g}, {b:g}]" for a, b in self.boxes[worst])
        return [f"scale factors (singular values of the Jacobian) within {self.lower.min():.4g} .. "
                f"{self.upper.max():.4g} over {len(self.boxes)} boxes; {axis}",
                f"largest distortion bound {self.distortion[worst]:.3g} (largest / smallest scale) on {box}"]


def scale_bounds(D: SplineFunction, boxes=None, subdivide: int = 2) -> ScaleBounds:
    """Guaranteed bounds on the scale factors of ``D`` per knot span, or per given parameter box.

    ``D``: a curve, surface or trivariate whose first three components are
    coordinates (a :class:`BSpline`; any channels are ignored) or, for a plain
    :class:`SplineFunction`, all components.  ``boxes`` (K, d, 2): parameter
    boxes inside D's domain, e.g. the cells tiles are paved into (each is cut at
    D's knots, so a box spanning several spans is bounded exactly); default: the
    knot spans.  ``subdivide``: each piece is cut into ``subdivide``^d equal
    sub-boxes before bounding (tighter, cost ``subdivide``^d).

    >>> from geometry import primitives
    >>> sb = scale_bounds(primitives.box((2.0, 1.0, 0.5)))
    >>> float(sb.lower.min()), float(sb.upper.max()), sb.axis_upper[0].tolist()
    (0.5, 2.0, [2.0, 1.0, 0.5])
    """
    if not isinstance(D, SplineFunction):
        raise SplineError(f"scale_bounds needs a spline, got {show(D)}")
    if not is_integer(subdivide) or not 1 <= subdivide <= 16:
        raise SplineError(f"subdivide must be an integer from 1 to 16, got {show(subdivide)}")
    d = D.dim
    check_memory(float(np.prod(D.n_elements)) * np.prod(np.add(D.degrees, 1)) * (D.n_components + 1) * 8.0,
                 f"the Bezier elements of a spline with {int(np.prod(D.n_elements)):,} elements", SplineError,
                 "bound a coarser spline (fewer knots)")
    hom, el_boxes = D.bezier_patches(homogeneous=True)
    ncoord = 3 if hasattr(D, "channels") else D.n_components
    comps = list(range(ncoord)) + ([hom.shape[-1] - 1] if D.is_rational else [])
    hom = hom[..., comps].reshape((-1,) + hom.shape[d:-1] + (len(comps),))
    el_boxes = el_boxes.reshape(-1, d, 2)
    want = el_boxes if boxes is None else _check_boxes(D, boxes)
    owner, elem, sub = _pieces(el_boxes, want, subdivide, [D.breakpoints(k) for k in range(d)])
    K = len(want)
    lower, upper = np.full(K, np.inf), np.zeros(K)
    alo, ahi = np.full((K, d), np.inf), np.zeros((K, d))
    per = int(np.prod([2 * p * (2 if D.is_rational else 1) + 1 for p in D.degrees])) * d * d
    step = max(1, _CHUNK // per)
    for s in range(0, len(elem), step):
        sl = slice(s, s + step)
        lo, hi, a_lo, a_hi = _piece_bounds(hom[elem[sl]], sub[sl], d, D.is_rational)
        np.minimum.at(lower, owner[sl], lo)
        np.maximum.at(upper, owner[sl], hi)
        np.minimum.at(alo, owner[sl], a_lo)
        np.maximum.at(ahi, owner[sl], a_hi)
    return ScaleBounds(want, np.sqrt(np.maximum(lower, 0.0)), np.sqrt(upper),
                       np.sqrt(np.maximum(alo, 0.0)), np.sqrt(ahi))


def _check_boxes(D, boxes) -> np.ndarray:
    b = np.asarray(boxes, float)
    d = D.dim
    if b.ndim == 2:
        b = b[None]
    if b.ndim != 3 or b.shape[1:] != (d, 2) or not np.all(np.isfinite(b)):
        raise SplineError(f"boxes must be finite, of shape (K, {d}, 2) (low, high per direction); got shape "
                          f"{np.shape(boxes)}")
    dom = D.domain
    tol = 1e-12 * max(1.0, float(np.abs(dom).max()))
    if np.any(b[..., 1] <= b[..., 0]) or np.any(b[..., 0] < dom[:, 0] - tol) or np.any(b[..., 1] > dom[:, 1] + tol):
        raise SplineError(f"every box must have low < high and lie in the domain {dom.tolist()}")
    return b


def _pieces(el_boxes, want, subdivide, breakpoints=None):
    """(box index, element index, local sub-box (P, d, 2) in [0, 1]) for every piece of every wanted box.

    ``breakpoints``: the spline's breakpoints per direction (``el_boxes`` is their tensor grid, C order); the
    elements each box meets are found per direction, so no (boxes x elements) array is formed."""
    d = el_boxes.shape[1]
    if breakpoints is None:
        breakpoints = [np.unique(el_boxes[:, k, :]) for k in range(d)]
    ne = [len(b) - 1 for b in breakpoints]
    # element i spans [b_i, b_i+1]; a box [lo, hi] meets those with b_i+1 > lo and b_i < hi
    first = np.stack([np.clip(np.searchsorted(b, want[:, k, 0], "right") - 1, 0, n - 1)
                      for k, (b, n) in enumerate(zip(breakpoints, ne))], 1)
    last = np.stack([np.clip(np.searchsorted(b, want[:, k, 1], "left") - 1, 0, n - 1)
                     for k, (b, n) in enumerate(zip(breakpoints, ne))], 1)
    counts = np.maximum(last - first + 1, 1)
    per_box = np.prod(counts, axis=1)
    pieces = float(per_box.sum()) * subdivide ** d
    check_memory(pieces * d * 8.0 * 12, f"scale bounds of {len(want):,} boxes over {int(np.prod(ne)):,} elements "
                 f"cut into {subdivide}^{d} sub-boxes ({pieces:,.0f} pieces)", SplineError,
                 "pass fewer or smaller boxes, or a smaller subdivide")
    owner = np.repeat(np.arange(len(want)), per_box)
    j = np.arange(len(owner)) - np.repeat(np.cumsum(per_box) - per_box, per_box)
    strides = np.ones_like(counts)  # C order within each box's block of elements
    strides[:, :-1] = np.cumprod(counts[:, :0:-1], axis=1)[:, ::-1]
    multi = first[owner] + (j[:, None] // strides[owner]) % counts[owner]
    elem = np.ravel_multi_index(tuple(multi.T), ne)
    lo = np.maximum(want[owner, :, 0], el_boxes[elem, :, 0])
    hi = np.minimum(want[owner, :, 1], el_boxes[elem, :, 1])
    width = el_boxes[elem, :, 1] - el_boxes[elem, :, 0]
    t0 = (lo - el_boxes[elem, :, 0]) / width
    t1 = (hi - el_boxes[elem, :, 0]) / width
    cuts = np.stack(np.meshgrid(*[np.arange(subdivide)] * d, indexing="ij"), -1).reshape(-1, d)  # (S, d)
    f0, f1 = cuts / subdivide, (cuts + 1) / subdivide
    span = (t1 - t0)[:, None, :]
    sub = np.stack([t0[:, None, :] + f0 * span, t0[:, None, :] + f1 * span], -1)  # (P, S, d, 2)
    # the derivative's scale: a unit local step is (t1 - t0) / subdivide of the element, i.e. this parameter length
    length = (el_boxes[elem, :, 1] - el_boxes[elem, :, 0])[:, None, :] * (f1 - f0) * span
    S = len(cuts)
    sub = np.concatenate([sub, length[..., None]], -1)  # (P, S, d, 3): t0, t1, parameter length
    return np.repeat(owner, S), np.repeat(elem, S), sub.reshape(-1, d, 3)


def _restrict(a, sub, d):
    """Bernstein coefficients (P, p+1..., C) of the elements ``a`` restricted to their local boxes ``sub``."""
    for k in range(d):
        M = bz.subinterval_matrices(a.shape[1 + k] - 1, sub[:, k, 0], sub[:, k, 1])  # (P, p+1, p+1)
        a = np.moveaxis(np.einsum("pij,pj...->pi...", M, np.moveaxis(a, 1 + k, 1)), 1, 1 + k)
    return a


def _piece_bounds(a, sub, d, rational):
    """Eigenvalue bounds of G and bounds of its diagonal on each piece: four arrays (P,), (P,), (P, d), (P, d)."""
    a = np.moveaxis(_restrict(a, sub, d), -1, 1)  # (P, C, bern...)
    length = sub[:, :, 2]
    shape = (-1,) + (1,) * (a.ndim - 1)

    def deriv(f, k):  # derivative along k w.r.t. the real parameter, elevated back to full degree along k
        return bz.elevate(bz.derivative(f, k, d) / length[:, k].reshape(shape), [int(j == k) for j in range(d)], d)

    if rational:
        X, w = a[:, :-1], a[:, -1:]
        dw = [deriv(w, k) for k in range(d)]
        rows = [bz.multiply(w, deriv(X, k), d) - bz.multiply(X, dw[k], d) for k in range(d)]  # w^2 dX/du_k
    else:
        rows = [deriv(a, k) for k in range(d)]
    entries = {}
    for i in range(d):
        for j in range(i, d):
            entries[i, j] = bz.multiply(rows[i], rows[j], d).sum(axis=1)  # (P, bern...)
    G = np.empty(entries[0, 0].shape + (d, d))
    for (i, j), e in entries.items():
        G[..., i, j] = G[..., j, i] = e
    if rational:
        # N = w^4 G and w^4 share the degree 4p: N(x) / w^4(x) = sum_k B_k W_k (N_k / W_k) / sum_k B_k W_k
        # with W_k > 0 is a convex combination of the matrices N_k / W_k (the rational convex hull)
        G /= bz.power(w, 4, d)[:, 0, ..., None, None]
    G = G.reshape(len(a), -1, d, d)
    eig = np.linalg.eigvalsh(G)  # (P, B, d) ascending
    diag = np.diagonal(G, axis1=2, axis2=3)  # (P, B, d)
    return eig[..., 0].min(1), eig[..., -1].max(1), diag.min(1), diag.max(1)
