"""Isogeometric analysis on micro-structures: spaces, assembly, heat problem, VTU export.

Public names: :class:`HeatProblem`, :class:`Solution`, :class:`TransientHeatProblem` (with
:class:`TransientSolution` and :class:`TransientState`), :class:`ElasticityProblem`, :class:`ElasticSolution`,
:class:`CubicMaterial` (with :class:`IsotropicMaterial`: :mod:`iga.elasticity.material`),
:func:`effective_conductivity`, :func:`effective_stiffness`, :func:`effective_table` and :func:`macro_map`
(graded macro models), :func:`stiffness_table` (a lattice's cubic stiffness over its parameter: an elastic macro
model), :func:`write_vtu`, :func:`write_pieces` (one VTU piece per MPI rank and a ``.pvtu``),
:class:`Expression` (a formula of the position, for values that G+Smo export writes),
:func:`adaptive_solve` (refinement by tiles, :mod:`iga.adaptivity`), :func:`optimize` (a material channel designed
by gradient, :mod:`iga.design`), :class:`ProblemError`.  Command line: ``iga --help``.
"""

from .errors import ProblemError, SingularProblemError
from .expressions import Expression
from iga.heat.problem import HeatProblem
from iga.elasticity.problem import ElasticityProblem
from iga.elasticity.solution import ElasticSolution
from iga.homogenisation.cells import effective_conductivity, effective_stiffness
from iga.homogenisation.macro import EffectiveTable, StiffnessTable, effective_table, macro_map, stiffness_table
from iga.elasticity.material import CubicMaterial, IsotropicMaterial
from iga.heat.solution import Solution
from iga.heat.transient import TransientHeatProblem
from iga.heat.transient_solution import TransientSolution, TransientState
from iga.io.vtu import write_pieces, write_vtu
from iga.adaptivity.loop import AdaptiveResult, adaptive_solve
from iga.design import DesignResult, optimize

__all__ = ["ProblemError", "SingularProblemError", "HeatProblem", "Solution", "ElasticityProblem", "ElasticSolution",
           "effective_conductivity", "effective_stiffness", "EffectiveTable", "effective_table", "macro_map",
           "write_vtu", "write_pieces", "Expression", "TransientHeatProblem", "TransientSolution",
           "TransientState", "adaptive_solve", "AdaptiveResult", "optimize", "DesignResult", "CubicMaterial",
           "IsotropicMaterial", "StiffnessTable", "stiffness_table"]
