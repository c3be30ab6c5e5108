"""Pictures of the built-in tiles and the page that shows them: benchmarks/out/figures/tiles/<name>.png (with
--figures: docs/tiles/<name>.png and docs/tiles.md, the table of every tile of ``tiling.library.TILES`` with
its picture and the first sentence of its docstring).

    python benchmarks/tile_gallery.py [--figures]

Each tile is shown in its unit cell (identity map) with its default arguments, coloured by patch.
"""

from __future__ import annotations

import inspect
import re
import sys

import tiling
from geometry import primitives as pr
from tiling.pictures import render_png
from tiling.library import TILES

from _common import figures_dir

OUT = figures_dir() / "tiles"  # benchmarks/out/figures/tiles; docs/tiles with --figures
PER_ROW = 4


def _summary(make) -> str:
    """The first paragraph of a tile function's docstring, on one line."""
    text = " ".join(inspect.getdoc(make).split("\n\n")[0].split()).replace("|", "\\|")
    return re.sub(r":\w+:`([^`]+)`", r"`\1`", text).replace("``", "`")  # reStructuredText roles as Markdown code


def _arg(value) -> str:
    return f"{value:.4g}" if isinstance(value, float) else repr(value)


def page() -> str:
    """docs/tiles.md: every tile with its picture, its call and what it is."""
    lines = ["# Tiles", "", "The built-in tiles of `tiling.library` (what a pipeline's `[tile] library` names), each in "
             "its unit cell with its default arguments, coloured by patch; `python benchmarks/tile_gallery.py "
             "--figures` redraws them and writes this page.", "", "| tile | what it is |", "|---|---|"]
    for name, make in TILES.items():
        args = ", ".join(f"{k}={_arg(v.default)}" for k, v in inspect.signature(make).parameters.items())
        lines.append(f"| ![{name}](tiles/{name}.png)<br>`{name}({args})` | {_summary(make)} |")
    return "\n".join(lines) + "\n"


def main():
    OUT.mkdir(parents=True, exist_ok=True)
    cell = pr.box()
    for name, make in TILES.items():
        ms = tiling.regular(cell, make(), (1, 1, 1))
        print(render_png(ms, OUT / f"{name}.png", samples=8, color_by="patch", window=(520, 440), title=name))
    if "--figures" in sys.argv:
        (OUT.parent / "tiles.md").write_text(page())
        print(OUT.parent / "tiles.md")


if __name__ == "__main__":
    main()
