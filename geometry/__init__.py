"""Splines of parametric dimension 1-3 with named channels, and their exact algebra.

Public names: :class:`BSpline`, :class:`SplineFunction`, :class:`SplineError`,
``compose``, ``compose_many``, ``map_points``, ``check_regular``,
``multiply``, ``save``, ``load``, ``invert``, the multi-patch model
(:class:`MultiPatch`, :class:`PlacedPatch`, :class:`Interface`) and the
``primitives`` and ``faces`` modules.
"""

from .errors import SplineError, ToolkitError
from .faces import FACE_AXIS, FACE_NAMES
from .spline import SplineFunction
from .bspline import BSpline
from . import faces, knots, bernstein
from . import primitives
from .products import multiply
from .io import save, load, save_all, load_all
from .composition import compose, compose_many, compose_placed, map_points, result_degrees
from .trimmed import TrimmedSurface
from .reduction import reduce_degree, reduce_model
from .regularity import check_regular, RegularityResult
from .inversion import invert
from .multipatch import Interface, MultiPatch, PlacedPatch, detect_interfaces

__all__ = [
    "compose_placed", "TrimmedSurface", "reduce_degree", "reduce_model","BSpline", "SplineFunction", "SplineError", "ToolkitError", "FACE_NAMES", "FACE_AXIS", "faces", "knots",
           "bernstein", "primitives", "multiply", "save", "load", "save_all", "load_all", "compose", "compose_many",
           "map_points", "result_degrees", "check_regular", "RegularityResult", "invert", "Interface", "MultiPatch",
           "PlacedPatch", "detect_interfaces"]
