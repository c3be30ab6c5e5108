"""Evaluation of tensor-product splines: values, derivatives, Jacobians, tensor grids.

:class:`SplineEvaluation` is the evaluation half of
:class:`geometry.SplineFunction` (which holds the data and the exact
structural operations).  Scattered points go to SciPy's ``NdBSpline`` on the
homogeneous coefficients, or for many points of a trivariate to the compiled
kernel of :mod:`geometry.compiled._fast` (values and first derivatives in one pass);
rational derivatives follow from the Leibniz rule (quotient rule).  Tensor
grids use one sparse basis matrix per direction (sum factorisation).
Parameters are checked: outside the domain (beyond a relative 1e-12) or
non-finite points raise :class:`SplineError` naming them.
"""

from __future__ import annotations

from itertools import product as iproduct
from math import comb

import numpy as np
from scipy.interpolate import NdBSpline

from geometry.compiled import _fast
from . import knots as kn
from .errors import SplineError
from .tolerances import ON_DOMAIN, ROUNDOFF

__all__ = ["SplineEvaluation"]


class SplineEvaluation:
    """Evaluation methods; the subclass provides degrees, knots, ``_hom``, ``dim``, ``domain``, ``is_rational``."""

    def _check_params(self, params) -> np.ndarray:
        x = np.asarray(params, dtype=float)
        if x.ndim == 1 and self.dim == 1:
            x = x[:, None]
        if x.ndim == 1 and x.shape[0] == self.dim:
            x = x[None, :]
        if x.ndim != 2 or x.shape[1] != self.dim:
            raise SplineError(f"parameters must have shape (N, {self.dim}), got {np.shape(params)}")
        dom = self.domain
        if len(x):
            lo, hi = x.min(axis=0), x.max(axis=0)  # two passes decide the common case (NaN propagates)
            if np.all(np.isfinite(lo) & np.isfinite(hi)) and np.all(lo >= dom[:, 0]) and np.all(hi <= dom[:, 1]):
                return x
        if not np.all(np.isfinite(x)):
            raise SplineError("parameters contain non-finite values")
        tol = ON_DOMAIN * (dom[:, 1] - dom[:, 0]) + ROUNDOFF
        out = np.any((x < dom[:, 0] - tol) | (x > dom[:, 1] + tol), axis=1)
        if out.any():
            bad = x[out][:3]
            raise SplineError(
                f"{int(out.sum())} parameter point(s) lie outside the domain {dom.tolist()}, e.g. {bad.tolist()}"
            )
        return np.clip(x, dom[:, 0], dom[:, 1])

    def _ev(self):
        if self._evaluator is None:
            self._evaluator = NdBSpline(self.knots, self._hom, self.degrees, extrapolate=False)
        return self._evaluator

    def _hom_eval(self, x, orders) -> np.ndarray:
        orders = tuple(int(o) for o in orders)
        if any(o > p for o, p in zip(orders, self.degrees)):
            return np.zeros((len(x), self._hom.shape[-1]))
        if len(x) == 0:
            return np.zeros((0, self._hom.shape[-1]))
        return self._ev()(x, nu=orders)

    def evaluate(self, params, compiled: bool | None = None) -> np.ndarray:
        """Values at parameter points ``params`` (N, d) -> (N, m).

        ``compiled``: None uses the compiled kernel for many points (numba, when
        installed); False keeps to SciPy (no numba import: about 90 MB less
        memory, for callers that evaluate a few hundred thousand points once).
        """
        h = None
        # compiled kernel for many points; it checks the domain itself and declines on any bad point
        if compiled is not False and _fast.applies(self.dim, np.shape(params)[0] if np.ndim(params) else 0):
            h = _fast.evaluate(self.knots, self.degrees, self._hom, np.asarray(params, dtype=float))
        if h is None:
            x = self._check_params(params)
            h = _fast.evaluate(self.knots, self.degrees, self._hom, x) if compiled is not False else None
            if h is None:
                h = self._hom_eval(x, (0,) * self.dim)
        if self.is_rational:
            return h[:, :-1] / h[:, -1:]
        return h

    __call__ = evaluate

    def derivative(self, params, orders) -> np.ndarray:
        """Partial derivative of the given ``orders`` (one int per direction), (N, m)."""
        orders = tuple(int(o) for o in np.atleast_1d(orders))
        if len(orders) != self.dim or min(orders) < 0:
            raise SplineError(f"orders must be {self.dim} non-negative integers, got {orders}")
        x = self._check_params(params)
        return self._derivs(x, [orders])[orders]

    def derivatives(self, params, max_order: int = 1) -> dict:
        """All partial derivatives of total order <= ``max_order``: {orders: (N, m)}."""
        x = self._check_params(params)
        alphas = [a for a in iproduct(range(max_order + 1), repeat=self.dim) if sum(a) <= max_order]
        return self._derivs(x, alphas)

    def jacobian(self, params) -> np.ndarray:
        """Matrix of first derivatives, shape (N, m, d)."""
        return self._value_jacobian(params, values=False)[1]

    def value_and_jacobian(self, params) -> tuple[np.ndarray, np.ndarray]:
        """Values (N, m) and the matrix of first derivatives (N, m, d) at ``params`` (N, d)."""
        return self._value_jacobian(params, values=True)

    def _value_jacobian(self, params, values: bool, checked: bool = False, compiled: bool | None = None):
        """``checked``: ``params`` is already a float (N, d) array inside the domain (an inner loop that clips
        its own iterates, :func:`geometry.maps.inversion.invert`): the 35 us of checks per call are skipped.
        ``compiled``: None takes the compiled kernel for many points; True for any number (a caller that runs
        compiled kernels anyway, so the import is paid); False never."""
        S, dS = self.value_and_derivatives(params, values, checked, compiled)
        return S, np.stack(dS, axis=-1)

    def value_and_derivatives(self, params, values: bool = True, checked: bool = False,
                              compiled: bool | None = None, columns: int | None = None
                              ) -> tuple[np.ndarray | None, list[np.ndarray]]:
        """Values (N, m) (None unless ``values``) and the first derivatives [d/dxi_k (N, m)] * d at ``params``
        (N, d), each derivative its own contiguous array (a chain rule then combines them column by column,
        without a (N, m, d) Jacobian).  ``checked``: ``params`` is a float (N, d) array already inside the
        domain (no checks); ``compiled``: None takes the compiled kernel for many points, True for any number,
        False never; ``columns``: the derivatives of the first ``columns`` components only (N, columns) (a
        map's geometry without its channels)."""
        x = params if checked else self._check_params(params)
        # compiled kernel for many points: values and first derivatives in one pass (3x SciPy's four passes)
        out = None if compiled is False else _fast.evaluate(self.knots, self.degrees, self._hom, x, derivs=True,
                                                            min_points=1 if compiled else _fast.MIN_POINTS)
        if out is not None:
            H, dH = out[0], list(out[1:])
            if not self.is_rational:
                return H, [d[:, :columns] for d in dH]
            w = H[:, -1:]  # S = A / w: dS = (dA - S dw) / w
            S = H[:, :-1] / w
            c = S.shape[1] if columns is None else columns
            return S, [(d[:, :c] - S[:, :c] * d[:, -1:]) / w for d in dH]
        zero = (0,) * self.dim
        eye = [tuple(int(i == k) for i in range(self.dim)) for k in range(self.dim)]
        D = self._derivs(x, ([zero] if values else []) + eye)
        return D.get(zero), [D[a][:, :columns] for a in eye]

    def _derivs(self, x, alphas) -> dict:
        """Derivatives for the multi-indices ``alphas`` (rational: Leibniz/quotient rule)."""
        if not self.is_rational:
            return {a: self._hom_eval(x, a) for a in alphas}
        hom = {}

        def H(a):
            if a not in hom:
                hom[a] = self._hom_eval(x, a)
            return hom[a]

        S = {}

        def deriv(a):
            # S^(a) = (A^(a) - sum_{b <= a, b != a} C(a,b) w^(a-b) S^(b)) / w
            if a in S:
                return S[a]
            num = H(a)[:, :-1].copy()
            for b in iproduct(*(range(ai + 1) for ai in a)):
                if b == a:
                    continue
                c = np.prod([comb(ai, bi) for ai, bi in zip(a, b)])
                diff = tuple(ai - bi for ai, bi in zip(a, b))
                num -= c * H(diff)[:, -1:] * deriv(b)
            S[a] = num / H((0,) * self.dim)[:, -1:]
            return S[a]

        return {a: deriv(a) for a in alphas}

    def evaluate_grid(self, axes, orders=None) -> np.ndarray:
        """Values (or a polynomial spline's derivative) on the tensor grid of ``axes``.

        ``axes``: one 1-D array of parameters per direction.  Returns an array
        of shape (len(axes[0]), ..., len(axes[d-1]), m).  Uses one sparse basis
        matrix per direction (sum factorisation), far faster than scattered
        evaluation on large grids.
        """
        orders = (0,) * self.dim if orders is None else tuple(orders)
        if self.is_rational and any(orders):
            raise SplineError("evaluate_grid returns derivatives of polynomial splines only; use derivatives()")
        out = self._hom
        for k, ax in enumerate(axes):
            ax = np.asarray(ax, float)
            lo, hi = self.knots[k][0], self.knots[k][-1]
            if ax.ndim != 1 or np.any(ax < lo - ON_DOMAIN * (hi - lo)) or np.any(ax > hi + ON_DOMAIN * (hi - lo)) or not np.all(np.isfinite(ax)):
                raise SplineError(f"grid axis {k} must be 1-D values inside [{lo}, {hi}]")
            B = kn.basis_matrix(self.knots[k], self.degrees[k], np.clip(ax, lo, hi), orders[k])
            out = kn.apply_along(out, k, B)
        if self.is_rational:
            return out[..., :-1] / out[..., -1:]
        return out

