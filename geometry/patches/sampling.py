"""Sampling a multi-patch model on conforming grids of linear hexahedra, welded into one mesh.

Each patch is sampled on a tensor grid: every element of its space (the
tile spline's knots, or those the caller names, e.g. an analysis space's) is
subdivided ``samples`` times per direction.  Grids are made *conforming* across
interfaces before evaluation: the sample parameters of two glued faces are
united (through the interface's orientation, and for a branch face through
the map of the child's face onto its sub-rectangle of the parent's) until no
interface adds a point, so that neighbouring faces carry the same points and
no T-junction is left (:func:`conforming_axes`).  A patch is evaluated piece
by piece between its discontinuity knots, each side of a discontinuity plane
with its own one-sided limit, so that the open part of a slot is two surfaces.
Finally coinciding points (shared faces, the closed part of a discontinuity
plane) are welded into one point (:func:`weld`), their data averaged, so the
mesh has no internal faces.  An adaptively refined model (patches with a
``refinement``) is made conforming only where that at most doubles its points
or keeps them within a million; otherwise a coarser patch keeps its own samples
against finer neighbours
(hanging points, as in any octree mesh: the volume and the fields are the same,
a surface filter also shows those faces).
"""

from __future__ import annotations

from itertools import product

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree

from geometry import knots as kn
from geometry import progress
from geometry.compiled._fast import applies
from geometry.patches.chain import gradient_and_det, patches_geometry_derivs
from geometry.faces import FACE_AXIS
from geometry.patches.multipatch import PlacedPatch
from geometry.grouping import ObjectIndex
from geometry.tolerances import ON_DOMAIN, SAME_SAMPLE

__all__ = ["conforming_axes", "sample_model", "sampled_mesh", "weld", "sample_axes", "piece_basis", "piece_boxes",
           "HEX_CORNERS"]

#: VTK hexahedron corner order as (di, dj, dk) offsets
HEX_CORNERS = np.array([(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0), (0, 0, 1), (1, 0, 1), (1, 1, 1), (0, 1, 1)])
_MAX_AXIS = 20_000  # sample points per direction and patch beyond which conformity is given up
_CONFORMING_COST = 2.0  # an adapted model's grid is made conforming if that at most doubles its points,
_CONFORMING_POINTS = 1_000_000  # or keeps it within this many (a million points: about 100 MB of VTU)
_SAME = SAME_SAMPLE  # normalised parameters closer than this are one sample (the weld is finer)


def sample_axes(knots, samples) -> list[np.ndarray]:
    """Per direction: every knot span subdivided ``samples`` times (one count, or one per direction), span
    ends included once."""
    out = []
    counts = [int(samples)] * len(knots) if np.ndim(samples) == 0 else [int(v) for v in samples]
    for U, n in zip(knots, counts):
        b = np.unique(U)
        t = np.linspace(0.0, 1.0, n + 1)[:-1]
        out.append(np.append((b[:-1, None] + np.diff(b)[:, None] * t[None, :]).ravel(), b[-1]))
    return out


def chord_samples(model, knots_of, tolerance: float, max_samples: int = 32) -> list[tuple]:
    """Per patch, the fewest subdivisions per element and direction (1, 2, 4, ...) for which the written
    linear cells stay within ``tolerance`` (model units) of the exact geometry: the chord error at the middle
    of every sample interval along that direction (the others sampled twice per element)."""
    out = []
    for pi, patch in enumerate(model.patches):
        knots = knots_of(pi)
        counts = []
        for d in range(3):
            s = 1
            while True:
                axes = sample_axes(knots, [s if k == d else 2 for k in range(3)])
                mids = list(axes)
                mids[d] = 0.5 * (axes[d][:-1] + axes[d][1:])
                grid = [np.stack(np.meshgrid(*a, indexing="ij"), -1) for a in (axes, mids)]
                ends = patch.image(grid[0].reshape(-1, 3))[:, :3].reshape(grid[0].shape)
                exact = patch.image(grid[1].reshape(-1, 3))[:, :3]
                chord = 0.5 * (np.take(ends, range(len(axes[d]) - 1), axis=d)
                               + np.take(ends, range(1, len(axes[d])), axis=d)).reshape(-1, 3)
                worst = float(np.linalg.norm(exact - chord, axis=1).max())
                if worst <= tolerance or 2 * s > max_samples:
                    break
                s *= 2
            counts.append(s)
        out.append(tuple(counts))
    return out


def _unite(axis: np.ndarray, new: np.ndarray) -> tuple[np.ndarray, bool]:
    """Sorted union of normalised parameters; values closer than 1e-9 are one (the first kept)."""
    if len(new) == len(axis) and (not len(new) or np.abs(new - axis).max() <= _SAME):
        return axis, False  # the same samples (the common case once neighbours agree): nothing to merge
    merged = np.sort(np.concatenate([axis, new]))
    keep = np.empty(len(merged), bool)
    keep[0] = True
    np.greater(np.diff(merged), _SAME, out=keep[1:])
    merged = merged[keep]
    return merged, len(merged) != len(axis)


def _face_dirs(face):
    k, _ = FACE_AXIS[face]
    return [d for d in range(3) if d != k]


def conforming_axes(model, knots_of, samples) -> list[list[np.ndarray]]:
    """Sample parameters per patch and direction, united across interfaces (see the module notes).

    ``knots_of(pi)``: the knot vectors whose elements patch ``pi`` samples; ``samples``: subdivisions per
    element, one count for all, or a list with one per patch (a count or one per direction).
    Parameters are handled normalised to [0, 1] per direction.
    """
    per = samples if isinstance(samples, list) else [samples] * len(model.patches)
    knots = [knots_of(pi) for pi in range(len(model.patches))]
    doms = [np.array([[U[0], U[-1]] for U in k]) for k in knots]
    made: dict = {}  # patches share knot vectors (their space's): each one's normalised samples made once
    axes = []
    for pi, k in enumerate(knots):
        key = (tuple(id(U) for U in k), repr(per[pi]))  # (the knot arrays live as long as this call)
        if key not in made:
            made[key] = [(a - d[0]) / (d[1] - d[0]) for a, d in zip(sample_axes(k, per[pi]), doms[pi])]
        axes.append([a.copy() for a in made[key]])
    # (patch a, dir a, patch b, dir b, box, flip, one way): t_b = flip((t_a - lo) / (hi - lo)) on a's box (an identity:
    # no box); one way: b takes a's samples, a keeps its own
    links = []
    for itf in model.interfaces:
        (pa, fa), (pb, fb) = itf.a, itf.b
        da, db = _face_dirs(fa), _face_dirs(fb)
        if itf.kind == "identity":
            order = [1, 0] if itf.swap else [0, 1]
            for j in range(2):  # face a's direction j <-> face b's direction order[j]
                links.append((pa, da[j], pb, db[order[j]], None, itf.flip[order[j]], False))
        else:
            order = [1, 0] if itf.swap else [0, 1]
            # between patches of an adaptively refined model (dyadic levels: the finer face's samples hold the
            # coarser one's) the coarser face may keep its own samples (hanging points, as in an octree mesh):
            # uniting both ways carries every fine patch's samples along whole rows of coarse ones (10x the
            # points on a refined L-shape), so it is done only where it costs little (_CONFORMING_COST, _POINTS)
            one_way = bool(model.patches[pa].refinement or model.patches[pb].refinement)
            for j in range(2):  # the child's direction order[j] spans the box side j of the parent's face
                lo, hi = itf.box[j]
                d0 = doms[pa][da[j]]
                links.append((pa, da[j], pb, db[order[j]],
                              ((lo - d0[0]) / (d0[1] - d0[0]), (hi - d0[0]) / (d0[1] - d0[0])), itf.flip[order[j]],
                              one_way))
    if any(link[6] for link in links):  # an adapted model: conforming unless that costs much (module notes)
        two_way = _united([[a.copy() for a in ax] for ax in axes], [(*link[:6], False) for link in links])
        one_way = _united(axes, links)
        size = [sum(int(np.prod([len(a) for a in ax])) for ax in version) for version in (two_way, one_way)]
        axes = two_way if size[0] <= max(_CONFORMING_COST * size[1], _CONFORMING_POINTS) else one_way
    else:
        axes = _united(axes, links)
    return [[d[0] + a * (d[1] - d[0]) for a, d in zip(ax, dom)] for ax, dom in zip(axes, doms)]


def _united(axes, links):
    """The normalised sample axes of every patch united across the ``links`` until none adds a point."""
    for _ in range(64):
        changed = False
        for pa, ka, pb, kb, box, flip, one_way in links:
            A, B = axes[pa][ka], axes[pb][kb]
            if box is None:
                to_b = 1 - A if flip else A
                to_a = 1 - B if flip else B
            else:
                lo, hi = box
                inside = A[(A >= lo - ON_DOMAIN) & (A <= hi + ON_DOMAIN)]
                to_b = np.clip((inside - lo) / (hi - lo), 0, 1)
                to_b = 1 - to_b if flip else to_b
                to_a = lo + (1 - B if flip else B) * (hi - lo)
            axes[pb][kb], cb = _unite(B, to_b)
            ca = False
            if not one_way:
                axes[pa][ka], ca = _unite(A, to_a)
            changed |= ca or cb
            if max(len(axes[pa][ka]), len(axes[pb][kb])) > _MAX_AXIS:
                changed = False  # a resolution race between incommensurate maps: stop, the weld does the rest
                break
        if not changed:
            break
    return axes


def piece_boxes(spline) -> list[np.ndarray]:
    """Parameter boxes (d, 2) between the full-multiplicity (discontinuity) knots of a spline.

    On each box the spline is continuous; across a box side that is a
    discontinuity knot the two boxes have their own one-sided limits (the two
    walls of a slot).
    """
    cuts = []
    for U, p in zip(spline.knots, spline.degrees):
        vals, mults = np.unique(U, return_counts=True)
        c = np.r_[vals[0], vals[1:-1][mults[1:-1] >= p + 1], vals[-1]]
        cuts.append(np.stack([c[:-1], c[1:]], axis=1))
    return [np.array(box) for box in product(*cuts)]


def _hexes(shape, flip: bool) -> np.ndarray:
    n1, n2, n3 = shape
    i, j, k = np.meshgrid(np.arange(n1 - 1), np.arange(n2 - 1), np.arange(n3 - 1), indexing="ij")
    corners = HEX_CORNERS[[1, 0, 3, 2, 5, 4, 7, 6]] if flip else HEX_CORNERS  # mirrored for left-handed maps
    idx = [((i + a) * n2 + (j + b)) * n3 + (k + c) for a, b, c in corners]
    return np.stack([c.ravel() for c in idx], axis=1)


def piece_basis(space1d, ax):
    """Values and derivatives (2, len(ax), n) of a 1-D space on a piece's axis; the last point as a left limit."""
    U, q = space1d.knots, space1d.degree
    out = []
    for nder in (0, 1):
        head = kn.basis_matrix(U, q, ax[:-1], nder).toarray() if len(ax) > 1 else np.zeros((0, len(U) - q - 1))
        tail = kn.basis_matrix(U, q, ax[-1:], nder, side="left").toarray()
        out.append(np.vstack([head, tail]))
    return out


def sample_model(model, samples: int = 3, knots_of=None, fields=None, spaces_key=None, patches=None):
    """Points, hexahedra, point data and cell data of the sampled model (before welding).

    ``knots_of(pi)``: the knot vectors whose elements patch ``pi`` samples
    (default: its spline's); ``spaces_key(pi)``: what else distinguishes the
    patches that may be evaluated together (e.g. their analysis space);
    ``fields(members, axes, x, D, chans, out) -> det``: adds per-point fields
    (P, N[, c]) of the patches ``members`` on a piece grid to ``out`` and
    returns the Jacobian determinants (P N,) it computed (the analysis adds
    temperatures this way).  Returns ``(points (N, 3), cells (M, 8),
    point_data {name: (N,) or (N, c)}, cell_data {name: (M,)}, rim (N,))``:
    every channel of the tiles and the deformation map is point data (NaN
    where a patch lacks it); ``rim`` marks the points on the boundary of their
    piece's grid (the only ones that can coincide with others).  ``patches``:
    the indices of the patches to sample (default all); the samples stay
    those of the whole model (conforming across every interface), so the
    meshes of disjoint subsets meet point for point.
    """
    if knots_of is None:
        def knots_of(pi):
            return model.patches[pi].spline.knots
    axes = conforming_axes(model, knots_of, samples)
    names = sorted({c for p in model.patches for c in p.channels})
    same = ObjectIndex()  # patches share splines: group by object
    groups: dict = {}
    chosen = range(len(model.patches)) if patches is None else sorted({int(i) for i in patches})
    for pi in chosen:
        patch = model.patches[pi]
        key = (same(patch.spline), spaces_key(pi) if spaces_key else None, tuple(a.tobytes() for a in axes[pi]))
        groups.setdefault(key, []).append(pi)
    # a model sampled at many points loads the compiled map kernel for its large groups: then every group takes
    # it (SciPy's four passes and the rational quotient rule cost 3-10x more per point)
    compiled_maps = applies(3, sum(int(np.prod([len(a) for a in axes[pi]])) for pi in chosen))
    pieces = _pieces(model, list(groups.values()), axes)
    # every array made once at its final size and filled piece by piece (lists of pieces concatenated at the
    # end held the sampled model twice: 200 MiB more at 1.5 M points)
    n_points = sum(len(m) * int(np.prod(shape)) for m, _, _, shape in pieces)
    n_cells = sum(len(m) * int(np.prod(np.subtract(shape, 1))) for m, _, _, shape in pieces)
    points, rims = np.empty((n_points, 3)), np.empty(n_points, bool)
    cells = np.empty((n_cells, 8), np.int64)
    kinds = ("patch", "tile", "level") + (("refinement",) if any(p.refinement for p in model.patches) else ())
    cdata = {k: np.empty(n_cells, np.int32) for k in kinds}  # (refinement: an adaptively refined model's)
    pdata: dict = {}
    at = ct = 0
    for members, sub, pax, shape in progress.bar(pieces, desc="sampling", unit="piece"):
        geos = [PlacedPatch(sub, p.placement, p.outer, p.tile, p.level) for p in (model.patches[i] for i in members)]
        x, D, chans = patches_geometry_derivs(geos, pax, compiled_maps=compiled_maps)
        P, N = x.shape[:2]
        data = {}
        det = fields(members, pax, x, D, chans, data) if fields else gradient_and_det(D, None)[1]
        det = det.reshape(P, N)
        for c in names:
            data[c] = np.asarray(chans[c], float).reshape(P, N) if c in chans else np.full((P, N), np.nan)
        points[at:at + P * N] = x.reshape(-1, 3)
        rims[at:at + P * N] = np.tile(_rim(shape), P)
        for key, v in data.items():  # (a field some pieces lack is NaN on theirs)
            if key not in pdata:
                size = (n_points,) + v.shape[2:]
                pdata[key] = np.empty(size) if at == 0 else np.full(size, np.nan)
            pdata[key][at:at + P * N] = v.reshape((P * N,) + v.shape[2:])
        flips = np.median(det, axis=1) < 0  # per patch: a left-handed map mirrors its hexahedra
        local = {bool(f): _hexes(shape, bool(f)) for f in np.unique(flips)}  # one connectivity per piece
        C = len(next(iter(local.values())))
        for j, pi in enumerate(members):
            np.add(local[bool(flips[j])], at + j * N, out=cells[ct:ct + C])
            patch = model.patches[pi]
            for key, value in (("patch", pi), ("tile", patch.tile), ("level", patch.level),
                               ("refinement", patch.refinement)):
                if key in cdata:
                    cdata[key][ct:ct + C] = value
            ct += C
        at += P * N
    return points, cells, pdata, cdata, rims


def _pieces(model, groups, axes) -> list[tuple]:
    """(members, piece spline, its sample axes, grid shape) of every group of patches sampled together and
    every piece of their spline between its discontinuity knots (:func:`piece_boxes`)."""
    out = []
    for members in groups:
        spline = model.patches[members[0]].spline
        for box in piece_boxes(spline):
            sub = spline.extract(box) if not np.array_equal(box, spline.domain) else spline
            # the piece's samples, clipped onto its box: a sample carried over from a neighbour through an
            # interface map may sit an ulp outside, on a discontinuity knot's other side, where the fields'
            # basis would take the other wall's limit while the geometry (the extracted piece) takes this one's
            pax = [np.clip(a[(a >= lo - 0.1 * ON_DOMAIN * (hi - lo)) & (a <= hi + 0.1 * ON_DOMAIN * (hi - lo))], lo, hi)
                   for a, (lo, hi) in zip(axes[members[0]], box)]
            out.append((members, sub, pax, tuple(len(a) for a in pax)))
    return out


def sampled_mesh(model, samples: int = 3, **options):
    """The welded linear-hexahedron mesh of a model, a ``pyvista.UnstructuredGrid``.

    ``options`` go to :func:`sample_model`; point data are averaged where points weld.
    """
    import pyvista as pv

    points, hexes, pdata, cdata, rim = sample_model(model, samples, **options)
    points, hexes, pdata, _ = weld(points, hexes, pdata, rim, consume=True)
    grid = pv.UnstructuredGrid({pv.CellType.HEXAHEDRON: hexes}, points)
    for key, v in pdata.items():
        grid.point_data[key] = v
    for key, v in cdata.items():
        grid.cell_data[key] = v
    return grid


def _rim(shape) -> np.ndarray:
    """Mask of the points on the boundary of a grid of ``shape`` (C order): only those can be shared."""
    m = np.zeros(shape, bool)
    m[[0, -1]] = True
    m[:, [0, -1]] = True
    m[:, :, [0, -1]] = True
    return m.ravel()


def weld(points, cells, point_data, candidates=None, tol: float = 1e-10, consume: bool = False):
    """Merge points closer than ``tol`` times the model size; their data are averaged.

    ``candidates``: mask of the points that may coincide with others (default
    all).  Returns ``(points, cells, point_data, merged)`` with ``merged`` the
    number of points removed.  Neighbours are found by a KD-tree and grouped by
    connected components (no bucket boundaries: points within the tolerance
    always merge).  ``consume``: the caller gives up ``cells`` and ``point_data``, which are then reused
    (the cells relabelled in place, each array of ``point_data`` dropped from it once its welded one is
    made), so that the model is not held twice at the peak.
    """
    n = len(points)
    idx = np.arange(n) if candidates is None else np.flatnonzero(candidates)
    # the model's size from the candidates (every patch's boundary: they span the model), a third of the points
    scale = max(1.0, float(np.ptp(points[idx], axis=0).max())) if len(idx) else 1.0
    # an unbalanced tree (split at the midpoint, not the median): built 2x faster, the pairs found as fast
    tree = cKDTree(points[idx], balanced_tree=False) if len(idx) else None
    pairs = tree.query_pairs(tol * scale, output_type="ndarray") if len(idx) else np.zeros((0, 2), int)
    if not len(pairs):
        return points, cells, point_data, 0
    # only the candidates in some pair take part in the merging: relabel them 0 .. k - 1 (a mask and a running
    # count: a sort of the pairs took 5x longer)
    paired = np.zeros(len(idx), bool)
    paired[pairs.ravel()] = True
    involved = idx[paired]
    k = len(involved)
    local = (np.cumsum(paired) - 1)[pairs]
    graph = coo_matrix((np.ones(len(local)), (local[:, 0], local[:, 1])), shape=(k, k))
    mc, lab = connected_components(graph, directed=False)  # components among the involved candidates
    first = np.unique(lab, return_index=True)[1]  # first involved point of each component
    rep = np.ones(n, bool)
    rep[involved] = False
    rep[involved[first]] = True  # kept points: every point not merged and one per component
    new = np.cumsum(rep) - 1
    label = new.copy()
    label[involved] = new[involved[first]][lab]
    counts = np.bincount(lab, minlength=mc).astype(float)
    out_data = {}
    kept = np.flatnonzero(rep)
    for key in list(point_data):
        v = point_data.pop(key) if consume else point_data[key]
        out = np.take(v, kept, axis=0)  # (take: several times faster than a mask or fancy index here)
        vc = v[involved].reshape(k, -1)
        avg = np.stack([np.bincount(lab, weights=vc[:, c], minlength=mc) for c in range(vc.shape[1])], 1)
        out.reshape(len(out), -1)[new[involved[first]]] = avg / counts[:, None]
        out_data[key] = out
        del v, vc  # (consumed: the array goes now, not when the loop ends)
    if consume:  # relabelled in blocks, each read before it is overwritten
        step = 1 << 18
        for a in range(0, len(cells), step):
            cells[a:a + step] = np.take(label, cells[a:a + step])
    else:
        cells = np.take(label, cells)
    return np.take(points, kept, axis=0), cells, out_data, n - len(kept)
