"""Repelling two colliding bridges (Hong and Elber 2021, Sections 3.3 and 3.6): one loop for both kinds.

Two bridges collide when their sampled axes (in space) come closer than the
sum of their inscribed radii ``need``.  Each step finds the axes' closest
points, the direction ``T1 x T2`` of the tangents there (or the line between
the points where the tangents are parallel), oriented from b towards a, and
moves the two bridges apart along it by :func:`step` each; how a bridge moves
(an inner control point, a far end sliding on its surface, the inner layers
of a quintic tube) is the caller's.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np
from geometry.numbers import TINY

__all__ = ["Collisions", "closest", "cross3", "direction", "step", "repel"]


@dataclass
class Collisions:
    """Counts of the collision handling: pairs found colliding, resolved by swapping their far ends (surface
    bridges only), resolved by repulsion, and resolved by eliminating the later bridge."""

    collisions: int = 0
    swapped: int = 0
    repelled: int = 0
    eliminated: int = 0


def closest(pa: np.ndarray, pb: np.ndarray) -> tuple[float, int, int]:
    """(distance, index in pa, index in pb) of the closest pair of two sampled axes (n, 3) and (m, 3).  The
    norms component by component (x, y, z summed in the order a norm sums them: the same numbers, without
    a reduction over a last axis of three; a thousand calls per union).  The collision screen batches the
    same sums over many pairs (:func:`tiling.vrep.union._axis_distances`, on contiguous components)."""
    sq = None
    for k in range(3):
        d = pa[:, None, k] - pb[None, :, k]
        sq = d * d if sq is None else sq + d * d
    d = np.sqrt(sq)
    i, j = np.unravel_index(np.argmin(d), d.shape)
    return float(d[i, j]), int(i), int(j)


def cross3(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """The cross product of two 3-vectors: ``np.cross``'s products and differences, without its set-up
    (moving axes and broadcasting cost it 30 us a call)."""
    a0, a1, a2 = float(a[0]), float(a[1]), float(a[2])
    b0, b1, b2 = float(b[0]), float(b[1]), float(b[2])
    return np.array([a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0])


def direction(pa: np.ndarray, pb: np.ndarray, ia: int, ib: int) -> np.ndarray:
    """Unit T1 x T2 at the closest points (the joining line where the tangents are parallel), pointing from
    b's point to a's."""
    ta = pa[min(ia + 1, len(pa) - 1)] - pa[max(ia - 1, 0)]
    tb = pb[min(ib + 1, len(pb) - 1)] - pb[max(ib - 1, 0)]
    v = cross3(ta, tb)
    if np.linalg.norm(v) < 1e-12 * max(np.linalg.norm(ta) * np.linalg.norm(tb), TINY):
        v = pa[ia] - pb[ib]
    v = v / max(np.linalg.norm(v), TINY)
    return -v if np.dot(v, pa[ia] - pb[ib]) < 0 else v


def step(need: float, dist: float) -> float:
    """How far each of the two bridges moves in one step: half the missing clearance and a little more, so
    that the pair separates in a few steps without overshooting far."""
    return 0.5 * (need - dist) + 1e-3 * need


def repel(sample_a: Callable[[], np.ndarray], sample_b: Callable[[], np.ndarray],
          move: Callable[[np.ndarray, float, int, int, np.ndarray, np.ndarray], None], need: float,
          max_steps: int) -> tuple[float, int]:
    """Step the two bridges apart until their axes clear ``need`` or ``max_steps`` steps are taken.

    ``sample_a()``, ``sample_b()``: the current axis samples (n, 3) in space; ``move(v, s, ia, ib, pa, pb)``
    moves a by ``s`` along ``v`` and b by ``s`` against it.  Returns (final distance, steps taken).
    """
    pa, pb = sample_a(), sample_b()
    dist, ia, ib = closest(pa, pb)
    steps = 0
    while dist < need and steps < max_steps:
        move(direction(pa, pb, ia, ib), step(need, dist), ia, ib, pa, pb)
        steps += 1
        pa, pb = sample_a(), sample_b()
        dist, ia, ib = closest(pa, pb)
    return dist, steps
