"""Pictures of random implicit structures: the surface, and the connectivity trees (Massarwi et al. 2018, Figs. 5, 14).

The trees are drawn as polylines between the cells' centres mapped through
D, one colour per tree (blue L1, red L2, green L3, as in Fig. 5).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from geometry.errors import show
from geometry.io.files import offscreen_plotter, save_screenshot

from tiling.errors import TilingError

__all__ = ["tree_lines", "render_png"]

TREE_COLOURS = ("#1f4fd1", "#d62728", "#2ca02c")


def tree_lines(structure) -> list:
    """One ``pyvista.PolyData`` of line segments per spanning tree, between the mapped cell centres."""
    import pyvista as pv

    counts = np.asarray(structure.counts)
    dom = structure.outer.domain
    h = (dom[:, 1] - dom[:, 0]) / counts
    centres = dom[:, 0] + h * (np.stack(np.unravel_index(np.arange(int(counts.prod())), counts), 1) + 0.5)
    points = structure.outer.evaluate(centres)[:, :3]
    out = []
    for tree in structure.trees:
        lines = np.hstack([np.full((len(tree), 1), 2), tree]).ravel()
        out.append(pv.PolyData(points, lines=lines))
    return out


def render_png(structure, path, *, trees: bool = False, surface: bool = True, color_by: str | None = None,
               resolution: int | None = None, window=(1000, 800), camera="iso", zoom: float = 1.4,
               title: str | None = None) -> Path:
    """Offscreen render of the structure's surface and/or its spanning trees to a PNG (atomic).

    ``color_by``: a point-data name of the surface (a channel of D, a material,
    or "u", "v", "w"); default a plain colour.  ``trees``: draw the trees
    (Fig. 5); with ``surface`` as well, the surface is drawn translucent.  ``title``: text in the upper left.
    """
    if not (trees or surface):
        raise TilingError("nothing to render: ask for the surface, the trees, or both")
    if title is not None and not isinstance(title, str):
        raise TilingError(f"title must be a string, got {show(title)}")
    pl = offscreen_plotter(window)
    if title:
        pl.add_text(title, position="upper_left", font_size=11, color="black")
    if surface:
        mesh = structure.surface(resolution)
        if color_by is not None and color_by not in mesh.point_data:
            raise TilingError(f"color_by must be one of {sorted(mesh.point_data)}, got {show(color_by)}")
        style = {"opacity": 0.35} if trees else {}
        if color_by is None:
            pl.add_mesh(mesh, color="#c9a66b", smooth_shading=True, **style)
        else:
            pl.add_mesh(mesh, scalars=color_by, cmap="viridis", smooth_shading=True, **style,
                        scalar_bar_args={"title": color_by, "vertical": True, "position_x": 0.86})
    if trees:
        size = float(np.ptp(structure.outer.control_points[..., :3].reshape(-1, 3), axis=0).max())
        for lines, colour in zip(tree_lines(structure), TREE_COLOURS):
            pl.add_mesh(lines.tube(radius=0.006 * size), color=colour)
    return save_screenshot(pl, path, TilingError, camera, zoom)
