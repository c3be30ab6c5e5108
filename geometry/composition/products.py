"""Exact products of spline functions (Bezier and B-spline form).

The product of two B-splines of degrees p and q on the same domain is a
B-spline of degree p + q whose continuity at each breakpoint is the smaller of
the two factors' continuities (Morken 1991).  We compute it element by element
in Bernstein form (exact bilinear map), then return to the B-spline space with
the left inverse of its Bezier extraction (exact because the piecewise product
lies in that space).  Rational factors multiply numerators and weights.
"""

from __future__ import annotations

import numpy as np

from geometry import bernstein
from geometry import knots as kn
from geometry.errors import SplineError
from geometry.spline import SplineFunction
from geometry.tolerances import ROUNDOFF

__all__ = ["multiply", "product_knots", "from_bezier_elements", "common_refinement"]


def product_knots(Uf, p, Ug, q) -> np.ndarray:
    """Knot vector of the product space of degree p + q."""
    vf, mf = kn.breakpoints(Uf)
    vg, mg = kn.breakpoints(Ug)
    vals = np.union1d(vf, vg)
    big = 10 ** 6
    cf = np.array([p - mf[vf == v][0] if np.any(vf == v) else big for v in vals])
    cg = np.array([q - mg[vg == v][0] if np.any(vg == v) else big for v in vals])
    mult = (p + q) - np.minimum(cf, cg)
    mult[0] = mult[-1] = p + q + 1
    return np.repeat(vals, np.clip(mult, 1, p + q + 1))


def common_refinement(f: SplineFunction, breaks) -> SplineFunction:
    """Insert (once) every breakpoint of ``breaks[k]`` that ``f`` lacks, per direction."""
    for k in range(f.dim):
        missing = np.setdiff1d(breaks[k], f.breakpoints(k))
        if len(missing):
            f, _ = f.insert_knots(k, missing)
    return f


def from_bezier_elements(elements: np.ndarray, knots, degrees) -> np.ndarray:
    """B-spline coefficients from per-element Bernstein coefficients.

    ``elements``: (ne_1, ..., ne_d, p_1+1, ..., p_d+1, m), consistent with the
    continuity encoded in ``knots`` -> coefficients (n_1, ..., n_d, m).
    """
    d = len(degrees)
    ne = elements.shape[:d]
    # interleave to (ne_1, p_1+1, ne_2, p_2+1, ...) then flatten each pair
    perm = [x for k in range(d) for x in (k, d + k)] + [2 * d]
    arr = np.transpose(elements, perm)
    arr = arr.reshape(tuple(ne[k] * (degrees[k] + 1) for k in range(d)) + (elements.shape[-1],))
    for k in range(d):
        arr = kn.apply_along(arr, k, kn.bezier_to_bspline(np.asarray(knots[k]), degrees[k]))
    return arr



def multiply(f: SplineFunction, g: SplineFunction) -> SplineFunction:
    """Exact product ``f * g`` as a :class:`SplineFunction`.

    Components broadcast: scalar x scalar, scalar x vector (either side), or
    vector x vector component-wise.  Both factors must share the parametric
    dimension and domain.
    """
    if f.dim != g.dim:
        raise SplineError(f"cannot multiply a {f.dim}-variate spline by a {g.dim}-variate one")
    if not np.allclose(f.domain, g.domain, rtol=0, atol=ROUNDOFF):
        raise SplineError(f"factors must share the parameter domain: {f.domain.tolist()} vs {g.domain.tolist()}")
    mf, mg = f.n_components, g.n_components
    if not (mf == 1 or mg == 1 or mf == mg):
        raise SplineError(f"cannot multiply {mf} components by {mg}; use a scalar factor or equal counts")
    d = f.dim
    breaks = [np.union1d(f.breakpoints(k), g.breakpoints(k)) for k in range(d)]
    fr, gr = common_refinement(f, breaks), common_refinement(g, breaks)
    Pf, _ = fr.bezier_patches(homogeneous=True)
    Pg, _ = gr.bezier_patches(homogeneous=True)
    Pf, Pg = np.moveaxis(Pf, -1, 0), np.moveaxis(Pg, -1, 0)  # (comp, ne..., p+1...)
    # a polynomial factor has weight 1, written at its own degree so that the
    # weight product has degree p + q like the numerators
    Af, wf = (Pf[:-1], Pf[-1:]) if f.is_rational else (Pf, np.ones_like(Pf[:1]))
    Ag, wg = (Pg[:-1], Pg[-1:]) if g.is_rational else (Pg, np.ones_like(Pg[:1]))
    num = bernstein.multiply(Af, Ag, d)
    rational = f.is_rational or g.is_rational
    parts = [num]
    if rational:
        parts.append(bernstein.multiply(wf, wg, d))
    prod = np.moveaxis(np.concatenate(parts, axis=0), 0, -1)
    degrees = [p + q for p, q in zip(f.degrees, g.degrees)]
    knots = [product_knots(f.knots[k], f.degrees[k], g.knots[k], g.degrees[k]) for k in range(d)]
    coefs = from_bezier_elements(prod, knots, degrees)
    return SplineFunction._from_hom(degrees, knots, coefs, rational)
