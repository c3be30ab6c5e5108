"""Implicit bifurcation structures on an adaptive subdivision (Massarwi et al. 2018, Section 5.1, Figs. 6, 7, 16(b, c)).

The cells of :func:`tiling.topo_subdiv` carry scalar trivariates f > 0
(inside) built, as in Section 5.1, from six face surfaces by the volumetric
Boolean sum:

1. every face that is not part of a larger one (a *unit* face) gets a bicubic
   scalar surface: the canonical pattern (positive disc in the middle, the
   rim at -1/2) randomised by Eq. 6 in its interior; D's boundary faces are
   negative throughout when capped (a closed solid).  A *complex* face (several
   smaller neighbours) is the exact merge of its neighbours' unit faces into
   one B-spline surface (Fig. 6): knots of every piece, multiplicity d at the
   junctions, each piece refined to the common knots by knot insertion;
2. the cell's trivariate is the Boolean sum of its six faces, computed on the
   control net with Greville abscissae (exact: splines reproduce linear
   blends).  All rims are the same constant, so the faces agree on every
   edge, and neighbours agree on shared faces exactly (C0): the big cell of a
   complex face interpolates the merged surface, which *is* its neighbours' faces;
3. the interior coefficients are randomised by Eq. 6 around the Boolean sum.

Guarantees, checked on samples of the build ``resolution`` (every cell is
sampled at the union of all cells' sample lines, so faces are sampled alike
from both sides): every unit face's inside part is one non-empty piece and
its outside part one piece touching the rim; every cell's inside samples
are one component and its voids reach the cell's boundary; where a random
draw breaks that, its amplitude is halved (down to the canonical pattern).
The draws are made face by face and cell by cell as before; the halving
rounds check all faces, then all cells, at once
(:mod:`tiling.implicit.checks`).  The whole inside region is then one
component and, capped, the outside one too: the surface is closed and
connected.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from geometry.cache import memo
from scipy import ndimage

from geometry import BSpline, SplineFunction, progress
from geometry import knots as kn
from geometry.errors import check_seed, show
from geometry.faces import FACE_NAMES

from tiling.errors import TilingError
from tiling.cell_splines import boolean_sum, grid_values, merge_pieces, scalar_surface
from tiling.implicit.checks import cells_ok, faces_ok
from tiling.implicit.surface import EdgeSplines, SurfaceOutputs, zero_surface
from tiling.checks import check_map
from tiling.branching.subdivision import CellComplex, topo_subdiv
from geometry.tolerances import ON_DOMAIN
from geometry.numbers import is_flag, is_integer, is_real

__all__ = ["implicit_bifurcation", "BifurcationStructure"]

RIM = -0.5  # every face's boundary curve: all faces agree on every edge (Boolean sum)
CAP = -1.0  # the inside of D's boundary faces when capped
_HALVINGS = 10  # after this many halvings of a random draw, the canonical pattern itself (amplitude 0)


@dataclass
class BifurcationStructure(SurfaceOutputs):
    """Implicit bifurcation structure: per cell of ``cells`` a scalar trivariate on its parameter box.

    ``fields[i]``: cell i's :class:`geometry.SplineFunction` over ``cells.boxes[i]``;
    ``stats``: halvings of the random amplitude per face and per cell.
    """

    outer: BSpline
    cells: CellComplex
    fields: list
    resolution: int
    cap: bool
    stats: dict = field(default_factory=dict)
    trees: list = field(default_factory=list)  # (no spanning trees here; for the renderer)
    _cache: dict = field(default_factory=dict, repr=False)  # the cell lookup table, the build resolution's samples

    def evaluate(self, params) -> np.ndarray:
        """f at parameter points (N, 3): each point evaluated by the cell containing it (equal on shared faces)."""
        x = np.asarray(params, float)
        cell = self.locate(x)
        out = np.empty(len(x))
        order = np.argsort(cell, kind="stable")
        bounds = np.searchsorted(cell[order], np.arange(len(self.fields) + 1))
        for i in np.flatnonzero(np.diff(bounds)):  # one evaluation per cell holding points
            idx = order[bounds[i]:bounds[i + 1]]
            out[idx] = self.fields[i].evaluate(x[idx], compiled=False)[:, 0]
        return out

    def locate(self, params) -> np.ndarray:
        """Index of a cell containing each parameter point (N, 3) (a table over all cells' boundary planes)."""
        if "table" not in self._cache:
            B = self.cells.boxes
            planes = [np.unique(B[:, k, :]) for k in range(3)]
            table = np.full(tuple(len(p) - 1 for p in planes), -1, np.int64)
            for i, b in enumerate(B):
                sl = tuple(slice(int(np.searchsorted(p, b[k, 0])), int(np.searchsorted(p, b[k, 1])))
                           for k, p in enumerate(planes))
                table[sl] = i
            self._cache["table"] = (planes, table)
        planes, table = self._cache["table"]
        x = np.asarray(params, float)
        dom = self.outer.domain
        if np.any((x < dom[:, 0] - ON_DOMAIN) | (x > dom[:, 1] + ON_DOMAIN)) or not np.all(np.isfinite(x)):
            raise TilingError("parameter points must lie in D's domain " + show(dom.tolist()))
        idx = tuple(np.clip(np.searchsorted(p, x[:, k], side="right") - 1, 0, len(p) - 2) for k, p in enumerate(planes))
        return table[idx]

    def axes(self, resolution: int | None = None) -> list:
        """Per direction, the union of every cell's ``resolution + 1`` sample lines (sorted)."""
        r = self.resolution if resolution is None else resolution
        if not is_integer(r) or r < 2 or r % 2:
            raise TilingError(f"resolution must be an even integer >= 2 (samples per cell and direction; the face "
                              f"centres are samples), got {show(r)}")
        B = self.cells.boxes
        t = np.linspace(0.0, 1.0, r + 1)
        return [np.unique(np.round((B[:, k, :1] + (B[:, k, 1:] - B[:, k, :1]) * t).ravel(), 13)) for k in range(3)]

    def sample(self, resolution: int | None = None):
        """Axes and f on the rectilinear grid of :meth:`axes` (the build resolution's is kept)."""
        axes = self.axes(resolution)
        if resolution in (None, self.resolution):
            if "samples" not in self._cache:
                self._cache["samples"] = _sample(self.cells.boxes, self.fields, axes)
            return axes, self._cache["samples"]
        return axes, _sample(self.cells.boxes, self.fields, axes)

    def surface(self, resolution: int | None = None, snap: bool = True):
        """The zero set mapped through D, one welded ``pyvista.PolyData`` (:mod:`tiling.implicit.surface`)."""
        axes, F = self.sample(resolution)
        scale = max(float(np.abs(f.coefficients).max()) for f in self.fields)
        return zero_surface(axes, F, self.outer, self.evaluate, snap_vertices=snap, scale=scale, stats=self.stats,
                            lines=self.edge_splines)

    def edge_splines(self, a, b, axis) -> EdgeSplines:
        """The field restricted to the grid edges from a (n, 3) to b along ``axis``: each by its cell's spline."""
        cell = self.locate(0.5 * (a + b))  # an edge lies in one cell (cell boundaries are sample lines)
        return EdgeSplines.of_cells(self.fields, cell, a, b, axis)


def _sample(boxes, fields, axes) -> np.ndarray:
    F = np.empty(tuple(len(a) for a in axes))
    for box, f in zip(boxes, fields):
        sl = _window(axes, box)
        F[sl] = grid_values(f, [a[s] for a, s in zip(axes, sl)])
    return F


def _window(axes, box) -> tuple:
    """Slices of the sample ``axes`` (sorted, per direction) that lie in the parameter ``box`` (3, 2), ends included."""
    return tuple(slice(int(np.searchsorted(a, lo - ON_DOMAIN)), int(np.searchsorted(a, hi + ON_DOMAIN, side="right")))
                 for a, (lo, hi) in zip(axes, box))


def _windows(axes, boxes) -> list:
    """Per box of ``boxes`` (N, 3, 2), :func:`_window`'s slices, all boxes searched at once."""
    lo = np.stack([np.searchsorted(a, boxes[:, k, 0] - ON_DOMAIN) for k, a in enumerate(axes)], 1).tolist()
    hi = np.stack([np.searchsorted(a, boxes[:, k, 1] + ON_DOMAIN, side="right") for k, a in enumerate(axes)],
                  1).tolist()
    return [tuple(slice(u, v) for u, v in zip(a, b)) for a, b in zip(lo, hi)]


def _canonical_face(degree, controls, radius=0.35):
    """Face pattern (controls, controls): positive disc of ``radius`` in the middle, the rim at RIM."""
    g = kn.greville(kn.uniform_knots(degree, controls - degree), degree)
    x, y = np.meshgrid(g, g, indexing="ij")
    p = np.clip((radius - np.hypot(x - 0.5, y - 0.5)) / radius, -1.0, 1.0)
    p[[0, -1], :] = RIM
    p[:, [0, -1]] = RIM
    return p


@memo(1024)
def _face_basis(degree: int, n: int, x: bytes) -> np.ndarray:
    """Values (len(x), n) of the uniform face basis at the sample coordinates x (cached: faces repeat them)."""
    return kn.basis_matrix(kn.uniform_knots(degree, n - degree), degree, np.frombuffer(x)).toarray()


def implicit_bifurcation(D: BSpline, epsilon: float, *, degree: int = 3, controls: int = 8, alpha: float = 0.0,
                         seed: int = 0, cap: bool = True, resolution: int = 8, directions=(0, 1, 2),
                         radius: float = 0.35) -> BifurcationStructure:
    """Implicit bifurcation structure over :func:`topo_subdiv` (D, epsilon) (module notes; Fig. 16(b), (c) with alpha).

    ``alpha``: randomisation (Eq. 6) of the faces and cell interiors; ``radius``:
    the canonical face disc's radius (fraction of the face); ``resolution``:
    samples per cell and direction of the checks and the surface.
    """
    check_map(D)  # the check every builder shares: a trivariate, not folded
    if not is_real(alpha) or not 0 <= alpha <= 1:
        raise TilingError(f"alpha must be a number in [0, 1] (the randomization factor of Eq. 6), got {show(alpha)}")
    for name, v, lo in (("degree", degree, 1), ("controls", controls, 4), ("resolution", resolution, 2)):
        if not is_integer(v) or v < lo or (name == "resolution" and v % 2):
            raise TilingError(f"{name} must be an integer >= {lo}{' and even' if name == 'resolution' else ''}, "
                              f"got {show(v)}")
    if controls < degree + 1:
        raise TilingError(f"controls must be at least degree + 1 = {degree + 1}, got {controls}")
    if not is_real(radius) or not 0 < radius < 0.5:
        raise TilingError(f"radius must be in (0, 0.5) (fraction of a face), got {show(radius)}")
    check_seed(seed, TilingError)
    if not is_flag(cap):
        raise TilingError(f"cap must be true or false, got {show(cap)}")
    cells = topo_subdiv(D, epsilon, directions=directions)
    rng = np.random.default_rng(seed)
    stats = {"face_halvings": {}, "cell_halvings": {}}
    out = BifurcationStructure(D, cells, [None] * len(cells), int(resolution), bool(cap), stats)
    axes = out.axes()
    F = np.empty(tuple(len(a) for a in axes))
    windows = _windows(axes, cells.boxes)
    unit = _unit_faces(cells, degree, controls, alpha, cap, rng, radius, axes, windows, stats)
    nested = cells.boxes.tolist()
    bases, noises = [], []
    for i in progress.bar(range(len(cells)), desc="implicit bifurcation cells", unit="cell"):
        faces = {f: _cell_face(cells, i, f, unit, degree) for f in FACE_NAMES}
        bases.append(_with_tubes(boolean_sum(faces, degree, cells.boxes[i], RIM), _targets(cells, nested, i, cap),
                                 radius))
        noises.append(rng.uniform(-1.0, 1.0, bases[-1].coefficients.shape[:-1]))  # Eq. 6's draw, cell by cell
    subs = [[a[s] for a, s in zip(axes, w)] for w in windows]
    out.fields, samples = _random_interiors(bases, noises, alpha, subs, stats, cells.boxes)
    for w, v in zip(windows, samples):
        F[w] = v  # the accepted cells' samples: the build resolution's grid, kept for the surface
    out._cache["samples"] = F
    if ndimage.label(F > 0)[1] != 1:
        raise TilingError("the implicit bifurcation structure is not connected on its samples; raise the "
                          "resolution or lower alpha")
    if cap and ndimage.label(np.pad(F, 1, constant_values=-1.0) <= 0)[1] != 1:
        raise TilingError("the implicit bifurcation structure encloses a void on its samples; lower alpha")
    return out


def _unit_faces(cells, degree, controls, alpha, cap, rng, radius, axes, windows, stats) -> dict:
    """{(cell, face): surface over [0, 1]^2} of every unit face, keyed by each cell that has it; ``windows[i]``
    cell i's slices of the sample ``axes``."""
    p0 = _canonical_face(degree, controls, radius)
    c = np.full((controls, controls), CAP)
    c[[0, -1], :] = RIM
    c[:, [0, -1]] = RIM
    capped = scalar_surface(c, degree)  # every capped boundary face: one (immutable) surface
    out, twin, todo = {}, {}, []  # todo: the faces to decide, in order (each face's draw made here, as before)
    for i, faces in enumerate(cells.faces):
        for f, (kind, nb) in faces.items():
            if kind == "complex" or (i, f) in out:
                continue
            if kind == "boundary" and cap:
                out[(i, f)] = capped
                continue
            noise = rng.uniform(-1.0, 1.0, p0.shape)
            k = FACE_NAMES.index(f) // 2
            box = cells.boxes[i]
            lines = []
            window = windows[i]
            for d in (j for j in range(3) if j != k):  # the face's sample lines, normalised
                a = axes[d][window[d]]
                lines.append(np.clip((a - box[d, 0]) / (box[d, 1] - box[d, 0]), 0.0, 1.0))
            todo.append(((i, f), noise, lines))
            out[(i, f)] = None  # (decided below)
            if kind == "neighbour":  # the neighbour sees the same face (its opposite face name)
                twin[(i, f)] = (nb[0], FACE_NAMES[2 * k + (1 - FACE_NAMES.index(f) % 2)])
                out[twin[(i, f)]] = None
    for key, c, h in _halved_faces(p0, todo, alpha, degree):
        stats["face_halvings"][key] = h
        out[key] = surface = scalar_surface(c, degree)  # one surface object, shared by both cells
        if key in twin:
            out[twin[key]] = surface
    return out


def _halved_faces(p0, todo, alpha, degree):
    """Each face of ``todo`` ((key, noise, sample lines)) as (key, coefficients, halvings): Eq. 6's draw, its
    amplitude halved until the face passes :func:`tiling.implicit.checks.faces_ok` (all faces a round)."""
    n = len(todo)
    if not n:
        return []
    noise = np.array([t[1] for t in todo])
    bases = [(_face_basis(degree, p0.shape[0], np.round(x, 13).tobytes()),
              _face_basis(degree, p0.shape[0], np.round(y, 13).tobytes())) for _, _, (x, y) in todo]
    centres = [(int(np.argmin(np.abs(x - 0.5))), int(np.argmin(np.abs(y - 0.5)))) for _, _, (x, y) in todo]
    halvings, chosen = np.full(n, _HALVINGS), np.empty_like(noise)
    pending = np.arange(n)
    for h in range(_HALVINGS + 1):
        a = 0.0 if h == _HALVINGS else alpha * 0.5 ** h
        c = (1 - a) * p0 + a * noise[pending]
        c[:, [0, -1], :] = RIM
        c[:, :, [0, -1]] = RIM
        chosen[pending] = c
        if h == _HALVINGS:  # the canonical pattern, whatever the check says
            break
        ok = faces_ok([bases[b][0] @ cb @ bases[b][1].T for b, cb in zip(pending, c)], [centres[b] for b in pending])
        halvings[pending[ok]] = h
        pending = pending[~ok]
        if not len(pending) or a == 0.0:  # (alpha 0: the canonical pattern failed; it stays, as at the end)
            break
    return [(t[0], chosen[b], int(halvings[b])) for b, t in enumerate(todo)]


def _cell_face(cells, i, f, unit, degree) -> SplineFunction:
    """Cell i's face f as a scalar surface over [0, 1]^2 (its two remaining directions in order)."""
    kind, nb = cells.faces[i][f]
    if kind != "complex":
        return unit[(i, f)]
    k, side = divmod(FACE_NAMES.index(f), 2)
    rest = [j for j in range(3) if j != k]
    mine = cells.boxes[i][rest]
    opposite = FACE_NAMES[2 * k + 1 - side]
    pieces = []
    for j in nb:  # each neighbour's unit face, placed on its part of this face (normalised coordinates)
        r = (cells.boxes[j][rest] - mine[:, :1]) / (mine[:, 1:] - mine[:, :1])
        pieces.append(scalar_surface(unit[(j, opposite)].coefficients[..., 0], degree, np.clip(r, 0.0, 1.0)))
    return merge_pieces(pieces, degree)


def _targets(cells, nested, i, cap) -> list:
    """Centres (normalised cell coordinates) and sizes of the discs on cell i's faces: (point [3], size);
    ``nested`` the cells' boxes as nested lists (a face's few numbers: plain floats, not small arrays)."""
    box = nested[i]
    out = []
    for fi, f in enumerate(FACE_NAMES):
        kind, nb = cells.faces[i][f]
        if kind == "boundary" and cap:
            continue
        k, side = divmod(fi, 2)
        rest = [j for j in range(3) if j != k]
        parts = [nested[j] for j in nb] if kind == "complex" else [box]
        for b in parts:
            c = [float(side)] * 3
            r = [((b[j][0] - box[j][0]) / (box[j][1] - box[j][0]), (b[j][1] - box[j][0]) / (box[j][1] - box[j][0]))
                 for j in rest]
            for j, (u, v) in zip(rest, r):
                c[j] = (u + v) / 2
            out.append((c, min(v - u for u, v in r)))
    return out


def _with_tubes(f, targets, radius) -> SplineFunction:
    """Interior coefficients raised to tubes from the cell's centre to every face disc (the canonical interior).

    The Boolean sum alone can dip below zero between two discs (a capped
    cell's discs on two faces); the tubes make the canonical cell one piece.
    """
    C = f.coefficients[..., 0].copy()
    if targets:
        unit = tuple(np.round((U - U[0]) / (U[-1] - U[0]), 13).tobytes() for U in f.knots)
        Y = _interior_grevilles(unit, f.degrees)  # (N, 3), from the centre
        D = np.array([p for p, _ in targets]) - 0.5  # (T, 3): the axes to the face discs, all targets at once
        r = radius * np.array([size for _, size in targets])
        YD, DD = Y @ D.T, np.einsum("ij,ij->i", D, D)
        t = np.clip(YD / DD, 0.0, 1.0)  # (N, T): the nearest point t D on each axis, at squared distance:
        dist = np.sqrt(np.maximum(np.einsum("ij,ij->i", Y, Y)[:, None] - t * (2.0 * YD - t * DD), 0.0))
        tube = np.clip((r - dist) / r, -1.0, 1.0).max(axis=1)
        inner = (slice(1, -1),) * 3
        C[inner] = np.maximum(C[inner], tube.reshape(C[inner].shape))
    return SplineFunction._trusted(f.degrees, f.knots, C[..., None], False)


@memo(256)
def _interior_grevilles(knots: tuple, degrees: tuple) -> np.ndarray:
    """The interior control points' Greville abscissae (N, 3), C order, of the unit-cube ``knots`` less the
    cube's centre (cached: cells repeat their knots up to scale)."""
    g = [kn.greville(np.frombuffer(U), d)[1:-1] for U, d in zip(knots, degrees)]
    Y = np.stack(np.meshgrid(*g, indexing="ij"), -1).reshape(-1, 3) - 0.5
    Y.setflags(write=False)
    return Y


def _random_interiors(bases, noises, alpha, subs, stats, boxes):
    """Eq. 6 on the interior coefficients of every cell's field ``bases[i]`` (its draw ``noises[i]``), the
    amplitude halved until the cell's samples on its sample lines ``subs[i]`` (three arrays) pass
    :func:`tiling.implicit.checks.cells_ok` (all cells a round).  Returns the fields and their samples."""
    n = len(bases)
    fields, samples, halvings = [None] * n, [None] * n, np.zeros(n, int)
    inner = (slice(1, -1),) * 3
    pending = np.arange(n)
    for h in range(_HALVINGS + 1):
        a = 0.0 if h == _HALVINGS or alpha == 0 else alpha * 0.5 ** h
        trial = []
        for i in pending:
            C = bases[i].coefficients[..., 0]
            c = C.copy()
            c[inner] = (1 - a) * C[inner] + a * noises[i][inner]
            g = SplineFunction._trusted(bases[i].degrees, bases[i].knots, c[..., None], False)
            trial.append((g, grid_values(g, subs[i])))
        ok = cells_ok([v for _, v in trial])
        for i, (g, v), good in zip(pending, trial, ok):
            if good:
                fields[i], samples[i], halvings[i] = g, v, h
        pending = pending[~ok]
        if not len(pending) or a == 0.0:
            break
    if len(pending):
        i = int(pending[0])
        raise TilingError(f"cell {i} (parameter box {show(boxes[i].tolist())}) is not one connected piece even "
                          "with its canonical faces; raise the resolution or the radius")
    stats["cell_halvings"].update({i: int(h) for i, h in enumerate(halvings)})
    return fields, samples
