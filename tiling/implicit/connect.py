"""The connectivity steps of random implicit micro-structures (Massarwi et al. 2018, Sections 4.2.1-4.2.2).

All cells' coefficients live in one global array G (cells share their
boundary layers, Eq. 7); :class:`Builder` holds it with the ``fixed`` mask of
coefficients no step may change (D's boundary layers when capping, the tree
faces' anchors).  The steps only look at samples of the field (``res``
intervals per cell and direction) and change G:

* :func:`connect_faces`: every spanning-tree face changes sign on its samples;
* :func:`connect_cells`: the inside samples of every cell are one
  6-connected component (scipy.ndimage.label);
* :func:`open_cavities`: no negative pocket is enclosed by the inside region
  (each would be one more surface component).

Bridges and tunnels follow least-cost paths on the sample grid
(scipy.sparse.csgraph.dijkstra): the coefficients supporting the path's
samples are raised to at least +1/2 (or lowered to at most -1/2), so by the
partition of unity those samples become inside (outside).  Each step returns
the work it did; the caller repeats them until none is needed.
"""

from __future__ import annotations

import numpy as np
from scipy import ndimage
from scipy.sparse import coo_matrix, csr_matrix
from scipy.sparse.csgraph import connected_components, depth_first_tree, dijkstra

from geometry import knots as kn
from geometry import progress

from tiling.errors import TilingError

__all__ = ["Builder", "cell_knots", "grid_graph", "spanning_trees", "connect_faces", "connect_cells",
           "open_cavities", "trace"]

STEP = 0.25  # raise per odd iteration of a face (coefficients live in [-1, 1])
MAX_ITER = 400
BRIDGE = 0.5  # coefficients along a bridge (tunnel) are raised to at least +BRIDGE (lowered to -BRIDGE)


def cell_knots(degree, controls):
    """Interior knots of one cell on [0, 1] (uniform), so that it has ``controls`` coefficients."""
    return np.linspace(0.0, 1.0, controls - degree + 1)[1:-1]



def grid_graph(shape):
    """6-neighbour pairs of a 3-D grid of ``shape`` (the cells' face adjacency): (E, 2) flat indices, each once."""
    idx = np.arange(int(np.prod(shape))).reshape(shape)
    edges = []
    for k in range(3):
        a = np.take(idx, np.arange(shape[k] - 1), axis=k).ravel()
        b = np.take(idx, np.arange(1, shape[k]), axis=k).ravel()
        edges.append(np.stack([a, b], 1))
    return np.concatenate(edges)


def spanning_trees(n_cells, edges, count, rng):
    """``count`` edge-disjoint spanning trees of the cell graph, or TilingError saying how many were found.

    As in Massarwi et al. 2018 (Section 4.2.1): a depth-first spanning tree
    (scipy.sparse.csgraph), then the next one among the edges left.  A
    depth-first tree is path-like (few branches), so it leaves every cell
    most of its edges; the nodes are relabelled at random (from ``rng``) and
    the search restarted until the trees are found (or a bound says they
    cannot exist: k trees need k (cells - 1) edges).
    """
    if n_cells == 1:
        return [np.zeros((0, 2), np.int64)] * count
    best = []
    key = np.sort(edges, axis=1)
    for _ in range(64 if count * (n_cells - 1) <= len(edges) else 1):
        perm = rng.permutation(n_cells)  # random relabelling: another depth-first order
        free = np.ones(len(edges), bool)
        trees = []
        for _t in range(count):
            e = perm[key[free]]
            graph = coo_matrix((np.ones(len(e)), (e[:, 0], e[:, 1])), shape=(n_cells, n_cells)).tocsr()
            if connected_components(graph, directed=False)[0] != 1:
                break
            tree = depth_first_tree(graph, int(rng.integers(n_cells)), directed=False).tocoo()
            inv = np.argsort(perm)
            pairs = np.sort(np.stack([inv[tree.row], inv[tree.col]], 1), axis=1)
            trees.append(pairs)
            free &= ~np.isin(key[:, 0] * n_cells + key[:, 1], pairs[:, 0] * n_cells + pairs[:, 1])
        if len(trees) > len(best):
            best = trees
        if len(best) == count:
            return best
    bound = len(edges) // (n_cells - 1)
    raise TilingError(f"connectivity={count} needs {count} edge-disjoint spanning trees of the cell graph "
                      f"({n_cells} cells, {len(edges)} shared faces: at most {bound} can exist); {len(best)} found; "
                      f"use connectivity={max(len(best), 1)} or more cells")


class Builder:
    """The global coefficient array G, the fixed mask and the sampling operators of the steps."""

    def __init__(self, counts, degree, controls, continuity):
        self.counts, self.d, self.N, self.c1 = tuple(counts), degree, controls, continuity == "C1"
        self.n = controls - 1
        self.G = np.zeros(tuple(c * self.n + 1 for c in counts))
        self.fixed = np.zeros(self.G.shape, bool)
        self.anchored = set()  # tree faces (cell index pairs) whose anchor is fixed
        self.passed = {}  # cell -> its coefficients when its inside samples were last found one component
        self.U = np.concatenate([np.zeros(degree + 1), cell_knots(degree, controls), np.ones(degree + 1)])
        self._basis = {}

    def cell_slices(self, cell):
        return tuple(slice(c * self.n, c * self.n + self.N) for c in cell)

    def verify(self, cell):
        """Record that ``cell``'s inside samples are one component with its present coefficients."""
        self.passed[tuple(int(x) for x in cell)] = self.G[self.cell_slices(cell)].copy()

    def verified(self, cell) -> bool:
        """Whether ``cell`` passed with the coefficients it has now (its samples depend on nothing else)."""
        old = self.passed.get(tuple(int(x) for x in cell))
        return old is not None and np.array_equal(old, self.G[self.cell_slices(cell)])

    def basis(self, res):
        """Values (res + 1, N) of one cell's basis at its ``res + 1`` samples per direction (all cells alike)."""
        if res not in self._basis:
            self._basis[res] = kn.basis_matrix(self.U, self.d, np.linspace(0.0, 1.0, res + 1)).toarray()
        return self._basis[res]

    def sampling(self, res):
        """Per direction, the global sample -> global coefficient basis values (counts res + 1, counts n + 1)."""
        if ("sampling", res) not in self._basis:
            Bm = self.basis(res)
            out = []
            for c in self.counts:
                M = np.zeros((c * res + 1, c * self.n + 1))
                for q in range(c):  # neighbours share their boundary sample, where only that layer is non-zero
                    M[q * res:(q + 1) * res + 1, q * self.n:q * self.n + self.N] = Bm
                out.append(M)
            self._basis[("sampling", res)] = out
        return self._basis[("sampling", res)]

    def cell_values(self, cells, res):
        """F at (res + 1)^3 samples of each cell in ``cells`` (C, 3): (C, res + 1, res + 1, res + 1)."""
        B = self.basis(res)
        blocks = np.stack([self.G[self.cell_slices(c)] for c in cells])
        return np.einsum("cabz,ia,jb,kz->cijk", blocks, B, B, B, optimize=True)

    def reachable(self, res, sign) -> np.ndarray:
        """Global samples that a bridge (sign +1) or tunnel (-1) can flip: bool (counts res + 1, ...).

        Setting every free supporting coefficient to ``sign * BRIDGE`` leaves
        the value at a sample at most sum_fixed B G + sign BRIDGE sum_free B
        away from the fixed part; the sample is reachable when that has the sign.
        """
        M = self.sampling(res)
        fixed = np.einsum("ia,jb,kc,abc->ijk", *M, np.where(self.fixed, self.G, 0.0), optimize=True)
        free = np.einsum("ia,jb,kc,abc->ijk", *M, (~self.fixed).astype(float), optimize=True)
        return sign * (fixed + sign * BRIDGE * free) > 0

    def set_supports(self, samples, res, raise_to=None, lower_to=None):
        """Raise (lower) to the value every free coefficient supporting the global samples (P, 3)."""
        supp = [m[samples[:, k]] > 0 for k, m in enumerate(self.sampling(res))]  # (P, n_k) each
        for p in range(len(samples)):  # a path of a few dozen samples
            ix = np.ix_(*(np.flatnonzero(s[p]) for s in supp))
            free = ~self.fixed[ix]
            if raise_to is not None:
                self.G[ix] = np.where(free, np.maximum(self.G[ix], raise_to), self.G[ix])
            if lower_to is not None:
                self.G[ix] = np.where(free, np.minimum(self.G[ix], lower_to), self.G[ix])

    def enforce_c1(self):
        """Inner layers symmetric about every shared boundary layer (Eq. 8); boundary layers unchanged."""
        if not self.c1:
            return
        for k in range(3):
            G = np.moveaxis(self.G, k, 0)
            for q in range(1, self.counts[k]):
                b = q * self.n
                delta = 0.5 * (G[b + 1] - G[b - 1])
                G[b - 1] = G[b] - delta
                G[b + 1] = G[b] + delta


def _face_view(B, a, b):
    """Direction k and global index of the face shared by cells a and b, and of its coefficients (N, N)."""
    k = int(np.flatnonzero(a != b)[0])
    lo = a if a[k] < b[k] else b
    idx = tuple((lo[k] + 1) * B.n if j == k else slice(lo[j] * B.n, lo[j] * B.n + B.N) for j in range(3))
    return k, idx


def _anchor_rows(B, Bm):
    """Face samples usable as anchors: with C1, those whose supporting coefficients avoid the face's rim.

    With C1 the rim (the face's edges and the next lines) is tied by Eq. 8 to
    the neighbouring faces and cannot be held fixed; with C0 every sample will do.
    """
    if not B.c1:
        return np.arange(len(Bm))
    rows = [r for r in range(len(Bm)) if np.all((np.flatnonzero(Bm[r]) >= 2) & (np.flatnonzero(Bm[r]) < B.N - 2))]
    return np.array(rows or [len(Bm) // 2])


def connect_faces(B, cells, tree_edges, res, stats) -> int:
    """Every tree face gets a non-empty zero set (Section 4.2.1); returns the iterations spent (0: all held).

    A face's values depend on its own layer of coefficients only (C0 knots).
    Each face is anchored once: its most negative sample (with C1, among
    those whose supporting coefficients avoid the rim, which Eq. 8 ties to the
    neighbouring faces) has its supporting coefficients fixed, so it stays
    negative whatever later steps raise; if no such sample is negative, the
    supports of the least positive one are first lowered to -1/2.  Then the
    paper's iteration raises the rest of the face (even iterations: one more
    coefficient positive; odd: all raised) until some sample is positive.  A
    face that already changes sign keeps its values: it is anchored only where
    a usable sample is negative already (nothing is lowered), and a later step
    that takes its sign change away brings it back here in the next round.
    """
    Bm = B.basis(res)
    rows = _anchor_rows(B, Bm)
    changed = 0
    for e in progress.bar(tree_edges, desc="inter-cell connectivity", unit="face"):
        a, b = cells[e[0]], cells[e[1]]
        k, idx = _face_view(B, a, b)
        key = (int(e[0]), int(e[1]))
        G = B.G[idx]  # (N, N) view of the face's coefficients
        its = 0
        full = Bm @ G @ Bm.T
        v = full[np.ix_(rows, rows)]
        if full.min() < 0 < full.max():  # the face changes sign already: its values stay as they are
            if key not in B.anchored and v.min() < 0:  # hold its most negative usable sample against later raising
                i, j = np.unravel_index(np.argmin(v), v.shape)
                B.fixed[idx][np.ix_(np.flatnonzero(Bm[rows[i]]), np.flatnonzero(Bm[rows[j]]))] = True
                B.anchored.add(key)
            continue
        if key not in B.anchored or v.min() >= 0:  # (a C1 symmetrization may have moved an anchor's rim)
            i, j = np.unravel_index(np.argmin(v), v.shape)
            si, sj = np.flatnonzero(Bm[rows[i]]), np.flatnonzero(Bm[rows[j]])
            if v[i, j] >= 0:
                G[np.ix_(si, sj)] = np.minimum(G[np.ix_(si, sj)], -BRIDGE)
                _symmetrize_face(B, k, idx)
                its += 1
            B.fixed[idx][np.ix_(si, sj)] = True
            B.anchored.add(key)
        free = ~B.fixed[idx]
        while (Bm @ G @ Bm.T).max() <= 0:
            if its >= MAX_ITER:
                raise TilingError(f"the face between cells {tuple(a)} and {tuple(b)} got no zero set in "
                                  f"{MAX_ITER} iterations")
            v = G[free]
            if its % 2 == 0 and np.any(v <= 0):
                neg = np.flatnonzero(v <= 0)
                v[neg[np.argmax(v[neg])]] = 0.5  # the least negative becomes positive
            else:
                v = v + STEP
            G[free] = v
            _symmetrize_face(B, k, idx)
            its += 1
        stats["face_iterations"][key] = stats["face_iterations"].get(key, 0) + its
        changed += its
    return changed


def _symmetrize_face(B, k, idx):
    """With C1, the inner layers on both sides of the face symmetric about it (Eq. 8)."""
    if not B.c1:
        return
    b0 = idx[k]
    sub = tuple(i for j, i in enumerate(idx) if j != k)
    G = np.moveaxis(B.G, k, 0)
    delta = 0.5 * (G[(b0 + 1,) + sub] - G[(b0 - 1,) + sub])
    G[(b0 - 1,) + sub] = G[(b0,) + sub] - delta
    G[(b0 + 1,) + sub] = G[(b0,) + sub] + delta


def connect_cells(B, cells, res, stats) -> int:
    """The sampled inside region of every cell is one connected component (Section 4.2.2).

    Rounds over all cells: every cell whose inside samples form several
    components (scipy.ndimage.label, 6-connected) gets one iteration: each
    smaller component is bridged to the largest along a least-cost path
    (:func:`_paths`) whose samples are made inside.  The paper raises
    coefficients in general ("other strategies of increasing the positivity
    ... can be employed", Section 4.2.1); raising only along a bridge keeps
    the voids open.  A component no bridge can reach (walled in by fixed
    coefficients) has the cell's free coefficients raised instead.  Every
    cell is checked again after each round, since a shared coefficient also
    changes the neighbour.  Returns the iterations spent.
    """
    its = np.zeros(len(cells), int)
    for _ in progress.bar(range(MAX_ITER), desc="intra-cell connectivity", unit="round", min_items=10**9):
        todo = [i for i, c in enumerate(cells) if not B.verified(c)]  # a cell that passed and kept its values passes
        if not todo:
            break
        inside = B.cell_values(cells[todo], res) > 0
        blocked = None
        work = 0
        for j, i in enumerate(todo):
            c = cells[i]
            label, n = _held_face_islands(B, c, res, *ndimage.label(inside[j]))
            if n <= 1:
                B.verify(c)
                continue
            if blocked is None:
                blocked = ~B.reachable(res, +1)
            main = 1 + int(np.argmax(np.bincount(label.ravel())[1:]))
            window = tuple(slice(x * res, x * res + res + 1) for x in c)
            paths = _paths(label == main, [label == lab for lab in range(1, n + 1) if lab != main],
                           inside[j], blocked[window])
            for path in paths:
                if path is None:  # walled in: raise every free coefficient of the cell
                    block, free = B.G[B.cell_slices(c)], ~B.fixed[B.cell_slices(c)]
                    block[free] += STEP
                else:
                    B.set_supports(np.asarray(c) * res + path, res, raise_to=BRIDGE)
            its[i] += 1
            work += 1
        if not work:
            break
        B.enforce_c1()
    else:
        raise TilingError(f"intra-cell connectivity could not be reached in {MAX_ITER} rounds")
    for i, c in enumerate(cells):
        key = tuple(int(x) for x in c)
        stats["cell_iterations"][key] = stats["cell_iterations"].get(key, 0) + int(its[i])
    return int(its.sum())


def _held_face_islands(B, c, res, label: np.ndarray, n: int) -> tuple[np.ndarray, int]:
    """Cell ``c``'s inside components without the islands that no step of this cell can change: pieces on
    its boundary samples alone whose every supporting coefficient is held (a spanning-tree face's anchor).

    Such a piece belongs to the neighbour across the face as much as to this cell, and with C1 the two
    cells cannot both bridge it: Eq. 8 ties the layers either side to the held face layer, so a bridge
    raised on one side lowers the other, and the two cells undid each other's bridges round after round
    until the round limit refused a valid input.  Whether such a piece is joined to the rest is the
    certificate's to prove on the spline (joined through the neighbour, or given a path); every other
    island is bridged here as before.  Returns the relabelled components and their count."""
    if n <= 1:
        return label, n
    sizes = np.bincount(label.ravel(), minlength=n + 1)
    sizes[0] = 0
    main = int(np.argmax(sizes))
    interior = np.zeros(n + 1, bool)
    interior[np.unique(label[1:-1, 1:-1, 1:-1])] = True
    interior[main] = True
    drop = [lab for lab in range(1, n + 1) if not interior[lab]]
    if not drop:
        return label, n
    M = B.sampling(res)
    for lab in drop:
        pts = np.argwhere(label == lab) + np.asarray(c) * res  # global samples
        supp = [M[k][pts[:, k]] > 0 for k in range(3)]
        held = all(np.all(B.fixed[np.ix_(*(np.flatnonzero(s[p]) for s in supp))]) for p in range(len(pts)))
        interior[lab] = not held
    interior[0] = False
    keep = np.flatnonzero(interior)
    if len(keep) == n:
        return label, n
    relabel = np.zeros(n + 1, label.dtype)
    relabel[keep] = np.arange(1, len(keep) + 1)
    return relabel[label], len(keep)


def open_cavities(field, B, res, stats) -> int:
    """Connect every negative pocket enclosed by the inside region to the outside by a tunnel.

    ``field`` samples the current G on the global grid.  The region f <= 0 is
    labelled (6-connected: a pocket joined only diagonally is opened too) with
    D's outside as one more layer; each other component gets a least-cost path
    to the outside whose samples are made outside (coefficients lowered to at
    most -1/2).  One round; returns the number of pockets found.
    """
    F = np.pad(field(res), 1, constant_values=-1.0)  # the outside of D: every pocket touching it is exterior
    label, n = ndimage.label(F <= 0)
    outside = label[0, 0, 0]
    if n <= 1:
        return 0
    blocked = np.pad(~B.reachable(res, -1), 1)
    paths = _paths(label == outside, [label == lab for lab in range(1, n + 1) if lab != outside], F <= 0, blocked)
    top = np.array(F.shape) - 3
    for path in paths:
        if path is None:
            raise TilingError("an enclosed void of the implicit structure cannot be opened (walled in by the "
                              "capped boundary); lower alpha or raise the resolution")
        B.set_supports(np.clip(path - 1, 0, top), res, lower_to=-BRIDGE)
    B.enforce_c1()
    stats["cavities_opened"] += n - 1
    return n - 1


def _paths(target, islands, good, blocked):
    """Least-cost 6-connected sample paths (L, 3) from each island to ``target``, or None where none exists.

    Entering a ``good`` sample is free (almost), any other costs 1;
    ``blocked`` samples that are not good cannot be entered.  One
    multi-source Dijkstra (scipy.sparse.csgraph) from the target serves every island.
    """
    shape = target.shape
    e = grid_graph(shape)
    e = np.concatenate([e, e[:, ::-1]])  # both directions
    ok = (good | ~blocked).ravel()
    e = e[ok[e[:, 0]] & ok[e[:, 1]]]
    cost = np.where(good.ravel(), 1e-6, 1.0)  # zero weights would be dropped by the sparse graph
    n = int(np.prod(shape))
    graph = csr_matrix((cost[e[:, 1]], (e[:, 0], e[:, 1])), shape=(n, n))
    dist, pred, _ = dijkstra(graph, indices=np.flatnonzero(target.ravel()), min_only=True,
                             return_predecessors=True)
    out = []
    for island in islands:
        nodes = np.flatnonzero(island.ravel())
        j = nodes[np.argmin(dist[nodes])]
        if not np.isfinite(dist[j]):
            out.append(None)
            continue
        out.append(np.stack(np.unravel_index(trace(pred, j), shape), 1))
    return out


def trace(pred, j) -> np.ndarray:
    """The nodes of the shortest path ending at ``j``, back to its source, from Dijkstra's predecessors."""
    path = [j]
    while pred[path[-1]] >= 0:  # a path of a few dozen nodes
        path.append(pred[path[-1]])
    return np.array(path)
