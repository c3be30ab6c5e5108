"""Adaptive topological subdivision of a map's parameter domain (Massarwi et al. 2018, Section 5, Algorithm 1).

``TopoSubdiv``: a parameter box whose longest edge image (the chord between
the images of the edge's end corners under D) exceeds ``epsilon`` is halved
across the direction of that edge, recursively.  Here the recursion runs in
rounds over all boxes at once (one batched evaluation of the corners per
round), starting from D's Bezier boxes so that every cell lies in one knot
span of D (exact composition works per Bezier piece).  ``directions``
restricts the directions that may be split: ``(2,)`` gives the layers of
Section 5.2.

The result, :class:`CellComplex`, classifies every face of every cell as in
Section 5.1: ``boundary`` (on D's boundary), ``neighbour`` (one neighbour
with the identical face), ``complex`` (several, smaller neighbours: a
bifurcation across this face) or ``partial`` (the other side of a complex
face: one larger neighbour).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from geometry import BSpline
from geometry.errors import show
from geometry.faces import FACE_NAMES
from geometry.ranges import concatenated_ranges
from geometry.resources import check_memory

from tiling.errors import TilingError
from geometry.tolerances import ON_DOMAIN
from geometry.numbers import is_real

__all__ = ["topo_subdiv", "CellComplex", "FACE_KINDS"]

FACE_KINDS = ("boundary", "neighbour", "complex", "partial")
_BYTES_PER_CELL = 600  # box, corners, edge lengths and the face table of one cell (NumPy arrays)
_CORNERS = np.array([[i, j, k] for i in (0, 1) for j in (0, 1) for k in (0, 1)])  # (8, 3), index 4 i + 2 j + k


def _edges():
    """The 12 edges of a box as corner index pairs, grouped by direction: (3, 4, 2)."""
    out = []
    for k in range(3):
        pairs = []
        for c in range(8):
            if _CORNERS[c, k] == 0:
                d = _CORNERS[c].copy()
                d[k] = 1
                pairs.append((c, int(4 * d[0] + 2 * d[1] + d[2])))
        out.append(pairs)
    return np.array(out)


_EDGES = _edges()


@dataclass
class CellComplex:
    """The cells of a topological subdivision and the classification of their faces.

    ``boxes``: (N, 3, 2) parameter boxes in D's domain; ``longest``: (N,)
    longest edge image of each cell (model units); ``faces``: per cell a
    dict {face name: (kind, neighbour cell indices)} with kind in
    :data:`FACE_KINDS`.
    """

    outer: BSpline
    epsilon: float
    boxes: np.ndarray
    longest: np.ndarray
    faces: list = field(default_factory=list)
    rounds: int = 0

    def __len__(self):
        return len(self.boxes)

    def kinds(self) -> dict:
        """How many faces of each kind (a complex face and its partial neighbours are counted on both sides)."""
        out = dict.fromkeys(FACE_KINDS, 0)
        for f in self.faces:
            for kind, _ in f.values():
                out[kind] += 1
        return out

    def adjacency(self) -> np.ndarray:
        """Cell pairs (E, 2), i < j, that share a face (any part of one)."""
        pairs = {(min(i, j), max(i, j)) for i, f in enumerate(self.faces) for _, nb in f.values() for j in nb}
        return np.array(sorted(pairs), dtype=np.int64).reshape(-1, 2)

    def edge_images(self) -> np.ndarray:
        """Image lengths (N, 3) of the longest edge of each cell per direction (chords, model units)."""
        return edge_lengths(self.outer, self.boxes)


def edge_lengths(D, boxes) -> np.ndarray:
    lo, hi = boxes[:, :, 0], boxes[:, :, 1]
    corners = lo[:, None, :] + _CORNERS[None, :, :] * (hi - lo)[:, None, :]  # (N, 8, 3)
    x = D.evaluate(corners.reshape(-1, 3))[:, :3].reshape(len(boxes), 8, 3)
    d = np.linalg.norm(x[:, _EDGES[..., 1]] - x[:, _EDGES[..., 0]], axis=-1)  # (N, 3, 4)
    return d.max(axis=2)


def topo_subdiv(D: BSpline, epsilon: float, *, directions=(0, 1, 2), max_rounds: int = 60) -> CellComplex:
    """Algorithm 1 (TopoSubdiv) over D's parameter domain; see the module notes.

    Parameters
    ----------
    D : trivariate deformation map (model units)
    epsilon : largest allowed image of a cell edge, model units (> 0)
    directions : parameter directions that may be split; a cell whose longest
        edge lies in another direction is split along its longest allowed one
        while that one exceeds ``epsilon``

    >>> from geometry import primitives
    >>> c = topo_subdiv(primitives.box((2.0, 1.0, 1.0)), 0.6)   # edges 2, 1, 1 halved to 0.5
    >>> len(c), c.kinds()["boundary"]
    (16, 40)
    """
    if not isinstance(D, BSpline) or D.dim != 3:
        raise TilingError(f"the deformation map must be a trivariate geometry.BSpline, got {type(D).__name__}")
    if not is_real(epsilon) or not (
            np.isfinite(epsilon) and epsilon > 0):
        raise TilingError(f"epsilon must be a positive length (model units), got {show(epsilon)}")
    dirs = tuple(directions) if isinstance(directions, (list, tuple)) else None
    if not dirs or any(d not in (0, 1, 2) for d in dirs) or len(set(dirs)) != len(dirs):
        raise TilingError(f"directions must be distinct parameter directions from (0, 1, 2), got {show(directions)}")
    allowed = np.isin(np.arange(3), dirs)
    spans = [D.breakpoints(k) for k in range(3)]
    grids = np.meshgrid(*[np.arange(len(b) - 1) for b in spans], indexing="ij")
    idx = np.stack([g.ravel() for g in grids], 1)
    boxes = np.stack([np.stack([spans[k][idx[:, k]], spans[k][idx[:, k] + 1]], 1) for k in range(3)], 1)
    # a lower bound of the final count: along each allowed direction, the chord of the whole domain / epsilon
    whole = edge_lengths(D, D.domain[None].astype(float))[0]
    estimate = float(np.prod(np.where(allowed, np.maximum(whole / epsilon, 1.0), 1.0)))
    check_memory(estimate * _BYTES_PER_CELL, f"the subdivision for epsilon={show(epsilon)} (at least "
                 f"{estimate:.3g} cells)", TilingError, "raise epsilon")
    for rounds in range(max_rounds + 1):
        lengths = np.where(allowed, edge_lengths(D, boxes), -np.inf)
        axis = np.argmax(lengths, axis=1)
        split = lengths[np.arange(len(boxes)), axis] >= epsilon  # Algorithm 1, line 3: stop when below
        if not split.any():
            break
        check_memory((len(boxes) + split.sum()) * _BYTES_PER_CELL, f"the subdivision for epsilon={show(epsilon)} "
                     f"({len(boxes) + int(split.sum()):,} cells after round {rounds + 1})", TilingError,
                     "raise epsilon")
        keep, cut, ax = boxes[~split], boxes[split], axis[split]
        mid = 0.5 * (cut[np.arange(len(cut)), ax, 0] + cut[np.arange(len(cut)), ax, 1])
        left, right = cut.copy(), cut.copy()
        left[np.arange(len(cut)), ax, 1] = mid
        right[np.arange(len(cut)), ax, 0] = mid
        boxes = np.concatenate([keep, left, right])
    else:
        raise TilingError(f"the subdivision did not end in {max_rounds} rounds (a degenerate edge of D that "
                          f"never shrinks below epsilon={show(epsilon)}?); raise epsilon")
    # a deterministic order: lexicographic by box corner (w fastest)
    order = np.lexsort((boxes[:, 2, 0], boxes[:, 1, 0], boxes[:, 0, 0]))
    boxes = boxes[order]
    longest = np.where(allowed, edge_lengths(D, boxes), 0.0).max(axis=1)
    return CellComplex(D, float(epsilon), boxes, longest, classify_faces(boxes, D.domain), rounds)


def classify_faces(boxes: np.ndarray, domain: np.ndarray) -> list:
    """Per cell {face: (kind, neighbours)} for a subdivision of ``domain`` into ``boxes`` (N, 3, 2).

    Faces meet on planes: for every direction the cells are grouped by the
    coordinate of their upper face, and every lower face on the same plane
    is tested for overlap (positive area) with the group only.
    """
    n = len(boxes)
    tol = ON_DOMAIN * float(np.abs(domain).max() + 1.0)
    out = [dict() for _ in range(n)]
    nested = boxes.tolist()
    for k in range(3):
        rest = [j for j in range(3) if j != k]
        upper: dict = {}
        for i in range(n):
            upper.setdefault(nested[i][k][1], []).append(i)
        lower: dict = {}
        for i in range(n):
            lower.setdefault(nested[i][k][0], []).append(i)
        for plane, below in upper.items():
            above = np.array(lower.get(plane, []), dtype=np.int64)
            below = np.array(below, dtype=np.int64)
            rb, ra = _overlapping(boxes[below][:, rest], boxes[above][:, rest], tol)  # pairs across the plane
            by_b = np.split(above[ra], np.searchsorted(rb, np.arange(1, len(below))))
            order = np.argsort(ra, kind="stable")
            by_a = np.split(below[rb[order]], np.searchsorted(ra[order], np.arange(1, len(above))))
            for r, i in enumerate(below):
                out[i][FACE_NAMES[2 * k + 1]] = _kind(nested, i, by_b[r], rest, tol)
            for c, j in enumerate(above):
                out[j][FACE_NAMES[2 * k]] = _kind(nested, j, by_a[c], rest, tol)
        for i in range(n):  # lower faces with nothing below them: D's boundary
            out[i].setdefault(FACE_NAMES[2 * k], ("boundary", ()))
            out[i].setdefault(FACE_NAMES[2 * k + 1], ("boundary", ()))
    for i in range(n):  # FACE_NAMES order
        out[i] = {f: out[i][f] for f in FACE_NAMES}
    return out


def _overlapping(B: np.ndarray, A: np.ndarray, tol: float) -> tuple[np.ndarray, np.ndarray]:
    """Index pairs (b, a), sorted by b, of the rectangles B (nb, 2, 2) and A (na, 2, 2) that overlap with
    positive area (more than ``tol`` along both axes).

    A sweep along the first axis: A sorted by its lower end; the candidates of a rectangle b are the A whose
    lower end lies in (b_lo - longest A, b_hi), one contiguous run of the sorted array, so the work is the
    number of candidates, not nb x na (a thin slab at fine epsilon has 16k x 16k cells on a plane)."""
    if not len(A) or not len(B):
        return np.zeros(0, np.int64), np.zeros(0, np.int64)
    order = np.argsort(A[:, 0, 0], kind="stable")
    lo_sorted = A[order, 0, 0]
    longest = float((A[:, 0, 1] - A[:, 0, 0]).max())
    start = np.searchsorted(lo_sorted, B[:, 0, 0] - longest - tol, side="left")
    stop = np.searchsorted(lo_sorted, B[:, 0, 1] - tol, side="left")
    count = np.maximum(stop - start, 0)
    rb = np.repeat(np.arange(len(B)), count)
    pos = concatenated_ranges(start, count)
    ra = order[pos]
    lo = np.maximum(B[rb, :, 0], A[ra, :, 0])
    hi = np.minimum(B[rb, :, 1], A[ra, :, 1])
    keep = np.all(hi - lo > tol, axis=-1)
    rb, ra = rb[keep], ra[keep]
    ranked = np.lexsort((ra, rb))
    return rb[ranked], ra[ranked]


def _kind(boxes, i, nbrs, rest, tol):
    """(kind, neighbours) of cell i's face whose neighbours across it are ``nbrs``; ``boxes`` nested lists
    (N, 3, 2) of floats (a face's two intervals: plain floats, far cheaper than small arrays)."""
    nbrs = tuple(int(j) for j in nbrs)
    if not nbrs:
        return "boundary", ()
    if len(nbrs) > 1:
        return "complex", nbrs
    mine, theirs = [boxes[i][r] for r in rest], [boxes[nbrs[0]][r] for r in rest]
    if all(abs(t[0] - m[0]) <= tol and abs(t[1] - m[1]) <= tol for t, m in zip(theirs, mine)):
        return "neighbour", nbrs
    if all(t[0] <= m[0] + tol and t[1] >= m[1] - tol for t, m in zip(theirs, mine)):
        return "partial", nbrs
    return "complex", nbrs  # one smaller neighbour covering part of the face (the rest is D's boundary)
