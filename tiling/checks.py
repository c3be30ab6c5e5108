"""Checks and helpers every way of paving shares: the map, counts, the memory budget, knot spans, cells.

Each refuses bad input with :class:`tiling.TilingError`, naming the input and the fix, before anything is built.
"""

from __future__ import annotations

import numpy as np

from geometry import BSpline, check_regular
from geometry.errors import show
from geometry.grouping import ObjectIndex
from geometry.numbers import is_integer
from geometry.resources import check_memory
from geometry.patches.sampling import sample_axes
from geometry.tolerances import COINCIDENT

from .errors import TilingError

__all__ = ["check_map", "check_counts", "check_budget", "check_spans", "parameter_cells", "BYTES_PER_PATCH"]


def check_map(D) -> None:
    if not isinstance(D, BSpline) or D.dim != 3:
        raise TilingError(f"the deformation map must be a trivariate geometry.BSpline, got {show(D)}")
    r = check_regular(D, max_depth=6)
    if r.status == "singular":
        raise TilingError(f"the deformation map is singular: {r.message}; fix its control net before paving")


def check_counts(counts, n, what):
    """``n`` positive integers (a list, tuple or integer array; a string is not a list of counts)."""
    ok = isinstance(counts, (list, tuple, np.ndarray)) and len(counts) == n and all(is_integer(v) and v >= 1
                                                                                     for v in counts)
    if not ok:
        raise TilingError(f"{what} must be {n} positive integers, got {show(counts)}")
    return tuple(int(v) for v in counts)


#: memory of one placed patch in a Microstructure, interfaces and tags included (measured with tracemalloc on
#: regular and hierarchical pavings: 6-9 KB at the peak of building)
BYTES_PER_PATCH = 10_000


def check_budget(n_tiles: float, tile, what: str, hint: str = "lower the counts or levels") -> None:
    """Refuse pavings whose patches would not fit the memory budget, before building anything."""
    n = float(n_tiles) * len(tile.patches)
    check_memory(n * BYTES_PER_PATCH, f"{what} ({n_tiles:.3g} tiles, {n:.3g} patches)", TilingError, hint)


def parameter_cells(D: BSpline, k: int, count: int) -> np.ndarray:
    """(N, 2) parameter intervals: ``count`` equal cells per knot span of D along direction k."""
    cuts = sample_axes([D.breakpoints(k)], count)[0]  # neighbouring cells share their end exactly
    return np.stack([cuts[:-1], cuts[1:]], axis=1)


def check_spans(D: BSpline, placed: list) -> None:
    """Every placed patch must lie inside one knot span of D (exact composition per Bezier piece)."""
    same = ObjectIndex()
    groups: dict = {}
    for i, P in enumerate(placed):
        groups.setdefault(same(P.spline), []).append(i)
    dom = D.domain
    tol = COINCIDENT * (dom[:, 1] - dom[:, 0])
    inner = [D.breakpoints(k)[1:-1] for k in range(3)]
    for members in groups.values():
        pts0 = placed[members[0]].spline.points.reshape(-1, 3)
        M = np.stack([placed[i].placement for i in members])
        pts = np.einsum("pij,nj->pni", M[:, :, :3], pts0) + M[:, None, :, 3]
        lo, hi = pts.min(axis=1), pts.max(axis=1)  # (P, 3)
        out = np.any((lo < dom[:, 0] - tol) | (hi > dom[:, 1] + tol), axis=1)
        if out.any():
            P = placed[members[int(np.argmax(out))]]
            raise TilingError(f"placed patch {members[int(np.argmax(out))]} (tile {P.tile}) leaves the deformation "
                              "map's domain")
        for k in range(3):
            if not len(inner[k]):
                continue
            cross = (inner[k][None, :] > lo[:, k : k + 1] + tol[k]) & (inner[k][None, :] < hi[:, k : k + 1] - tol[k])
            if cross.any():
                r, c = np.argwhere(cross)[0]
                i = members[int(r)]
                P = placed[i]
                raise TilingError(
                    f"placed patch {i} (tile {P.tile}, level {P.level}) crosses the deformation map's knot line "
                    f"{'uvw'[k]} = {inner[k][c]:g}; use a map with one knot span along {'uvw'[k]} for this paving "
                    "or counts that align tiles with its knot spans"
                )
