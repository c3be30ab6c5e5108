"""Splines of parametric dimension 1-3 with named channels, and their exact algebra.

Public names: :class:`BSpline`, :class:`SplineFunction`, :class:`SplineError`,
``compose``, ``compose_many``, ``map_points``, ``check_regular``,
``multiply``, ``save``, ``load``, ``invert``, ``scale_bounds``, the multi-patch model
(:class:`MultiPatch`, :class:`PlacedPatch`, :class:`Interface`) and the
``primitives`` and ``faces`` modules.
"""

from importlib import import_module

from .errors import SplineError, ToolkitError

# the rest is loaded on first use (PEP 562): ``import geometry.errors`` (as the solvers package does, for the
# base exception and the progress display) must not pull in the whole spline stack
_LAZY = {
    "FACE_AXIS": "faces", "FACE_NAMES": "faces", "SplineFunction": "spline", "BSpline": "bspline",
    "multiply": "composition.products", "save": "io.files", "load": "io.files", "save_all": "io.files", "load_all": "io.files",
    "compose": "composition.core", "compose_many": "composition.core", "compose_placed": "composition.core",
    "map_points": "composition.core", "result_degrees": "composition.core", "TrimmedSurface": "shapes.trimmed",
    "reduce_degree": "composition.reduction", "reduce_model": "composition.reduction", "reduced_model": "composition.reduction", "check_regular": "maps.regularity",
    "RegularityResult": "maps.regularity", "invert": "maps.inversion", "Interface": "patches.multipatch",
    "MultiPatch": "patches.multipatch", "PlacedPatch": "patches.multipatch", "detect_interfaces": "patches.multipatch",
    "scale_bounds": "maps.scale", "ScaleBounds": "maps.scale",
}
_MODULES = {"faces", "knots", "bernstein", "primitives"}


def __getattr__(name: str):
    if name in _LAZY:
        value = getattr(import_module(f".{_LAZY[name]}", __name__), name)
    elif name in _MODULES:
        value = import_module(f".{name}", __name__)
    else:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    globals()[name] = value  # later lookups are plain attribute reads
    return value


def __dir__():
    return sorted(set(globals()) | set(_LAZY) | _MODULES)


__all__ = [
    "compose_placed", "TrimmedSurface", "reduce_degree", "reduce_model", "reduced_model", "BSpline", "SplineFunction", "SplineError", "ToolkitError", "FACE_NAMES", "FACE_AXIS", "faces", "knots",
           "bernstein", "primitives", "multiply", "save", "load", "save_all", "load_all", "compose", "compose_many",
           "map_points", "result_degrees", "check_regular", "RegularityResult", "invert", "Interface", "MultiPatch",
           "PlacedPatch", "detect_interfaces", "scale_bounds", "ScaleBounds"]
