"""Pictures of the built-in tiles: benchmarks/out/figures/tiles/<name>.png (docs/tiles/ with --figures).

    python benchmarks/tile_gallery.py

Each tile is shown in its unit cell (identity map), coloured by patch.
"""

from __future__ import annotations



from geometry import primitives as pr
import tiling
from tiling import library as L
from tiling.export import render_png

from _common import figures_dir

OUT = figures_dir() / "tiles"  # benchmarks/out/figures/tiles; docs/tiles with --figures


def main():
    OUT.mkdir(parents=True, exist_ok=True)
    cell = pr.box()
    for make in (L.heat_sink_t1, L.heat_sink_t2, L.skinned_branching, L.fractal, L.hollow_box, L.cross, L.helix):
        tile = make()
        ms = tiling.regular(cell, tile, (1, 1, 1))
        path = render_png(ms, OUT / f"{tile.name}.png", samples=8, color_by="patch", window=(520, 440))
        print(path)


if __name__ == "__main__":
    main()
