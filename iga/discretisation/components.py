"""Connected components of the coupled model, and the conditions each one touches.

Two unknowns are coupled when they share an element or a constraint (a
column of the prolongation ``P``), so the connected components of that graph
(SciPy's csgraph, on the patches' continuous pieces and the reduced unknowns,
:func:`dof_labels`) are the parts of the model that exchange heat: tiles glued by interfaces, and the
pieces of a tile that its discontinuities leave connected.  A missing
interface splits a component; a tile whose paving leaves no path between two
walls gives one component per wall.

A component that no Dirichlet or Robin condition touches floats (its
temperature is defined only up to a constant), and the solve is refused.  A
component that exactly one Dirichlet or Robin condition of constant value
touches, with no Neumann face and no source, carries no heat: its temperature is that
condition's, and the user is warned (:class:`IdleComponentWarning`).
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components

from geometry.errors import show

from iga.errors import SingularProblemError
from geometry.grouping import ObjectIndex

__all__ = ["Component", "IdleComponentWarning", "model_components", "check_components", "analyse_components"]


class IdleComponentWarning(UserWarning):
    """A piece of the model that no heat flows through: one condition touches it, nothing else drives it."""


@dataclass
class Component:
    """One coupled piece: its DOF count, patches and the tags of the conditions on its faces, by kind."""

    dofs: int
    patches: list
    conditions: dict = field(default_factory=dict)  # kind -> sorted tags
    idle: bool = False  # one condition of constant value touches it, and no flux: it carries no heat

    def as_dict(self) -> dict:
        return {"dofs": self.dofs, "patches": len(self.patches), "first_patch": int(self.patches[0]),
                "conditions": {k: list(v) for k, v in self.conditions.items()}}


def _piece_of_dofs(space) -> np.ndarray:
    """Piece number (C order over the pieces) of every DOF of a tensor space, (ndof,).

    A full-multiplicity knot v splits a direction's basis: function i lies left
    of v when its support ends at v, right when it starts there.  So along
    each direction the block of function i is the number of discontinuity
    knots at or below its first knot.
    """
    blocks = []
    for d in space.dirs:
        U, p = d.knots, d.degree
        vals, mults = np.unique(U, return_counts=True)
        cuts = vals[1:-1][mults[1:-1] >= p + 1]
        blocks.append((np.searchsorted(cuts, U[: d.n], side="right"), len(cuts) + 1))
    label = np.zeros(space.shape, np.int64)
    for k, (b, n) in enumerate(blocks):
        label = label * n + b.reshape([-1 if j == k else 1 for j in range(len(blocks))])
    return label.ravel()


def dof_labels(problem, P: sp.spmatrix | None) -> tuple[int, np.ndarray]:
    """(number of components, component per DOF (ndof,)) of the coupled system (module notes).

    Inside a piece of a patch (between its discontinuity knots) every DOF is
    coupled to every other through the elements, so the graph is built on the
    pieces and the reduced unknowns: a piece is joined to every reduced
    unknown one of its DOFs depends on (the pattern of ``P``).  Its size is
    that of ``P``, not of the stiffness matrix.
    """
    return patch_dof_labels(problem.spaces, P)


def patch_dof_labels(spaces, P) -> tuple[int, np.ndarray]:
    """:func:`dof_labels` of the patches with ``spaces`` (P's rows: their DOFs one patch after the other)."""
    same = ObjectIndex()  # patches share splines and maps: group by object
    piece, count = [], 0
    known: dict = {}  # patches share space objects: one labelling per distinct space, for this call only
    for s in spaces:
        if same(s) not in known:
            lab = _piece_of_dofs(s)
            known[same(s)] = (lab, int(lab.max()) + 1)
        lab, n = known[same(s)]
        piece.append(lab + count)
        count += n
    piece = np.concatenate(piece)
    if P is None:
        n_comp, lab = connected_components(sp.csr_matrix((count, count)), directed=False)
        return n_comp, lab[piece]
    Pc = sp.coo_matrix(P)
    B = sp.csr_matrix((np.ones(Pc.nnz), (piece[Pc.row], Pc.col)), shape=(count, P.shape[1]))
    A = sp.bmat([[None, B], [B.T, None]], format="csr")
    _, lab = connected_components(A, directed=False)
    used, comp = np.unique(lab[:count], return_inverse=True)
    return len(used), comp[piece]


def model_components(problem, P, faces_by_kind: dict) -> list[Component]:
    """The components of a heat problem's coupled system with the tagged conditions each one touches.

    ``P``: the prolongation (ndof x nred) or None (one patch without
    discontinuities); ``faces_by_kind``: {kind: {(patch, face): condition}} as
    the problem books them.
    """
    same = ObjectIndex()  # patches share splines and maps: group by object
    count, labels = dof_labels(problem, P)
    offsets = problem.offsets
    patch_of = np.repeat(np.arange(len(offsets) - 1), np.diff(offsets))
    sizes = np.bincount(labels, minlength=count)
    n_patches = len(offsets) - 1
    pairs = np.unique(labels.astype(np.int64) * n_patches + patch_of)  # (component, patch) keys, by component
    comp_of, patch_in = np.divmod(pairs, n_patches)
    starts = np.searchsorted(comp_of, np.arange(count + 1))
    comps = [Component(int(sizes[c]), patch_in[starts[c]:starts[c + 1]].tolist(), {}) for c in range(count)]
    touching: list = [dict() for _ in comps]  # per component: the condition objects on its faces, by id
    for kind, faces in faces_by_kind.items():
        keys = list(faces)
        if not keys:
            continue
        for key, fd in zip(keys, problem.faces(keys)):
            for c in np.unique(labels[fd.dofs]):
                comps[int(c)].conditions.setdefault(kind, set()).add(faces[key].tag)
                touching[int(c)][same(faces[key])] = faces[key]
    for comp, conds in zip(comps, touching):
        comp.conditions = {k: sorted(v) for k, v in sorted(comp.conditions.items())}
        only = list(conds.values())
        comp.idle = ("neumann" not in comp.conditions and len(only) == 1 and only[0].value.constant is not None)
    return comps


def analyse_components(problem, constraints, faces_by_kind: dict, source_W: float) -> tuple[list, list]:
    """(components, idle components) of a heat problem about to be solved; refuses floating ones, warns about
    idle ones (:func:`check_components`).  ``constraints``: :class:`iga.discretisation.constraints.Constraints` or None."""
    comps = model_components(problem, None if constraints is None else constraints.P, faces_by_kind)
    return comps, check_components(comps, has_source=source_W != 0.0)


def check_components(comps: list[Component], has_source: bool) -> list[Component]:
    """Refuse floating components; warn about idle ones (module notes).  Returns the idle components."""
    floating = [c for c in comps if not ({"dirichlet", "robin", "radiation"} & set(c.conditions))]
    if floating:
        c = floating[0]
        touched = ", ".join(f"{k} on {show(t)}" for k, ts in c.conditions.items() for t in ts) or "no condition"
        raise SingularProblemError(
            f"the model falls apart into {len(comps)} connected pieces and {len(floating)} of them float: no "
            f"Dirichlet or Robin condition touches them, so their temperature is not defined (e.g. the piece of "
            f"{c.dofs} DOFs on {len(c.patches)} patch(es) from patch {c.patches[0]}, with {touched}); add a "
            "condition there, or check that the tiles meet their neighbours face to face (a missing interface "
            "splits the model)")
    if has_source:
        return []
    idle = [c for c in comps if c.idle]
    if idle:
        tags = sorted({t for c in idle for ts in c.conditions.values() for t in ts})
        warnings.warn(
            f"{len(idle)} of the model's {len(comps)} connected pieces carry no heat: each touches a single "
            f"condition ({', '.join(map(show, tags))}) and nothing else drives it, so its temperature is that "
            "condition's and no heat path joins conditions of different values; "
            + ("check that the tiles connect the tagged faces (this paving leaves them apart)" if len(comps) > 1
               else "add a condition of another value, a flux or a source"),
            IdleComponentWarning, stacklevel=4)  # the caller of HeatProblem.solve
    return idle
