"""Coefficients of the heat problem: numbers, channel names, callables, and conductivity tensors.

A scalar coefficient (source W/m^3, flux W/m^2, film coefficient W/(m^2 K),
temperature) is a number, the name of a channel carried by every patch (a
tile's or the deformation map's), or a callable ``c(x) -> (N,)`` of physical
points x (N, 3).  The conductivity (W/(m K)) is a scalar coefficient
(isotropic) or a symmetric positive definite tensor: a constant 3 x 3 matrix,
six channel names in the order (xx, yy, zz, xy, xz, yz), or a callable
returning (N, 3, 3).  Tensors are stored as (N, 6) components in that order,
the pair order of the stiffness kernels.
"""

from __future__ import annotations

import inspect

import numpy as np
from scipy.interpolate import PchipInterpolator

from geometry.numbers import TINY, is_real

from iga.errors import ProblemError
from iga.expressions import Expression
from geometry.errors import show
from geometry.tolerances import ON_DOMAIN

__all__ = ["ScalarField", "Conductivity", "is_number", "TENSOR_PAIRS", "tensor_matrix", "takes_time", "at_time"]

#: component order of symmetric tensors and of the six stiffness coefficient fields
TENSOR_PAIRS = ((0, 0), (1, 1), (2, 2), (0, 1), (0, 2), (1, 2))


def is_number(v) -> bool:
    """A real number (bool excluded: ``True`` is not a temperature): :func:`geometry.numbers.is_real`."""
    return is_real(v)


def tensor_matrix(K6: np.ndarray) -> np.ndarray:
    """(N, 6) symmetric tensor components -> (N, 3, 3) matrices."""
    K = np.empty(K6.shape[:-1] + (3, 3))
    for j, (r, s) in enumerate(TENSOR_PAIRS):
        K[..., r, s] = K6[..., j]
        K[..., s, r] = K6[..., j]
    return K


def _check_channels(names, model, what):
    for i, p in enumerate(model.patches):
        missing = [c for c in names if c not in p.channels]
        if missing:
            raise ProblemError(
                f"{what} refers to channel {show(missing[0])}, but patch {i} only has channels {list(p.channels)}; "
                "add the channel to the tile or the deformation map"
            )


class ScalarField:
    """A number, a channel name or a callable ``c(x (N, 3)) -> (N,)``; checked at construction.

    ``positive``: values must be > 0 (conductivity, film coefficients).
    ``channels``: whether a channel name is accepted (needs ``model``).
    """

    def __init__(self, spec, what: str, positive: bool = False, model=None, channels: bool = True):
        self.what, self.positive = what, positive
        if is_number(spec):
            if not np.isfinite(spec) or (positive and spec <= 0):
                raise ProblemError(f"{what} must be a finite{' positive' if positive else ''} number, got {show(spec)}")
            self.spec, self.kind = float(spec), "number"
        elif isinstance(spec, str) and channels and model is not None:
            _check_channels([spec], model, what)
            self.spec, self.kind = spec, "channel"
        elif callable(spec):
            self.spec, self.kind = spec, "callable"
        else:
            allowed = "a number, a channel name or a callable of x (N, 3)" if channels else \
                "a number or a callable of x (N, 3)"
            raise ProblemError(f"{what} must be {allowed}, got {show(spec)} ({type(spec).__name__})")

    @property
    def constant(self) -> float | None:
        """The value when the field is a number, else None."""
        return self.spec if self.kind == "number" else None

    def values(self, x: np.ndarray, chans: dict, where: str) -> np.ndarray:
        """Values (N,) at physical points x (N, 3) with channel values ``chans`` {name: (N,)}."""
        n = len(x)
        if self.kind == "number":
            v = np.full(n, self.spec)
        elif self.kind == "channel":
            v = np.asarray(chans[self.spec], float)
        else:
            v = _call(self.spec, x, self.what, where)
            if v.shape == ():
                v = np.full(n, float(v))
            if v.shape != (n,):
                raise ProblemError(f"{self.what} callable must return shape ({n},) for x of shape ({n}, 3), got {v.shape}")
        if not np.all(np.isfinite(v)):
            raise ProblemError(f"{self.what} is not finite at some points of {where}")
        if self.positive and np.any(v <= 0):
            i = int(np.argmin(v))
            raise ProblemError(f"{self.what} must be positive, but is {v[i]:g} at x = {np.round(x[i], 6).tolist()} "
                               f"on {where}")
        return v


def user_values(fn, x: np.ndarray, tail: tuple, what: str, where: str, constant: bool = False) -> np.ndarray:
    """A user's callable at the points x (N, 3) as an (N,) + ``tail`` float array: one that fails, returns another
    shape or values that are not finite raises :class:`ProblemError` naming ``what`` and ``where`` (a
    ProblemError of its own, e.g. from an :class:`iga.Expression`, passes as it is).  ``constant``: a number
    returned stands for every point."""
    try:
        v = np.asarray(fn(x), float)
    except ProblemError:
        raise
    except Exception as exc:  # the user's callable: say whose and where
        raise ProblemError(f"{what} failed on {where}: {type(exc).__name__}: {exc}") from None
    shape = (len(x),) + tuple(tail)
    if constant and v.ndim == 0:
        v = np.full(shape, float(v))
    if v.shape != shape:
        raise ProblemError(f"{what} must return shape {shape} for x of shape {x.shape}, got {v.shape}")
    if not np.all(np.isfinite(v)):
        bad = np.argmax(~np.isfinite(v.reshape(len(x), -1)).any(axis=1))
        raise ProblemError(f"{what} returned values that are not finite on {where}, e.g. at x = "
                           f"{np.round(x[bad], 6).tolist()}")
    return v


def _call(fn, x, what, where) -> np.ndarray:
    try:
        return np.asarray(fn(x), float)
    except Exception as exc:  # a user callable failed: say which input
        raise ProblemError(f"{what} callable failed on {where}: {exc}") from exc


def _check_spd(K6: np.ndarray, x: np.ndarray, where: str) -> None:
    """Raise unless every tensor (N, 6) is finite, symmetric positive definite (Sylvester's criterion)."""
    if not np.all(np.isfinite(K6)):
        raise ProblemError(f"conductivity tensor is not finite at some points of {where}")
    k00, k11, k22, k01, k02, k12 = K6.T
    m2 = k00 * k11 - k01 * k01
    det = k00 * (k11 * k22 - k12 * k12) - k01 * (k01 * k22 - k12 * k02) + k02 * (k01 * k12 - k11 * k02)
    bad = (k00 <= 0) | (m2 <= 0) | (det <= 0)
    if bad.any():
        i = int(np.argmax(bad))
        at = f" at x = {np.round(x[i], 6).tolist()}" if len(x) else ""
        raise ProblemError(f"conductivity tensor must be symmetric positive definite, but "
                           f"{np.round(tensor_matrix(K6[i]), 6).tolist()}{at} on {where} is not")


class Conductivity:
    """Isotropic (a :class:`ScalarField`) or anisotropic (a symmetric positive definite tensor) conductivity.

    ``values`` returns (N,) for isotropic and (N, 6) for tensor conductivity.
    """

    def __init__(self, spec, model=None):
        self.tensor = False
        self.scalar = None
        self.K6 = None  # constant tensor components (6,)
        self.channels = None  # six channel names
        self.callable = None
        #: k(x (N, 3), T (N,)) -> (N,) where the conductivity depends on the temperature, else None
        self.of_temperature = None
        self.table = None  # (T, k) rows of a tabulated k(T)
        self.table_slope = None
        if takes_time(spec):  # two arguments: k(x, T)
            self.of_temperature = spec
            return
        table = _table(spec)
        if table is not None:
            self.table = table
            pchip = PchipInterpolator(table[:, 0], table[:, 1])
            self.table_slope = pchip.derivative()  # dk/dT of the interpolant, for Newton's tangent
            lo, hi = table[0, 0], table[-1, 0]

            def k_of_T(x, T, pchip=pchip):
                if np.any(T < lo) or np.any(T > hi):
                    bad = T[(T < lo) | (T > hi)][0]
                    raise ProblemError(f"the temperature reaches {bad:g}, outside the conductivity table's range "
                                       f"[{lo:g}, {hi:g}]; extend the table")
                return pchip(T)

            self.of_temperature = k_of_T
            return
        if isinstance(spec, (list, tuple)) and len(spec) == 6 and all(isinstance(c, str) for c in spec):
            _check_channels(spec, model, "conductivity")
            self.tensor, self.channels = True, tuple(spec)
            return
        if not (is_number(spec) or isinstance(spec, str) or callable(spec)):
            try:
                M = np.asarray(spec, float)
            except (TypeError, ValueError):
                M = None
            if M is None or M.shape != (3, 3):
                raise ProblemError(
                    "conductivity must be a number, a channel name, a callable of x (N, 3), a constant 3 x 3 "
                    f"symmetric positive definite matrix or six channel names (xx, yy, zz, xy, xz, yz); got {show(spec)}")
            if not np.allclose(M, M.T, rtol=ON_DOMAIN, atol=0):
                raise ProblemError(f"conductivity matrix must be symmetric, got {M.tolist()}")
            K6 = np.array([M[r, s] for r, s in TENSOR_PAIRS])
            _check_spd(K6[None], np.zeros((0, 3)), "the model")
            self.tensor, self.K6 = True, K6
            return
        if callable(spec) and not isinstance(spec, (str, Expression)):
            self.callable = spec  # scalar or tensor, decided by what it returns (a formula is a scalar)
            return
        self.scalar = ScalarField(spec, "conductivity", positive=True, model=model)

    def at_temperature(self, x: np.ndarray, T: np.ndarray, where: str, derivative: bool = False):
        """k(x, T) (N,) of a temperature-dependent conductivity, checked positive and finite; with
        ``derivative`` also dk/dT (N,): the table's interpolant's own, or a central difference of the callable
        (step 1e-6 (|T| + 1))."""
        k = _call_T(self.of_temperature, x, T, where)
        if np.any(k <= 0):
            i = int(np.argmin(k))
            raise ProblemError(f"the conductivity k(T) is {k[i]:g} (not positive) at T = {T[i]:g}, x = "
                               f"{np.round(x[i], 6).tolist()} on {where}: the temperatures reached leave the "
                               "range where k(T) is positive")
        if not derivative:
            return k
        if self.table is not None:
            return k, self.table_slope(T)
        step = 1e-6 * (np.abs(T) + 1.0)
        up, down = _call_T(self.of_temperature, x, T + step, where), _call_T(self.of_temperature, x, T - step, where)
        return k, (up - down) / (2 * step)

    @property
    def constant(self):
        """A number (isotropic) or the (6,) tensor components when constant, else None."""
        if self.K6 is not None:
            return self.K6
        return self.scalar.constant if self.scalar is not None else None

    def values(self, x: np.ndarray, chans: dict, where: str, T: np.ndarray | None = None) -> np.ndarray:
        """Conductivity at points x (N, 3): (N,) isotropic, (N, 6) tensor components (xx, yy, zz, xy, xz, yz);
        ``T`` (N,): the temperature there, which a temperature-dependent conductivity needs."""
        n = len(x)
        if self.of_temperature is not None:
            if T is None:
                raise ProblemError(f"the conductivity depends on the temperature, which is not known on {where} "
                                   "here (a linear assembly or a quantity before the solve)")
            return self.at_temperature(x, np.asarray(T, float), where)
        if self.scalar is not None:
            return self.scalar.values(x, chans, where)
        if self.K6 is not None:
            return np.broadcast_to(self.K6, (n, 6))
        if self.channels is not None:
            K6 = np.stack([np.asarray(chans[c], float) for c in self.channels], axis=1)
        else:
            v = _call(self.callable, x, "conductivity", where)
            if v.shape == (n,) or v.shape == ():
                return ScalarField(lambda _: v, "conductivity", positive=True).values(x, chans, where)
            if v.shape != (n, 3, 3):
                raise ProblemError(f"conductivity callable must return shape ({n},) or ({n}, 3, 3) for x of shape "
                                   f"({n}, 3), got {v.shape}")
            if not np.allclose(v, np.transpose(v, (0, 2, 1)), rtol=ON_DOMAIN, atol=TINY):
                raise ProblemError(f"conductivity callable returned non-symmetric tensors on {where}")
            K6 = np.stack([v[:, r, s] for r, s in TENSOR_PAIRS], axis=1)
        _check_spd(K6, x, where)
        return K6


def takes_time(fn) -> bool:
    """Whether ``fn`` is a callable of (x, t): two required positional parameters (a formula or a callable of
    x alone is not)."""
    if not callable(fn) or isinstance(fn, (str, Expression)):
        return False
    try:
        params = inspect.signature(fn).parameters.values()
    except (TypeError, ValueError):  # a builtin without a signature: a callable of x
        return False
    positional = (inspect.Parameter.POSITIONAL_ONLY, inspect.Parameter.POSITIONAL_OR_KEYWORD)
    return sum(p.kind in positional and p.default is p.empty for p in params) >= 2


def at_time(fn, t: float, what: str, model=None, positive: bool = False, channels: bool = True) -> ScalarField:
    """The scalar field x -> ``fn(x, t)`` at the time ``t`` (s), checked as any field (``what`` names it)."""
    return ScalarField(lambda x: fn(x, t), f"{what} at t = {t:g} s", positive=positive, model=model,
                       channels=channels)


def _table(spec) -> np.ndarray | None:
    """A conductivity table: rows (T, k) with increasing T and positive k, as an (n, 2) array; None when
    ``spec`` is not a table of pairs (a 3 x 3 matrix or six channel names are not)."""
    if isinstance(spec, (str, Expression)) or callable(spec) or is_number(spec):
        return None
    try:
        a = np.asarray(spec, float)
    except (TypeError, ValueError):
        return None
    if a.ndim != 2 or a.shape[1] != 2 or a.shape[0] < 2:
        return None
    if not np.all(np.isfinite(a)) or np.any(np.diff(a[:, 0]) <= 0) or np.any(a[:, 1] <= 0):
        raise ProblemError(f"a conductivity table holds rows (T, k) with strictly increasing T and positive, "
                           f"finite k; got {a.tolist()}")
    return a


def _call_T(fn, x, T, where) -> np.ndarray:
    """k = fn(x, T) as an (N,) float array, the user's failure or shape named."""
    try:
        k = np.asarray(fn(x, T), float)
    except ProblemError:
        raise
    except Exception as exc:  # the user's callable
        raise ProblemError(f"the conductivity k(x, T) failed on {where}: {type(exc).__name__}: {exc}") from None
    if k.shape == ():
        k = np.full(len(x), float(k))
    if k.shape != (len(x),) or not np.all(np.isfinite(k)):
        raise ProblemError(f"the conductivity k(x, T) must return {len(x)} finite values on {where}, got shape "
                           f"{k.shape}")
    return k
