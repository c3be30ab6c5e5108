"""Splines of parametric dimension 1-3 with named channels, and their exact algebra.

Public names: :class:`BSpline`, :class:`SplineFunction`, :class:`SplineError`,
``compose``, ``compose_many``, ``map_points``, ``check_regular``,
``multiply``, ``save``, ``load``, and the ``primitives`` module.
"""

from .errors import SplineError, ToolkitError
from .spline import SplineFunction, FACE_NAMES
from .bspline import BSpline
from . import knots, bernstein

__all__ = ["BSpline", "SplineFunction", "SplineError", "ToolkitError", "FACE_NAMES", "knots", "bernstein"]
from . import primitives
from .products import multiply
from .io import save, load, save_all, load_all

__all__ += ["primitives", "multiply", "save", "load", "save_all", "load_all"]
from .compose import compose, compose_many, map_points, result_degrees

__all__ += ["compose", "compose_many", "map_points", "result_degrees"]
from .regularity import check_regular, RegularityResult

__all__ += ["check_regular", "RegularityResult"]
