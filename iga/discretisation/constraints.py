"""Linear constraints between patch spaces, resolved into one sparse prolongation.

Every trivariate patch keeps its own space (Massarwi et al. 2018, Remark 2).  The temperature
of the whole micro-structure is ``u = P u_red`` where ``P`` (ndof x nred)
encodes

* identity constraints across faces shared by neighbouring patches (with the
  interface's orientation): the two face coefficients are equal;
* C0 coupling inside a tile with partial discontinuities: on a
  full-multiplicity knot plane, the coefficients on both sides are equal
  wherever the two sides coincide as material (Massarwi et al. 2018, Section 3.1);
* branch constraints (Massarwi et al. 2018, Eqs. 11-12): child branch-in face coefficients =
  R @ parent branch-out face coefficients, R the knot-insertion
  (refinement) matrix between the two analysis face spaces.

Equalities are merged into classes, the connected components of the equality
graph (chains, shared edges and corners collapse to one unknown); branch rows
make a class a *slave* expressed through other classes, and slaves of slaves
are substituted until only master classes remain.

Number of free unknowns (``Solution.info["free_dofs"]``)::

    classes - slave classes - prescribed unknowns - induced rank

*classes*: equivalence classes of DOFs under the identity and C0 equalities;
*slave classes*: classes on child branch-in faces; *prescribed unknowns*:
master classes owning a Dirichlet DOF; *induced rank*: the rank of the
conditions that Dirichlet DOFs of slave classes put on their masters (a slot
of a child tile that reaches its base meets the parent's branch-out face
inside an element, so its Dirichlet data fix combinations of the parent's
face coefficients; :func:`solvers.elimination.induced_elimination`).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components

from geometry.errors import SplineError
from geometry.faces import FACE_AXIS, discontinuity_slots, nested_refinement, oriented_face_knots, slot_face_id
from geometry.grouping import ObjectIndex

from solvers.elimination import elimination
from iga.errors import ProblemError
from geometry.tolerances import CONSISTENT, ROUNDOFF

# coefficients of a branch row below this are round-off of the knot insertion (entries are O(1));
# two branch rows of one DOF class that differ by more than _CONSISTENT prescribe it differently
_ZERO_WEIGHT, _CONSISTENT = ROUNDOFF, CONSISTENT


@dataclass
class Constraints:
    """The prolongation ``u = P u_red`` of all interface constraints.

    ``P`` (ndof x nred, CSR); ``dof_master`` (ndof,) the reduced unknown
    owning each DOF (-1 for DOFs of slave classes, which are combinations of
    others); ``stats`` the counts reported in ``Solution.info["constraints"]``.
    """

    P: sp.csr_matrix
    dof_master: np.ndarray
    stats: dict = field(default_factory=dict)


def owners_of(master: np.ndarray, n: int | None = None) -> np.ndarray:
    """For each of the ``n`` reduced unknowns (default: up to the largest owner) one DOF it owns (u_full = P
    u_red reads the unknown there), from :attr:`Constraints.dof_master`; -1 for an unknown that owns no DOF."""
    own = master >= 0
    out = np.full(n if n is not None else int(master.max()) + 1 if own.any() else 0, -1)
    out[master[own][::-1]] = np.flatnonzero(own)[::-1]
    return out


@dataclass
class BranchRows:
    """Branch constraints as triplets: row ``r`` says DOF ``child[r]`` = sum of ``weight`` x ``parent``
    over the entries ``e`` with ``row[e] == r``; ``interface[r]`` indexes ``model.interfaces``."""

    child: np.ndarray  # (rows,) global DOF on a child branch-in face
    interface: np.ndarray  # (rows,)
    row: np.ndarray  # (entries,)
    parent: np.ndarray  # (entries,) global DOF on the parent's branch-out face
    weight: np.ndarray  # (entries,)


def face_dof_grid(spaces, offsets, pi, face):
    """Global DOFs of a patch face as an (n_s, n_t) grid in face-parameter order."""
    space = spaces[pi]
    return (space.face_dofs(face) + offsets[pi]).reshape(space.face_space(face).shape)


def _oriented(grid, swap, flip):
    """Face-b DOF grid re-indexed so that entry [s, t] sits where face a has its [s, t].

    The interface says B(s', t') = A(s, t) with (s', t') = (s, t) swapped if
    ``swap``, then reversed per ``flip``; the flips refer to B's own axes, so
    they are applied before the transpose.
    """
    g = grid
    if flip[0]:
        g = g[::-1, :]
    if flip[1]:
        g = g[:, ::-1]
    return g.T if swap else g


def _face_space_knots(space, face):
    k, _ = FACE_AXIS[face]
    return [(d.knots, d.degree) for i, d in enumerate(space.dirs) if i != k]


def _branch_R(spaces, itf, cache: dict) -> sp.csr_matrix:
    """The refinement matrix of a branch interface (child face coefficients, on the child's DOF grid re-indexed
    along the parent's face axes by the interface's orientation, = R @ parent's), cached on the two face
    spaces, the box and the orientation: a hierarchy repeats the same pair many times."""
    (pa, fa), (pb, fb) = itf.a, itf.b
    parent = _face_space_knots(spaces[pa], fa)
    child = oriented_face_knots(_face_space_knots(spaces[pb], fb), itf.swap, itf.flip)
    key = (tuple((U.tobytes(), p) for U, p in parent), tuple(map(tuple, itf.box)),
           tuple((U.tobytes(), p) for U, p in child))
    if key not in cache:
        try:
            cache[key] = nested_refinement(parent, itf.box, child).tocsr()
        except SplineError as exc:
            raise ProblemError(
                f"branch faces patch {pa} {fa} -> patch {pb} {fb}: {exc}; use the same refine/degree_elevation "
                "for all patches of a hierarchy"
            ) from None
    return cache[key]


def identity_pairs(model, spaces, offsets) -> tuple[np.ndarray, np.ndarray]:
    """DOF pairs (a, b) made equal by the identity interfaces (each face pair with its orientation).

    Interfaces between the same two spaces, faces and orientation share their local index pairs
    (a paving repeats a handful of them thousands of times); each group is shifted by its offsets at once.
    """
    objects = ObjectIndex()
    groups: dict = {}
    for itf in model.interfaces:
        if itf.kind == "identity":
            (pa, fa), (pb, fb) = itf.a, itf.b
            key = (objects(spaces[pa]), fa, objects(spaces[pb]), fb, itf.swap, tuple(itf.flip))
            groups.setdefault(key, []).append((pa, pb))
    a, b = [], []
    for (_, fa, _, fb, swap, flip), members in groups.items():
        pa, pb = np.array(members).T
        ga = face_dof_grid(spaces, np.zeros(len(spaces), np.int64), pa[0], fa)
        gb = _oriented(face_dof_grid(spaces, np.zeros(len(spaces), np.int64), pb[0], fb), swap, flip)
        if ga.shape != gb.shape:
            raise ProblemError(f"identity interface patch {pa[0]} {fa} / patch {pb[0]} {fb}: face spaces differ "
                               f"({ga.shape} vs {gb.shape} coefficients); refine all patches alike")
        a.append((offsets[pa][:, None] + ga.ravel()).ravel())
        b.append((offsets[pb][:, None] + gb.ravel()).ravel())
    return _cat(a), _cat(b)


def _cat(parts) -> np.ndarray:
    return np.concatenate(parts).astype(np.int64) if parts else np.zeros(0, np.int64)


def _support_range(space1d, breaks) -> tuple[np.ndarray, np.ndarray]:
    """Per basis function of a 1-D space, its support as the element range [lo, hi) of ``breaks``."""
    U, p = space1d.knots, space1d.degree
    n = len(U) - p - 1
    return np.searchsorted(breaks, U[:n]), np.searchsorted(breaks, U[p + 1 : p + 1 + n])


def plane_pairs(space, slots) -> tuple[np.ndarray, np.ndarray]:
    """Local DOF pairs to equate across the full-multiplicity knot planes of one patch where both sides
    coincide as material (Massarwi et al. 2018, Section 3.1).

    ``slots``: :func:`geometry.faces.discontinuity_slots` of the patch's tile
    spline, the free (non-coinciding) rectangles of each plane; the rest of the
    plane is one material.  A pair is the last function ending on the plane and
    the first starting there, for every function pair whose support meets a
    coinciding element piece of the plane.
    """
    a, b = [], []
    idx = np.arange(space.ndof).reshape(space.shape)
    for d in range(3):
        sd = space.dirs[d]
        vals, mults = np.unique(sd.knots, return_counts=True)
        rest = [k for k in range(3) if k != d]
        b1, b2 = np.unique(space.dirs[rest[0]].knots), np.unique(space.dirs[rest[1]].knots)
        m1, m2 = np.meshgrid(0.5 * (b1[:-1] + b1[1:]), 0.5 * (b2[:-1] + b2[1:]), indexing="ij")
        lo1, hi1 = _support_range(space.dirs[rest[0]], b1)
        lo2, hi2 = _support_range(space.dirs[rest[1]], b2)
        for v in vals[1:-1][mults[1:-1] >= sd.degree + 1]:
            coincide = np.ones(m1.shape, bool)  # analysis element pieces of the plane outside every slot
            for (a1, c1), (a2, c2) in slots.get(slot_face_id(d, v, -1), []):
                coincide &= ~((m1 > a1) & (m1 < c1) & (m2 > a2) & (m2 < c2))
            # a summed-area table counts the coinciding pieces in each function pair's support box
            S = np.zeros((m1.shape[0] + 1, m1.shape[1] + 1), np.int64)
            S[1:, 1:] = coincide.cumsum(0).cumsum(1)
            count = (S[hi1[:, None], hi2[None, :]] - S[lo1[:, None], hi2[None, :]]
                     - S[hi1[:, None], lo2[None, :]] + S[lo1[:, None], lo2[None, :]])
            # with v repeated p + 1 times from index s, N_{s-1} is the last function ending at v
            # and N_s the first starting at v: the two DOF layers on either side of the plane
            left = int(np.searchsorted(sd.knots, v, side="left")) - 1
            hit = count > 0
            a.append(np.take(idx, left, axis=d)[hit])
            b.append(np.take(idx, left + 1, axis=d)[hit])
    return _cat(a), _cat(b)


def c0_pairs(model, spaces, offsets) -> tuple[np.ndarray, np.ndarray]:
    """Global DOF pairs of :func:`plane_pairs` for every patch; patches that share their tile spline and
    space share the local pairs (found once, then shifted by each patch's offset)."""
    objects = ObjectIndex()
    local: dict = {}
    a, b = [], []
    for pi, patch in enumerate(model.patches):
        key = (objects(patch.spline), spaces[pi].key())
        if key not in local:
            local[key] = plane_pairs(spaces[pi], discontinuity_slots(patch.spline))
        la, lb = local[key]
        a.append(la + offsets[pi])
        b.append(lb + offsets[pi])
    return _cat(a), _cat(b)


def equivalence_classes(n: int, a: np.ndarray, b: np.ndarray) -> tuple[int, np.ndarray]:
    """(number of classes, class of each of the n DOFs) of the equalities a[i] = b[i]: the connected
    components of the equality graph (SciPy's csgraph); classes are numbered by their smallest DOF."""
    graph = sp.coo_matrix((np.ones(len(a), np.int8), (a, b)), shape=(n, n))
    return connected_components(graph, directed=False)


def branch_rows(model, spaces, offsets) -> BranchRows:
    """Every branch interface's rows (Massarwi et al. 2018, Eqs. 11-12) as triplets."""
    cache: dict = {}
    child, interface, row, parent, weight = [], [], [], [], []
    nrows = 0
    for j, itf in enumerate(model.interfaces):
        if itf.kind == "identity":
            continue
        (pa, fa), (pb, fb) = itf.a, itf.b
        R = _branch_R(spaces, itf, cache)
        child.append(_oriented(face_dof_grid(spaces, offsets, pb, fb), itf.swap, itf.flip).ravel())
        interface.append(np.full(R.shape[0], j))
        row.append(nrows + np.repeat(np.arange(R.shape[0]), np.diff(R.indptr)))
        parent.append(face_dof_grid(spaces, offsets, pa, fa).ravel()[R.indices])
        weight.append(R.data)
        nrows += R.shape[0]
    return BranchRows(_cat(child), _cat(interface), _cat(row), _cat(parent),
                      np.concatenate(weight) if weight else np.zeros(0))


def _rows_by_class(ncls: int, cls: np.ndarray, rows: BranchRows):
    """(M, owner, slaves, first): every branch row over classes (nr x ncls, duplicates summed, round-off dropped),
    the class each row constrains, the sorted slave classes and the first row of each."""
    nr = len(rows.child)
    M = sp.csr_matrix((rows.weight, (rows.row, cls[rows.parent])), shape=(nr, ncls))  # sums duplicates
    M.data[np.abs(M.data) <= _ZERO_WEIGHT] = 0.0
    M.eliminate_zeros()
    owner = cls[rows.child]
    slaves, first = np.unique(owner, return_index=True)
    return M, owner, slaves, first


def class_expressions(model, ncls: int, cls: np.ndarray, rows: BranchRows) -> tuple[sp.csr_matrix, np.ndarray]:
    """(C, slaves): C (ncls x ncls) expresses every class through classes (the identity for masters, the first
    branch row of a slave class); ``slaves`` the sorted slave classes.  A class reached by several branch rows
    (edges and corners shared by child faces) must be given the same expression by all of them once slaves are
    substituted, or imply conditions between masters: :func:`implied_conditions`."""
    M, _, slaves, first = _rows_by_class(ncls, cls, rows)
    is_slave = np.zeros(ncls, bool)
    is_slave[slaves] = True
    masters = np.flatnonzero(~is_slave)
    S = M[first].tocoo()
    C = sp.csr_matrix((np.r_[S.data, np.ones(len(masters))], (np.r_[slaves[S.row], masters], np.r_[S.col, masters])),
                      shape=(ncls, ncls))
    return C, slaves


def implied_conditions(model, ncls: int, cls: np.ndarray, rows: BranchRows, Q: sp.csr_matrix) -> sp.csr_matrix:
    """The conditions among master classes that branch rows of one DOF class imply: every row, with its slaves
    substituted (``Q``: :func:`substitute_slaves`), must equal its class's expression; rows that differ give
    ``(row - expression) u = 0`` (a matrix over the classes, one row per condition, none when all agree).

    Two rows from *different* parent faces that differ say that the two parents' traces agree where the
    child's edge runs along both (a patch split next to two coarse neighbours that touch only along an edge:
    the child was their only link), a continuity condition the model needs.  Two rows from one parent face that
    differ contradict each other (a face constrained twice over overlapping boxes) and are refused.
    """
    nr = len(rows.child)
    if not nr:
        return sp.csr_matrix((0, ncls))
    M, owner, _, _ = _rows_by_class(ncls, cls, rows)
    D = (M @ Q - Q[owner]).tocsr()
    worst = np.zeros(nr)
    nz = np.diff(D.indptr) > 0
    worst[nz] = np.maximum.reduceat(abs(D).data, D.indptr[:-1][nz]) if D.nnz else 0.0
    bad = np.flatnonzero(worst > _CONSISTENT)
    if not len(bad):
        return sp.csr_matrix((0, ncls))
    first = np.full(ncls, -1)
    first[owner[::-1]] = np.arange(nr)[::-1]  # the row each class's expression came from
    for r in bad.tolist():
        one, two = model.interfaces[rows.interface[first[owner[r]]]], model.interfaces[rows.interface[r]]
        if tuple(one.a) == tuple(two.a):
            raise ProblemError(
                f"inconsistent constraints: DOF {rows.child[r]} is constrained by branch faces patch {one.a[0]} "
                f"{one.a[1]} -> patch {one.b[0]} {one.b[1]} and patch {two.a[0]} {two.a[1]} -> patch "
                f"{two.b[0]} {two.b[1]} with different values; check these faces and their refinement")
    out = D[bad]
    out.data[np.abs(out.data) <= _ZERO_WEIGHT] = 0.0
    out.eliminate_zeros()
    return out


def substitute_slaves(C: sp.csr_matrix, slaves: np.ndarray) -> sp.csr_matrix:
    """C^k: slaves expressed through master classes only.

    A slave's row may name other slaves (a child face whose parent face DOFs
    are themselves on a branch-in face, e.g. a tile branching sideways from a
    tile that branched upwards); each product substitutes one level.  A cycle
    among slaves (a face its own ancestor) has no solution and is refused.
    """
    if not len(slaves):
        return C
    among = C[slaves][:, slaves]
    nscc, _ = connected_components(among, directed=True, connection="strong")
    if nscc < len(slaves) or among.diagonal().any():
        raise ProblemError("branch constraints form a cycle (a face is its own ancestor); check the interfaces")
    Q = C
    while Q[:, slaves].nnz:  # ends: the slave graph is acyclic, so its longest chain bounds the rounds
        Q = (C @ Q).tocsr()
        Q.data[np.abs(Q.data) < 0.1 * _ZERO_WEIGHT] = 0.0
        Q.eliminate_zeros()
    return Q


def needs_constraints(model, spaces) -> bool:
    """Interfaces, or patches with full-multiplicity (discontinuity) knots, need a prolongation."""
    if model.interfaces:
        return True
    for s in spaces:
        for d in s.dirs:
            _, m = np.unique(d.knots, return_counts=True)
            if np.any(m[1:-1] >= d.degree + 1):
                return True
    return False


def prolongation(model, spaces, offsets, weights=None) -> Constraints:
    """The sparse prolongation P (ndof x nred) of all interface constraints, with its statistics.

    ``spaces``: each patch's :class:`iga.discretisation.space.TensorSpace`; ``offsets`` (patches + 1,) the first global
    DOF of each patch.  Identity and C0 equalities become classes, branch rows make slave classes, slaves
    are substituted down to masters, and each DOF reads its class's expression.  ``weights``: per patch, the
    NURBS weights of a patch analysed in the NURBS basis (:mod:`iga.discretisation.rational`) or None; two DOFs made equal
    must then carry equal weights, or the two bases would not glue (refused, naming the patches).
    """
    offsets = np.asarray(offsets, np.int64)
    n = int(offsets[-1])
    ia, ib = identity_pairs(model, spaces, offsets)
    ca, cb = c0_pairs(model, spaces, offsets)
    if weights is not None and any(w is not None for w in weights):
        _refuse_unequal_weights(weights, offsets, np.r_[ia, ca], np.r_[ib, cb])
    ncls, cls = equivalence_classes(n, np.r_[ia, ca], np.r_[ib, cb])
    rows = branch_rows(model, spaces, offsets)
    C, slaves = class_expressions(model, ncls, cls, rows)
    Q = substitute_slaves(C, slaves)
    implied = implied_conditions(model, ncls, cls, rows, Q)
    is_slave = np.zeros(ncls, bool)
    is_slave[slaves] = True
    masters = np.flatnonzero(~is_slave)
    E = sp.csr_matrix((np.ones(n), (np.arange(n), cls)), shape=(n, ncls))
    P = (E @ Q[:, masters]).tocsr()
    column = np.full(ncls, -1)
    column[masters] = np.arange(len(masters))
    eliminated = 0
    if implied.shape[0]:  # masters linked by the implied conditions: each block's dependent ones eliminated
        T, _, _, keep = elimination(implied[:, masters], np.zeros(implied.shape[0]))
        P = (P @ T).tocsr()
        renumber = np.full(len(masters), -1)
        renumber[keep] = np.arange(int(keep.sum()))
        column[masters] = renumber
        eliminated = int((~keep).sum())
    stats = {"identity_pairs": int(len(ia)), "c0_pairs": int(len(ca)), "branch_rows": int(len(rows.child)),
             "classes": int(ncls), "slave_classes": int(len(slaves)), "implied_conditions": eliminated,
             "reduced": int(P.shape[1])}
    return Constraints(P, column[cls], stats)


def _refuse_unequal_weights(weights, offsets, a: np.ndarray, b: np.ndarray) -> None:
    """Equated DOFs must carry proportional NURBS weights (1 for a polynomial basis), one ratio per pair of
    patches: a NURBS basis is unchanged by scaling all its weights, and otherwise a field glued to another
    basis by equal control values is continuous only where both bases agree on the shared face."""
    if not len(a):
        return
    w = np.concatenate([np.ones(int(offsets[i + 1] - offsets[i])) if wi is None else np.asarray(wi).reshape(-1)
                        for i, wi in enumerate(weights)])
    pa, pb = np.searchsorted(offsets, a, side="right") - 1, np.searchsorted(offsets, b, side="right") - 1
    ratio = w[a] / w[b]
    key = pa * len(weights) + pb
    order = np.argsort(key, kind="stable")
    k, r = key[order], ratio[order]
    starts = np.r_[0, np.flatnonzero(np.diff(k)) + 1]
    lo, hi = np.minimum.reduceat(r, starts), np.maximum.reduceat(r, starts)
    bad = np.flatnonzero(hi - lo > CONSISTENT * hi)
    if len(bad):
        i = order[starts[bad[0]]]
        raise ProblemError(f"patches {int(pa[i])} and {int(pb[i])} share a face on which their NURBS weights are not "
                           f"proportional (ratios {lo[bad[0]]:.6g} to {hi[bad[0]]:.6g}): a patch analysed in the NURBS "
                           "basis of its own weights (iga.discretisation.rational) glues only to a face with the same weights, up to "
                           "one factor; give both patches the same weights on the shared face")
