"""Graded pavings: a tile family whose parameter varies along w, each layer of cells its own member.

A lattice graded in density (arms thickening from one face to the other,
Massarwi et al. 2018, Section 6.1: heterogeneous micro-structures) needs tiles
that still meet face to face where the parameter changes.  ``family(lower,
upper)`` returns the tile whose bottom face (z = 0) has the parameter's value
``lower`` and its top face ``upper`` (:func:`tiling.library.graded_cross`);
:func:`graded` gives every layer of D's cell grid along w the member between
the values at its two boundaries, so neighbouring layers share their face's
value and conform.  The interfaces come by construction, as in a regular paving
(:mod:`tiling.topology`).
"""

from __future__ import annotations

import numpy as np

from geometry import BSpline
from geometry.errors import show

from .errors import TilingError
from .microstructure import Microstructure, PlacedPatch
from .checks import check_budget, check_counts, check_map, check_spans, parameter_cells
from .paving import grid_identity
from .tile import Tile, refuse_trimmed

__all__ = ["graded"]


def _values(D: BSpline, values, w: np.ndarray) -> np.ndarray:
    """The family's parameter at the layer boundaries ``w`` (D's parameters): a channel of D read on the axis
    through the middle of D's (u, v) domain, or a callable of the normalised w in [0, 1]."""
    dom = D.domain
    if isinstance(values, str):
        if values not in D.channels:
            raise TilingError(f"graded: {show(values)} is not a channel of the map (its channels: "
                              f"{list(D.channels)}); give a channel name or a callable of the normalised w")
        x = np.column_stack([np.full(len(w), dom[0].mean()), np.full(len(w), dom[1].mean()), w])
        out = D.evaluate(x)[:, 3 + list(D.channels).index(values)]
    elif callable(values):
        out = np.asarray(values((w - dom[2, 0]) / (dom[2, 1] - dom[2, 0])), float).reshape(-1)
    else:
        raise TilingError(f"graded: values must be a channel name of the map or a callable of the normalised w, "
                          f"got {show(values)}")
    if out.shape != w.shape or not np.all(np.isfinite(out)):
        raise TilingError(f"graded: the parameter must be finite at the {len(w)} layer boundaries, got "
                          f"{show(out)}")
    return out


def graded(D: BSpline, family, counts, values, name: str = "graded") -> Microstructure:
    """Regular paving of D by ``counts`` = (cx, cy, cz) cells per knot span, layer k along w holding
    ``family(p_k, p_k+1)`` with p the parameter at the layer boundaries (``values``: a channel of D or a callable
    of the normalised w; module notes).  ``ms.info["parameter"]`` holds p.

    >>> from geometry import primitives
    >>> from tiling import library
    >>> ms = graded(primitives.box(), library.graded_cross, (2, 2, 4), lambda s: 0.2 + 0.2 * s)
    >>> ms.n_tiles, [round(p, 2) for p in ms.info["parameter"]]
    (16, [0.2, 0.25, 0.3, 0.35, 0.4])
    """
    check_map(D)
    if not callable(family):
        raise TilingError(f"graded: family must be a callable (lower, upper) -> Tile, e.g. "
                          f"tiling.library.graded_cross; got {show(family)}")
    counts = check_counts(counts, 3, "counts")
    cells = [parameter_cells(D, k, counts[k]) for k in range(3)]
    w = np.append(cells[2][:, 0], cells[2][-1, 1])
    p = _values(D, values, w)
    layers = []
    for k in range(len(w) - 1):
        try:
            t = family(float(p[k]), float(p[k + 1]))
        except TilingError as exc:
            raise TilingError(f"graded: layer {k} (parameter {p[k]:g} to {p[k + 1]:g}): {exc}") from None
        if not isinstance(t, Tile):
            raise TilingError(f"graded: family must return a tiling.Tile, got {show(t)} for layer {k}")
        refuse_trimmed(t, "the graded paving")
        layers.append(t)
    shape = tuple(len(c) for c in cells)
    check_budget(float(np.prod(shape)), layers[0], "the graded paving")
    placed, tiles = [], []
    for i, j, k in np.ndindex(shape):
        lo = np.array([cells[0][i, 0], cells[1][j, 0], cells[2][k, 0]])
        hi = np.array([cells[0][i, 1], cells[1][j, 1], cells[2][k, 1]])
        M = np.column_stack([np.diag(hi - lo), lo])
        tiles.append(layers[k])
        placed += [PlacedPatch(patch, M, D, len(tiles) - 1, 0, pi) for pi, patch in enumerate(layers[k].patches)]
    check_spans(D, placed)
    ms = Microstructure.build(D, placed, tiles, [], name=name, identity=grid_identity(D, tiles, shape))
    ms.info = {"parameter": [float(v) for v in p]}
    return ms
