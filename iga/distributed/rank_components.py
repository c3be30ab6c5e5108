"""The connected components of a distributed heat problem (:mod:`iga.discretisation.components`) from each rank's own
patches and its part of the constraints (:mod:`iga.distributed.rank_constraints`), without a global graph of DOFs.

Each rank labels the pieces of its own patches joined by the classes they read (the serial graph
restricted to them); a class that other ranks' patches read too joins those ranks' components.  The
classes are known everywhere by their smallest DOF (their key), so each rank sends, for the classes it
shares, (key, its component): one ``allgather`` of a surface's worth of pairs, whose connected components
(SciPy's csgraph, on the components of every rank) are the model's.  The summaries (DOFs, patches, the
conditions on their faces) are gathered the same way, and every rank refuses floating components and
warns of idle ones exactly as a serial solve does (:func:`iga.discretisation.components.check_components`).
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components

from iga.discretisation.components import Component, patch_dof_labels, check_components

__all__ = ["rank_components"]


def _local(problem, rc, faces_by_kind):
    """(number of components of the own patches, (key, component) pairs of the classes shared with other
    ranks, per component (DOFs, patches, {(kind, condition index)}))."""
    P = rc.constraints.P
    own_rows = P[rc.own]
    count, labels = patch_dof_labels([problem.spaces[i] for i in rc.own_patches], own_rows)
    Po = own_rows.tocoo()
    rest = np.flatnonzero(np.diff(P.indptr) > 0)
    rest = rest[~np.isin(rest, rc.own)]  # the closure's rows of other ranks' patches
    # classes other ranks read: those the closure's other rows read, and those on its border
    other = rc.on_border.copy()
    other[P[rest].indices] = True
    read = np.unique(Po.col)
    shared = read[other[read]]
    keys = rc.keys()
    sel = np.isin(Po.col, shared)
    pairs = np.unique(np.stack([keys[Po.col[sel]], labels[Po.row[sel]]], axis=1), axis=0)
    sizes = np.bincount(labels, minlength=count)
    patch_of = np.repeat(rc.own_patches, np.diff(problem.offsets)[rc.own_patches])
    cp = np.unique(np.stack([labels, patch_of], axis=1), axis=0)  # (component, patch) pairs, by component
    cut = np.searchsorted(cp[:, 0], np.arange(count + 1))
    comp_patches = [cp[a:b, 1].tolist() for a, b in zip(cut[:-1], cut[1:])]
    index = {id(c): i for i, c in enumerate(problem.conditions)}
    mine = set(rc.own_patches.tolist())
    conds: list = [set() for _ in range(count)]
    for kind, faces in faces_by_kind.items():
        keys_f = [k for k in faces if k[0] in mine]
        for key, fd in zip(keys_f, problem.faces(keys_f)):
            for c in np.unique(labels[np.searchsorted(rc.own, rc.local(fd.dofs))]):
                conds[int(c)].add((kind, index[id(faces[key])]))
    return count, pairs, [(int(n), p, s) for n, p, s in zip(sizes, comp_patches, conds)]


def rank_components(problem, rc, faces_by_kind: dict, source_W: float, comm) -> tuple[list, list]:
    """(components, idle components) of a distributed heat problem, the same on every rank and as a serial
    solve finds them (up to their order); refuses floating ones, warns of idle ones."""
    count, pairs, summary = _local(problem, rc, faces_by_kind)
    counts = np.asarray(comm.allgather(count), np.int64)
    first = np.concatenate([[0], np.cumsum(counts)])
    rank = comm.Get_rank()
    pairs = pairs.copy()
    pairs[:, 1] += first[rank]
    every = np.concatenate(comm.allgather(pairs)) if len(counts) else pairs
    n = int(first[-1])
    every = every[np.lexsort((every[:, 1], every[:, 0]))]
    same = np.flatnonzero(every[1:, 0] == every[:-1, 0])  # consecutive pairs of one class: an edge
    G = sp.coo_matrix((np.ones(len(same)), (every[same, 1], every[same + 1, 1])), shape=(n, n))
    _, label = connected_components(G, directed=False)
    parts = [s for part in comm.allgather(summary) for s in part]
    merged: dict = {}
    for lab, (dofs, patches, conds) in zip(label.tolist(), parts):
        d, p, c = merged.get(lab, (0, [], set()))
        merged[lab] = (d + dofs, p + patches, c | conds)
    comps = []
    for dofs, patches, conds in sorted(merged.values(), key=lambda m: min(m[1])):
        kinds: dict = {}
        for kind, i in conds:
            kinds.setdefault(kind, set()).add(problem.conditions[i].tag)
        only = {i for _, i in conds}
        idle = ("neumann" not in kinds and len(only) == 1
                and problem.conditions[next(iter(only))].value.constant is not None)
        comps.append(Component(dofs, sorted(patches), {k: sorted(v) for k, v in sorted(kinds.items())}, idle))
    return comps, check_components(comps, has_source=source_W != 0.0)
