"""Discrete spaces: tensor products of 1-D B-spline spaces with quadrature data.

A :class:`Space1D` holds everything the sum-factorised assembly needs in one
direction: the basis values and derivatives at the Gauss points, arranged in
*windows*.  Basis function ``i`` is supported on at most ``p + 1`` elements
starting at element ``start[i]``; its window is the ``L = (p + 1) g``
quadrature points of those elements (padded with a zero column past the end).
For a pair ``(i, j = i + d - p)``, ``W[(a, b)][i, d, l]`` is the product of the
``a``-th derivative of ``N_i`` and the ``b``-th derivative of ``N_j`` at window
point ``l``: contracting a quadrature field against ``W`` along one direction
yields the banded (``2p + 1`` wide) 1-D operator without forming element
matrices.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property

import numpy as np

from geometry import knots as kn
from geometry.errors import show
from geometry.faces import FACE_AXIS

from iga.errors import ProblemError
from iga.discretisation.quadrature import element_rule
from geometry.grouping import ObjectIndex



@dataclass(eq=False)
class Space1D:
    """1-D spline space with Gauss quadrature (``g`` points per element)."""

    knots: np.ndarray
    degree: int
    g: int
    #: derived tables, computed once per space and kept: ("W", a, b) by :meth:`W`, ("stage", a, b) by
    #: :func:`iga.assembly.tensor.stage_matrix`, "fast" by :func:`iga.assembly.compiled` (the compiled kernels' layout)
    tables: dict = field(default_factory=dict, init=False, repr=False)

    def __post_init__(self):
        U, p = self.knots, self.degree
        self.n = len(U) - p - 1
        self.breaks = np.unique(U)
        self.E = len(self.breaks) - 1
        self.qpts, self.qw = element_rule(self.breaks, self.g)
        self.nq = len(self.qpts)
        spans, ders = kn.basis_functions(U, p, self.qpts, 1)
        first = spans - p
        # dense (n, nq + 1) value / derivative tables; the last column is the zero pad
        self.B = np.zeros((2, self.n, self.nq + 1))
        cols = np.arange(self.nq)
        for a in range(p + 1):
            self.B[0, first + a, cols] = ders[:, 0, a]
            self.B[1, first + a, cols] = ders[:, 1, a]
        # window of basis i: p+1 elements from the element where its support starts
        elem_lo = np.searchsorted(self.breaks, U[:-p - 1], side="right") - 1
        self.start = np.clip(elem_lo, 0, self.E - 1)
        L = (p + 1) * self.g
        idx = self.start[:, None] * self.g + np.arange(L)[None, :]
        self.qidx = np.where(idx < self.nq, idx, self.nq)  # (n, L) -> pad column past the end
        self.L = L

    @cached_property
    def pair_index(self) -> np.ndarray:
        """``j = i + d - p`` for every (i, d), clipped, with validity mask (n, 2p+1)."""
        p = self.degree
        j = np.arange(self.n)[:, None] + np.arange(2 * p + 1)[None, :] - p
        return j

    def W(self, a: int, b: int) -> np.ndarray:
        """(n, 2p+1, L): d^a N_i * d^b N_j at the window points of i (zero where j is out of range)."""
        key = ("W", a, b)
        if key not in self.tables:
            j = self.pair_index
            valid = (j >= 0) & (j < self.n)
            jj = np.clip(j, 0, self.n - 1)
            Bi = self.B[a][np.arange(self.n)[:, None], self.qidx]  # (n, L)
            Bj = self.B[b][jj[:, :, None], self.qidx[:, None, :]]  # (n, 2p+1, L)
            self.tables[key] = Bi[:, None, :] * Bj * valid[:, :, None]
        return self.tables[key]

    def window_values(self, a: int = 0) -> np.ndarray:
        """(n, L): d^a N_i at its window points (for load vectors)."""
        return self.B[a][np.arange(self.n)[:, None], self.qidx]


def space_knots(knots: np.ndarray, degree: int, elevate: int = 0, refine: int = 0,
                target: int | None = None) -> tuple[np.ndarray, int]:
    """Knot vector and degree of the analysis space of one direction.

    The degree becomes ``target`` (default ``degree + elevate``); every
    breakpoint keeps the continuity it has in ``knots``, capped at
    ``C^{p-1}`` (so raising the degree keeps continuity, like degree
    elevation, and lowering it is allowed for analysis on high-degree
    geometry).  Then every span is bisected ``refine`` times.
    """
    U, p = np.asarray(knots, float), int(degree)
    q = p + elevate if target is None else int(target)
    vals, mults = kn.breakpoints(U)
    cont = np.minimum(p - mults, q - 1)  # C^cont at each breakpoint (-1: discontinuous)
    new = q - cont
    new[0] = new[-1] = q + 1
    U = np.repeat(vals, new)
    for _ in range(refine):
        b = np.unique(U)
        U = np.sort(np.concatenate([U, 0.5 * (b[:-1] + b[1:])]))
    return U, q


@dataclass(eq=False)
class TensorSpace:
    """Tensor-product space of 2 or 3 :class:`Space1D` (C-order numbering of the DOFs)."""

    dirs: list

    def __post_init__(self):
        #: basis functions and Gauss points per direction, and their totals (the space is immutable)
        self.shape = tuple(s.n for s in self.dirs)
        self.qshape = tuple(s.nq for s in self.dirs)
        self.ndof = int(np.prod(self.shape))
        self.nq_total = int(np.prod(self.qshape))
        # formed once: models with 10^5 faces group their face data by it (it hashes the knot bytes)
        self._key = tuple((s.degree, s.g, s.knots.tobytes()) for s in self.dirs)

    @property
    def dim(self) -> int:
        """Parametric dimension (2 or 3)."""
        return len(self.dirs)

    @property
    def qaxes(self) -> list[np.ndarray]:
        """Gauss points per direction (parameter values)."""
        return [s.qpts for s in self.dirs]

    def key(self) -> tuple:
        """Hashable identity: spaces with equal keys share all quadrature data (batching)."""
        return self._key

    def face_dofs(self, face: str) -> np.ndarray:
        """Indices (C-order) of the DOFs on a boundary face, ordered as the face space numbers them."""
        k, side = FACE_AXIS[face]
        idx = np.arange(self.ndof).reshape(self.shape)
        return np.take(idx, -1 if side else 0, axis=k).ravel()

    def face_space(self, face: str) -> "TensorSpace":
        """The 2-D space of the face ``face`` (its two remaining directions, in order)."""
        k, _ = FACE_AXIS[face]
        return TensorSpace([s for i, s in enumerate(self.dirs) if i != k])


def make_space(knots, degrees, g_extra: int = 0, elevate=0, refine: int = 0, target=None) -> TensorSpace:
    """Analysis space from a patch's knot vectors and degrees (Remark 2: the tile's own basis).

    ``elevate``: int or one int per direction; ``target``: optional degrees per direction.
    """
    d = len(degrees)
    elevate = [elevate] * d if np.isscalar(elevate) else list(elevate)
    target = [None] * d if target is None else list(target)
    dirs = []
    for U, p, e, t in zip(knots, degrees, elevate, target):
        U2, p2 = space_knots(U, p, e, refine, t)
        dirs.append(Space1D(U2, p2, p2 + 1 + g_extra))
    return TensorSpace(dirs)


def space_size(knots, degrees, g_extra: int = 0, elevate=0, refine: int = 0, target=None) -> tuple[int, int, int]:
    """(DOFs, quadrature points, bytes of the 1-D tables) of :func:`make_space`'s result, without building it.

    Knot vectors only (cheap even for many refinements): used to refuse a
    space that would not fit in memory before its tables are allocated.
    """
    d = len(degrees)
    elevate = [elevate] * d if np.isscalar(elevate) else list(elevate)
    target = [None] * d if target is None else list(target)
    ndof, nq, table = 1, 1, 0
    for U, p, e, t in zip(knots, degrees, elevate, target):
        U0, q = space_knots(U, p, e, 0, t)  # unrefined: cheap
        E0 = len(np.unique(U0)) - 1
        E = E0 * 2 ** refine
        n = len(U0) - q - 1 + (E - E0)  # each bisection adds one simple knot per span
        g = q + 1 + g_extra
        ndof *= n
        nq *= E * g
        table += 8 * 2 * n * (E * g + 1) * 2  # value/derivative tables, and the pair tables built from them
    return int(ndof), int(nq), int(table)


def estimate(model, quadrature_extra=0, degree_elevation=0, refine=0, degree=None, bases=None) -> dict:
    """DOFs and a memory estimate (bytes) of the analysis of ``model``, from knot vectors only.

    Memory: the stiffness matrix (12 bytes per non-zero: value and column), the
    reduced matrix and the solver's hierarchy (together about 1.6 times the
    matrix, measured on the unit cube up to 1M unknowns), and the quadrature
    tables of every distinct space.  ``bases``: per patch (knots, degrees) of the solution basis (default:
    each patch geometry's).
    """
    same = ObjectIndex()  # patches share splines and maps: group by object
    sizes: dict = {}
    dofs, nbytes = 0, 0.0
    for i, p in enumerate(model.patches):
        knots, degrees = (p.spline.knots, p.spline.degrees) if bases is None else bases[i]
        key = same(p.spline) if bases is None else (tuple(U.tobytes() for U in knots), degrees)
        if key not in sizes:
            n, _, tables = space_size(knots, degrees, quadrature_extra, degree_elevation, refine, degree)
            q = [pd + (degree_elevation[k] if isinstance(degree_elevation, tuple) else degree_elevation)
                 if degree is None else degree[k] for k, pd in enumerate(degrees)]
            sizes[key] = (n, n * float(np.prod([2 * v + 1 for v in q])) * 12 * 1.6)
            nbytes += tables
        dofs += sizes[key][0]
        nbytes += sizes[key][1]
    return {"dofs": int(dofs), "bytes": nbytes}


def solution_bases(model, bases=None) -> list:
    """Per patch (knot vectors, degrees) of the solution basis: the geometry's, or ``bases`` checked."""
    own = [(p.spline.knots, p.spline.degrees) for p in model.patches]
    if bases is None:
        return own
    if not isinstance(bases, (list, tuple)) or len(bases) != len(own):
        raise ProblemError(f"bases must give (knots, degrees) for each of the {len(own)} patches, got {show(bases)}")
    out = []
    for i, ((U0, _), b) in enumerate(zip(own, bases)):
        try:
            knots, degrees = [np.asarray(U, float).ravel() for U in b[0]], tuple(int(d) for d in b[1])
        except (TypeError, ValueError, IndexError):
            raise ProblemError(f"bases[{i}] must be (knot vectors, degrees), got {show(b)}") from None
        if (len(knots) != len(U0) or len(degrees) != len(U0) or any(len(U) < 2 for U in knots)
                or any(U[0] != V[0] or U[-1] != V[-1] for U, V in zip(knots, U0))):
            raise ProblemError(f"bases[{i}] must span patch {i}'s parameter domain with {len(U0)} knot vectors")
        out.append((knots, degrees))
    return out
