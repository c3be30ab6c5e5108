"""The public multi-field spline: 3 coordinates plus named material channels."""

from __future__ import annotations

import numpy as np

from .errors import SplineError
from geometry.maps.sign_net import element_windows, window_extremes
from .spline import SplineFunction
from .errors import show


class BSpline(SplineFunction):
    """Tensor-product B-spline or NURBS of parametric dimension 1, 2 or 3.

    Parameters
    ----------
    degrees : tuple of int
        One degree (>= 1) per parametric direction.
    knots : sequence of 1-D arrays
        One open (clamped) knot vector per direction.
    control_points : array (n_1, ..., n_d, 3 + len(channels))
        x, y, z (model units, e.g. m) followed by the channel values (their own
        units, e.g. conductivity in W/(m K)).
    weights : array (n_1, ..., n_d), optional
        Positive NURBS weights; ``None`` for a polynomial B-spline.
    channels : sequence of str
        Names of the extra components, e.g. ``("k",)``.

    Every operation (refinement, elevation, extraction, products, composition)
    acts on coordinates and channels together and keeps the channel names.

    Example: a quarter circle (exact quadratic NURBS) with a temperature channel.

    >>> import numpy as np
    >>> w = np.array([1.0, np.sqrt(0.5), 1.0])
    >>> arc = BSpline((2,), [[0, 0, 0, 1, 1, 1]], [[1, 0, 0, 20], [1, 1, 0, 25], [0, 1, 0, 30]], w, channels=("T",))
    >>> x = arc.evaluate(np.linspace(0, 1, 7)[:, None])
    >>> bool(np.allclose(np.hypot(x[:, 0], x[:, 1]), 1.0)), arc.channels
    (True, ('T',))
    >>> finer, R = arc.insert_knots(0, [0.5])   # exact: same curve, refinement matrix R (4 x 3)
    >>> R.shape, bool(np.allclose(finer.evaluate(np.array([[0.3]])), arc.evaluate(np.array([[0.3]]))))
    ((4, 3), True)
    """

    def __init__(self, degrees, knots, control_points, weights=None, channels=()):
        if isinstance(channels, str):
            channels = (channels,)
        channels = tuple(channels)
        for c in channels:
            if not isinstance(c, str) or not c:
                raise SplineError(f"channel names must be non-empty strings, got {show(c)}")
        if len(set(channels)) != len(channels):
            raise SplineError(f"channel names must be unique, got {list(channels)}")
        cp = self._as_array(control_points, "control points")
        if cp.ndim < 2 or cp.shape[-1] != 3 + len(channels):
            raise SplineError(
                f"control points must have shape (n_1, ..., n_d, {3 + len(channels)}) for 3 coordinates + "
                f"channels {list(channels)}; got {cp.shape}. Pad 2-D points with z = 0 and name every channel."
            )
        self.channels = channels
        super().__init__(degrees, knots, cp, weights)

    def _extra(self) -> dict:
        return {"channels": self.channels}

    @property
    def control_points(self) -> np.ndarray:
        """Cartesian control points (n_1, ..., n_d, 3 + n_channels)."""
        return self.coefficients

    @property
    def points(self) -> np.ndarray:
        """Only the x, y, z part of the control points."""
        return self.coefficients[..., :3]

    def channel_index(self, name: str) -> int:
        """Index of channel ``name`` in the last axis of :attr:`control_points` (3 + its position)."""
        if name not in self.channels:
            raise SplineError(f"unknown channel {show(name)}; this spline has channels {list(self.channels)}")
        return 3 + self.channels.index(name)

    def channel(self, name: str) -> np.ndarray:
        """Control values of one channel, shape (n_1, ..., n_d)."""
        return self.coefficients[..., self.channel_index(name)]

    def with_channel(self, name: str, values) -> "BSpline":
        """Copy with channel ``name`` set (added if new) from control values or a constant."""
        vals = np.broadcast_to(np.asarray(values, float), self.shape)
        if not np.all(np.isfinite(vals)):
            raise SplineError(f"channel {show(name)} values must be finite")
        if name in self.channels:
            cp = self.coefficients.copy()
            cp[..., self.channel_index(name)] = vals
            channels = self.channels
        else:
            cp = np.concatenate([self.coefficients, vals[..., None]], axis=-1)
            channels = self.channels + (name,)
        return BSpline(self.degrees, self.knots, cp, self.weights, channels)

    def without_channels(self, names=None) -> "BSpline":
        """Copy keeping only the channels not in ``names`` (all removed by default)."""
        names = self.channels if names is None else ([names] if isinstance(names, str) else list(names))
        for n in names:
            self.channel_index(n)
        keep = [c for c in self.channels if c not in names]
        idx = [0, 1, 2] + [self.channel_index(c) for c in keep]
        return BSpline(self.degrees, self.knots, self.coefficients[..., idx], self.weights, keep)

    def affine(self, A=None, b=None) -> "BSpline":
        """Image under ``x -> A x + b`` (exact: splines are affinely invariant). Channels unchanged."""
        A = np.eye(3) if A is None else np.asarray(A, float)
        b = np.zeros(3) if b is None else np.asarray(b, float)
        if A.shape != (3, 3) or b.shape != (3,) or not (np.all(np.isfinite(A)) and np.all(np.isfinite(b))):
            raise SplineError(f"affine map needs a finite 3x3 matrix and a 3-vector, got {A.shape} and {b.shape}")
        cp = self.coefficients.copy()
        cp[..., :3] = cp[..., :3] @ A.T + b
        return BSpline(self.degrees, self.knots, cp, self.weights, self.channels)

    def translate(self, b) -> "BSpline":
        """Image under ``x -> x + b`` (b: 3-vector, model units); channels unchanged."""
        return self.affine(None, b)

    def scale(self, s) -> "BSpline":
        """Image under ``x -> s x`` (s: a number or one factor per axis); channels unchanged."""
        s = np.broadcast_to(np.asarray(s, float), (3,))
        return self.affine(np.diag(s))

    def bounding_box(self) -> np.ndarray:
        """Axis-aligned box (3, 2) containing the image (convex hull of control points)."""
        P = self.points.reshape(-1, 3)
        return np.stack([P.min(0), P.max(0)], axis=1)

    def element_boxes(self) -> np.ndarray:
        """Axis-aligned boxes (E, 3, 2) containing the image of each knot span (element) in C order: the box of
        the (p + 1)^d control points that span's basis functions weigh (the local convex hull property)."""
        hi, lo = window_extremes(self.points, [p + 1 for p in self.degrees])
        at = np.ix_(*[first for _, first in element_windows(self)])  # each element's first control point
        return np.stack([lo[at].reshape(-1, 3), hi[at].reshape(-1, 3)], axis=-1)

    def __repr__(self) -> str:
        base = super().__repr__()[:-1]
        return f"{base}, channels={list(self.channels)})"
