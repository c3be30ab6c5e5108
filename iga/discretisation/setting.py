"""The discrete setting every physics shares: the model, its proven regularity, each patch's analysis space
(the tile's own basis, Massarwi et al. 2018, Remark 2), the global DOF offsets, and the volume and face
quadrature built on them."""

from __future__ import annotations

import time

import numpy as np

from geometry.errors import show
from geometry.resources import check_memory

from iga.errors import ProblemError
from iga.discretisation.faces import FaceQuadrature
from iga.model import as_model
from iga.discretisation.rational import own_rational, rational_quadrature_extra
from iga.discretisation.regularity import prove_regular
from iga.discretisation.space import estimate, make_space, solution_bases
from iga.heat.volume import VolumeAssembler
from geometry.numbers import is_integer

__all__ = ["Discretisation", "count"]


def count(name: str, v, minimum: int, three: bool = False):
    """A non-negative integer (or, with ``three``, one integer or three), else ProblemError."""
    vals = list(v) if three and isinstance(v, (list, tuple, np.ndarray)) else [v]
    ok = len(vals) in ((1, 3) if three else (1,)) and all(
        is_integer(x) and x >= minimum for x in vals)
    if not ok:
        what = "an integer" if not three else "an integer or three integers"
        raise ProblemError(f"{name} must be {what} >= {minimum}, got {show(v)}")
    return tuple(int(x) for x in vals) if three and len(vals) == 3 else int(vals[0])


class Discretisation:
    """Scalar analysis spaces of a model (one per patch, shared by patches with equal bases).

    ``components``: unknowns per basis function (1 for temperature, 3 for displacement): the memory
    estimate is checked for that many.  Attributes: ``model``, ``bases``, ``regularity`` (counts of the
    exact fold-free proof), ``space_args``, ``estimate``, ``spaces``, ``offsets`` (patches + 1,), ``ndof``
    (scalar DOFs), ``volume`` (:class:`iga.heat.volume.VolumeAssembler`), ``faces``
    (:class:`iga.discretisation.faces.FaceQuadrature`), ``timings`` (s).
    """

    def __init__(self, model, degree_elevation=0, refine: int = 0, quadrature_extra: int = 0, degree=None,
                 bases=None, components: int = 1):
        self.model = as_model(model)
        self.bases = solution_bases(self.model, bases)
        refine = count("refine", refine, 0)
        quadrature_extra = count("quadrature_extra", quadrature_extra, 0)
        degree_elevation = count("degree_elevation", degree_elevation, 0, three=True)
        if degree is not None:
            degree = count("degree", degree, 1, three=True)
            degree = degree if isinstance(degree, tuple) else (degree,) * 3
        t0 = time.perf_counter()
        self.regularity = prove_regular(self.model)  # exact: a folded patch never reaches the assembly
        t_regular = time.perf_counter() - t0
        args = (quadrature_extra, degree_elevation, refine, degree)
        self.space_args = args  # (quadrature_extra, degree_elevation, refine, degree): coarse levels reuse them
        self.estimate = estimate(self.model, *args, bases=self.bases)
        n = len(self.model.patches)
        what = f"{self.estimate['dofs'] * components:,} DOFs" if components > 1 else f"{self.estimate['dofs']:,} DOFs"
        check_memory(self.estimate["bytes"] * components ** 2, f"the analysis ({what} on {n} "
                     f"patch{'' if n == 1 else 'es'})", ProblemError,
                     "lower refine, degree_elevation or degree, or analyse fewer tiles")
        shared: dict = {}  # patches with equal knot vectors and degrees share one space (and its tables)
        self.spaces = []
        for patch, (knots, degrees) in zip(self.model.patches, self.bases):
            key = (tuple(U.tobytes() for U in knots), degrees)
            if own_rational(patch):  # the NURBS basis's integrands are rational: more Gauss points (iga.discretisation.rational)
                key += (id(patch.spline),)
            if key not in shared:
                space = make_space(knots, degrees, *args)
                if own_rational(patch):
                    extra = max(quadrature_extra, rational_quadrature_extra(patch.spline, space))
                    space = space if extra == quadrature_extra else make_space(knots, degrees, extra, *args[1:])
                shared[key] = space
            self.spaces.append(shared[key])
        self.offsets = np.concatenate([[0], np.cumsum([s.ndof for s in self.spaces])]).astype(np.int64)
        self.ndof = int(self.offsets[-1])
        self.volume = VolumeAssembler(self.model, self.spaces, self.offsets)
        #: per patch, the NURBS weights in its space where it is analysed in the NURBS basis (iga.discretisation.rational)
        self.weights = self.volume.weights
        self.faces = FaceQuadrature(self.model, self.spaces, self.offsets, compiled=self.volume.compiled,
                                    weights=self.weights)
        self.timings = {"regularity": t_regular, "spaces": time.perf_counter() - t0 - t_regular}
