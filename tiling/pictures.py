"""Pictures of a micro-structure: its boundary (:func:`tiling.export.surface`) drawn with pyvista, coloured by
level, tile or patch, titled; off screen to a ``.png`` (:func:`render_png`) or into a plotter (:func:`draw`)."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from geometry.errors import show
from geometry.io.files import offscreen_plotter, save_screenshot
from tiling.errors import TilingError
from tiling.export import drawn_patches, surface

if TYPE_CHECKING:  # annotations only
    from tiling.microstructure import Microstructure

__all__ = ["render_png", "draw"]


def render_png(ms: Microstructure, path, samples: int = 6, color_by: str = "level", window=(1000, 800),
               camera: str = "iso", title: str | None = None, mesh=None) -> Path:
    """Offscreen pyvista render of the boundary, coloured by ``level``, ``tile`` or ``patch``; ``title``
    (default: the structure's name, tiles, patches and levels) in the upper left; ``mesh``: the boundary
    already computed by :func:`surface` (see :func:`draw`)."""
    return save_screenshot(draw(ms, offscreen_plotter(window), samples, color_by, title, mesh), path, TilingError,
                           camera)


def draw(ms: Microstructure, pl, samples: int = 6, color_by: str = "level", title: str | None = None, mesh=None):
    """``pl`` (a ``pyvista.Plotter``) with the boundary of ``ms`` coloured by ``color_by`` and the title added.

    ``mesh``: the boundary :func:`surface` (or ``ms.surface``) already gave for ``ms``, drawn instead of
    computing it again (``samples`` is then not used); its ``patch`` cell numbers must be this structure's."""
    drawn = drawn_patches(ms)
    attr = {"level": [p.level for p in drawn], "tile": [p.tile for p in drawn], "patch": list(range(len(drawn)))}
    if color_by not in attr:
        raise TilingError(f"color_by must be one of {sorted(attr)}, got {show(color_by)}")
    if mesh is None:
        mesh = surface(ms, samples)
    elif not hasattr(mesh, "cell_data") or "patch" not in mesh.cell_data or (
            mesh.n_cells and int(np.max(mesh.cell_data["patch"])) >= len(drawn)):
        raise TilingError(f"mesh must be the boundary surface(ms) gave for this structure ({len(drawn)} patches "
                          "numbered in its 'patch' cell data); pass mesh=ms.surface(...) or leave it out")
    levels = ms.levels
    pl.add_text(title if title is not None else
                f"{ms.name or 'micro-structure'}: {ms.n_tiles:,} tiles, {len(ms.patches):,} patches"
                + (f", {levels} levels" if levels > 1 else ""), position="upper_left", font_size=11, color="black")
    tris = mesh.extract_cells_by_type(5)
    if tris.n_cells:
        tris.cell_data[color_by] = np.asarray(attr[color_by])[tris.cell_data["patch"]]
        n = len(np.unique(tris.cell_data[color_by]))
        if n > 1:
            pl.add_mesh(tris, scalars=color_by, cmap="viridis", smooth_shading=True, split_sharp_edges=True,
                        scalar_bar_args={"title": color_by, "vertical": True, "position_x": 0.86,
                                         "position_y": 0.15, "width": 0.08, "height": 0.6, "n_labels": min(n, 6),
                                         "fmt": "%.0f"})
        else:  # one value: a plain colour reads better than the colour map's end
            pl.add_mesh(tris, color="#8fb3de", smooth_shading=True, split_sharp_edges=True)
    lines = mesh.extract_cells_by_type(3)
    if lines.n_cells:
        size = float(np.ptp(np.asarray(lines.points), axis=0).max())
        pl.add_mesh(lines.extract_surface(algorithm="dataset_surface").tube(radius=0.01 * size), color="darkred")
    return pl
