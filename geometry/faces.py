"""Face vocabulary of tensor-product splines, shared by tiling and analysis.

* The six boundary faces of a trivariate (``umin`` .. ``wmax``) and their
  (parametric direction, side) pairs.
* Slot faces: one side of a full-multiplicity ("discontinuity") knot plane,
  written ``u=0.5-`` (the plane u = 0.5 seen from u < 0.5) or ``u=0.5+``; the
  free (non-coinciding) rectangles of such planes are boundary too (Massarwi
  et al. 2018, Section 3.1, partial discontinuities).
* Nested face spaces: the refinement (knot-insertion) matrix from a parent
  face space restricted to a sub-rectangle to a child face space that
  contains it (Massarwi et al. 2018, Eqs. 11-12).
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from . import knots as kn
from .errors import SplineError
from .tolerances import COINCIDENT, SAME_KNOT, SNAP

__all__ = ["FACE_NAMES", "FACE_AXIS", "face_name", "slot_face_id", "parse_slot_face", "is_face", "face_knots",
           "discontinuity_slots", "nested_refinement"]

FACE_NAMES = ("umin", "umax", "vmin", "vmax", "wmin", "wmax")
#: face name -> (parametric direction, side): side 0 is the min face, 1 the max face
FACE_AXIS = {name: divmod(i, 2) for i, name in enumerate(FACE_NAMES)}


def face_name(direction: int, side: int) -> str:
    """The face on side ``side`` (0 min, 1 max) of parametric direction ``direction``."""
    return FACE_NAMES[2 * int(direction) + int(side)]


def slot_face_id(direction: int, value: float, side: int) -> str:
    """Name of one side of a discontinuity plane, e.g. ``u=0.5-`` (seen from u < 0.5)."""
    return f"{'uvw'[direction]}={value:.17g}{'-' if side < 0 else '+'}"


def parse_slot_face(face: str):
    """(direction, value, side) of a slot face id, or None for the six patch faces and anything else."""
    if not isinstance(face, str) or face in FACE_NAMES or len(face) < 4 or face[1] != "=" or face[-1] not in "+-":
        return None
    if face[0] not in "uvw":
        return None
    try:
        value = float(face[2:-1])
    except ValueError:
        return None
    return "uvw".index(face[0]), value, (-1 if face[-1] == "-" else 1)


def is_face(face) -> bool:
    """Whether ``face`` names a patch face or a slot face."""
    return face in FACE_NAMES or parse_slot_face(face) is not None


def face_knots(spline, face: str):
    """[(knots, degree)] * 2 of the two directions spanning ``face`` of a trivariate, in order."""
    k, _ = FACE_AXIS[face]
    return [(spline.knots[d], spline.degrees[d]) for d in range(3) if d != k]


def oriented_face_knots(knots, swap: bool, flip) -> list:
    """Face-b knot vectors [(U, p)] * 2 along face a's axes under an interface's orientation (b's parameters are
    a's swapped if ``swap``, then reversed per ``flip`` on b's own axes): b's axes reversed per ``flip``, then
    swapped."""
    out = [(U[0] + U[-1] - U[::-1], p) if f else (U, p) for (U, p), f in zip(knots, flip)]
    return out[::-1] if swap else out


def discontinuity_slots(spline) -> dict:
    """Free parts of the discontinuity planes of a trivariate: {slot face id: [rectangles]}.

    Each full-multiplicity interior knot plane is compared side by side on the
    element pieces of the other two directions (3 x 3 points per piece, each
    side evaluated on its one-sided sub-patch); pieces where the two sides do
    not coincide are free surface (a slot), on both sides.  A rectangle is
    ((a1, b1), (a2, b2)) in the two remaining parameters, in order.
    """
    out = {}
    size = float(np.ptp(spline.points.reshape(-1, 3), axis=0).max())
    for d in range(3):
        vals, mults = np.unique(spline.knots[d], return_counts=True)
        for v in vals[1:-1][mults[1:-1] >= spline.degrees[d] + 1]:
            rest = [k for k in range(3) if k != d]
            b1, b2 = spline.breakpoints(rest[0]), spline.breakpoints(rest[1])
            t = np.array([0.1, 0.5, 0.9])
            sides = []
            for side in (-1, 1):
                box = spline.domain.copy()
                box[d] = [box[d, 0], v] if side < 0 else [v, box[d, 1]]
                sub = spline.extract(box)  # one side of the plane: exact one-sided evaluation
                x = np.empty((len(b1) - 1, len(b2) - 1, 3, 3, 3))
                x[..., d] = v
                x[..., rest[0]] = (b1[:-1, None] + np.diff(b1)[:, None] * t)[:, None, :, None]
                x[..., rest[1]] = (b2[:-1, None] + np.diff(b2)[:, None] * t)[None, :, None, :]
                sides.append(sub.evaluate(x.reshape(-1, 3))[:, :3].reshape(x.shape[:4] + (3,)))
            free = np.linalg.norm(sides[0] - sides[1], axis=-1).max(axis=(2, 3)) > COINCIDENT * size
            if free.any():
                rects = [((float(b1[i]), float(b1[i + 1])), (float(b2[j]), float(b2[j + 1])))
                         for i, j in zip(*np.nonzero(free))]
                for side in (-1, 1):
                    out[slot_face_id(d, v, side)] = rects
    return out


def _normalised(U):
    U = np.asarray(U, float)
    return (U - U[0]) / (U[-1] - U[0])


def _snap(x: float, U) -> float:
    """``x``, or the knot of U within 1e-10 of U's length (a box end computed in floating point)."""
    kv = np.unique(np.asarray(U, float))
    i = int(np.argmin(np.abs(kv - x)))
    return float(kv[i]) if abs(kv[i] - x) <= SNAP * (kv[-1] - kv[0]) else x


def nested_refinement(parent_knots, box, child_knots) -> sp.csr_matrix:
    """R with child face coefficients = R @ parent face coefficients (Kronecker product of two directions).

    ``parent_knots``, ``child_knots``: [(U, p)] * 2 of the two faces; ``box``:
    the sub-rectangle ((a1, b1), (a2, b2)) of the parent face (in its
    parameters) that carries the child's face, whose parameters are mapped
    affinely onto it.  A child of higher degree (p-refinement) takes the
    parent's restricted space degree-elevated first (every knot's multiplicity
    raised with the degree: the continuity kept).  Raises :class:`SplineError`
    unless the child's face space contains the parent's restricted space (a
    degree at least the parent's, every parent knot present with at least its
    multiplicity, raised by the elevation).
    """
    Rs = []
    for d in range(2):
        (Up, pp), (Uc, pc) = parent_knots[d], child_knots[d]
        a, b = (_snap(float(x), Up) for x in box[d])
        if pc < pp:
            raise SplineError(f"the child face's degree {pc} is below its parent's {pp} (face direction {d}); the "
                              "spaces are not nested")
        sub, S = kn.restriction(np.asarray(Up, float), pp, a, b)
        if pc > pp:
            sub, E = kn.elevation_matrix(sub, pp, pc - pp)
            S = E @ S
        mapped = a + _normalised(Uc) * (b - a)
        vals_s, m_s = kn.breakpoints(sub)
        vals_c, m_c = kn.breakpoints(mapped)
        need = []
        for v, m in zip(vals_c, m_c):
            have = m_s[np.abs(vals_s - v) < SAME_KNOT]
            have = int(have[0]) if len(have) else 0
            need += [v] * max(0, m - have)
        for v, m in zip(vals_s, m_s):
            if not np.any((np.abs(vals_c - v) < SAME_KNOT) & (m_c >= m)):
                raise SplineError(
                    f"the child face space does not contain the parent face space: parent knot {v:g} "
                    f"(multiplicity {m}) is missing on the child (face direction {d}); the spaces are not nested"
                )
        inner = [v for v in need if a < v < b]
        _, Rins = kn.insertion_matrix(sub, pc, inner)
        Rs.append(sp.csr_matrix(Rins @ S))
    return sp.csr_matrix(sp.kron(Rs[0], Rs[1]))
