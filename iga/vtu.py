"""VTU export (ParaView / VTK) of models and solutions.

Each patch is sampled on a tensor grid: every Bezier element of the analysis
space is subdivided ``samples`` times per direction, grid points are shared
inside a patch (no duplicates), and neighbouring grid points form linear
hexahedra (VTK type 12).  Point data: ``temperature`` (if a solution is
given), ``heat_flux`` (W/m^2, vector), ``conductivity`` and every channel of
the tiles and the deformation map; cell data: ``patch``, ``tile`` and
``level`` (filter by level in ParaView with Threshold).  Written with meshio
to a temporary file and renamed into place (atomic).
"""

from __future__ import annotations

from pathlib import Path

import meshio
import numpy as np

from geometry.io import atomic_write, check_folder

from .coefficients import tensor_matrix
from .errors import ProblemError
from .geometry_eval import patch_geometry_grid
from .model import as_model
from .solution import Solution, flux_vector

# VTK hexahedron corner order as (di, dj, dk) offsets
_HEX = np.array([(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0), (0, 0, 1), (1, 0, 1), (1, 1, 1), (0, 1, 1)])


def _axes(knots, samples: int):
    out = []
    for U in knots:
        b = np.unique(U)
        t = np.linspace(0.0, 1.0, samples + 1)[:-1]
        ax = (b[:-1, None] + np.diff(b)[:, None] * t[None, :]).ravel()
        out.append(np.append(ax, b[-1]))
    return out


def _hexes(shape, flip: bool) -> np.ndarray:
    n1, n2, n3 = shape
    i, j, k = np.meshgrid(np.arange(n1 - 1), np.arange(n2 - 1), np.arange(n3 - 1), indexing="ij")
    corners = _HEX[[1, 0, 3, 2, 5, 4, 7, 6]] if flip else _HEX  # mirror in i for left-handed maps
    idx = [((i + a) * n2 + (j + b)) * n3 + (k + c) for a, b, c in corners]
    return np.stack([c.ravel() for c in idx], axis=1)


def write_vtu(path, solution_or_model, samples: int = 3, cells: str = "linear") -> Path:
    """Write one ``.vtu`` file with every patch of a model or solution.

    Parameters
    ----------
    path : output file (``.vtu``); its folder must exist and be writable
    solution_or_model : :class:`iga.Solution`, or anything :func:`iga.model.as_model` accepts
    samples : subdivisions of every Bezier element per direction (>= 1), for ``cells="linear"``
    cells : ``"linear"`` (sampled linear hexahedra, with heat flux) or ``"bezier"``: one exact
        rational Bezier hexahedron (VTK type 79) per element, geometry and temperature exact
        (:mod:`iga.vtu_bezier`; composes every patch, so heavier for large models)
    """
    if not isinstance(samples, (int, np.integer)) or samples < 1:
        raise ProblemError(f"samples must be a positive integer, got {samples!r}")
    if cells not in ("linear", "bezier"):
        raise ProblemError(f"cells must be 'linear' or 'bezier', got {cells!r}")
    path = Path(path)
    check_folder(path, ProblemError)  # before sampling: fail fast on a bad output path
    sol = solution_or_model if isinstance(solution_or_model, Solution) else None
    model = sol.problem.model if sol is not None else as_model(solution_or_model)
    if cells == "bezier":
        from .vtu_bezier import write_bezier_vtu

        return atomic_write(path, lambda tmp: write_bezier_vtu(tmp, sol, model), ".vtu", ProblemError)
    points, cells, pdata, cdata = [], [], {}, {"patch": [], "tile": [], "level": []}
    offset = 0
    names = sorted({c for p in model.patches for c in p.channels})
    for pi, patch in enumerate(model.patches):
        knots = [d.knots for d in sol.problem.spaces[pi].dirs] if sol is not None else patch.spline.knots
        axes = _axes(knots, samples)
        shape = tuple(len(a) for a in axes)
        x, J, chans = patch_geometry_grid(patch, axes)
        det = np.linalg.det(J)
        flip = bool(np.median(det) < 0)
        fields = {}
        if sol is not None:
            Tsp = sol.temperature_spline(pi)
            T = Tsp.evaluate_grid(axes).reshape(-1)
            dxi = np.stack([Tsp.evaluate_grid(axes, tuple(int(i == k) for i in range(3))).reshape(-1) for k in range(3)], -1)
            ok = np.abs(det) > 0
            grad = np.zeros_like(dxi)
            grad[ok] = np.linalg.solve(np.transpose(J[ok], (0, 2, 1)), dxi[ok][:, :, None])[:, :, 0]
            kval = sol.conductivity_at(x, chans, pi)
            fields["temperature"] = T
            fields["heat_flux"] = flux_vector(kval, grad)
            fields["conductivity"] = kval if kval.ndim == 1 else tensor_matrix(kval).reshape(-1, 9)
        for c in names:
            fields[c] = np.asarray(chans[c], float) if c in chans else np.full(len(x), np.nan)
        for key, v in fields.items():
            pdata.setdefault(key, []).append(v)
        points.append(x)
        hexes = _hexes(shape, flip) + offset
        cells.append(hexes)
        n = len(hexes)
        cdata["patch"].append(np.full(n, pi, np.int32))
        cdata["tile"].append(np.full(n, patch.tile, np.int32))
        cdata["level"].append(np.full(n, patch.level, np.int32))
        offset += len(x)
    mesh = meshio.Mesh(
        np.concatenate(points),
        [("hexahedron", np.concatenate(cells))],
        point_data={k: np.concatenate(v) for k, v in pdata.items()},
        cell_data={k: [np.concatenate(v)] for k, v in cdata.items()},
    )
    return atomic_write(path, lambda tmp: meshio.write(tmp, mesh, file_format="vtu"), ".vtu", ProblemError)

