"""Results at hand in scripts and notebooks: a solution as a ``pyvista`` grid, and a picture of it that states
its case.

:func:`plot_field` draws one point array of a sampled grid (:func:`iga.io.vtu.sampled_grid`) with a title, the
array's range and units on the scalar bar, optionally warped by a displacement; it writes a PNG off screen
(no display needed) or shows the window.  A narrow range is said in the title: a colour map stretched over
0.2 K looks like a strong gradient unless the picture says how small it is.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from geometry.errors import show
from geometry.io.files import offscreen_plotter, save_screenshot, window_plotter
from geometry.numbers import TINY, is_real
from iga.errors import ProblemError

__all__ = ["plot_field", "range_note", "count", "UNITS", "render_temperature"]

#: units of the arrays the toolkit writes (for the scalar bar)
UNITS = {"temperature": "C", "heat_flux": "W/m^2", "displacement": "m", "von_mises": "Pa", "stress": "Pa"}


def plot_field(grid, field: str, title: str, screenshot=None, warp=None, window=(1200, 850)):
    """Draw point array ``field`` of ``grid`` (vectors by their magnitude) titled ``title``; ``warp``: a
    factor for the ``displacement`` array (the deformed shape); ``screenshot``: a ``.png`` path written off
    screen (returned), else the window is shown (returns None)."""
    if field not in grid.point_data:
        raise ProblemError(f"plot: no field {show(field)}; this result has {sorted(grid.point_data.keys())}")
    if screenshot is not None and Path(screenshot).suffix.lower() != ".png":
        raise ProblemError(f"plot: screenshot {show(str(screenshot))} must be a .png path")
    if warp is not None:
        if not (is_real(warp) and np.isfinite(warp)):
            raise ProblemError(f"plot: warp must be a finite factor, got {show(warp)}")
        if "displacement" not in grid.point_data:
            raise ProblemError("plot: warp needs a displacement field (an elastic solution)")
        grid = grid.warp_by_vector("displacement", factor=float(warp))
    values = np.asarray(grid.point_data[field], float)
    magnitude = np.linalg.norm(values, axis=1) if values.ndim == 2 else values
    finite = magnitude[np.isfinite(magnitude)]
    lo, hi = (float(finite.min()), float(finite.max())) if finite.size else (0.0, 0.0)
    unit = UNITS.get(field, "")
    label = f"{field}{' magnitude' if values.ndim == 2 else ''} ({unit})" if unit else field
    span = hi - lo
    scale = max(abs(lo), abs(hi), TINY)
    note = range_note(field, lo, hi, unit)
    fmt = "%.3g"
    if 0 < span and scale < 1e4:  # enough decimals that the bar's five labels differ
        fmt = f"%.{max(0, int(np.ceil(-np.log10(span / 4))) + 1)}f"
    grid = grid.copy(deep=False)
    grid.point_data["_shown"] = magnitude
    pl = offscreen_plotter(window) if screenshot is not None else window_plotter(window)
    pl.add_mesh(grid, scalars="_shown", cmap="viridis", clim=(lo, hi if hi > lo else lo + 1.0),
                scalar_bar_args={"title": label, "vertical": True, "position_x": 0.86, "fmt": fmt})
    pl.add_text(f"{title}\n{note}", position="upper_left", font_size=11, color="black")
    if screenshot is None:
        pl.set_background("white")
        pl.show()
        return None
    return save_screenshot(pl, screenshot, ProblemError, "iso", 0.85)


def range_note(field: str, lo: float, hi: float, unit: str = "") -> str:
    """``field lo .. hi unit``, with the width said in words where it is under 5% of the values (a colour map
    stretched over 0.2 K looks like a strong gradient)."""
    note = f"{field} {lo:.6g} .. {hi:.6g} {unit}".strip()
    if hi - lo < 0.05 * max(abs(lo), abs(hi), TINY):
        note += f" (a range of {hi - lo:.3g} {unit})".replace(" )", ")")
    return note


def count(n: int, noun: str) -> str:
    """``n`` with its noun, singular or plural (``1 patch``, ``3 patches``)."""
    plural = noun + ("es" if noun.endswith(("s", "h", "x")) else "s")
    return f"{n:,} {noun if n == 1 else plural}"


def render_temperature(source, png_path: Path, title: str = "temperature (C)", scalars: str = "temperature",
                       warp: float | None = None, cmap: str = "inferno", fmt: str = "%.2f",
                       above: float | None = None, caption: str | None = None):
    """Offscreen render of a sampled grid (a ``pyvista`` grid, or the path of a written .vtu) coloured by
    ``scalars`` (a point array), with a scalar bar (atomic);
    ``warp``: the surface moved by that factor times its ``displacement`` array (an elastic solution);
    ``above``: colour by the rise of ``scalars`` above this value on a logarithmic scale (from 1e-3 of the
    largest rise), so that a part that stays near the ambient temperature still shows its gradient;
    ``caption``: the case, written in the upper left above the shown array's range."""
    import pyvista as pv

    grid = pv.read(source) if isinstance(source, (str, Path)) else source
    lean = pv.UnstructuredGrid()  # the grid's points and cells (shared, not copied) with the arrays shown only:
    lean.copy_structure(grid)  # the surface filter copies every point array
    for name in [scalars] + (["displacement"] if warp is not None else []):
        lean.point_data[name] = grid.point_data[name]
    # vtkGeometryFilter: the same boundary faces as vtkDataSetSurfaceFilter, whose hash of every cell face took
    # 280 MiB at 1.3 M hexahedra (4 MiB here) and 0.86 s (0.62 s)
    mesh = lean.extract_surface(algorithm="geometry")
    log = above is not None
    if log:
        rise = np.asarray(mesh.point_data[scalars], float) - above
        top = float(rise.max())
        mesh.point_data[f"{scalars} rise"] = np.clip(rise, 1e-3 * top, None)
        scalars, fmt = f"{scalars} rise", "%.3g"
    if warp is not None:
        mesh = mesh.warp_by_vector("displacement", factor=warp)
    pl = offscreen_plotter((1200, 850))
    if caption is not None:
        shown = np.asarray(mesh.point_data[scalars], float)
        unit = "K" if log else UNITS.get(scalars, "")
        pl.add_text(f"{caption}\n{range_note(scalars, float(shown.min()), float(shown.max()), unit)}",
                    position="upper_left", font_size=11, color="black")
    pl.add_mesh(mesh, scalars=scalars, cmap=cmap, smooth_shading=True, split_sharp_edges=True, ambient=0.3,
                log_scale=log, scalar_bar_args={"title": title, "vertical": True, "fmt": fmt, "position_x": 0.86,
                                 "position_y": 0.12, "width": 0.08, "height": 0.7, "title_font_size": 18,
                                 "label_font_size": 16})
    save_screenshot(pl, png_path, ProblemError, "iso", 0.85)  # zoom out: room for the scalar bar beside the model
