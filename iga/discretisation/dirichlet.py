"""Strong Dirichlet data: L2 projection onto the trace space of the Dirichlet faces.

The prescribed temperatures g on the Dirichlet faces are projected in the
(unconstrained) space of all patches: M g_h = b with the boundary mass
``M_ij = int N_i N_j dA`` and ``b_i = int g N_i dA`` over those faces
(:func:`iga.heat.forms.boundary_mass`, :func:`iga.heat.forms.boundary_load`).  With
interface constraints, every reduced unknown that owns a Dirichlet DOF is
prescribed (the mean of its members' values); Dirichlet DOFs of slave classes
fix combinations of unknowns instead and are returned separately
(:func:`solvers.elimination.induced_elimination` handles them).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from geometry.numbers import TINY
from iga.heat.forms import boundary_load, boundary_load_columns, boundary_mass
from geometry.grouping import ObjectIndex

from iga.errors import ProblemError

from geometry.tolerances import ROUNDOFF

__all__ = ["DirichletData", "project_dirichlet"]


@dataclass
class DirichletData:
    """Prescribed unknowns and the data the flux computation needs.

    ``dofs``, ``values``: prescribed (reduced) unknowns and their values;
    ``G`` sparse (unknowns x faces) whose column f holds int_f N_i dA, with
    ``keys`` its faces; ``slave_rows`` / ``slave_values``: Dirichlet DOFs
    constrained by others, with their values; ``slave_faces``: per slave row the conditions (their
    descriptions) of the faces it lies inside of (not on their edges; empty where it is on edges only).
    """

    dofs: np.ndarray
    values: np.ndarray
    G: sp.csr_matrix | None
    keys: list
    slave_rows: np.ndarray
    slave_values: np.ndarray
    slave_faces: list = field(default_factory=list)
    master_faces: dict = field(default_factory=dict)  # prescribed unknown -> conditions of faces it lies inside

    def homogeneous(self) -> "DirichletData":
        """The same prescribed unknowns held at zero: what an adjoint solve eliminates."""
        return DirichletData(self.dofs, np.zeros(len(self.dofs)), self.G, self.keys, self.slave_rows,
                             np.zeros(len(self.slave_rows)), self.slave_faces, self.master_faces)


def _solve_mass(M: sp.csc_matrix, b: np.ndarray) -> np.ndarray:
    """Solve the SPD boundary mass system of the projection.

    Jacobi-preconditioned CG to 1e-14 (boundary mass matrices are well
    conditioned once their diagonal is scaled, and CG beats a sparse LU on
    large boundaries, docs/performance.md), with a sparse LU fallback if CG stalls.
    """
    if M.shape[0] <= 200:
        return np.atleast_1d(np.linalg.solve(M.toarray(), b))
    d = M.diagonal()
    x, info = spla.cg(M, b, rtol=ROUNDOFF, atol=0.0, maxiter=2000, M=sp.diags(1.0 / d))
    if info != 0 or not np.all(np.isfinite(x)):
        x = spla.splu(M.tocsc(), permc_spec="MMD_AT_PLUS_A").solve(b)
    return x


def project_dirichlet(faces, dirichlet: dict, ndof: int, constraints=None) -> DirichletData:
    """Project the Dirichlet data onto the trace space.

    ``faces``: an :class:`iga.discretisation.faces.FaceQuadrature`; ``dirichlet``: {(patch,
    face): (value field, where)} with a :class:`iga.heat.coefficients.ScalarField`
    per face; ``constraints``: the :class:`iga.discretisation.constraints.Constraints` or None.
    """
    same = ObjectIndex()  # patches share splines and maps: group by object
    empty = np.zeros(0, np.int64)
    if not dirichlet:
        return DirichletData(empty, np.zeros(0), None, [], empty, np.zeros(0))
    keys = list(dirichlet)
    fds = faces(keys)
    by_cond: dict = {}
    for j, key in enumerate(keys):
        by_cond.setdefault(same(dirichlet[key][0]), []).append(j)
    gs = [None] * len(keys)
    for idx in by_cond.values():
        field_, where = dirichlet[keys[idx[0]]]
        x = np.concatenate([fds[j].x for j in idx])
        vals = field_.values(x, {}, where)
        for j, g in zip(idx, np.split(vals, np.cumsum([len(fds[j].x) for j in idx])[:-1])):
            gs[j] = g
    M = boundary_mass(fds, [fd.dAw for fd in fds], ndof)
    rhs = boundary_load(fds, [g * fd.dAw for g, fd in zip(gs, fds)], ndof)
    G = boundary_load_columns(fds, [fd.dAw for fd in fds], ndof)  # column per face: int N_i dA
    # DOFs whose functions have no trace on the faces (e.g. masked parts of slot faces) are not prescribed
    cand = np.unique(np.concatenate([fd.dofs for fd in fds]))
    diag = M.diagonal()[cand]
    dofs = cand[diag > ROUNDOFF * max(diag.max(), TINY)]
    vals = _solve_mass(M[dofs][:, dofs].tocsc(), rhs[dofs])
    slave_rows, slave_vals, slave_faces, master_faces = empty, np.zeros(0), [], {}
    if constraints is not None:
        inside = _inside_of(fds, [dirichlet[k][1] for k in keys])
        owners = constraints.dof_master[dofs]
        keep = owners >= 0
        slave_rows, slave_vals = dofs[~keep], vals[~keep]
        slave_faces = [inside.get(int(i), frozenset()) for i in slave_rows]
        red, inv = np.unique(owners[keep], return_inverse=True)
        _refuse_overlaps(dofs[keep], vals[keep], inv, inside)
        for i, o in zip(dofs[keep], owners[keep]):
            if int(i) in inside:
                master_faces[int(o)] = master_faces.get(int(o), frozenset()) | inside[int(i)]
        vals = np.bincount(inv, weights=vals[keep]) / np.bincount(inv)
        dofs = red
        G = (constraints.P.T @ G).tocsc()
    return DirichletData(dofs, vals, G.tocsr(), keys, slave_rows, slave_vals, slave_faces, master_faces)


def _inside_of(fds, names) -> dict:
    """{DOF: frozenset of condition descriptions} for the DOFs inside a Dirichlet face (off its edges)."""
    out: dict = {}
    for fd, name in zip(fds, names):
        grid = fd.dofs.reshape(fd.space.shape)
        for i in grid[1:-1, 1:-1].ravel():
            out.setdefault(int(i), set()).add(name)
    return {k: frozenset(v) for k, v in out.items()}


def _refuse_overlaps(dofs, vals, group, inside) -> None:
    """Refuse two conditions that give one unknown different values where a face of one lies on a face of
    the other (DOFs inside faces of two conditions tied to one unknown).  Where faces only share an edge the
    unknown takes the mean of their values: the usual reading of data that jump along an edge."""
    if not len(dofs):
        return
    scale = max(float(np.abs(vals).max()), TINY)
    lo = np.full(group.max() + 1, np.inf)
    hi = np.full(group.max() + 1, -np.inf)
    np.minimum.at(lo, group, vals)
    np.maximum.at(hi, group, vals)
    for g in np.flatnonzero(hi - lo > 1e-8 * scale):
        names = sorted(set().union(*[inside.get(int(i), frozenset()) for i in dofs[group == g]]))
        if len(names) >= 2:
            raise ProblemError(
                f"two Dirichlet conditions give one unknown different values ({lo[g]:.6g} and {hi[g]:.6g}) where "
                f"their faces lie on each other: {names[0]} and {names[1]}; give the overlap one condition "
                "(the tag algebra helps: 'A - B')")
