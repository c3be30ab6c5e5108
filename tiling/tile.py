"""Tiles: patches in the unit cube with labelled branch-in / branch-out faces (Massarwi et al. 2018, Section 3).

A :class:`Tile` holds one or more patches (curves, surfaces, trivariates; any
may carry channels) whose coordinates lie in ``[0, 1]^3``.  Hierarchical tiles
label one *branch-in* face and any number of *branch-out* faces; each
branch-out face carries the affine map of the tile's coordinates that puts a
child tile on it (its branch-in face onto the branch-out face, growing
outwards).  Branch faces are planar and axis-aligned in tile coordinates; a
branch face may be a sub-rectangle (in face parameters) of a patch face, as
produced by partial Euclidean discontinuities (Massarwi et al. 2018, Section 3.1).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from geometry.numbers import TINY
from geometry import BSpline, TrimmedSurface
from geometry.errors import SplineError, show
from geometry.faces import FACE_AXIS, FACE_NAMES
from geometry.tolerances import COINCIDENT

from .errors import TilingError

TOL = COINCIDENT  # unit-cell tiles: walls on the cell faces, flat patches


@dataclass
class BranchFace:
    """A labelled face: ``patch`` index, ``face`` name and an optional parameter sub-rectangle.

    ``box``: ((a1, b1), (a2, b2)) in the face's own parameters (the two
    remaining directions in order), or None for the whole face.
    ``map``: (3, 4) affine map [A | b] of tile coordinates placing a child
    tile on this face (branch-out faces only).
    """

    patch: int
    face: str
    box: tuple | None = None
    map: np.ndarray | None = None

    def surface(self, tile: "Tile") -> BSpline:
        """The face as a surface spline (restricted to ``box`` when given)."""
        s = tile.patches[self.patch].boundary(self.face)
        return s if self.box is None else s.extract(np.asarray(self.box, float))


def _rect(tile: "Tile", bf: BranchFace, what: str):
    """Axis-aligned rectangle of a planar branch face: (normal axis, level, lo (3,), hi (3,))."""
    if not 0 <= bf.patch < len(tile.patches) or tile.patches[bf.patch].dim != 3:
        raise TilingError(f"{what}: patch {bf.patch} is not a trivariate of this tile")
    if bf.face not in FACE_NAMES:
        raise TilingError(f"{what}: {show(bf.face)} is not a face name; use one of {list(FACE_NAMES)}")
    try:
        pts = bf.surface(tile).points.reshape(-1, 3)
    except (SplineError, ValueError, TypeError, IndexError) as exc:  # a bad sub-rectangle (shape, order, range)
        raise TilingError(f"{what}: cannot extract the face ({exc})") from None
    lo, hi = pts.min(0), pts.max(0)
    flat = np.nonzero(hi - lo < TOL)[0]
    if len(flat) != 1:
        raise TilingError(f"{what}: branch faces must be planar and axis-aligned in tile coordinates; "
                          f"its control points span {lo.round(6).tolist()}..{hi.round(6).tolist()}")
    return int(flat[0]), float(lo[flat[0]]), lo, hi


def _face_frame(tile: "Tile", bf: BranchFace, what: str):
    """Origin, two in-face edge vectors (following the face parameters) and the outward unit normal."""
    axis, level, lo, hi = _rect(tile, bf, what)
    s = bf.surface(tile)
    dom = s.domain
    c = s.evaluate(np.array([[dom[0, 0], dom[1, 0]], [dom[0, 1], dom[1, 0]], [dom[0, 0], dom[1, 1]]]))[:, :3]
    e1, e2 = c[1] - c[0], c[2] - c[0]
    # outward: away from the patch interior
    k, side = FACE_AXIS[bf.face]
    P = tile.patches[bf.patch]
    inner = P.evaluate(np.array([[0.5 * (a + b) for a, b in P.domain]]))[0, :3]
    n = np.zeros(3)
    n[axis] = 1.0 if level > inner[axis] else -1.0
    return c[0], e1, e2, n


def _in_unit_cube(p: BSpline, what: str) -> None:
    pts = p.points.reshape(-1, 3)
    if pts.min() < -TOL or pts.max() > 1 + TOL:
        raise TilingError(f"{what} leaves the unit cube (control points span {pts.min(0).round(6).tolist()}.."
                          f"{pts.max(0).round(6).tolist()}); scale it into [0, 1]^3")


def refuse_trimmed(tile: "Tile", builder: str) -> None:
    """Raise :class:`TilingError` where ``tile`` has trimmed members and ``builder`` does not place them."""
    if getattr(tile, "trimmed", None):
        raise TilingError(f"tile {show(tile.name)} has {len(tile.trimmed)} trimmed surface members, which {builder} "
                          "does not place; pave it with tiling.regular (or compose_levels), or leave the trimmed "
                          "members out")


@dataclass
class Tile:
    """A tile: patches in [0, 1]^3 plus optional branch labels.

    Parameters
    ----------
    patches : list of geometry.BSpline (curves, surfaces, trivariates) and
        geometry.TrimmedSurface (trimmed surfaces, Elber 2017, Fig. 7); the
        trimmed ones are moved to ``trimmed``
    branch_in : BranchFace or (patch, face) for hierarchical tiles
    branch_outs : list of BranchFace or (patch, face[, box])
    scale : height factor of a child relative to its parent along the
        growth direction (Massarwi et al. 2018, Section 3.1, Fig. 11: 0.5, 0.8); ``None`` keeps
        children similar (the in-face scale ratio)
    name : label used in messages and exports
    trimmed : list of geometry.TrimmedSurface, tile members paved and
        composed with the patches, their loops carried unaltered
        (:class:`tiling.members.trimmed.PlacedTrimmed`)
    """

    patches: list
    branch_in: BranchFace | None = None
    branch_outs: list = field(default_factory=list)
    scale: float | None = None
    name: str = "tile"
    trimmed: list = field(default_factory=list)

    def __post_init__(self):
        given = list(self.patches)
        self.patches = [p for p in given if not isinstance(p, TrimmedSurface)]
        self.trimmed = list(self.trimmed) + [p for p in given if isinstance(p, TrimmedSurface)]
        if not self.patches and not self.trimmed:
            raise TilingError(f"tile {show(self.name)} has no patches")
        for i, p in enumerate(self.patches):
            if not isinstance(p, BSpline):
                raise TilingError(f"tile {show(self.name)} patch {i} is a {type(p).__name__}, not a geometry.BSpline "
                                  "or geometry.TrimmedSurface")
            _in_unit_cube(p, f"tile {show(self.name)} patch {i}")
        for i, t in enumerate(self.trimmed):
            if not isinstance(t, TrimmedSurface):
                raise TilingError(f"tile {show(self.name)} trimmed member {i} is a {type(t).__name__}, not a "
                                  "geometry.TrimmedSurface")
            _in_unit_cube(t.surface, f"tile {show(self.name)} trimmed member {i}")
        if self.scale is not None and not (np.isfinite(self.scale) and self.scale > 0):
            raise TilingError(f"tile {show(self.name)}: scale must be positive, got {show(self.scale)}")
        as_bf = lambda b: b if isinstance(b, BranchFace) else BranchFace(*b)  # noqa: E731
        if self.branch_in is not None:
            self.branch_in = as_bf(self.branch_in)
            _rect(self, self.branch_in, f"tile {show(self.name)} branch-in face")
        self.branch_outs = [as_bf(b) for b in self.branch_outs]
        if self.branch_outs and self.branch_in is None:
            raise TilingError(f"tile {show(self.name)} has branch-out faces but no branch-in face")
        for j, bf in enumerate(self.branch_outs):
            what = f"tile {show(self.name)} branch-out face {j}"
            if bf.map is None:
                bf.map = self._branch_map(bf, what)
            bf.map = np.asarray(bf.map, float)
            self._check_map(bf, what)

    @property
    def hierarchical(self) -> bool:
        """Whether the tile has a branch-in face and branch-out faces."""
        return self.branch_in is not None and bool(self.branch_outs)

    @property
    def trivariates(self) -> list[int]:
        """Indices of the tile's trivariate patches."""
        return [i for i, p in enumerate(self.patches) if p.dim == 3]

    def _branch_map(self, bf: BranchFace, what: str) -> np.ndarray:
        """Affine map sending the branch-in face frame onto the branch-out face frame (growing outwards)."""
        o0, a0, b0, n0 = _face_frame(self, self.branch_in, f"tile {show(self.name)} branch-in face")
        o1, a1, b1, n1 = _face_frame(self, bf, what)
        n0 = -n0  # the branch-in face's inward direction is where the tile grows
        h_in = 1.0  # tile height along the growth direction (unit cube)
        ratio = np.sqrt(np.linalg.norm(np.cross(a1, b1)) / max(np.linalg.norm(np.cross(a0, b0)), TINY))
        height = (self.scale if self.scale is not None else ratio) * h_in
        S = np.column_stack([a0, b0, n0 * h_in])
        T = np.column_stack([a1, b1, n1 * height])
        if abs(np.linalg.det(S)) < 1e-12:
            raise TilingError(f"{what}: the branch-in face is degenerate")
        A = T @ np.linalg.inv(S)
        return np.column_stack([A, o1 - A @ o0])

    def _check_map(self, bf: BranchFace, what: str):
        if bf.map.shape != (3, 4) or not np.all(np.isfinite(bf.map)):
            raise TilingError(f"{what}: map must be a finite (3, 4) array [A | b]")
        src = self.branch_in.surface(self)
        dst = bf.surface(self)
        uv = np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0], [1.0, 1.0], [0.5, 0.5]])
        ps = src.evaluate(src.domain[:, 0] + uv * (src.domain[:, 1] - src.domain[:, 0]))[:, :3]
        pd = dst.evaluate(dst.domain[:, 0] + uv * (dst.domain[:, 1] - dst.domain[:, 0]))[:, :3]
        mapped = ps @ bf.map[:, :3].T + bf.map[:, 3]
        if np.abs(mapped - pd).max() > 1e-8:
            raise TilingError(f"{what}: its map does not take the branch-in face onto this face "
                              f"(off by {np.abs(mapped - pd).max():.2e}); fix the map or the labels")
        if np.linalg.det(bf.map[:, :3]) <= 0:
            raise TilingError(f"{what}: its map must preserve orientation (positive determinant)")


def discontinuity_branches(spline: BSpline, face: str = "wmax") -> list[BranchFace]:
    """Branch-out faces of a trivariate with partial discontinuities (Massarwi et al. 2018, Section 3.1).

    Interior knots of full multiplicity (degree + 1) along the two in-face
    directions split ``face`` into (n + 1)(m + 1) sub-rectangles; each is one
    branch-out face (patch 0).
    """
    k, _ = FACE_AXIS[face]
    dirs = [d for d in range(3) if d != k]
    cuts = []
    for d in dirs:
        vals, mults = np.unique(spline.knots[d], return_counts=True)
        inner = vals[1:-1][mults[1:-1] >= spline.degrees[d] + 1]
        cuts.append(np.r_[vals[0], inner, vals[-1]])
    out = []
    for i in range(len(cuts[0]) - 1):
        for j in range(len(cuts[1]) - 1):
            out.append(BranchFace(0, face, ((cuts[0][i], cuts[0][i + 1]), (cuts[1][j], cuts[1][j + 1]))))
    return out
