"""What the problem of every physics shares: its :class:`Discretisation`, the one check of a condition's tag,
and the record of a solve that its solution keeps.

A problem describes; a solve finds.  Everything a solve finds (the rank of every patch under MPI, the coupled
pieces, the constraint counts, the unknowns left, the solve's timings) is a :class:`SolveRecord` handed to the
:class:`iga.Solution` or :class:`iga.ElasticSolution` it returns; the problem is never written by a solve, so
solving it twice, or with another solver, starts from the same object.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from geometry.errors import show
from iga.discretisation.setting import Discretisation
from iga.errors import ProblemError
from iga.model import tag_faces
from iga.tags import check_expression, mentions_rest

__all__ = ["Problem", "SolveRecord"]


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
