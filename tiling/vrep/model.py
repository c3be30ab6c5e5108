"""V-models: trivariate primitives combined by Booleans, and point membership (Hong and Elber 2021, Section 3).

A :class:`Primitive` is a deformation map with its own tile, counts and
priority.  A :class:`VModel` is a Boolean tree over primitives
(``a | b`` union, ``a - b`` subtraction, ``a & b`` intersection; nested
freely).  Its V-cells are implicit: a point's cell is the set of primitives
containing it, decided by point inversion into each primitive
(:func:`geometry.invert`: Gauss-Newton from the nearest point of a sampled
parameter grid, so a point far from a first guess still lands in the right
element).  Primitives on the positive side of the tree (union and
intersection operands, the left side of a subtraction) carry tiles; where
several of them contain a point, the one of highest priority tiles it
(Section 3.4: a V-cell shared by A and B is tiled from one of them).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from geometry import BSpline
from geometry.errors import show
from geometry.faces import FACE_NAMES
from geometry.maps.inversion import box_gaps, invert, invert_nearest

from ..errors import TilingError
from ..checks import check_budget
from ..tile import Tile, refuse_trimmed
from geometry.tolerances import COINCIDENT
from geometry.numbers import is_integer, is_real

__all__ = ["Primitive", "VModel", "VCell"]

_INSIDE_TOL = COINCIDENT  # relative to the model size: inversion distances below this are inside


@dataclass(eq=False)
class Primitive:
    """A trivariate primitive: map ``D``, ``tile`` paved ``counts`` times per knot span, ``priority``, ``name``."""

    def __repr__(self) -> str:
        return (f"Primitive({self.name!r}: tile {getattr(self.tile, 'name', '?')!r} x {tuple(self.counts)}, priority "
                f"{self.priority}, map of degrees {getattr(self.D, 'degrees', '?')})")

    D: BSpline
    tile: Tile
    counts: tuple
    priority: int = 0
    name: str = "primitive"

    def __post_init__(self):
        if not isinstance(self.D, BSpline) or self.D.dim != 3:
            raise TilingError(f"primitive {show(self.name)}: the map must be a trivariate geometry.BSpline, "
                              f"got {show(self.D)}")
        if not isinstance(self.tile, Tile):
            raise TilingError(f"primitive {show(self.name)}: tile must be a tiling.Tile, got {show(self.tile)}")
        refuse_trimmed(self.tile, "a V-rep primitive")
        c = self.counts
        if not (isinstance(c, (tuple, list)) and len(c) == 3
                and all(is_integer(n) and n >= 1 for n in c)):
            raise TilingError(f"primitive {show(self.name)}: counts must be three integers >= 1 (tiles per knot "
                              f"span in u, v, w), got {show(c)}")
        self.counts = tuple(int(n) for n in c)
        spans = np.prod([len(self.D.breakpoints(k)) - 1 for k in range(3)])
        check_budget(float(np.prod(self.counts, dtype=float)) * spans, self.tile,
                      f"the paving of primitive {show(self.name)}", "lower its counts")
        if not (isinstance(self.priority, (int, np.integer)) and not isinstance(self.priority, bool)):
            raise TilingError(f"primitive {show(self.name)}: priority must be an integer, got {show(self.priority)}")

    def contains(self, points: np.ndarray) -> np.ndarray:
        """Whether physical points (N, 3) lie in the primitive (point inversion).

        Points outside the bounding box of the control points are outside (the convex hull property), so
        only the others are inverted.
        """
        pts = np.asarray(points, float)
        tol = _INSIDE_TOL * self.size
        box = self.D.bounding_box()
        cand = np.flatnonzero(np.all((pts >= box[:, 0] - tol) & (pts <= box[:, 1] + tol), axis=1))
        out = np.zeros(len(pts), bool)
        if len(cand):
            out[cand] = invert(self.D, pts[cand], kernel=True).distance <= tol  # inside or not: no foot point
        return out

    def distance(self, points: np.ndarray) -> np.ndarray:
        """Distance (model units) from points (N, 3) to the primitive (0 inside).

        A point outside the solid is nearest to its boundary: its distance is the least over the six boundary
        surfaces, by damped Gauss-Newton on each (``invert(..., damped=True)``).  The trivariate's own Newton
        iterates, clipped at the domain's bound, stop short of the foot point: up to 0.34 too far for points
        around the cylinder of :func:`tiling.vrep.examples.box_cylinder`, more than its margin.
        """
        pts = np.asarray(points, float)
        d = invert(self.D, pts, kernel=True).distance
        inside = d <= _INSIDE_TOL * self.size
        d[inside] = 0.0
        out = np.flatnonzero(~inside)
        if len(out):
            d[out] = invert_nearest(self._boundary, pts[out], damped=True, kernel=True)[1].distance
        return d

    def within(self, points: np.ndarray, r: float) -> np.ndarray:
        """Whether points (N, 3) lie nearer than ``r`` (model units, > 0) to the primitive: :meth:`distance` < r,
        asked only where the bounds cannot tell.  The boxes of the map's elements (local convex hull) bound the
        distance from below; the inversion into the trivariate bounds it from above."""
        if not is_real(r) or not np.isfinite(r) or r <= 0:
            raise TilingError(f"primitive {show(self.name)}: the distance to test within must be a positive "
                              f"number (model units), got {show(r)}")
        pts = np.asarray(points, float)
        near = np.zeros(len(pts), bool)
        cand = np.flatnonzero(_box_gap(pts, self._made("boxes", lambda: self.D.element_boxes())) < r)
        if not len(cand):
            return near
        near[cand] = invert(self.D, pts[cand], kernel=True).distance < r
        todo = cand[~near[cand]]
        if len(todo):
            near[todo] = invert_nearest(self._boundary, pts[todo], damped=True, kernel=True)[1].distance < r
        return near

    @property
    def _boundary(self) -> list:
        """The six boundary surfaces of the map (made once: the inversion keeps a start grid per surface)."""
        return self._made("faces", lambda: [self.D.boundary(f) for f in FACE_NAMES])

    def _made(self, name: str, make):
        """What ``make()`` derives from the map ``D``, made once while ``D`` stays the same object."""
        known = self.__dict__.get("_" + name)
        if known is None or known[0] is not self.D:
            known = self.__dict__["_" + name] = (self.D, make())
        return known[1]

    @property
    def size(self) -> float:
        return max(1.0, float(np.abs(self.D.points).max()))

    # Boolean operators build trees
    def __or__(self, other):
        return VModel("union", [_node(self), _node(other)])

    def __sub__(self, other):
        return VModel("subtract", [_node(self), _node(other)])

    def __and__(self, other):
        return VModel("intersect", [_node(self), _node(other)])


def _box_gap(points: np.ndarray, boxes: np.ndarray, chunk: int = 1 << 21) -> np.ndarray:
    """Distance (N,) from each point (N, 3) to the nearest of ``boxes`` (E, 3, 2), in chunks of points so that
    no more than ``chunk`` point-box pairs are held at once."""
    out = np.empty(len(points))
    step = max(1, chunk // max(1, len(boxes)))
    for a in range(0, len(points), step):
        out[a:a + step] = box_gaps(points[a:a + step], boxes).min(axis=1)
    return out


def _node(x):
    if isinstance(x, (Primitive, VModel)):
        return x
    raise TilingError(f"V-model operands must be Primitives or V-models, got {show(x)}")


@dataclass
class VCell:
    """A V-cell: the zone of the model inside exactly the primitives ``inside`` (and outside the others).

    ``owner``: the positive primitive of highest priority among ``inside`` (it tiles the cell);
    ``trimmed_by``: the primitives whose boundaries bound the cell (trimming surfaces: the boundaries of the
    primitives it is inside, and of those it borders from outside); ``fraction``: its share of the samples.
    """

    inside: tuple
    owner: Primitive
    trimmed_by: tuple
    fraction: float


@dataclass(eq=False)
class VModel:
    """A Boolean tree: ``op`` in ('union', 'subtract', 'intersect') over two children."""

    op: str
    children: list = field(default_factory=list)

    __or__ = Primitive.__or__
    __sub__ = Primitive.__sub__
    __and__ = Primitive.__and__

    def __repr__(self) -> str:
        """The Boolean expression of primitive names, e.g. ``VModel((body | wing) - hole)``."""
        return f"VModel({self._expression()})"

    def _expression(self) -> str:
        sign = {"union": "|", "subtract": "-", "intersect": "&"}.get(self.op, self.op)
        terms = [c.name if isinstance(c, Primitive) else f"({c._expression()})" for c in self.children]
        return f" {sign} ".join(terms)

    def primitives(self) -> list[Primitive]:
        """Every primitive of the tree, left to right, once."""
        out = []
        for c in self.children:
            for p in ([c] if isinstance(c, Primitive) else c.primitives()):
                if p not in out:
                    out.append(p)
        return out

    def positive(self) -> list[Primitive]:
        """The primitives that carry tiles: union and intersection operands, the left side of subtractions."""
        out = []
        for i, c in enumerate(self.children):
            if self.op == "subtract" and i == 1:
                continue
            for p in ([c] if isinstance(c, Primitive) else c.positive()):
                if p not in out:
                    out.append(p)
        return out

    def contains_from(self, inside: dict) -> np.ndarray:
        """Membership of points given each primitive's membership ``inside[primitive] (N,)``."""
        vals = [inside[c] if isinstance(c, Primitive) else c.contains_from(inside) for c in self.children]
        if self.op == "union":
            return vals[0] | vals[1]
        if self.op == "intersect":
            return vals[0] & vals[1]
        return vals[0] & ~vals[1]

    def contains(self, points: np.ndarray) -> np.ndarray:
        """Whether physical points (N, 3) lie in the V-model (evaluated lazily, as :meth:`territory`)."""
        pts = np.asarray(points, float)
        return self._lazy(None, pts, np.arange(len(pts)))

    def territory(self, owner: Primitive, points: np.ndarray) -> np.ndarray:
        """Whether points of ``owner`` (inside it by construction) are tiled by ``owner``: in the model and in no
        positive primitive of higher priority.  The tree is evaluated lazily: a primitive is asked only about
        the points its operation can still decide (a point outside the left side of an intersection never
        meets the right side), which saves most of the point inversions."""
        pts = np.asarray(points, float)
        keep = self._lazy(owner, pts, np.arange(len(pts)))
        for p in self.positive():
            if p is not owner and p.priority > owner.priority:
                idx = np.flatnonzero(keep)
                keep[idx[p.contains(pts[idx])]] = False
        return keep

    def _lazy(self, owner: Primitive, pts: np.ndarray, idx: np.ndarray) -> np.ndarray:
        """Membership (len(pts),) of pts[idx] (False elsewhere), asking each primitive about as few as possible."""
        def leaf(c, sub):
            out = np.zeros(len(pts), bool)
            if len(sub):
                out[sub] = True if c is owner else c.contains(pts[sub])
            return out

        def node(c, sub):
            return leaf(c, sub) if isinstance(c, Primitive) else c._lazy(owner, pts, sub)

        left = node(self.children[0], idx)
        if self.op == "union":
            return left | node(self.children[1], idx[~left[idx]])
        if self.op == "intersect":
            return node(self.children[1], idx[left[idx]])
        return left & ~node(self.children[1], idx[left[idx]])

    def cells(self, per_dir: int = 12) -> list[VCell]:
        """The V-cells of the model, found by sampling every primitive on a ``per_dir``^3 parameter grid: each
        sample's membership signature (which primitives contain it) names its cell; a primitive trims the
        cell when a sample of the cell lies within one grid step of its boundary."""
        prims = self.primitives()
        pts = np.concatenate([_samples(p.D, per_dir) for p in prims])
        inside = {p: p.contains(pts) for p in prims}
        keep = self.contains_from(inside)
        sig = np.stack([inside[p] for p in prims], 1)[keep]
        kept = pts[keep]
        step = max(float(np.ptp(p.D.points.reshape(-1, 3), axis=0).max()) for p in prims) / (per_dir - 1)
        out = []
        for row in np.unique(sig, axis=0):
            sel = np.all(sig == row, axis=1)
            members = tuple(p for p, on in zip(prims, row) if on)
            owners = [p for p in self.positive() if p in members]
            near = tuple(p for p, on in zip(prims, row) if on or
                         np.any(p.distance(kept[sel][:: max(1, int(sel.sum()) // 200)]) < step))
            out.append(VCell(members, max(owners, key=lambda p: p.priority) if owners else None, near,
                             float(sel.mean())))
        return out

    def check(self) -> None:
        """Refuse trees whose tiling is ambiguous: positive primitives of equal priority that overlap."""
        pos = self.positive()
        if not pos:
            raise TilingError("the V-model has no primitive that carries tiles (everything is subtracted)")
        for i, a in enumerate(pos):
            for b in pos[i + 1:]:
                if a.priority == b.priority and _overlap(a, b):
                    raise TilingError(f"primitives {show(a.name)} and {show(b.name)} overlap and have the same "
                                      f"priority {a.priority}: which one tiles their common V-cell is undefined; "
                                      "give them different priorities")
        self._check_intersections()

    def _check_intersections(self) -> None:
        if self.op == "intersect":
            a, b = ([c] if isinstance(c, Primitive) else c.primitives() for c in self.children)
            if not any(_overlap(p, q) for p in a for q in b):
                raise TilingError(f"the intersection of {[p.name for p in a]} and {[q.name for q in b]} is empty: "
                                  "the primitives do not overlap")
        for c in self.children:
            if isinstance(c, VModel):
                c._check_intersections()


def _samples(D: BSpline, n: int = 9) -> np.ndarray:
    """Physical points of an n^3 grid over D's parameter domain."""
    axes = [np.linspace(lo, hi, n) for lo, hi in D.domain]
    return D.evaluate(np.stack(np.meshgrid(*axes, indexing="ij"), -1).reshape(-1, 3))[:, :3]


def _overlap(a: Primitive, b: Primitive) -> bool:
    """Whether two primitives share volume (a's or b's sample points inside the other)."""
    return bool(b.contains(_samples(a.D)).any() or a.contains(_samples(b.D)).any())
