"""Isogeometric analysis on micro-structures: spaces, assembly, heat problem, VTU export.

Public names: :class:`HeatProblem`, :class:`Solution`, :func:`write_vtu`,
:class:`ProblemError`.  Command line: ``iga --help``.
"""

from .errors import ProblemError, SingularProblemError
from .problem import HeatProblem
from .solution import Solution
from .vtu import write_vtu

__all__ = ["ProblemError", "SingularProblemError", "HeatProblem", "Solution", "write_vtu"]
