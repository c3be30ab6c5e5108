"""The analysis model: anything with ``patches``, ``interfaces`` and ``tags`` (:class:`geometry.MultiPatch`).

:func:`as_model` accepts what users pass to :class:`iga.HeatProblem` and
:func:`iga.write_vtu`:

* a single trivariate :class:`geometry.BSpline` -> one patch, tags ``umin`` ..
  ``wmax`` (its faces) and ``boundary`` (all six);
* a list of trivariate BSplines -> a :class:`geometry.MultiPatch` whose
  conforming shared faces are coupled automatically (identity interfaces,
  :func:`geometry.detect_interfaces`); tags are the free faces by name, each
  face of each patch as ``patch{i}.{face}``, and ``boundary``;
* a ``tiling.Microstructure`` or any object with ``patches`` (each with a
  trivariate ``spline`` and optional ``placement``, ``outer``, ``tile``,
  ``level``), ``tags`` and ``interfaces``.

A patch is analysed in the parameter space of its ``spline`` (the tile's own
patch, whose B-spline basis is the analysis basis; Massarwi et al. 2018,
Remark 2); its physical geometry is ``outer(A spline(xi) + b)``.
"""

from __future__ import annotations

from geometry import BSpline, MultiPatch, PlacedPatch
from geometry.errors import SplineError
from geometry.faces import is_face

from tiling.microstructure import Microstructure

from .errors import ProblemError
from .tags import resolve
from geometry.errors import show

__all__ = ["as_model", "tag_faces", "same_kind", "PlacedPatch"]


def _check_spline(s, i):
    if not isinstance(s, BSpline):
        raise ProblemError(f"patch {i} is a {type(s).__name__}; heat analysis needs trivariate geometry.BSpline patches")
    if s.dim != 3:
        raise ProblemError(f"patch {i} is a {s.dim}-variate spline; heat analysis needs trivariate patches")


def as_model(obj) -> MultiPatch:
    """Normalise a BSpline, a list of BSplines or a model object into a :class:`geometry.MultiPatch` (see module)."""
    if isinstance(obj, BSpline):
        obj = [obj]
    if isinstance(obj, (list, tuple)):
        if not obj:
            raise ProblemError("the model has no patches; pass a trivariate BSpline, a list of them or a Microstructure")
        for i, s in enumerate(obj):
            _check_spline(s, i)
        try:
            return MultiPatch.from_splines(obj)
        except SplineError as exc:
            raise ProblemError(str(exc)) from None
    if not (hasattr(obj, "patches") and hasattr(obj, "tags")):
        raise ProblemError(
            f"cannot analyse a {type(obj).__name__}; pass a trivariate BSpline, a list of them or a Microstructure"
        )
    if not obj.patches:
        raise ProblemError("the model has no patches")
    for i, p in enumerate(obj.patches):
        _check_spline(getattr(p, "spline", None), i)
    if isinstance(obj, MultiPatch) and all(isinstance(p, PlacedPatch) for p in obj.patches):
        return obj
    patches = [PlacedPatch(p.spline, getattr(p, "placement", None), getattr(p, "outer", None), getattr(p, "tile", i),
                           getattr(p, "level", 0), refinement=getattr(p, "refinement", 0))
               for i, p in enumerate(obj.patches)]
    return MultiPatch(patches, list(getattr(obj, "interfaces", [])), {t: list(v) for t, v in obj.tags.items()},
                      dict(getattr(obj, "face_regions", {})))


def tag_faces(model, tag, rest: list | None = None) -> list:
    """The (patch, face) pairs of ``tag``: a tag of the model, an expression of tags or a list of them
    (:mod:`iga.tags`; ``rest``: the faces the tag ``rest`` stands for); :class:`ProblemError` naming the known
    tags otherwise."""
    faces = model.tags[tag] if isinstance(tag, str) and tag in model.tags else resolve(model, tag, rest)
    for pi, face in faces:
        if not (0 <= pi < len(model.patches)) or not is_face(face):
            raise ProblemError(f"tag {show(tag)} holds an invalid face ({pi}, {show(face)}); faces are (patch index, "
                               "face name or slot face id)")
    return faces


def same_kind(source, patches, interfaces, tags, regions=None):
    """A model of the same kind as ``source`` from new patches, interfaces, tags and slot-face regions: a
    ``tiling.Microstructure`` keeps its map, tiles, name, caps, trimmed members and the builder's report; anything
    else becomes a :class:`geometry.MultiPatch` (refined or redesigned models: :mod:`iga.adaptivity`,
    :mod:`iga.design`)."""
    if isinstance(source, Microstructure):
        ms = Microstructure(source.outer, patches, interfaces, tags, source.tiles, source.name, regions or {})
        ms.caps, ms.trimmed, ms.info, ms.struts = source.caps, source.trimmed, dict(source.info), source.struts
        return ms
    return MultiPatch(patches, interfaces, tags, regions or {})
