"""Trimmed tile members (Elber 2017, Fig. 7) and shelled surface tiles (Massarwi et al. 2018, Fig. 9(c, d)).

    python benchmarks/trimmed_tiles.py [--figures]

Fig. 7: the three concentric trimmed through-cylinders paved (4, 4, 2) in a bent triquadratic block:
the times to pave, compose every member exactly, write IGES (entity 144) and tessellate, our area of
the composed members (quadrature over the trimmed regions) and, where gmsh is installed, the area
OpenCASCADE integrates from the IGES file.  Shells: the hollow cross shelled in a twisted block,
closedness, components and the Euler characteristic beside the one the topology predicts.  Boolean
sealing: square tubes crossing the cell walls obliquely, cut by the cell's planes and capped; closed,
one sphere per tube.  Renders ``fig7_trimmed_tiles.png`` and ``shelled_tiles.png`` (cut open).
"""

from __future__ import annotations

import tempfile
import time
from pathlib import Path

import numpy as np

from geometry import BSpline, primitives
from geometry.io.files import offscreen_plotter, save_screenshot
from tiling import library, regular
from tiling.members.cylinders import through_cylinders
from tiling.export import boundary_splines, watertightness, write_iges
from tiling.pictures import render_png

from _common import figures_dir


def _bent_block():
    D = primitives.box((4.0, 4.0, 2.0)).elevate_to((2, 2, 2))
    P = D.control_points.copy()
    P[..., 2] += 0.4 * np.sin(0.8 * P[..., 0]) * (1 + 0.2 * P[..., 1])
    return BSpline(D.degrees, D.knots, P)


def _gmsh_area(path) -> tuple[int, float] | None:
    try:
        import gmsh
    except ImportError:
        return None
    gmsh.initialize()
    try:
        gmsh.option.setNumber("General.Terminal", 0)
        gmsh.model.occ.importShapes(str(path))
        gmsh.model.occ.synchronize()
        tags = [t for _, t in gmsh.model.getEntities(2)]
        return len(tags), sum(gmsh.model.occ.getMass(2, t) for t in tags)
    finally:
        gmsh.finalize()


def fig7() -> None:
    D = _bent_block()
    tile = through_cylinders(0.25)
    t0 = time.perf_counter()
    ms = regular(D, tile, (4, 4, 2), name="Fig. 7")
    t1 = time.perf_counter()
    members = boundary_splines(ms)
    t2 = time.perf_counter()
    with tempfile.TemporaryDirectory() as tmp:
        path = write_iges(Path(tmp) / "fig7.igs", ms, units="mm")
        t3 = time.perf_counter()
        mesh = ms.surface(samples=4)
        t4 = time.perf_counter()
        ours = sum(T.area(3e-3) for T in members)
        t5 = time.perf_counter()
        occ = _gmsh_area(path)
    degrees = members[0].surface.degrees
    print("Fig. 7: three trimmed through-cylinders, (4, 4, 2) in a bent triquadratic block")
    print(f"  members {len(ms.trimmed)} (tiles {ms.n_tiles}), composed degrees {degrees}")
    print(f"  pave {t1 - t0:.3f} s | compose {t2 - t1:.2f} s | IGES {t3 - t2:.2f} s | tessellate "
          f"{t4 - t3:.2f} s ({mesh.n_cells:,} triangles) | area {t5 - t4:.1f} s")
    line = f"  area: ours {ours:.9f}"
    if occ is not None:
        line += f" | OpenCASCADE (gmsh) {occ[1]:.9f} over {occ[0]} faces, relative {occ[1] / ours - 1:+.1e}"
    print(line)
    render_png(ms, figures_dir() / "fig7_trimmed_tiles.png", samples=4, color_by="tile", window=(1000, 600))


def _predicted_euler(counts) -> int:
    n = np.array(counts)
    cells = int(np.prod(n))
    tubes = sum(cells // n[d] * (n[d] - 1) for d in range(3)) + 2 * sum(cells // n[d] for d in range(3))
    return 2 * (2 + cells - tubes)


def shells() -> None:
    D = primitives.twisted(primitives.box((3.0, 3.0, 2.0), degrees=(2, 2, 2)), 0.5, axis_point=(1.5, 1.5))
    counts = (3, 3, 2)
    t0 = time.perf_counter()
    ms = regular(D, library.hollow_cross(), counts, seal="shell", thickness=0.12)
    t1 = time.perf_counter()
    w = watertightness(ms, samples=4)
    t2 = time.perf_counter()
    print("Shells: hollow cross, (3, 3, 2) in a twisted block, thickness 0.12 of a cell")
    print(f"  pave {t1 - t0:.2f} s | surface + check {t2 - t1:.2f} s ({w['triangles']:,} triangles) | closed "
          f"{w['closed']} | manifold {w['manifold']} | components {w['components']} | Euler "
          f"{w['euler_characteristic']} (predicted {_predicted_euler(counts)})")
    mesh = ms.surface(samples=4).connectivity()  # two regions: the skin's outside; its inside with the tubes
    cut = mesh.clip(normal=(0, -1, 0), origin=mesh.center)  # keep the back half, looked at from the cut
    pl = offscreen_plotter((1000, 700))
    for region, colour in ((0, "#c9d6e8"), (1, "#e07b39")):
        part = cut.threshold((region - 0.5, region + 0.5), scalars="RegionId")
        if part.n_cells:
            pl.add_mesh(part, color=colour, smooth_shading=True, split_sharp_edges=True)
    pl.view_vector((0.35, -1.0, 0.45))
    save_screenshot(pl, figures_dir() / "shelled_tiles.png", camera=pl.camera_position)


def boolean() -> None:
    D = primitives.twisted(primitives.box((4.0, 2.0, 3.0), degrees=(2, 2, 2)), 0.4, axis_point=(2.0, 1.0))
    counts = (4, 2, 3)
    t0 = time.perf_counter()
    tile = library.oblique_tubes(0.16)
    ms = regular(D, tile, counts, seal="cap")
    t1 = time.perf_counter()
    w = watertightness(ms, samples=4)
    t2 = time.perf_counter()
    j = np.arange(-2 * counts[0] - 4, 2 * counts[2] + 4)
    tubes = counts[1] * int(np.sum((0.25 + 0.5 * (counts[0] + j) > 0) & (0.25 + 0.5 * j < counts[2])))
    print("Boolean sealing: oblique square tubes, (4, 2, 3) in a twisted block, cut by the cells' planes, capped")
    print(f"  cut + pave + cap {t1 - t0:.2f} s ({len(ms.patches)} pieces, {len(ms.caps)} caps) | surface + check "
          f"{t2 - t1:.2f} s | closed {w['closed']} | manifold {w['manifold']} | components {w['components']} "
          f"(tubes {tubes}) | Euler {w['euler_characteristic']} (2 per tube: {2 * tubes})")


def main():
    fig7()
    shells()
    boolean()


if __name__ == "__main__":
    main()
