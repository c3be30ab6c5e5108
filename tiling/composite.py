"""Two-level composites of strips on a surface (Elber 2017, Section 3, Fig. 8).

The chain of the paper: a strip of the surface's domain is composed into the surface (for a
rectangle of the domain that is its exact sub-patch), "offset a bit to yield some real
thickness" (:func:`geometry.shapes.offset.offset`, within a stated tolerance), a ruled trivariate is
formed between the strip and its offset (:func:`geometry.primitives.ruled`, exact), and that
trivariate is paved with stitch tiles.  With a curve tile and a radius the stitches are swept
with circular sections along their composed axes (:func:`tiling.round_struts`), which is what
the paper suggests in Section 4 to keep the stitches round.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from geometry import BSpline, check_regular, primitives
from geometry.composition.core import compose_curves
from geometry.errors import SplineError, show
from geometry.patches.multipatch import PlacedPatch
from geometry.shapes.offset import Offset, offset

from .errors import TilingError
from .microstructure import Microstructure
from .checks import check_counts
from tiling.members.struts import round_struts
from .tile import Tile
from geometry.numbers import is_real

__all__ = ["StitchedStrip", "stitched_strip"]


@dataclass
class StitchedStrip:
    """One strip of a Fig. 8 composite: ``strip`` (the exact sub-surface), ``offset`` (:class:`geometry.shapes.offset.Offset`,
    with its measured error), ``volume`` (the ruled trivariate between them) and ``stitches`` (the paving of the
    volume: composed tiles, or round struts when a radius was given)."""

    strip: BSpline
    offset: Offset
    volume: BSpline
    stitches: Microstructure


def stitched_strip(surface: BSpline, box, thickness: float, tile: Tile, counts, radius: float | None = None,
                   tolerance: float | None = None) -> StitchedStrip:
    """Build one strip of Elber 2017, Fig. 8 on ``surface``.

    box : ((u0, u1), (v0, v1)), the strip in the surface's parameter domain
    thickness : the offset distance (model units; its sign picks the side of S_u x S_v)
    tile, counts : a curve tile (the stitches) and its copies along the strip's u and v and through its thickness
    radius : sweep the stitches (a curve tile) with circles of this radius (model units)
    tolerance : of the offset and the sweeps (model units; default 1e-3 |thickness|)
    """
    if not isinstance(surface, BSpline) or surface.dim != 2:
        raise TilingError(f"stitched_strip needs a BSpline surface, got {show(surface)}")
    if not (is_real(thickness) and np.isfinite(thickness) and thickness != 0):
        raise TilingError(f"strip thickness must be a non-zero length (model units; its sign picks the side), got "
                          f"{show(thickness)}")
    tol = 1e-3 * abs(thickness) if tolerance is None else tolerance
    try:
        strip = surface.extract(np.asarray(box, float))
        off = offset(strip, thickness, tol)
    except SplineError as exc:
        raise TilingError(f"strip {show(box)}: {exc}") from None
    bottom, top = (strip, off.surface) if thickness > 0 else (off.surface, strip)
    volume = primitives.ruled(bottom, top)
    proof = check_regular(volume, max_depth=6)
    if not proof.regular:
        raise TilingError(f"the ruled volume of strip {show(box)} is not proven regular ({proof.message}); use a "
                          "thinner strip or offset, thinner than the surface's radius of curvature")
    stitches = _pave_curves(volume, strip, tile, check_counts(counts, 3, "counts"))
    if radius is not None:
        stitches = round_struts(stitches, radius, tolerance=tol)
    return StitchedStrip(strip, off, volume, stitches)


def _pave_curves(volume: BSpline, strip: BSpline, tile: Tile, counts) -> Microstructure:
    """``counts`` equal cells over the volume's whole domain (not per knot span: the volume's spans also carry the
    offset's interpolation knots, which should not set the stitches' length), each with the curve tile composed
    into the volume exactly; a curve crossing the volume's knot lines is split and joined (:func:`geometry.compose`)."""
    if tile.trivariates or any(p.dim != 1 for p in tile.patches):
        raise TilingError(f"stitched_strip paves curve tiles (e.g. library.stitch()); {show(tile.name)} has surface "
                          "or volume patches")
    dom = volume.domain  # curves may cross its knot lines: equal cells keep a tangent-continuous stitch so
    edges = [np.linspace(a, b, n + 1) for (a, b), n in zip(dom, counts)]  # across the cells
    cells = [np.stack([e[:-1], e[1:]], 1) for e in edges]
    lo = np.stack(np.meshgrid(*[c[:, 0] for c in cells], indexing="ij"), -1).reshape(-1, 3)
    hi = np.stack(np.meshgrid(*[c[:, 1] for c in cells], indexing="ij"), -1).reshape(-1, 3)
    place = [np.hstack([np.diag(b - a), a[:, None]]) for a, b in zip(lo, hi)]
    patches = [PlacedPatch(curve, A, volume, t, 0, j) for t, A in enumerate(place) for j, curve in enumerate(tile.patches)]
    for P, image in zip(patches, compose_curves(volume, [P.spline.affine(P.placement[:, :3], P.placement[:, 3])
                                                         for P in patches])):
        P.set_composed(image)
    return Microstructure(volume, patches, [], {"boundary": []}, [tile] * len(lo), name="stitches")
