"""Cubic B-spline interpolation on knot-span nodes, restarted at C0 joints: the approximation step of
sweeps and offsets, whose errors the callers measure against their tolerances."""

from __future__ import annotations

import numpy as np

__all__ = ["span_nodes", "c0_joints", "interpolate", "evaluate"]

DEGREE = 3


def span_nodes(breaks: np.ndarray, per_span: int) -> np.ndarray:
    """``per_span`` equal steps in every knot span between ``breaks``: (per_span * spans + 1,) increasing."""
    t = np.linspace(0.0, 1.0, per_span + 1)[:-1]
    return np.r_[(breaks[:-1, None] + t[None, :] * np.diff(breaks)[:, None]).ravel(), breaks[-1]]


def c0_joints(U: np.ndarray, p: int) -> np.ndarray:
    """Interior knots of multiplicity >= ``p`` in the knot vector ``U`` of degree ``p`` (C0 in the parameter:
    the speed may jump there, e.g. where curves were joined end to start, or a composed curve was split)."""
    b, counts = np.unique(U[p + 1:-(p + 1)], return_counts=True)
    return b[counts >= p]


def interpolate(v: np.ndarray, values: np.ndarray, joints=()) -> tuple[int, np.ndarray, np.ndarray]:
    """Cubic interpolation of ``values`` (n, ...) at increasing nodes ``v`` (n,) along their first axis,
    restarted at ``joints`` (nodes where the result is only C0; each piece needs at least 4 nodes).

    Returns ``(degree, knots, coefficients (n_c, ...))``: a clamped B-spline through every value.
    """
    from scipy.interpolate import make_interp_spline

    k = DEGREE
    cuts = np.r_[0, np.searchsorted(v, np.asarray(joints, float)), len(v) - 1].astype(int)
    knots, coefs = [], []
    flat = values.reshape(len(v), -1)
    for a, b in zip(cuts[:-1], cuts[1:]):
        f = make_interp_spline(v[a:b + 1], flat[a:b + 1], k=k)
        knots.append(f.t[:-1] if b < len(v) - 1 else f.t)  # a C0 joint: its knot k times, not k + 1
        coefs.append(f.c if a == 0 else f.c[1:])  # both pieces pass through the joint's value
    t = np.concatenate([knots[0]] + [kv[k + 1:] for kv in knots[1:]])
    return k, t, np.concatenate(coefs).reshape((-1,) + values.shape[1:])


def evaluate(k: int, t: np.ndarray, coef: np.ndarray, v: np.ndarray) -> np.ndarray:
    """The interpolant of :func:`interpolate` at ``v``: (len(v), ...)."""
    from scipy.interpolate import BSpline as _SciPy

    return _SciPy(t, coef.reshape(len(coef), -1), k)(v).reshape((len(v),) + coef.shape[1:])
