"""Supports and loads that are not on whole faces: control points held on patch edges, at patch corners or picked
by a geometric selection, discrete springs on them, and point loads.

A B-spline patch with open knot vectors interpolates its corner control points, and its restriction to a patch
edge is the curve of the edge's control points; so holding every control point of an edge holds the displacement
along the whole edge, and holding a corner control point holds the corner: a line support and a point support,
exactly. A geometric selection (``where=`` a callable or a box of the nodes, or a point) picks control points by
their *nodes*, the images of their Greville abscissae (:func:`iga.elasticity.rigid.greville_points`); away from
patch edges, holding a control point holds a control value, not the displacement at its node (the two differ by
O(h^2) for a smooth field, and agree for a linear one).

The weak-form consequences: a point load on a 3-D body has infinite energy and the stress at its point is
infinite, so the displacement and stress *away* from the point converge under refinement while the values at it
grow without bound; :meth:`iga.ElasticSolution.stress` refuses the stress at a point load's point. A point
support is the same in reverse (its reaction is finite, the stress around it is not).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from geometry.errors import show
from geometry.faces import FACE_NAMES
from geometry.numbers import TINY, is_real

from iga.discretisation.dirichlet import DirichletData
from iga.elasticity.data import VectorField
from iga.errors import ProblemError
from iga.model import tag_faces
from iga.tags import as_expression

__all__ = ["Hold", "Spring", "PointLoad", "select_nodes", "hold_dirichlet", "spring_matrix", "POINT_MARGIN",
           "NODE_MARGIN"]

_AXES = "xyz"
#: a node lies in a box (or at a point) when it is within this fraction of the model's size of it: the decision
#: does not rest on the last bits of the nodes' coordinates
NODE_MARGIN = 1e-9
#: points this close (relative to the model's size) to a point load are where its stress is infinite
POINT_MARGIN = 1e-9


@dataclass(frozen=True)
class Hold:
    """Control points held: ``dofs`` (scalar DOFs (k,)), their ``nodes`` (k, 3), the ``value`` (m) imposed on
    ``components`` (indices 0..2), named ``name`` (for :meth:`iga.ElasticSolution.reaction`)."""
    name: str
    dofs: np.ndarray
    nodes: np.ndarray
    value: VectorField
    components: tuple


@dataclass(frozen=True)
class Spring:
    """Discrete springs on control points: ``stiffness`` (3,) in N/m per node along x, y, z (0 where free)."""
    name: str
    dofs: np.ndarray
    stiffness: np.ndarray


@dataclass(frozen=True)
class PointLoad:
    """A force ``force`` (3,) in N at the physical point ``point`` (3,)."""
    name: str
    point: np.ndarray
    force: np.ndarray


def components_of(components, what: str) -> tuple:
    """The component indices of a string of distinct letters of 'xyz'."""
    if not (isinstance(components, str) and components and set(components) <= set(_AXES)
            and len(set(components)) == len(components)):
        raise ProblemError(f"{what}: components must be a string of distinct letters from 'xyz' (e.g. 'z' or 'xy'), "
                           f"got {show(components)}")
    return tuple(_AXES.index(c) for c in components)


def _size(nodes: np.ndarray) -> float:
    return max(float(np.ptp(nodes, axis=0).max()), TINY)


def select_nodes(problem, where, nodes: np.ndarray, what: str) -> np.ndarray:
    """The scalar DOFs (sorted) that ``where`` picks; ``nodes`` (ndof, 3) the DOFs' nodes.

    ``where``: a tuple of two face tags (the control points on the patch edges where a face of each meets, patch
    by patch: ``("umin", "wmin")``), of three (the corners where three meet), a point (three numbers: the nodes at
    it), a box ``((x0, y0, z0), (x1, y1, z1))`` (the nodes inside, bounds included) or a callable
    ``where(x (N, 3)) -> (N,) bool`` of the nodes.  Selecting nothing is refused, naming ``what``.
    """
    size = _size(nodes)
    if isinstance(where, tuple) and len(where) in (2, 3) and all(isinstance(t, str) for t in where):
        dofs = _edge_or_corner(problem, where, what)
        kind = "edge" if len(where) == 2 else "corner"
        if not len(dofs):
            raise ProblemError(f"{what}: no patch has a face of each of the tags {list(where)}, so they meet in no "
                               f"patch {kind}; name faces of one patch that meet (e.g. ('umin', 'wmin')), or select "
                               "by a box or a callable of the nodes")
        return dofs
    if callable(where):
        try:
            picked = np.asarray(where(nodes.copy()))
        except Exception as exc:  # the user's callable: say where it failed
            raise ProblemError(f"{what}: the where= callable failed on the nodes (N, 3): {exc}") from exc
        if picked.shape != (len(nodes),) or picked.dtype != bool:
            raise ProblemError(f"{what}: the where= callable must return a boolean array (N,) for the nodes (N, 3), "
                               f"got {picked.dtype} of shape {picked.shape}")
        found, description = picked, "the where= callable"
    else:
        box = _box(where, what)
        pad = NODE_MARGIN * size
        found = np.all((nodes >= box[0] - pad) & (nodes <= box[1] + pad), axis=1)
        description = (f"the point {box[0].tolist()}" if np.array_equal(box[0], box[1])
                       else f"the box {box[0].tolist()} .. {box[1].tolist()}")
        if not found.any():
            centre = box.mean(0)
            d = np.linalg.norm(nodes - centre, axis=1)
            near = int(np.argmin(d))
            raise ProblemError(f"{what}: {description} holds no node (the control points' Greville images); the "
                               f"nearest node is {np.round(nodes[near], 9).tolist()}, {d[near]:.3g} from its "
                               "centre; widen the box, or name a patch edge or corner by its face tags")
    dofs = np.flatnonzero(found)
    if not len(dofs):
        raise ProblemError(f"{what}: {description} selects no node")
    return dofs


def _box(where, what: str) -> np.ndarray:
    """(2, 3) lower and upper corner of a box, or a point as a box of no extent."""
    try:
        arr = np.asarray(where, float)
    except (TypeError, ValueError):
        arr = None
    if arr is not None and arr.shape == (3,):
        arr = np.stack([arr, arr])
    if arr is None or arr.shape != (2, 3) or not np.all(np.isfinite(arr)) or isinstance(where, (str, bytes)):
        raise ProblemError(f"{what}: where must be two or three face tags (a patch edge or corner), a point "
                           f"(x, y, z), a box ((x0, y0, z0), (x1, y1, z1)) or a callable of the nodes (N, 3), got "
                           f"{show(where)}")
    if np.any(arr[0] > arr[1]):
        raise ProblemError(f"{what}: the box's first corner must be its lower one, got {arr.tolist()}")
    return arr


def _edge_or_corner(problem, tags: tuple, what: str) -> np.ndarray:
    """Per patch, the DOFs common to a named face of every tag (a patch edge for two tags, a corner for three)."""
    per_tag = []
    for tag in tags:
        faces = tag_faces(problem.model, as_expression(tag))
        if not faces:
            raise ProblemError(f"{what}: tag {show(tag)} has no faces in this model")
        by_patch: dict = {}
        for pi, face in faces:
            if face in FACE_NAMES:  # slot faces lie inside a patch: no edge of its own
                by_patch.setdefault(pi, []).append(face)
        per_tag.append(by_patch)
    out = []
    for pi in set.intersection(*(set(d) for d in per_tag)):
        space, o = problem.spaces[pi], problem.offsets[pi]
        sets = [np.unique(np.concatenate([space.face_dofs(f) for f in d[pi]])) for d in per_tag]
        common = sets[0]
        for s in sets[1:]:
            common = np.intersect1d(common, s)
        out.append(common + o)
    return np.unique(np.concatenate(out)).astype(np.int64) if out else np.zeros(0, np.int64)


def stiffness_per_node(k, what: str) -> np.ndarray:
    """A spring's stiffness (N/m per node): a number for every component or three numbers, each >= 0."""
    arr = np.full(3, float(k)) if is_real(k) else None
    if arr is None:
        try:
            arr = np.asarray(k, float)
        except (TypeError, ValueError):
            arr = None
    if arr is None or arr.shape != (3,) or not np.all(np.isfinite(arr)) or isinstance(k, (str, bytes)):
        raise ProblemError(f"{what}: stiffness must be a number or three numbers (N/m per node), got {show(k)}")
    if np.any(arr < 0) or not np.any(arr > 0):
        raise ProblemError(f"{what}: stiffness must be >= 0 in every component and > 0 in one (N/m per node), got "
                           f"{arr.tolist()}; a negative spring pushes the body away and makes the problem indefinite")
    return arr


def hold_dirichlet(dd: DirichletData, holds: list, ndof: int, scalar) -> tuple[DirichletData, dict]:
    """``dd`` (the face conditions, component-major reduced unknowns) with every hold's control points prescribed,
    and {hold name: per component the reduced unknowns it prescribes}.  A control point of an identity class
    prescribes the class's unknown; one whose value is a combination of others (a child face on a branch face)
    is held only where every unknown of its combination is held to zero by the same hold, and refused otherwise.
    A component held twice (by a face condition or another hold) is refused."""
    nred = ndof if scalar is None else scalar.P.shape[1]
    owner = np.full(3 * nred, -1, np.int64)  # who prescribes each unknown: -1 nobody, 0 a face, i + 1 hold i
    owner[dd.dofs] = 0
    dofs, values, owned = [dd.dofs], [dd.values], {}
    for number, h in enumerate(holds, start=1):
        vals = h.value.values(h.nodes, f"the nodes of {show(h.name)}")
        mine = [np.zeros(0, np.int64)] * 3
        for a in h.components:
            red = h.dofs if scalar is None else scalar.dof_master[h.dofs]
            if scalar is not None and np.any(red < 0):
                _combination_held(scalar, h, red, vals[:, a], a)
            keep = red >= 0
            unknowns, first = np.unique(red[keep] + a * nred, return_index=True)
            clash = owner[unknowns] >= 0
            if clash.any():
                by = int(owner[unknowns[np.argmax(clash)]])
                other = "a face condition" if by == 0 else show(holds[by - 1].name)
                raise ProblemError(f"displacement component {_AXES[a]} of a node of {show(h.name)} is already "
                                   f"prescribed by {other}; give each component of a node one condition")
            owner[unknowns] = number
            dofs.append(unknowns)
            values.append(vals[keep][first, a])
            mine[a] = unknowns
        owned[h.name] = mine
    return DirichletData(np.concatenate(dofs).astype(np.int64), np.concatenate(values), dd.G, dd.keys,
                         dd.slave_rows, dd.slave_values, dd.slave_faces, dd.master_faces), owned


def _combination_held(scalar, h: Hold, red: np.ndarray, vals: np.ndarray, a: int) -> None:
    """A held control point whose value combines other unknowns (refinement constraints) is held by holding those
    unknowns at zero; refused unless its value is zero and every unknown of its combination is held too."""
    held = set(int(r) for r in red[red >= 0])
    P = sp.csr_matrix(scalar.P)
    for i in np.flatnonzero(red < 0):
        row = P.indices[P.indptr[h.dofs[i]]:P.indptr[h.dofs[i] + 1]]
        if vals[i] != 0 or not set(int(j) for j in row) <= held:
            raise ProblemError(f"{show(h.name)} holds a control point on a branch face, whose value is a combination "
                               f"of the parent face's (component {_AXES[a]}); hold it only at zero together with "
                               "the parent face's control points, or select nodes away from branch faces")


def spring_matrix(springs: list, ndof: int) -> sp.csr_matrix:
    """The springs' stiffness (3 ndof x 3 ndof, component-major, diagonal; N/m)."""
    rows, vals = [], []
    for s in springs:
        for a in range(3):
            if s.stiffness[a] > 0:
                rows.append(s.dofs + a * ndof)
                vals.append(np.full(len(s.dofs), s.stiffness[a]))
    if not rows:
        return sp.csr_matrix((3 * ndof, 3 * ndof))
    r = np.concatenate(rows)
    return sp.csr_matrix((np.concatenate(vals), (r, r)), shape=(3 * ndof, 3 * ndof))
