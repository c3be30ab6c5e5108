"""Isogeometric analysis on micro-structures: spaces, assembly, heat problem, VTU export.

Public names: :class:`HeatProblem`, :class:`Solution`, :func:`write_vtu`,
:class:`ProblemError`.  Command line: ``iga --help``.
"""

from geometry.errors import ToolkitError


class ProblemError(ToolkitError):
    """Invalid analysis set-up: unknown tag, bad material data, bad output path..."""


from .problem import HeatProblem, SingularProblemError  # noqa: E402
from .solution import Solution  # noqa: E402
from .vtu import write_vtu  # noqa: E402

__all__ = ["ProblemError", "SingularProblemError", "HeatProblem", "Solution", "write_vtu"]
