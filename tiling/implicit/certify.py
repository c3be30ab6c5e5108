"""Connectivity of random implicit structures certified on the spline itself, not on samples.

The sampled steps of :mod:`tiling.implicit.connect` make the structure
connected on the samples of the build resolution; between samples the
field can still dip below zero (a neck that parts at a finer sampling) or
rise above it (an island no sample hit), and a finer ``surface(r)`` then
shows more components.  This module proves connectivity on F itself.

Every knot span of the global field is split into ``per_span`` parts per
direction; on each sub-box F is one polynomial with Bernstein coefficients
(convex combinations of the B-spline coefficients supporting the box;
:mod:`tiling.implicit.boxes`), so

* all coefficients > 0: F > 0 on the closed box (a *positive* box, P);
  all < 0: F < 0 on it (*negative*, N); otherwise *mixed*;
* all Bernstein coefficients of dF/dx_k > 0 on a mixed box: F increases
  strictly along +x_k there, so every point of the box with F > 0 reaches
  the box's +x_k face with F still > 0, and goes on into the neighbour
  across it (and likewise for the other signs and directions).

A box *joins* the main region on the positive side when the largest
face-connected set of P boxes (the seeds; D's outside when shelled) is
reached from it along these edges: a P box to any face neighbour that
joins (their shared face is positive), a mixed box across a face towards
which F rises (reachability by one breadth-first search,
scipy.sparse.csgraph).  Then every positive point of the box is joined to
the seeds.  Boxes left doubtful are split (2^3 up to 8^3 children) and
their children judged the same way with the neighbours' verdicts.  When
every P and mixed box joins, the region F > 0 is connected; the negative
side alike with falling directions, D's outside counting as negative
unless the structure is shelled (then each void need only reach a negative
box).  The closed surface of a region whose inside and outside are both
connected has one component (each component of a closed surface in space
separates it: Jordan-Brouwer).

A sampling resolves that topology only if nothing is thinner than its
step.  The certificate also asks that no critical value of F, nor of F on
an open face of D, lie within ``MARGIN`` of zero (every box whose bounds
meet [-MARGIN, MARGIN] is, down to 8^3 children, monotone in a direction
along the faces it touches): no neck, island, pocket or dome then appears
or vanishes as the level moves by MARGIN.  It does not bound thickness: a
sheet can be thinner than a step where F is steep.

Where the certificate fails, coefficients are changed as the paper's steps
do (Massarwi et al. 2018, Section 4.2): a near-critical place has its free
supporting coefficients nudged to at least ``NUDGE`` from zero on the side
its values lean to; every group of boxes that does not join is joined to
the joined ones by a least-cost path of boxes whose supporting free
coefficients are raised to at least +1/2 (lowered to -1/2 on the negative
side), which makes the path's boxes P (N), or, walled in by fixed
coefficients, is turned to the other sign; a spanning-tree face without a
pair of P boxes across it gets one.  The caller repeats all steps until
the certificate holds unchanged (:class:`Certifier`).
"""

from __future__ import annotations

import numpy as np
from scipy import ndimage
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import breadth_first_order, dijkstra

from geometry.ranges import concatenated_ranges

from tiling.implicit.boxes import BAND, BoxGrid, classify, judge, judge_children, sign_at
from tiling.implicit.connect import BRIDGE, grid_graph, trace

__all__ = ["Certifier", "MARGIN"]

SPLITS = (2, 2, 4, 4, 8, 8, 8)  # the children per direction of doubtful boxes, pass by pass
PUSHES = 3  # near-critical pushes of one box each way (first where it leans) before it is left as held
MARGIN = BAND  # no critical value of F within MARGIN of zero (coefficients live in [-1, 1]; bits are there)
NUDGE = 0.25  # near-critical places: free supporting coefficients pushed to at least this far from zero


def _graph(sign, mono, side, exits, seeds=None):
    """The joining edges of boxes in blocks (L, a, b, c), reversed (CSR; node ``sign.size`` is "joined").

    A box of the side's sign joins any face neighbour that joins (their shared
    face is of that sign); a mixed box joins a neighbour across a face towards
    which F moves away from zero (rises on the positive side, falls on the
    negative).  Crossing face j (0: -x, 1: +x, 2: -y, ...) of block l joins
    when ``exits[l, j]``; ``seeds`` (bool, shape of ``sign``) join by definition.
    """
    shape, n = sign.shape, sign.size
    ids = np.arange(n).reshape(shape)
    own, mixed = sign == side, sign == 0
    rows, cols = [], []
    for k in range(3):
        for step, bit in ((1, 2 * k), (-1, 2 * k + 1)):
            towards = ((mono >> (bit if side > 0 else bit ^ 1)) & 1).astype(bool)
            src = own | (mixed & towards)
            dest = np.roll(ids, -step, axis=1 + k)
            edge = np.zeros(shape, bool)
            np.moveaxis(edge, 1 + k, 0)[-1 if step > 0 else 0] = True
            through = exits[:, 2 * k + (step > 0)].reshape(-1, 1, 1, 1)
            dest = np.where(edge, np.where(through, n, -1), dest)
            keep = src & (dest >= 0)
            rows.append(ids[keep])
            cols.append(dest[keep])
    if seeds is not None:
        rows.append(ids[seeds])
        cols.append(np.full(np.count_nonzero(seeds), n))
    src, dest = np.concatenate(rows), np.concatenate(cols)
    return csr_matrix((np.ones(len(src)), (dest, src)), shape=(n + 1, n + 1))


def _reach(graph, shape):
    """Boxes (bool, ``shape``) reached from the "joined" node along the reversed edges (one breadth-first search)."""
    n = int(np.prod(shape))
    reached = np.zeros(n + 1, bool)
    reached[breadth_first_order(graph, n, directed=True, return_predecessors=False)] = True
    return reached[:n].reshape(shape)


def _spread(graph, ok, new):
    """``ok`` grown by what the ``new`` boxes reach (bool arrays of one shape), front by front along the edges."""
    flat = ok.ravel().copy()
    front = np.flatnonzero(new.ravel() & ~flat)
    while len(front):
        flat[front] = True
        starts, ends = graph.indptr[front], graph.indptr[front + 1]
        counts = ends - starts
        pos = concatenated_ranges(starts, counts)
        nxt = graph.indices[pos]
        front = np.unique(nxt[(nxt < len(flat)) & ~flat[np.minimum(nxt, len(flat) - 1)]])
    return flat.reshape(ok.shape)


def _main_component(sign, side):
    """The largest face-connected component of boxes of ``side``'s sign (bool)."""
    label, n = ndimage.label(sign == side)  # 6-connected: joined boxes share a whole face
    if n == 0:
        return np.zeros(sign.shape, bool)
    return label == 1 + int(np.argmax(np.bincount(label.ravel())[1:]))


def _exits(ok, boxes, outside):
    """Per box (L, 3) and face (6): does the coarse neighbour across it join (or D's outside, where it counts)?"""
    out = np.zeros((len(boxes), 6), bool)
    for k in range(3):
        for step in (-1, 1):
            nb = boxes.copy()
            nb[:, k] += step
            inside = (nb[:, k] >= 0) & (nb[:, k] < ok.shape[k])
            nb[:, k] = np.clip(nb[:, k], 0, ok.shape[k] - 1)
            out[:, 2 * k + (step > 0)] = np.where(inside, ok[tuple(nb.T)], outside)
    return out


def _certified(G, grid, sign, mono, side, outside, connected):
    """Boxes whose points of ``side``'s sign all join the main region: coarse reachability, then doubtful boxes
    split (``SPLITS``: 2^3 up to 8^3 children) and judged with their neighbours' verdicts, until none is left."""
    if connected and not outside:
        seeds = _main_component(sign, side)
    else:
        seeds = (sign == side) if not connected else np.zeros(sign.shape, bool)
    graph = _graph(sign[None], mono[None], side, np.full((1, 6), outside), seeds[None])
    ok = _reach(graph, sign.shape)
    for split in SPLITS:
        boxes = np.argwhere(((sign == side) | (sign == 0)) & ~ok)
        if len(boxes) == 0:
            break
        clow, chigh, cmono = judge(G, grid, boxes, split)
        csign = sign_at(clow, chigh)
        cok = _reach(_graph(csign, cmono, side, _exits(ok, boxes, outside)), csign.shape)
        settled = np.all((csign == -side) | cok, axis=(1, 2, 3))
        if not settled.any():
            continue
        new = np.zeros(ok.shape, bool)
        new[tuple(boxes[settled].T)] = True
        ok = _spread(graph, ok, new)  # what the newly settled boxes join (the rest is known)
    return ok


def _allowed(boxes, children, shape, split, open_faces):
    """Monotonicity bits that count for child ``children[l]`` (of ``split``) of box ``boxes[l]`` (L,).

    On an open structure (``open_faces``: D's boundary is no wall of fixed
    sign) a child touching D's boundary face normal to x_k must be monotone
    along the face, not across it: the zero set meets the face, and the face
    is a stratum of its own (a dome that barely touches it is critical there).
    """
    out = np.full(len(boxes), 0b111111, np.uint8)
    if not open_faces:
        return out
    for k in range(3):
        touch = ((boxes[:, k] == 0) & (children[:, k] == 0)) | ((boxes[:, k] == shape[k] - 1)
                                                                  & (children[:, k] == split - 1))
        out[touch] &= ~np.uint8(0b11 << 2 * k)
    return out


def _unstable(G, grid, low, high, mono, open_faces, known=None):
    """Boxes (bool) where the zero set may be near-critical: F's range meets [-MARGIN, MARGIN] and some part of
    the box stays, down to 8^3 children, neither away from that band nor monotone in a direction that counts
    (:func:`_allowed`).

    Where every box passes, F has no critical point (of F, or of F on D's
    faces) with a value within MARGIN of zero, so the zero set keeps its
    topology when the level moves by MARGIN: no neck, pocket or dome thinner
    than that change of F, which a sampling would split or miss.  Only the
    children that fail are split again (2, 4, 8 per direction).  Boxes
    ``known`` (bool) to pass already are not judged again.
    """
    near = (low <= MARGIN) & (high >= -MARGIN)
    if known is not None:
        near &= ~known
    boxes = np.argwhere(near)
    zero = np.zeros((len(boxes), 3), np.int64)
    bad = (mono[near] & _allowed(boxes, zero, low.shape, 1, open_faces)) == 0
    rows, children, split = boxes[bad], zero[bad], 1
    eight = np.stack(np.unravel_index(np.arange(8), (2, 2, 2)), 1)
    while len(rows) and split < max(SPLITS):
        rows, children, split = np.repeat(rows, 8, axis=0), (2 * children[:, None] + eight).reshape(-1, 3), 2 * split
        clow, chigh, cmono = judge_children(G, grid, rows, children, split)
        fail = ((clow <= MARGIN) & (chigh >= -MARGIN)
                & ((cmono & _allowed(rows, children, low.shape, split, open_faces)) == 0))
        rows, children = rows[fail], children[fail]
    out = np.zeros(low.shape, bool)
    out[tuple(rows.T)] = True
    return out


def _groups(label, ids):
    """Flat box indices of each labelled group in ``ids`` (a list of arrays)."""
    flat = label.ravel()
    nodes = np.flatnonzero(np.isin(flat, ids))
    nodes = nodes[np.argsort(flat[nodes], kind="stable")]
    return np.split(nodes, np.flatnonzero(np.diff(flat[nodes])) + 1) if len(nodes) else []


def _tree_face_pairs(grid, sign, blocked, cells, tree_edges):
    """Box pairs to raise: one for every tree face with no pair of face-adjacent P boxes across it, (L, 3).

    The pair is chosen among boxes not ``blocked`` (that can be made
    positive), preferring boxes that are not negative already.
    """
    out = []
    pc = np.asarray(grid.per_cell)
    for e in tree_edges:
        a, b = cells[e[0]], cells[e[1]]
        k = int(np.flatnonzero(a != b)[0])
        lo = np.minimum(a, b)
        window = [slice(lo[j] * pc[j], (lo[j] + 1) * pc[j]) for j in range(3)]
        left, right = list(window), list(window)
        left[k] = (lo[k] + 1) * pc[k] - 1
        right[k] = (lo[k] + 1) * pc[k]
        both = (sign[tuple(left)] == 1) & (sign[tuple(right)] == 1)
        if both.any():
            continue
        score = (sign[tuple(left)] >= 0).astype(float) + (sign[tuple(right)] >= 0)
        score[blocked[tuple(left)] | blocked[tuple(right)]] = -np.inf
        if not np.isfinite(score.max()):
            continue  # every pair is held negative by fixed coefficients: the sampled face step decides
        i, j = np.unravel_index(np.argmax(score), score.shape)
        box = np.array([w.start for w in window])
        box[[m for m in range(3) if m != k]] += [i, j]
        box[k] = left[k]
        out.extend([box.copy(), box + np.eye(3, dtype=int)[k]])
    return np.array(out, dtype=int).reshape(-1, 3)


class Certifier:
    """The certificate's state across the rounds of a build: the box grid, its support windows, and the verdicts
    (bounds, monotonicity) of the coefficients last seen, so that a round re-judges only the boxes whose
    supporting coefficients changed."""

    def __init__(self, grid: BoxGrid, shape):
        self.grid = grid
        self.W = [grid.window(k, n) for k, n in enumerate(shape)]  # (nb_k, n_k) support indicators
        self.G = self.verdicts = None
        self.pushes = np.zeros(grid.shape, np.uint8)  # near-critical pushes per box
        self.stable = np.zeros(grid.shape, bool)  # boxes that passed the near-critical test, until they change

    def _boxes_on(self, mask) -> np.ndarray:
        """Boxes (bool, grid shape) supported by any coefficient of ``mask`` (bool, coefficient shape)."""
        return np.einsum("ai,bj,ck,ijk->abc", *self.W, mask.astype(float), optimize=True) > 0

    def classify(self, G):
        """Bounds and monotonicity (low, high, mono) of every box of G, re-judging only boxes whose supports changed."""
        if self.G is None:
            self.verdicts = classify(G, self.grid)
        else:
            changed = self._boxes_on(G != self.G)
            self.stable &= ~changed
            boxes = np.argwhere(changed)
            if len(boxes):
                for old, new in zip(self.verdicts, judge(G, self.grid, boxes)):
                    old[tuple(boxes.T)] = new[:, 0, 0, 0]
        self.G = G.copy()
        return self.verdicts

    @staticmethod
    def capped(B) -> bool:
        """Whether D's boundary layers of coefficients are held fixed (a capped structure)."""
        return bool(np.all(B.fixed[0]) and np.all(B.fixed[-1]))

    def blocked(self, B, side):
        """Boxes that cannot be made of ``side``'s sign: a supporting coefficient is fixed with the other sign."""
        return self._boxes_on(B.fixed & (side * B.G <= 0))

    def set_boxes(self, B, boxes, side, value=BRIDGE):
        """Free coefficients supporting ``boxes`` (L, 3) raised to at least +value (side +1) or lowered to -value."""
        W = [self.W[k][boxes[:, k]] for k in range(3)]
        mask = (np.einsum("la,lb,lc->abc", *W, optimize=True) > 0) & ~B.fixed
        for _ in range(30 if B.c1 else 1):
            # With C1 the layers beside a cell boundary stay symmetric about it (Eq. 8): raise, symmetrize, again;
            # the lopsided part halves each time, so the values settle on the side's sign.
            before = B.G.copy()
            B.G[mask] = side * np.maximum(side * B.G[mask], value)
            B.enforce_c1()
            if np.abs(B.G - before).max() < 1e-3:
                break

    def join(self, B, sign, targets, groups, side, outside):
        """Join every group (flat box indices) to ``targets`` along least-cost box paths (Dijkstra); returns joins."""
        shape, n = sign.shape, sign.size
        if outside:  # a path may also end at D's boundary, where the outside has the side's sign
            targets = targets.copy()
            for k in range(3):
                np.moveaxis(targets, k, 0)[[0, -1]] = True
        blocked = self.blocked(B, side) & (sign != side)
        cost = np.where(sign == side, 1e-6, np.where(sign == 0, 1.0, 2.0)).ravel()
        e = grid_graph(shape)
        e = np.concatenate([e, e[:, ::-1]])
        e = e[~blocked.ravel()[e[:, 0]]]  # a path may end in a blocked box (the group's own), not pass through one
        graph = csr_matrix((cost[e[:, 1]], (e[:, 0], e[:, 1])), shape=(n, n))
        start = np.flatnonzero(targets.ravel() & ~blocked.ravel())
        if len(start) == 0:
            return 0, 0
        dist, pred, _ = dijkstra(graph, indices=start, min_only=True, return_predecessors=True)
        paths, stuck = [], []
        for nodes in groups:
            j = nodes[np.argmin(dist[nodes])]
            if not np.isfinite(dist[j]):  # walled in by fixed coefficients of the other sign: remove the group instead
                stuck.append(nodes)
                continue
            paths.append(trace(pred, j))
        if paths:
            self.set_boxes(B, np.stack(np.unravel_index(np.concatenate(paths), shape), 1), side)
        if stuck:
            self.set_boxes(B, np.stack(np.unravel_index(np.concatenate(stuck), shape), 1), -side)
        return len(paths), len(stuck)

    def round(self, B, cells, tree_edges, shell, stats) -> int:
        """One round of the certificate (module notes) on the builder's coefficients; returns the repairs made.

        0: the certificate holds (``stats["certificate"]["certified"]``), or
        what fails is held by fixed coefficients (a capped boundary, the tree
        faces' anchors) that no repair may change: then ``certified`` is
        False and ``held`` counts the places.  The record also has the boxes,
        how many are mixed and uncertified, and the repairs so far: joins on
        each side, groups removed (walled in by fixed coefficients), tree
        faces, near-critical places.
        """
        before = B.G.copy()
        record = stats.setdefault("certificate", {"per_cell": self.grid.per_cell, "margin": MARGIN, "raised": 0,
                                                  "lowered": 0, "removed": 0, "tree faces": 0, "near-critical": 0})
        work = self._repair(B, cells, tree_edges, shell, record)
        if work and np.array_equal(before, B.G):
            record.update(certified=False, held=work)
            return 0
        record["certified"] = work == 0 and record.get("near-critical held", 0) == 0
        return work

    def _push(self, B, low, high, mono, shell, record) -> int:
        """Near-critical places: each group of boxes pushed away from zero, to the side its values lean to (the
        other way after PUSHES pushes); returns the groups pushed.  A push moves the free supporting
        coefficients only, to at least NUDGE from zero, so a critical value held by fixed coefficients may stay:
        a place pushed PUSHES times each way and still near-critical (held by fixed coefficients, or by a
        neighbouring place pushed the other way) is left, and reported (certified False)."""
        unstable = _unstable(B.G, self.grid, low, high, mono, shell is None and not self.capped(B), self.stable)
        self.stable |= ~unstable
        held = unstable & (self.pushes >= 2 * PUSHES)
        record["near-critical held"] = int(ndimage.label(held, structure=np.ones((3, 3, 3)))[1])
        unstable &= ~held
        label, n = ndimage.label(unstable, structure=np.ones((3, 3, 3)))
        if not n:
            return 0
        self.pushes[unstable] += 1
        record["near-critical"] += n
        lean = ndimage.mean(low + high, label, np.arange(1, n + 1)) >= 0  # per group
        lean ^= ndimage.maximum(self.pushes, label, np.arange(1, n + 1)) > PUSHES  # the other way after PUSHES
        for side in (1, -1):
            boxes = np.argwhere(unstable & np.isin(label, 1 + np.flatnonzero(lean == (side > 0))))
            if len(boxes):
                self.set_boxes(B, boxes, side, value=NUDGE)
        return n

    def _repair(self, B, cells, tree_edges, shell, record) -> int:
        """The checks of one round in order, repairing the first that fails; returns its repairs (0: all hold)."""
        low, high, mono = self.classify(B.G)
        sign = sign_at(low, high)
        record["boxes"] = int(sign.size)
        record["mixed"] = int(np.count_nonzero(sign == 0))
        pairs = _tree_face_pairs(self.grid, sign, self.blocked(B, 1), cells, tree_edges)
        if len(pairs):
            self.set_boxes(B, pairs, +1)
            record["tree faces"] += len(pairs) // 2
            return len(pairs) // 2
        # near-critical places first (they move the most), pushed until none is left before the other checks
        pushed = 0
        for _ in range(2 * PUSHES + 1):
            n = self._push(B, low, high, mono, shell, record)
            if not n:
                break
            pushed += n
            low, high, mono = self.classify(B.G)
        if pushed:
            return pushed
        sign = sign_at(low, high)
        record["uncertified"] = 0
        # the inside joined through the shell if there is one; the outside (and a shell's voids) negative
        for side, outside, connected in ((1, shell is not None, True), (-1, shell is None, shell is None)):
            ok = _certified(B.G, self.grid, sign, mono, side, outside, connected)
            bad = ((sign == side) | (sign == 0)) & ~ok
            record["uncertified"] += int(np.count_nonzero(bad))
            label, n = ndimage.label(bad, structure=np.ones((3, 3, 3)))
            if n:
                joined, removed = self.join(B, sign, ok, _groups(label, np.arange(1, n + 1)), side, outside)
                record["raised" if side > 0 else "lowered"] += joined
                record["removed"] += removed
                if joined + removed:
                    return joined + removed  # the rest is judged on the changed coefficients next round
        return 0
