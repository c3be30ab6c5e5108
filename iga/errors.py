"""Exception types of the analysis package (all derive from :class:`geometry.ToolkitError`)."""

from geometry.errors import ToolkitError
from solvers.errors import SolverError


class ProblemError(ToolkitError):
    """Invalid analysis set-up: unknown tag, bad material data, bad output path..."""


class SingularProblemError(ProblemError, SolverError):
    """The heat problem has no Dirichlet or Robin condition: its temperature is not unique."""
