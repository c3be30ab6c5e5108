"""Round struts and fibres: a curve tile's axes composed into the map, then swept with a circular section.

Elber 2017 (Section 4, Fig. 10) and Massarwi et al. 2018 (Section 1): composing a
beam with a round section into a map distorts the section; composing only the axis
curves (exact, :func:`geometry.compose`) and sweeping a circle along the deformed
axes keeps every section a circle, within the sweep's tolerance
(:func:`geometry.shapes.sweep.sweep`).  Each strut becomes a capsule (tube and two exact
hemispheres), a closed surface; struts meeting at a lattice node end in the same sphere
there, so the lattice is a union of closed shells that overlap at the nodes (what
slicers for additive manufacturing take; no Boolean union is formed).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from geometry import BSpline
from geometry.errors import SplineError, show
from geometry.patches.multipatch import PlacedPatch
from geometry.shapes.sweep import kinks, points_and_tangents, sweep
from geometry.shapes.trimmed import join_curves, reversed_curve

from tiling.errors import TilingError
from tiling.microstructure import Microstructure
from geometry.numbers import is_real

__all__ = ["round_struts", "StrutReport"]


@dataclass
class StrutReport:
    """What :func:`round_struts` built: ``sweeps`` (one :class:`geometry.shapes.sweep.Sweep` per strut piece),
    ``radius`` and ``tolerance`` (model units) and ``error``, the largest measured sweep error."""

    sweeps: list
    radius: float
    tolerance: float

    @property
    def error(self) -> float:
        return max(s.error for s in self.sweeps)


def round_struts(ms: Microstructure, radius: float, tolerance: float | None = None) -> Microstructure:
    """The curve patches of ``ms`` (a paving of a curve tile) as round struts of ``radius`` (model units).

    Every curve patch is composed exactly into the map, split where its tangent turns
    abruptly (a C0 knot of the map), and each piece swept with the exact circle and a
    rotation-minimising frame within ``tolerance`` (default 1e-3 of the radius) and closed
    by two hemispheres.  Returns a :class:`Microstructure` of surface patches in physical
    space (placed with no map: they are already composed) with ``.struts``, a
    :class:`StrutReport`; its ``surface()``, ``write_iges`` and watertightness report work
    as for any surface paving.

    >>> from geometry import primitives
    >>> from tiling import library, regular
    >>> lattice = regular(primitives.box((2.0, 1.0, 1.0), degrees=(2, 2, 2)), library.struts("bcc"), (2, 1, 1))
    >>> round = round_struts(lattice, 0.05)
    >>> len(round.struts.sweeps), len(round.patches), round.struts.error <= 5e-5   # 16 half-diagonals, joined
    (8, 24, True)
    """
    if not isinstance(ms, Microstructure):
        raise TilingError(f"round_struts needs a Microstructure (a paving of a curve tile), got {show(ms)}")
    if not (is_real(radius) and np.isfinite(radius) and radius > 0):
        raise TilingError(f"strut radius must be a positive length (model units), got {show(radius)}")
    tol = 1e-3 * radius if tolerance is None else tolerance
    curves = [(i, P) for i, P in enumerate(ms.patches) if P.spline.dim == 1]
    if not curves:
        raise TilingError(f"{ms.name or 'the micro-structure'} has no curve patches to sweep; pave a curve tile "
                          "(library.struts, library.helix or a Tile of BSpline curves)")
    composed = ms.compose_all()
    pieces = [(i, c) for i, P in curves for c in _smooth_pieces(composed[i])]
    sweeps, patches = [], []
    for chain in _chains([c for _, c in pieces], radius):
        first = ms.patches[pieces[chain[0][0]][0]]
        axis = join_curves([pieces[j][1] if fwd else reversed_curve(pieces[j][1]) for j, fwd in chain])
        try:
            s = sweep(axis, radius=float(radius), tolerance=tol)
        except SplineError as exc:
            raise TilingError(f"strut through patch {pieces[chain[0][0]][0]} (tile {first.tile}): {exc}") from None
        sweeps.append(s)
        patches += [PlacedPatch(surf, None, None, first.tile, first.level, first.patch_in_tile) for surf in s.closed()]
    out = Microstructure(ms.outer, patches, [], {"boundary": []}, ms.tiles, name=f"{ms.name} round struts".strip())
    out.struts = StrutReport(sweeps, float(radius), float(tol))
    return out


def _ends(curves):
    """Endpoints (2n, 3) and outward unit tangents (2n, 3) of ``curves``: rows 2i (start) and 2i + 1 (end)."""
    ends = [points_and_tangents(c, c.domain[0]) for c in curves]  # per curve (an object): both ends at once
    X = np.concatenate([x for x, _ in ends])
    T = np.concatenate([t * np.array([[-1.0], [1.0]]) for _, t in ends])
    return X, T


def _chains(curves, radius: float) -> list[list[tuple[int, bool]]]:
    """Curves that continue each other (an end of one at the start or end of another, tangent-continuous) as
    chains: lists of (curve, forward), each a path; a closed loop is opened where it was found."""
    from scipy.spatial import cKDTree

    X, T = _ends(curves)
    pairs = np.array(sorted(cKDTree(X).query_pairs(1e-9 * max(radius, float(np.abs(X).max())))), int).reshape(-1, 2)
    pairs = pairs[pairs[:, 0] // 2 != pairs[:, 1] // 2]
    straight = np.einsum("ni,ni->n", T[pairs[:, 0]], T[pairs[:, 1]]) < -np.cos(1e-6)
    pairs = pairs[straight]
    once = np.bincount(pairs.ravel(), minlength=len(X)) == 1  # a node where three struts continue: leave them
    pairs = pairs[once[pairs[:, 0]] & once[pairs[:, 1]]]
    partner = np.full(len(X), -1)
    partner[pairs[:, 0]], partner[pairs[:, 1]] = pairs[:, 1], pairs[:, 0]
    n = len(curves)
    chains, seen = [], np.zeros(n, bool)
    free = [i for i in range(n) if partner[2 * i] < 0 or partner[2 * i + 1] < 0]
    for start in free + list(range(n)):  # paths from a free end first; what is left are closed loops
        if seen[start]:
            continue
        fwd = bool(partner[2 * start] < 0 or start not in free)  # leave through the end that has a partner
        chain, c = [], start
        while c >= 0 and not seen[c]:
            seen[c] = True
            chain.append((c, fwd))
            nxt = partner[2 * c + (1 if fwd else 0)]
            c, fwd = (nxt // 2, nxt % 2 == 0) if nxt >= 0 else (-1, True)
        chains.append(chain)
    return chains


def _smooth_pieces(curve: BSpline) -> list[BSpline]:
    """``curve`` split at its kinks (exact sub-curves, each tangent-continuous)."""
    cuts = kinks(curve)
    if not len(cuts):
        return [curve]
    edges = np.r_[curve.domain[0, 0], cuts, curve.domain[0, 1]]
    return [curve.extract([[a, b]]) for a, b in zip(edges[:-1], edges[1:])]

