"""What the problem of every physics shares: its :class:`Discretisation`, the one check of a condition's tag,
the record of a solve that its solution keeps, and the typed records of what a solution reports
(:class:`SolutionInfo`, :class:`ElasticInfo`, :class:`HeatBalance`, :class:`WorkBalance`).

The typed records are frozen dataclasses read by attribute (``solution.info.balance.inflow_W``,
``info.solver.iterations``) and, for scripts written against the earlier dictionaries, by key as well:
``info["balance"]["inflow_W"]`` gives the same number (a nested record or :class:`solvers.SolveInfo` is then
handed out as a plain dict).  :meth:`Record.as_dict` is the plain, JSON-ready form the pipelines' summaries
write.

A problem describes; a solve finds.  Everything a solve finds (the rank of every patch under MPI, the coupled
pieces, the constraint counts, the unknowns left, the solve's timings) is a :class:`SolveRecord` handed to the
:class:`iga.Solution` or :class:`iga.ElasticSolution` it returns; the problem is never written by a solve, so
solving it twice, or with another solver, starts from the same object.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field, fields

import numpy as np

from geometry.errors import show
from iga.discretisation.fields import GaussGeometry
from iga.discretisation.setting import Discretisation
from iga.errors import ProblemError
from iga.model import tag_faces
from iga.tags import check_expression, mentions_rest
from solvers.info import SolveInfo

__all__ = ["Problem", "SolveRecord", "Record", "HeatBalance", "WorkBalance", "SolveSummary", "SolutionInfo",
           "ElasticInfo"]


@dataclass
class SolveRecord:
    """What one solve found (kept by its solution, never by the problem).

    ``partition``: the MPI rank of every patch (``None`` in a serial solve); ``components`` and
    ``idle_components``: the coupled pieces (:mod:`iga.discretisation.components`); ``constraint_stats``:
    counts of the constraints and prescribed unknowns; ``reduced_dofs``: the unknowns solved for;
    ``timings``: seconds per stage, the discretisation's and the solve's; ``newton``: Newton's residuals.
    """

    partition: np.ndarray | None = None
    components: list = field(default_factory=list)
    idle_components: list = field(default_factory=list)
    constraint_stats: dict = field(default_factory=dict)
    reduced_dofs: int = 0
    timings: dict = field(default_factory=dict)
    #: the reduced residual norms of Newton's iterations (a nonlinear problem: radiation), else empty
    newton: list = field(default_factory=list)
    #: the interface constraints and the Dirichlet data of a serial solve, which an adjoint of the same problem
    #: solves with again (:func:`iga.sensitivity.adjoint`); None under MPI
    constraints: object = None
    dirichlet: object = None
    #: a kept solver of the same system with zero Dirichlet data (``solve(keep=True)``), load -> coefficients
    again: object = None


class Problem:
    """The base of :class:`iga.HeatProblem` and :class:`iga.ElasticityProblem`: builds the
    :class:`Discretisation` (``components`` field components per basis function) and keeps its parts as
    attributes; :meth:`faces_of` is the one check that a condition's tag names faces."""

    def __init__(self, model, degree_elevation=0, refine: int = 0, quadrature_extra: int = 0, degree=None,
                 bases=None, components: int = 1):
        d = Discretisation(model, degree_elevation, refine, quadrature_extra, degree, bases,
                           **({"components": components} if components != 1 else {}))
        self.disc = d
        self.model, self.bases, self.regularity, self.space_args = d.model, d.bases, d.regularity, d.space_args
        self.estimate, self.spaces, self.offsets, self.ndof = d.estimate, d.spaces, d.offsets, d.ndof
        self.volume, self.faces, self.timings = d.volume, d.faces, d.timings
        self.weights = d.weights  # NURBS basis where a patch is its own rational geometry (iga.discretisation.rational)
        self.gauss_geometry = GaussGeometry()  # the Gauss points' geometry, kept once a design step asks

    def faces_of(self, tag, what: str) -> list:
        """The faces of a condition's ``tag`` (an expression of the model's tags); ``what`` names the
        condition in the message.  A tag that names no face is refused; one that mentions ``rest`` is checked
        for its syntax only (its faces are known once every condition is) and gives []."""
        if mentions_rest(self.model, tag):
            check_expression(self.model, tag)
            return []
        faces = tag_faces(self.model, tag)
        if not faces:
            raise ProblemError(f"{what}: tag {show(tag)} has no faces in this model (every face it named is glued to "
                               f"a neighbour or absent); choose another tag from {sorted(self.model.tags)[:20]}")
        return faces


def _plain(value):
    """A record, :class:`solvers.SolveInfo`, dict or list with records inside, as plain dicts and lists."""
    if isinstance(value, (Record, SolveInfo)):
        return value.as_dict()
    if isinstance(value, dict):
        return {k: _plain(v) for k, v in value.items()}
    if isinstance(value, list):
        return [_plain(v) for v in value]
    return value


class Record(Mapping):
    """A frozen dataclass that reads as a mapping of its fields too (values as plain dicts and lists)."""

    def __getitem__(self, key: str):
        if not isinstance(key, str) or key not in self._names():
            raise KeyError(key)
        return _plain(getattr(self, key))

    def __iter__(self):
        return iter(self._names())

    def __len__(self) -> int:
        return len(self._names())

    @classmethod
    def _names(cls) -> tuple:
        return tuple(f.name for f in fields(cls))

    def as_dict(self) -> dict:
        """The record as plain dicts, lists and numbers (JSON-ready)."""
        return {name: _plain(getattr(self, name)) for name in self._names()}


@dataclass(frozen=True, eq=False)
class HeatBalance(Record):
    """The global heat balance of a solution (W): ``inflow_W`` (through faces, and a positive source) against
    ``outflow_W`` (through faces, and a negative source) and ``stored_W`` (the heat stored per second, a
    transient state's; 0 for a steady one); ``relative_error`` of inflow = outflow + stored against the larger
    of the flows and ``reference_flow_W``, a flow the model could carry (:meth:`iga.Solution.balance`)."""

    inflow_W: float
    outflow_W: float
    source_W: float
    relative_error: float
    reference_flow_W: float
    stored_W: float = 0.0


@dataclass(frozen=True, eq=False)
class WorkBalance(Record):
    """The work balance of an elastic solution (J): the virtual work of the stresses ``internal_J`` against the
    loads' and supports' ``external_J``, their ``relative_error``, the ``strain_energy_J``, and whether a thermal
    strain was applied (:meth:`iga.ElasticSolution.work_balance`)."""

    external_J: float | None
    internal_J: float | None
    strain_energy_J: float
    relative_error: float | None
    thermal: bool


@dataclass(frozen=True, eq=False)
class SolveSummary(Record):
    """What every solve reports: DOFs and the unknowns solved for, constraint counts, patches, the linear
    solver's report (:class:`solvers.SolveInfo`) and seconds per stage."""

    dofs: int
    free_dofs: int
    constraints: dict
    patches: int
    solver: SolveInfo
    timings: dict


@dataclass(frozen=True, eq=False)
class SolutionInfo(SolveSummary):
    """What a heat solve found (:class:`SolveSummary`'s fields first): the :class:`HeatBalance`, the coupled
    pieces (count, idle, the first ten), and Newton's reduced residuals (nonlinear problems; else empty)."""

    balance: HeatBalance
    components: dict
    newton: list = field(default_factory=list)


@dataclass(frozen=True, eq=False)
class ElasticInfo(SolveSummary):
    """What an elastic solve found (:class:`SolveSummary`'s fields first, DOFs three per basis function): the
    :class:`WorkBalance`, the applied loads per tag (N) and the body force's resultant (N)."""

    work: WorkBalance
    applied_N: dict
    body_force_N: list
