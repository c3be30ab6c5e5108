"""Boundary conditions of the heat problem and their face forms: the Neumann load, the Robin load and mass, and
the Dirichlet data kept for the projection (Massarwi et al. 2018, Eq. 9)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from geometry.errors import show

from iga.errors import ProblemError, SingularProblemError
from iga.heat.coefficients import ScalarField
from iga.heat.forms import boundary_load, boundary_mass

__all__ = ["Condition", "face_terms", "face_values", "flat_values", "per_face"]


@dataclass
class Condition:
    """One boundary condition: its kind, the tag (expression) of its faces, its value and film coefficient."""

    kind: str  # "dirichlet", "neumann", "robin" or "radiation"
    tag: str
    value: ScalarField  # temperature, inward flux or ambient temperature
    h: ScalarField | None = None  # film coefficient (Robin) or emissivity (radiation)
    #: radiation: added to the problem's temperatures to make them absolute (273.15 for degrees Celsius)
    offset: float = 0.0
    #: a value that changes in time, a callable of (x, t) (:class:`iga.heat.transient.TransientHeatProblem`);
    #: ``value`` then stands for it at no particular time
    timed: object = None


def face_terms(problem, by_kind, patches=None):
    """The face forms of the conditions ``by_kind`` ({kind: {(patch, face): condition}}, as
    :meth:`iga.HeatProblem.faces_by_kind` gives them) of ``problem``: (load (ndof,): + int_F q v over
    Neumann faces and + int_F h T_inf v over Robin faces; the Robin mass int_F h T v (CSR) or None;
    bookkeeping {"neumann": {face: q}, "robin": {face: (h, T_inf)}, "radiation": {face: (emissivity,
    T_amb, offset)}, "dirichlet": {face: (value, description)}} at the faces' Gauss points).
    ``patches``: only the Neumann and Robin faces of these patches (an MPI rank's)."""
    problem.faces([key for faces in by_kind.values() for key in faces])  # all at once: grouped by space
    neumann, robin = {}, {}
    for key, c in by_kind["neumann"].items():
        neumann.setdefault(c.tag, []).append(key)
    for key, c in by_kind["robin"].items():
        robin.setdefault(c.tag, []).append(key)
    book = {"neumann": {}, "robin": {}, "dirichlet": {k: (c.value, f"the faces tagged {show(c.tag)}")
                                                       for k, c in by_kind["dirichlet"].items()}}
    f = np.zeros(problem.ndof)
    for tag, keys in neumann.items():  # + int_F q v
        c, fds = by_kind["neumann"][keys[0]], problem.faces(keys)
        qs = face_values(c.value, fds, tag)
        f += boundary_load(fds, [q * fd.dAw for q, fd in zip(qs, fds)], problem.ndof, patches)
        book["neumann"].update(zip(keys, qs))
    robin_fds, robin_h = [], []
    for tag, keys in robin.items():  # + int_F h T v on the left, + int_F h T_inf v on the right
        c, fds = by_kind["robin"][keys[0]], problem.faces(keys)
        # on all faces at once (one array each, sliced per face): 136k faces on the winged duck
        h, T = flat_values(c.h, fds, tag), flat_values(c.value, fds, tag)
        hA = h * np.concatenate([fd.dAw for fd in fds])
        robin_fds += fds
        robin_h += per_face(hA, fds)
        f += boundary_load(fds, per_face(hA * T, fds), problem.ndof, patches)
        book["robin"].update(zip(keys, zip(per_face(h, fds), per_face(T, fds))))
    mass = boundary_mass(robin_fds, robin_h, problem.ndof, patches) if robin_fds else None
    book["radiation"] = {}  # nonlinear: the emissivity and ambient at the Gauss points (iga.heat.radiation)
    radiation: dict = {}
    for key, c in by_kind.get("radiation", {}).items():
        radiation.setdefault(c.tag, []).append(key)
    for tag, keys in radiation.items():
        c, fds = by_kind["radiation"][keys[0]], problem.faces(keys)
        eps, T = flat_values(c.h, fds, tag), flat_values(c.value, fds, tag)
        if np.any(eps < 0) or np.any(eps > 1):
            raise ProblemError(f"the emissivity on {show(tag)} must lie in [0, 1], but reaches "
                               f"{eps.min() if eps.min() < 0 else eps.max():g}")
        if np.any(T + c.offset < 0):
            raise ProblemError(f"the ambient temperature of the radiation on {show(tag)} is below absolute zero "
                               f"({T.min() + c.offset:g} K); for degrees Celsius pass scale='C' to radiation()")
        book["radiation"].update(zip(keys, zip(per_face(eps, fds), per_face(T, fds), [c.offset] * len(keys))))
    return f, mass, book


def per_face(values: np.ndarray, fds) -> list[np.ndarray]:
    """Views of ``values`` (the faces' Gauss points one after the other, first axis) per face: slicing, as
    np.split pays a swapaxes per piece (0.2 s for the winged duck's 136k faces)."""
    ends = np.cumsum([len(fd.x) for fd in fds]).tolist()
    return [values[a:b] for a, b in zip([0] + ends[:-1], ends)]


def face_values(field: ScalarField, fds, tag) -> list[np.ndarray]:
    """A scalar field evaluated on several faces at once -> one (N_f,) array per face."""
    if not fds:
        return []
    return per_face(flat_values(field, fds, tag), fds)


def flat_values(field: ScalarField, fds, tag) -> np.ndarray:
    """A scalar field on several faces at once, their Gauss points one after the other (sum N_f,)."""
    ends = np.cumsum([len(fd.x) for fd in fds])
    constant = field.constant
    if constant is not None and np.ndim(constant) == 0:  # a number (checked when given): nothing to gather
        v = np.full(int(ends[-1]), float(constant))
    else:
        x = np.concatenate([fd.x for fd in fds])
        common = [c for c in fds[0].chans if all(c in fd.chans for fd in fds)]
        chans = {c: np.concatenate([fd.chans[c] for fd in fds]) for c in common}
        where = f"the faces tagged {show(tag)} (e.g. patch {fds[0].patch} face {fds[0].face})"
        v = field.values(x, chans, where)
    return v


def refuse_floating(conditions) -> None:
    """:class:`iga.errors.SingularProblemError` unless some condition fixes the temperature's level (Dirichlet,
    Robin or radiation): with fluxes alone it is defined up to a constant."""
    if not ({"dirichlet", "robin", "radiation"} & {c.kind for c in conditions}):
        raise SingularProblemError(
            "the heat problem has no Dirichlet, Robin or radiation condition, so its temperature is only defined "
            "up to a constant (the system is singular); add problem.dirichlet(tag, T) or problem.robin(tag, h, "
            "T_inf)")
