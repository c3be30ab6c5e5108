"""The analysis model: trivariate patches, their geometry maps, tags and interfaces.

``as_model`` accepts what users pass to :class:`iga.HeatProblem`:

* a single trivariate :class:`geometry.BSpline` -> one patch, tags ``umin`` ..
  ``wmax`` (its faces) and ``boundary`` (all six);
* a list of trivariate BSplines -> independent patches (no coupling), each
  face tagged with its face name, plus ``boundary``;
* a ``tiling.Microstructure`` (anything with ``patches``, ``tags`` and
  ``interfaces``) -> its patches, tags and interfaces.

A :class:`Patch` is analysed in the parameter space of its ``spline`` (the
tile's own patch, whose B-spline basis is the analysis basis, 000 Remark 2);
its physical geometry is ``outer(A @ spline(xi) + b)`` when an ``outer``
deformation map is given, else ``spline(xi)``.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from geometry import BSpline

from .errors import ProblemError
from .space import FACE_AXES

FACES = tuple(FACE_AXES)


@dataclass(eq=False)
class Patch:
    """One trivariate patch of the analysis model."""

    spline: BSpline
    placement: np.ndarray | None = None  # (3, 4) [A | b] into the outer map's domain
    outer: BSpline | None = None
    tile: int = 0
    level: int = 0

    @property
    def channels(self) -> tuple[str, ...]:
        return tuple(self.spline.channels) + (tuple(self.outer.channels) if self.outer is not None else ())


@dataclass(eq=False)
class Model:
    patches: list
    tags: dict  # tag -> list of (patch index, face name or slot face id such as "u=0.5-")
    interfaces: list = field(default_factory=list)
    face_regions: dict = field(default_factory=dict)  # (patch, slot face id) -> free rectangles

    def faces(self, tag: str) -> list[tuple[int, str]]:
        if tag not in self.tags:
            raise ProblemError(f"unknown boundary tag {tag!r}; this model has tags {sorted(self.tags)}")
        return self.tags[tag]


def _check_trivariate(s, what):
    if not isinstance(s, BSpline):
        raise ProblemError(f"{what} is a {type(s).__name__}; heat analysis needs trivariate geometry.BSpline patches")
    if s.dim != 3:
        raise ProblemError(f"{what} is a {s.dim}-variate spline; heat analysis needs trivariate patches")


def as_model(obj) -> Model:
    """Normalise a BSpline, a list of BSplines or a Microstructure into a :class:`Model`."""
    if isinstance(obj, Model):
        return obj
    if isinstance(obj, BSpline):
        obj = [obj]
    if isinstance(obj, (list, tuple)):
        patches = []
        for i, s in enumerate(obj):
            _check_trivariate(s, f"patch {i}")
            patches.append(Patch(s, tile=i))
        tags = {f: [(i, f) for i in range(len(patches))] for f in FACES}
        tags["boundary"] = [(i, f) for i in range(len(patches)) for f in FACES]
        return Model(patches, tags)
    if hasattr(obj, "patches") and hasattr(obj, "tags"):
        patches = []
        for i, p in enumerate(obj.patches):
            spline = getattr(p, "spline", None)
            _check_trivariate(spline, f"patch {i}")
            patches.append(Patch(spline, getattr(p, "placement", None), getattr(p, "outer", None),
                                 getattr(p, "tile", 0), getattr(p, "level", 0)))
        tags = {t: list(v) for t, v in obj.tags.items()}
        return Model(patches, tags, list(getattr(obj, "interfaces", [])), dict(getattr(obj, "face_regions", {})))
    raise ProblemError(
        f"cannot analyse a {type(obj).__name__}; pass a trivariate BSpline, a list of them or a Microstructure"
    )
