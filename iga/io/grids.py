"""Sampled grids of models and solutions: conforming linear hexahedra welded into one ``pyvista`` grid, its size
checked against the memory budget before any point is made (the VTU writer and ``Solution.to_pyvista`` share it).
"""

from __future__ import annotations

import numpy as np

from geometry.grouping import ObjectIndex
from geometry.patches.sampling import chord_samples, sampled_mesh
from geometry.resources import check_memory
from iga.errors import ProblemError

__all__ = ["sample_grid"]


#: bytes per written point while a grid is sampled, welded and handed to VTK (coordinates, fields, their
#: temporaries, cells): a bound for the size check before sampling
_BYTES_PER_POINT = 400


def _check_sampling(model, basis_of, knots_of, samples, patches) -> None:
    """Refuse a sampling whose points would not fit the memory budget, before any is made: the user's
    ``samples`` (one count, or per patch and direction) times each patch's elements.  ``basis_of(pi)``: the
    object whose knots patch ``pi`` samples (its space or spline, shared by many patches: elements are
    counted once per object), ``knots_of(obj)`` its knot vectors."""
    chosen = range(len(model.patches)) if patches is None else patches
    same, elements = ObjectIndex(), {}
    total = 0.0
    for pi in chosen:
        key = same(basis_of(pi))
        if key not in elements:
            elements[key] = [len(np.unique(U)) - 1 for U in knots_of(basis_of(pi))]
        s = samples[pi] if isinstance(samples, list) else samples
        per = [int(s)] * 3 if np.ndim(s) == 0 else [int(v) for v in s]
        total += float(np.prod([e * n + 1 for e, n in zip(elements[key], per)]))
    check_memory(total * _BYTES_PER_POINT, f"the sampled VTU grid ({total:,.0f} points)", ProblemError,
                 "lower samples (subdivisions per element) or use a tolerance")


def sample_grid(model, samples: int = 3, tolerance: float | None = None, patches=None, problem=None, fields=None):
    """The welded linear-hexahedron grid (a ``pyvista.UnstructuredGrid``) of ``model``, or of a solution of
    ``problem`` whose ``fields`` (:mod:`iga.io.sampling`) it samples on the analysis spaces; with ``tolerance``
    the samples per patch and direction that keep the cells within it of the exact geometry; ``patches``: only
    those (their samples still conform with every neighbour's).  The grid's size is checked against the memory
    budget before it is sampled."""
    if problem is None:
        if tolerance is not None:
            samples = chord_samples(model, lambda pi: model.patches[pi].spline.knots, tolerance)
        _check_sampling(model, lambda pi: model.patches[pi].spline, lambda s: s.knots, samples, patches)
        return sampled_mesh(model, samples, patches=patches)
    prob = problem
    if tolerance is not None:
        samples = chord_samples(model, lambda pi: [d.knots for d in prob.spaces[pi].dirs], tolerance)
    _check_sampling(model, lambda pi: prob.spaces[pi], lambda s: [d.knots for d in s.dirs], samples, patches)
    return sampled_mesh(model, samples, knots_of=lambda pi: [d.knots for d in prob.spaces[pi].dirs],
                        spaces_key=lambda pi: prob.spaces[pi].key(), fields=fields, patches=patches)

