"""Tensor-product B-spline / NURBS functions of parametric dimension 1, 2 or 3.

:class:`SplineFunction` is the generic kernel: ``m`` components, polynomial or
rational.  Coefficients are stored in *homogeneous* form (``w * P`` followed by
``w`` for rational splines), so that every refinement, elevation, extraction,
restriction and product is one linear map applied along one axis, acting on
coordinates, channels and weights at once.

:class:`geometry.BSpline` (in ``bspline.py``) specialises it to the public
layout "3 coordinates + named channels".
"""

from __future__ import annotations


import numpy as np
import scipy.sparse as sp

from . import knots as kn
from .evaluation import SplineEvaluation
from .errors import SplineError
from .faces import FACE_NAMES
from .errors import show
from .numbers import is_integer


def _read_only(U) -> np.ndarray:
    """A float knot vector that nothing can write into: ``U`` itself when it already is one, else a copy."""
    U = np.asarray(U, float)
    if U.flags.writeable:
        U = U.copy()
        U.setflags(write=False)
    return U


class SplineFunction(SplineEvaluation):
    """A tensor-product B-spline function ``R^d -> R^m`` (d = 1, 2, 3).

    Parameters
    ----------
    degrees : sequence of int, one per parametric direction (each >= 1)
    knots : sequence of 1-D arrays, one open (clamped) knot vector per direction
    coefficients : array (n_1, ..., n_d, m)
    weights : optional array (n_1, ..., n_d) of positive weights (NURBS)
    """

    def __init__(self, degrees, knots, coefficients, weights=None):
        coefficients = self._as_array(coefficients, "control points")
        if coefficients.ndim < 2:
            raise SplineError(
                f"control points must have shape (n_1, ..., n_d, components), got {coefficients.shape}"
            )
        d = coefficients.ndim - 1
        degs = list(degrees) if isinstance(degrees, (list, tuple, np.ndarray)) else [degrees]
        if not all(is_integer(p) for p in degs):
            raise SplineError(f"degrees must be integers, one per parametric direction, got {show(degrees)}")
        degrees = tuple(int(p) for p in degs)
        if d not in (1, 2, 3):
            raise SplineError(f"parametric dimension must be 1, 2 or 3, got control-point array of shape {coefficients.shape}")
        if len(degrees) != d:
            raise SplineError(
                f"{len(degrees)} degrees given but control points of shape {coefficients.shape} describe "
                f"a {d}-variate spline; give one degree per parametric direction"
            )
        if knots is None or len(knots) != d:
            raise SplineError(f"need {d} knot vectors (one per direction), got {0 if knots is None else len(knots)}")
        bad = ~np.isfinite(coefficients)
        if bad.any():
            idx = tuple(int(i) for i in np.argwhere(bad)[0])
            raise SplineError(f"control point {idx[:-1]} component {idx[-1]} is not finite ({show(coefficients[idx])})")
        self.degrees = degrees
        self.knots = tuple(
            kn.validate_knots(U, p, n, k) for k, (U, p, n) in enumerate(zip(knots, degrees, coefficients.shape[:-1]))
        )
        for U in self.knots:
            U.setflags(write=False)
        if weights is None:
            self._hom = coefficients.copy()
            self.weights = None
        else:
            w = self._as_array(weights, "weights")
            if w.shape != coefficients.shape[:-1]:
                raise SplineError(f"weights must have shape {coefficients.shape[:-1]}, got {w.shape}")
            badw = ~(np.isfinite(w) & (w > 0))
            if badw.any():
                idx = tuple(int(i) for i in np.argwhere(badw)[0])
                raise SplineError(f"weight at {idx} must be finite and positive, got {show(w[idx])}")
            self._hom = np.concatenate([coefficients * w[..., None], w[..., None]], axis=-1)
            self.weights = w.copy()
            self.weights.setflags(write=False)
        self._hom.setflags(write=False)
        self._coefs = coefficients.copy()
        self._coefs.setflags(write=False)
        self._evaluator = None

    # ------------------------------------------------------------------ basics
    @staticmethod
    def _as_array(a, what):
        try:
            complex_ = np.iscomplexobj(a)
            out = None if complex_ else np.array(a, dtype=float)
        except (TypeError, ValueError) as exc:
            if "inhomogeneous" in str(exc):
                raise SplineError(f"{what} must form one rectangular array: some rows have a different length "
                                  "(give every control point 3 coordinates plus one value per channel)") from None
            raise SplineError(f"{what} must be a numeric array ({exc})") from None
        if complex_:
            raise SplineError(f"{what} must be real numbers, got complex values")
        return out

    @classmethod
    def _from_hom(cls, degrees, knots, hom, rational, **extra):
        """Build from homogeneous coefficients (internal, after a linear map)."""
        hom = np.asarray(hom, float)
        if not rational:
            return cls(degrees, knots, hom, None, **extra)
        w = hom[..., -1]
        out = cls(degrees, knots, hom[..., :-1] / w[..., None], w, **extra)
        # keep the homogeneous coefficients bit-exact (no divide/multiply round trip)
        out._hom = hom.copy()
        out._hom.setflags(write=False)
        return out

    @classmethod
    def _trusted(cls, degrees, knots, hom, rational, **extra):
        """Build from homogeneous coefficients computed by this package (internal; no validation).

        For results of exact operations on validated splines (e.g. thousands of
        composed tiles): the knot vectors must already be valid (a writable one
        is kept as a read-only copy, a read-only one as it is) and ``hom``
        finite with positive weights.
        """
        obj = cls.__new__(cls)
        for key, value in extra.items():
            setattr(obj, key, tuple(value) if key == "channels" else value)
        obj.degrees = tuple(int(p) for p in degrees)
        obj.knots = tuple(_read_only(U) for U in knots)
        hom = np.array(hom, dtype=float)  # own copy
        hom.setflags(write=False)
        obj._hom = hom
        if rational:
            w = hom[..., -1]
            obj.weights = w
            obj._coefs = hom[..., :-1] / w[..., None]
            obj._coefs.setflags(write=False)
        else:
            obj.weights = None
            obj._coefs = hom
        obj._evaluator = None
        return obj

    def _extra(self) -> dict:
        """Constructor keywords a derived copy must keep (overridden by BSpline)."""
        return {}

    def _new(self, degrees, knots, hom):
        return type(self)._from_hom(degrees, knots, hom, self.is_rational, **self._extra())

    @property
    def coefficients(self) -> np.ndarray:
        """Cartesian (de-homogenised) coefficients, shape (n_1, ..., n_d, m)."""
        return self._coefs

    @property
    def homogeneous(self) -> np.ndarray:
        """Homogeneous coefficients: ``coefficients`` or ``[w * P, w]`` if rational."""
        return self._hom

    @property
    def dim(self) -> int:
        """Parametric dimension d."""
        return len(self.degrees)

    @property
    def shape(self) -> tuple[int, ...]:
        """Number of coefficients per direction."""
        return self._coefs.shape[:-1]

    @property
    def n_components(self) -> int:
        """Number of components m (coordinates and channels; the weight not counted)."""
        return self._coefs.shape[-1]

    @property
    def is_rational(self) -> bool:
        """Whether the spline has weights (NURBS)."""
        return self.weights is not None

    @property
    def domain(self) -> np.ndarray:
        """Parameter domain, shape (d, 2)."""
        return np.array([[U[0], U[-1]] for U in self.knots])

    def breakpoints(self, direction: int) -> np.ndarray:
        """Distinct knot values along ``direction`` (the element boundaries)."""
        return np.unique(self.knots[direction])

    @property
    def n_elements(self) -> tuple[int, ...]:
        """Number of non-empty knot spans per direction."""
        return tuple(len(self.breakpoints(k)) - 1 for k in range(self.dim))

    def _check_direction(self, direction) -> int:
        if not is_integer(direction) or not 0 <= direction < self.dim:
            raise SplineError(f"direction must be an integer in 0..{self.dim - 1}, got {show(direction)}")
        return int(direction)

    # ------------------------------------------------------------ refinement
    def insert_knots(self, direction: int, values):
        """Insert knots (repeats allowed) along ``direction``.

        Returns ``(new_spline, R)`` with ``R`` a sparse (n_new, n_old) matrix:
        new homogeneous coefficients = R @ old ones along that direction.
        """
        k = self._check_direction(direction)
        U, R = kn.insertion_matrix(self.knots[k], self.degrees[k], values)
        knots = list(self.knots)
        knots[k] = U
        return self._new(self.degrees, knots, kn.apply_along(self._hom, k, R)), R

    def refine(self, times: int = 1, directions=None):
        """Bisect every knot span ``times`` times in the given directions (default all).

        Returns ``(new_spline, [R_0, ..., R_{d-1}])`` (identity where unrefined).
        """
        if not is_integer(times) or times < 0:
            raise SplineError(f"refinement times must be a non-negative integer, got {show(times)}")
        directions = range(self.dim) if directions is None else [self._check_direction(k) for k in directions]
        out = self
        Rs = [None] * self.dim

        for k in range(self.dim):
            Rk = sp.identity(self.shape[k], format="csr")
            if k in directions:
                for _ in range(int(times)):
                    b = out.breakpoints(k)
                    out, R = out.insert_knots(k, 0.5 * (b[:-1] + b[1:]))
                    Rk = R @ Rk
            Rs[k] = sp.csr_array(Rk)
        return out, Rs

    def elevate(self, direction: int, times: int = 1):
        """Raise the degree along ``direction`` by ``times`` (continuity kept); exact."""
        k = self._check_direction(direction)
        if not is_integer(times) or times < 0:
            raise SplineError(f"elevation times must be a non-negative integer, got {show(times)}")
        U, E = kn.elevation_matrix(self.knots[k], self.degrees[k], int(times))
        knots = list(self.knots)
        knots[k] = U
        degrees = list(self.degrees)
        degrees[k] += int(times)
        return self._new(degrees, knots, kn.apply_along(self._hom, k, E))

    def elevate_to(self, degrees):
        """Elevate every direction to the given degrees (each >= current)."""
        out = self
        for k, p in enumerate(degrees):
            if p < out.degrees[k]:
                raise SplineError(f"cannot elevate direction {k} from degree {out.degrees[k]} down to {p}")
            out = out.elevate(k, p - out.degrees[k])
        return out

    # -------------------------------------------------------- Bezier extraction
    def extraction_operators(self, direction: int):
        """Per-element Bezier extraction operators along ``direction``.

        Returns ``(C, first)``: ``C`` (ne, p+1, p+1), ``first`` (ne,) so that
        element ``e``'s Bernstein coefficients are ``C[e] @ coefs[first[e]:first[e]+p+1]``.
        """
        k = self._check_direction(direction)
        return kn.extraction_operators(self.knots[k], self.degrees[k])

    def bezier_patches(self, homogeneous: bool = False):
        """All Bezier elements as one array.

        Returns ``(patches, boxes)``: ``patches`` of shape
        (ne_1, ..., ne_d, p_1+1, ..., p_d+1, m) (or m+1 homogeneous components
        when ``homogeneous``), ``boxes`` of shape (ne_1, ..., ne_d, d, 2) with
        each element's parameter box.
        """
        arr = self._hom
        d = self.dim
        for k in range(d):
            C, first = self.extraction_operators(k)
            # gather each element's local coefficients, then apply its operator C[e];
            # after k steps the array carries 2k (element, local) axes in front
            idx = first[:, None] + np.arange(C.shape[1])  # (ne, p+1)
            arr = _apply_local(np.take(arr, idx, axis=2 * k), C, 2 * k)
        # arr axes: (ne_1, p_1+1, ne_2, p_2+1, ..., m) -> (ne_1..ne_d, p_1+1.., m)
        perm = [2 * k for k in range(d)] + [2 * k + 1 for k in range(d)] + [2 * d]
        patches = np.transpose(arr, perm)
        if not homogeneous and self.is_rational:
            patches = patches[..., :-1] / patches[..., -1:]
        elems = [np.stack([b[:-1], b[1:]], 1) for b in (self.breakpoints(k) for k in range(d))]
        grids = np.meshgrid(*[np.arange(len(e)) for e in elems], indexing="ij")
        boxes = np.stack([elems[k][grids[k]] for k in range(d)], axis=-2)
        return patches, boxes

    # ------------------------------------------------------ sub-patches, maps
    def split(self, direction: int, t: float):
        """Split at parameter ``t`` along ``direction`` into two splines (left, right)."""
        k = self._check_direction(direction)
        lo, hi = self.knots[k][0], self.knots[k][-1]
        if not lo < t < hi:
            raise SplineError(f"split parameter {show(t)} must lie strictly inside [{lo}, {hi}] (direction {k})")
        box = self.domain.copy()
        left_box, right_box = box.copy(), box.copy()
        left_box[k, 1] = t
        right_box[k, 0] = t
        return self.extract(left_box), self.extract(right_box)

    def extract(self, box):
        """Exact sub-patch on the parameter box ``[[a_1, b_1], ..., [a_d, b_d]]``."""
        box = np.asarray(box, float)
        if box.shape != (self.dim, 2):
            raise SplineError(f"box must have shape ({self.dim}, 2), got {box.shape}")
        hom = self._hom
        knots = list(self.knots)
        for k in range(self.dim):
            a, b = box[k]
            if (a, b) == (knots[k][0], knots[k][-1]):
                continue
            try:
                U, S = kn.restriction(knots[k], self.degrees[k], a, b)
            except SplineError as exc:
                raise SplineError(f"direction {k}: {exc}") from None
            knots[k] = U
            hom = kn.apply_along(hom, k, S)
        return self._new(self.degrees, knots, hom)

    def reverse(self, direction: int):
        """Reverse the parameter along ``direction`` (same image, opposite orientation)."""
        k = self._check_direction(direction)
        U = self.knots[k]
        knots = list(self.knots)
        knots[k] = (U[0] + U[-1]) - U[::-1]
        return self._new(self.degrees, knots, np.flip(self._hom, axis=k))

    def permute(self, order):
        """Reorder the parametric directions (``order`` is a permutation of range(d))."""
        order = [int(o) for o in order]
        if sorted(order) != list(range(self.dim)):
            raise SplineError(f"{order} is not a permutation of the {self.dim} directions")
        hom = np.transpose(self._hom, order + [self.dim])
        return self._new([self.degrees[o] for o in order], [self.knots[o] for o in order], hom)

    def swap(self, d1: int, d2: int):
        """Exchange two parametric directions."""
        order = list(range(self.dim))
        order[self._check_direction(d1)], order[self._check_direction(d2)] = d2, d1
        return self.permute(order)

    def reparametrize(self, domain):
        """Affinely map the knot vectors onto ``domain`` (d, 2); the image is unchanged."""
        domain = np.asarray(domain, float).reshape(self.dim, 2)
        knots = []
        for U, (a, b) in zip(self.knots, domain):
            if not b > a:
                raise SplineError(f"new domain interval [{a}, {b}] is empty")
            knots.append(a + (U - U[0]) * (b - a) / (U[-1] - U[0]))
        return self._new(self.degrees, knots, self._hom)

    def boundary(self, name: str):
        """Boundary face (trivariate -> surface, surface -> curve) as a spline, keeping components."""
        names = FACE_NAMES[: 2 * self.dim]
        if name not in names or self.dim == 1:
            raise SplineError(
                f"unknown boundary {show(name)} for a {self.dim}-variate spline; use one of {list(names)}"
                if self.dim > 1
                else "a curve's boundary is two points; evaluate the curve at its domain ends instead"
            )
        k, side = divmod(names.index(name), 2)
        hom = np.take(self._hom, -1 if side else 0, axis=k)
        degrees = [p for i, p in enumerate(self.degrees) if i != k]
        knots = [U for i, U in enumerate(self.knots) if i != k]
        return self._new(degrees, knots, hom)

    def __repr__(self) -> str:
        kind = "NURBS" if self.is_rational else "B-spline"
        return (
            f"{type(self).__name__}({kind}, dim={self.dim}, degrees={self.degrees}, "
            f"shape={self.shape}, components={self.n_components})"
        )


def _apply_local(loc: np.ndarray, C: np.ndarray, axis: int) -> np.ndarray:
    """Apply per-element operators ``C[e]`` along the local axis ``axis + 1`` of ``loc``.

    ``loc`` has the element axis at ``axis`` and the local (p+1) axis right after.
    """
    moved = np.moveaxis(loc, (axis, axis + 1), (0, 1))  # (ne, p+1, ...)
    ne, p1 = moved.shape[:2]
    flat = moved.reshape(ne, p1, -1)
    out = np.matmul(C, flat).reshape(moved.shape)
    return np.moveaxis(out, (0, 1), (axis, axis + 1))
