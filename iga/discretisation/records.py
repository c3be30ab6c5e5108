"""Typed records of what a solve found: :class:`SolutionInfo` (heat), :class:`ElasticInfo`, :class:`HeatBalance`
and :class:`WorkBalance`.

Each is a frozen dataclass read by attribute (``solution.info.balance.inflow_W``, ``info.solver.iterations``)
and, for scripts written against the earlier dictionaries, by key as well: ``info["balance"]["inflow_W"]``
gives the same number (a nested record or :class:`solvers.SolveInfo` is then handed out as a plain dict).
:meth:`Record.as_dict` is the plain, JSON-ready form the pipelines' summaries write.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field, fields

from solvers.info import SolveInfo

__all__ = ["Record", "HeatBalance", "WorkBalance", "SolutionInfo", "ElasticInfo"]


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
class SolutionInfo(Record):
    """What a heat solve found: DOFs and the unknowns solved for, constraint counts, patches, the linear
    solver's report (:class:`solvers.SolveInfo`), seconds per stage, the :class:`HeatBalance`, the coupled
    pieces (count, idle, the first ten), and Newton's reduced residuals (nonlinear problems; else empty)."""

    dofs: int
    free_dofs: int
    constraints: dict
    patches: int
    solver: SolveInfo
    timings: dict
    balance: HeatBalance
    components: dict
    newton: list = field(default_factory=list)


@dataclass(frozen=True, eq=False)
class ElasticInfo(Record):
    """What an elastic solve found: DOFs (three per basis function) and unknowns, constraint counts, patches,
    the solver's report, seconds per stage, the :class:`WorkBalance`, the applied loads per tag (N) and the
    body force's resultant (N)."""

    dofs: int
    free_dofs: int
    constraints: dict
    patches: int
    solver: SolveInfo
    timings: dict
    work: WorkBalance
    applied_N: dict
    body_force_N: list
