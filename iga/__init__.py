"""Isogeometric analysis on micro-structures: spaces, assembly, heat problem, VTU export.

Public names: :class:`HeatProblem`, :class:`Solution`, :class:`ElasticityProblem`, :class:`ElasticSolution`,
:func:`write_vtu`,
:class:`ProblemError`.  Command line: ``iga --help``.
"""

from .errors import ProblemError, SingularProblemError
from .problem import HeatProblem
from .elasticity import ElasticityProblem
from .elastic_solution import ElasticSolution
from .solution import Solution
from .vtu import write_vtu

__all__ = ["ProblemError", "SingularProblemError", "HeatProblem", "Solution", "ElasticityProblem", "ElasticSolution",
           "write_vtu"]
