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

Equalities are merged with a union-find (chains, shared edges and corners
collapse to one unknown); branch rows make a class a *slave* expressed
through other classes, and slaves of slaves are substituted until only
master classes remain.

Number of free unknowns (``Solution.info["free_dofs"]``)::

    classes - slave classes - prescribed unknowns - induced rank

*classes*: equivalence classes of DOFs under the identity and C0 equalities;
*slave classes*: classes on child branch-in faces; *prescribed unknowns*:
master classes owning a Dirichlet DOF; *induced rank*: the rank of the
conditions that Dirichlet DOFs of slave classes put on their masters (a slot
of a child tile that reaches its base meets the parent's branch-out face
inside an element, so its Dirichlet data fix combinations of the parent's
face coefficients; :func:`induced_elimination`).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from types import SimpleNamespace

import numpy as np
import scipy.sparse as sp
from scipy.linalg import qr, solve_triangular
from scipy.sparse.csgraph import connected_components

from geometry.errors import SplineError
from geometry.faces import FACE_AXIS, discontinuity_slots, nested_refinement, slot_face_id

from .errors import ProblemError


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


class _UnionFind:
    def __init__(self, n):
        self.parent = np.arange(n)

    def find(self, a):
        root = a
        while self.parent[root] != root:
            root = self.parent[root]
        while self.parent[a] != root:  # path compression
            self.parent[a], a = root, self.parent[a]
        return root

    def union(self, a, b):
        ra, rb = self.find(a), self.find(b)
        if ra != rb:
            self.parent[max(ra, rb)] = min(ra, rb)


def _face_grid(problem, pi, face):
    """Global DOFs of a patch face as an (n_s, n_t) grid in face-parameter order."""
    space = problem.spaces[pi]
    fs = space.face_space(face)
    return (space.face_dofs(face) + problem.offsets[pi]).reshape(fs.shape)


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


def _face_space_knots(problem, pi, face):
    k, _ = FACE_AXIS[face]
    return [(d.knots, d.degree) for i, d in enumerate(problem.spaces[pi].dirs) if i != k]


def _branch_R(problem, itf, cache: dict | None = None) -> sp.csr_matrix:
    (pa, fa), (pb, fb) = itf.a, itf.b
    parent, child = _face_space_knots(problem, pa, fa), _face_space_knots(problem, pb, fb)
    key = (tuple((U.tobytes(), p) for U, p in parent), tuple(map(tuple, itf.box)),
           tuple((U.tobytes(), p) for U, p in child))
    if cache is not None and key in cache:  # a hierarchy repeats the same pair of face spaces many times
        return cache[key]
    try:
        R = nested_refinement(parent, itf.box, child)
        if cache is not None:
            cache[key] = R
        return R
    except SplineError as exc:
        raise ProblemError(
            f"branch faces patch {pa} {fa} -> patch {pb} {fb}: {exc}; use the same refine/degree_elevation "
            "for all patches of a hierarchy"
        ) from None


def _discontinuity_pairs(problem, pi, slots):
    """DOF pairs to equate across full-multiplicity knot planes of patch ``pi`` where both sides coincide.

    ``slots``: :func:`tiling.microstructure.discontinuity_slots` of the patch's
    tile spline, the free (non-coinciding) rectangles of each plane; the rest
    of the plane is one material.
    """
    space = problem.spaces[pi]
    pairs = []
    for d in range(3):
        sd = space.dirs[d]
        vals, mults = np.unique(sd.knots, return_counts=True)
        for v in vals[1:-1][mults[1:-1] >= sd.degree + 1]:
            # with v repeated p + 1 times from index s, N_{s-1} is the last function ending at v
            # and N_s the first starting at v: the two DOF layers on either side of the plane
            left = int(np.searchsorted(sd.knots, v, side="left")) - 1
            right = left + 1
            rest = [k for k in range(3) if k != d]
            # analysis element pieces of the plane that are not in a free slot rectangle coincide
            b1, b2 = np.unique(space.dirs[rest[0]].knots), np.unique(space.dirs[rest[1]].knots)
            m1, m2 = np.meshgrid(0.5 * (b1[:-1] + b1[1:]), 0.5 * (b2[:-1] + b2[1:]), indexing="ij")
            coincide = np.ones(m1.shape, bool)
            for (a1, c1), (a2, c2) in slots.get(slot_face_id(d, v, -1), []):
                coincide &= ~((m1 > a1) & (m1 < c1) & (m2 > a2) & (m2 < c2))
            if not coincide.any():
                continue
            # couple the functions whose support meets a coinciding piece
            idx = np.arange(space.ndof).reshape(space.shape) + problem.offsets[pi]
            L = np.take(idx, left, axis=d)
            R = np.take(idx, right, axis=d)
            for j in range(L.shape[0]):
                e1 = _support(space.dirs[rest[0]], j, b1)
                for k in range(L.shape[1]):
                    e2 = _support(space.dirs[rest[1]], k, b2)
                    if coincide[np.ix_(e1, e2)].any():
                        pairs.append((int(L[j, k]), int(R[j, k])))
    return pairs


def _support(sp1, i, breaks):
    """Element indices in the support of basis function i of a 1-D space."""
    U = sp1.knots
    a, b = U[i], U[i + sp1.degree + 1]
    return np.nonzero((breaks[:-1] >= a) & (breaks[1:] <= b) & (breaks[1:] > breaks[:-1]))[0]


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


def prolongation(problem) -> Constraints:
    """The sparse prolongation P (ndof x nred) of all interface constraints, with its statistics."""
    n = problem.ndof
    uf = _UnionFind(n)
    stats = {"identity_pairs": 0, "c0_pairs": 0, "branch_rows": 0}
    branch_rows = []  # (child dof, parent dofs, coefficients)
    cache: dict = {}  # refinement matrices by (parent face space, box, child face space)
    for itf in problem.model.interfaces:
        (pa, fa), (pb, fb) = itf.a, itf.b
        ga, gb = _face_grid(problem, pa, fa), _face_grid(problem, pb, fb)
        if itf.kind == "identity":
            gb = _oriented(gb, itf.swap, itf.flip)
            if ga.shape != gb.shape:
                raise ProblemError(f"identity interface patch {pa} {fa} / patch {pb} {fb}: face spaces differ "
                                   f"({ga.shape} vs {gb.shape} coefficients); refine all patches alike")
            for x, y in zip(ga.ravel(), gb.ravel()):
                uf.union(int(x), int(y))
            stats["identity_pairs"] += ga.size
        else:
            R = _branch_R(problem, itf, cache).tocsr()
            parent, child = ga.ravel(), gb.ravel()
            for r in range(R.shape[0]):
                cols = R.indices[R.indptr[r] : R.indptr[r + 1]]
                branch_rows.append((int(child[r]), parent[cols], R.data[R.indptr[r] : R.indptr[r + 1]], itf))
            stats["branch_rows"] += R.shape[0]
    pairs_of: dict = {}  # tiles share their spline and space: find each patch's pairs once, then shift them
    for pi, patch in enumerate(problem.model.patches):
        key = (id(patch.spline), id(problem.spaces[pi]))
        if key not in pairs_of:
            local = SimpleNamespace(spaces=[problem.spaces[pi]], offsets=np.zeros(1, np.int64))
            pairs_of[key] = _discontinuity_pairs(local, 0, discontinuity_slots(patch.spline))
        off = int(problem.offsets[pi])
        for a, b in pairs_of[key]:
            uf.union(a + off, b + off)
            stats["c0_pairs"] += 1
    roots = np.array([uf.find(i) for i in range(n)])
    classes, cls = np.unique(roots, return_inverse=True)
    ncls = len(classes)
    # class-level slave expressions (branch rows), checked for consistency
    expr: dict = {}
    source: dict = {}
    for child, parents, coef, itf in branch_rows:
        c = int(cls[child])
        row = {}
        for p, w in zip(cls[parents], coef):
            row[int(p)] = row.get(int(p), 0.0) + float(w)
        row = {k: w for k, w in row.items() if abs(w) > 1e-14}
        if c in expr:
            old = expr[c]
            keys = set(old) | set(row)
            if max(abs(old.get(k, 0.0) - row.get(k, 0.0)) for k in keys) > 1e-10:
                first = source[c]
                raise ProblemError(
                    f"inconsistent constraints: DOF {child} is constrained by branch faces patch {first.a[0]} "
                    f"{first.a[1]} -> patch {first.b[0]} {first.b[1]} and patch {itf.a[0]} {itf.a[1]} -> patch "
                    f"{itf.b[0]} {itf.b[1]} with different values; check these faces and their refinement"
                )
        else:
            expr[c] = row
            source[c] = itf
    slaves = np.array(sorted(expr), dtype=np.int64)
    is_slave = np.zeros(ncls, bool)
    is_slave[slaves] = True
    rows, cols, vals = [], [], []
    for c in range(ncls):
        if is_slave[c]:
            for k, w in expr[c].items():
                rows.append(c); cols.append(k); vals.append(w)
        else:
            rows.append(c); cols.append(c); vals.append(1.0)
    C = sp.csr_matrix((vals, (rows, cols)), shape=(ncls, ncls))
    Q = C
    for _ in range(200):  # substitute slaves of slaves (one round per hierarchy level)
        if not len(slaves) or Q[:, slaves].nnz == 0:
            break
        Q = (C @ Q).tocsr()
        Q.data[np.abs(Q.data) < 1e-15] = 0.0
        Q.eliminate_zeros()
    else:
        raise ProblemError("branch constraints form a cycle (a face is its own ancestor); check the interfaces")
    masters = np.nonzero(~is_slave)[0]
    Qm = Q[:, masters]
    E = sp.csr_matrix((np.ones(n), (np.arange(n), cls)), shape=(n, ncls))
    P = (E @ Qm).tocsr()
    column = np.full(ncls, -1)
    column[masters] = np.arange(len(masters))
    stats.update({"classes": int(ncls), "slave_classes": int(len(slaves)), "reduced": int(len(masters))})
    return Constraints(P, column[cls], stats)


def induced_elimination(C: sp.spmatrix, rhs: np.ndarray, tol: float = 1e-10):
    """Solve the linear constraints ``C x = rhs`` on free unknowns by elimination.

    Dirichlet DOFs that are *slaves* (child branch-in DOFs on a Dirichlet face,
    e.g. the bottom edge of a slot inside a parent's branch-out face) fix a
    combination of their masters, not one master: ``P[row] u = g``.  These rows
    are split into independent blocks (connected components of the columns they
    share, SciPy's csgraph); per block a column-pivoted QR finds the rank ``r``
    and expresses ``r`` pivot columns through the others.

    Returns ``(T, x0, touched)``: every ``x`` with ``C x = rhs`` (in the least-squares
    sense when the rows conflict) is ``x = T z + x0``; ``T`` is sparse (n x nz)
    with unit columns for the untouched unknowns; ``touched`` are the columns C involves.
    """
    C = sp.csr_matrix(C)
    n = C.shape[1]
    C.data[np.abs(C.data) < 1e-14] = 0.0
    C.eliminate_zeros()
    rows = np.nonzero(np.diff(C.indptr))[0]
    touched = np.unique(C.indices)
    x0 = np.zeros(n)
    if not len(touched):
        return sp.identity(n, format="csc"), x0, touched
    Ct = C[rows][:, touched].tocsc()
    # columns linked through a shared row belong to one block
    link = (abs(Ct.T) @ abs(Ct)).tocsr()
    nb, label = connected_components(link, directed=False)
    keep = np.ones(n, bool)  # columns that stay unknowns
    t_rows, t_cols, t_vals = [], [], []  # entries of T for eliminated columns: x_piv = sum_j t x_j
    for b in range(nb):
        cols_b = np.nonzero(label == b)[0]
        sub = Ct[:, cols_b]
        rows_b = np.unique(sub.indices)
        A = sub[rows_b].toarray()
        y = rhs[rows[rows_b]]
        Q, R, perm = qr(A, mode="economic", pivoting=True)
        d = np.abs(np.diag(R))
        r = int(np.sum(d > tol * max(d[0], 1e-300))) if len(d) else 0
        if r == 0:
            continue
        piv, rest = perm[:r], perm[r:]
        # A[:, piv] x_piv + A[:, rest] x_rest = y  ->  x_piv = R11^-1 (Q1^T y - R12 x_rest)
        R11, R12 = R[:r, :r], R[:r, r:]
        base = solve_triangular(R11, Q[:, :r].T @ y)
        coup = -solve_triangular(R11, R12) if len(rest) else np.zeros((r, 0))
        gp, gr = touched[cols_b[piv]], touched[cols_b[rest]]
        x0[gp] = base
        keep[gp] = False
        ii, jj = np.nonzero(np.abs(coup) > 1e-15)
        t_rows.append(gp[ii]); t_cols.append(gr[jj]); t_vals.append(coup[ii, jj])
    col_of = np.full(n, -1)
    col_of[keep] = np.arange(int(keep.sum()))
    kept = np.nonzero(keep)[0]
    r_all = np.concatenate([kept] + t_rows)
    c_all = np.concatenate([col_of[kept]] + [col_of[c] for c in t_cols])
    v_all = np.concatenate([np.ones(len(kept))] + t_vals)
    T = sp.csc_matrix((v_all, (r_all, c_all)), shape=(n, int(keep.sum())))
    return T, x0, touched
