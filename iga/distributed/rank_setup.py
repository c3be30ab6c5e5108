"""What a rank of a distributed heat solve builds before its matrix (:mod:`iga.distributed.solve`): the constraints
its patches read (:mod:`iga.distributed.rank_constraints`), the Dirichlet data of its closure's faces, and the model's
components found across the ranks (:mod:`iga.distributed.rank_components`); or, where Dirichlet slot faces meet a
branch face inside an element on some rank (their induced conditions tie unknowns of the whole model
together, :func:`solvers.elimination.induced_elimination`), the whole model's, as a serial solve builds them."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from iga.discretisation.components import analyse_components
from iga.discretisation.constraints import prolongation
from iga.discretisation.dirichlet import project_dirichlet
from iga.errors import ProblemError
from iga.distributed.rank_components import rank_components
from iga.distributed.rank_constraints import rank_constraints

__all__ = ["rank_setup", "together"]


def together(comm, fn):
    """``fn()`` on every rank; where it raises :class:`ProblemError` on some ranks (bad data that only their
    patches hold, e.g. two Dirichlet conditions at odds on one face), every rank raises it, naming the rank,
    instead of the others waiting for it in the next collective call."""
    try:
        out, error = fn(), None
    except ProblemError as exc:
        out, error = None, str(exc)
    errors = [(r, e) for r, e in enumerate(comm.allgather(error)) if e is not None]
    if errors:
        r, e = errors[0]
        raise ProblemError(e if r == comm.Get_rank() else f"on MPI rank {r}: {e}")
    return out


def rank_setup(problem, world, part, book, record):
    """(constraints, Dirichlet data, :class:`iga.distributed.rank_constraints.RankConstraints`) of this rank's patches in
    its closure numbering, or (the whole model's constraints, Dirichlet data, None), of a
    :class:`iga.HeatProblem` about to be solved on ``world`` = (comm, rank, size), ``part`` the rank of every
    patch, ``book`` its assembly's bookkeeping; sets the components and constraint counts of ``record``
    (:class:`iga.discretisation.problem.SolveRecord`)."""
    from mpi4py import MPI

    comm, rank, _ = world

    def local():
        rc = rank_constraints(problem.model, problem.spaces, problem.offsets, part, rank)
        closure = set(rc.patches.tolist())

        def faces(keys):  # the faces' data with their DOFs in the closure numbering
            return [replace(fd, dofs=rc.local(fd.dofs)) for fd in problem.faces(keys)]

        return rc, project_dirichlet(faces, {k: v for k, v in book["dirichlet"].items() if k[0] in closure},
                                     len(rc.rows), rc.constraints)

    rc, dd = together(comm, local)
    by_kind = problem.faces_by_kind()
    if comm.allreduce(len(dd.slave_rows)):
        constraints = prolongation(problem.model, problem.spaces, problem.offsets)
        record.constraint_stats = dict(constraints.stats)
        record.components, record.idle_components = analyse_components(problem, constraints, by_kind,
                                                                        book["source"])
        return constraints, project_dirichlet(problem.faces, book["dirichlet"], problem.ndof, constraints), None
    record.components, record.idle_components = rank_components(problem, rc, by_kind, book["source"], comm)
    stats = rc.constraints.stats
    keys = rc.keys()[dd.dofs]
    mine = int(np.count_nonzero(part[np.searchsorted(problem.offsets, keys, side="right") - 1] == rank))
    record.constraint_stats = {  # the prescribed unknowns counted once, by the owner of their key
        "closure_patches_max": comm.allreduce(stats["closure_patches"], op=MPI.MAX),
        "closure_layers_max": comm.allreduce(stats["closure_layers"], op=MPI.MAX),
        "prescribed": comm.allreduce(mine)}
    return rc.constraints, dd, rc
