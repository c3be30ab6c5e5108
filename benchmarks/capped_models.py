"""Capped micro-structures: Elber 2017, Fig. 2(d) and Massarwi et al. 2018, Fig. 12 analogues.

    python benchmarks/capped_models.py            # table, JSON, renders
    python benchmarks/capped_models.py --no-png

Cases, each in a fresh subprocess (peak memory is per case, imports included):
  * ``fig2d``: a hollow tile (the 24 arm walls of the cross, ``library.hollow_cross``) paved 4 x 4 x 4 in a
    curved (twisted, tapered) map and capped on all six sides by planar trimmed caps over the tile's
    boundary curves (Massarwi et al. 2018, Section 6.2 item 1).
  * ``fig2d duck``: the same tile in the duck map, 4 x 4 per knot span (4 x 4 x 5 tiles), capped.
  * ``fig12``: two composition levels (Massarwi et al. 2018, Section 8, Fig. 12): the cross paved 2 x 2 x 1 in a
    curved map, every one of its 28 trivariates reduced to triquadratic (Section 6.3) and used as the
    deformation map of 2 x 2 x 2 hollow tiles, capped on every side that is a boundary of the first level.
Each: build time, surface time (welded triangles with the caps), triangles, closed / manifold, components,
the Euler characteristic against the one of the tube graph (2 - 2 x cycle rank), and peak memory.
Writes benchmarks/out/capped_models.json and, with renders, capped_<case>.png in benchmarks/out/figures
(docs/ with --figures).
"""

from __future__ import annotations

import resource
import time

from _common import figures_dir, print_table, run_cases, save_json

DOCS = figures_dir()  # benchmarks/out/figures; docs/ with --figures
CASES = ("fig2d", "fig2d duck", "fig12")


def _curved_map():
    from geometry import primitives as pr

    box = pr.box((1.0, 1.0, 1.6), degrees=(2, 2, 2))
    return pr.tapered(pr.twisted(box, 0.5, axis_point=(0.5, 0.5)), 0.6, axis_point=(0.5, 0.5))


def run(case: str, png: bool) -> dict:
    import numpy as np
    import pyvista  # noqa: F401  (imports are not the work measured)

    import tiling
    from geometry import compose
    from geometry.shapes.examples import duck
    from tiling import library as L

    t0 = time.perf_counter()
    extra = {}
    if case == "fig12":
        first = tiling.regular(_curved_map(), L.cross(), (2, 2, 1))
        ms = tiling.compose_levels(first, L.hollow_cross(), (2, 2, 2), degree=2, seal="cap")
        nodes, tubes = 8 * len(first.patches), 12 * len(first.patches) + 4 * len(first.interfaces)
        P = ms.patches[0]
        extra["degrees"] = f"tile {P.spline.degrees} -> {compose(P.outer, P.spline).degrees}"
    else:
        D, counts = (duck(), (4, 4, 1)) if "duck" in case else (_curved_map(), (4, 4, 4))
        ms = tiling.regular(D, L.hollow_cross(), counts, seal="cap")
        n = [c * (len(D.breakpoints(k)) - 1) for k, c in enumerate(counts)]
        nodes = int(np.prod(n))
        tubes = sum(nodes // c * (c - 1) for c in n)
        extra["degrees"] = f"tile {ms.patches[0].spline.degrees} -> {ms.patches[0].composed.degrees}"
    t_build = time.perf_counter() - t0
    t0 = time.perf_counter()
    mesh = ms.surface(samples=3)
    w = tiling.export.mesh_watertightness(mesh)
    t_surf = time.perf_counter() - t0
    row = {"case": case, "surfaces": len(ms.patches), "caps": len(ms.caps), "build s": t_build,
           "surface s": t_surf, "triangles": w["triangles"], "closed": "yes" if w["closed"] and w["manifold"] else "NO",
           "components": w["components"], "euler": w["euler_characteristic"],
           "euler of tube graph": 2 - 2 * (tubes - nodes + 1),
           "peak MiB": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024, **extra}
    if png:
        from geometry.io.files import offscreen_plotter, save_screenshot

        pl = offscreen_plotter((1100, 900))
        pl.add_mesh(mesh, color="#d9b38c", smooth_shading=True, split_sharp_edges=True)
        save_screenshot(pl, DOCS / f"capped_{case.replace(' ', '_')}.png", zoom=1.4)
    return row


def main():
    rows = run_cases(__file__, CASES, run, renders=True)
    if rows is None:
        return
    bad = [r["case"] for r in rows if r["closed"] != "yes" or r["components"] != 1
           or r["euler"] != r["euler of tube graph"]]
    print_table(rows, [("case", "s"), ("surfaces", "d"), ("caps", "d"), ("build s", ".2f"), ("surface s", ".2f"),
                       ("triangles", "d"), ("closed", "s"), ("components", "d"), ("euler", "d"),
                       ("euler of tube graph", "d"), ("peak MiB", ".0f")])
    for r in rows:
        print(f"{r['case']}: degrees {r['degrees']}")
    save_json("capped_models.json", rows)
    if bad or len(rows) != len(CASES):
        raise SystemExit(f"not one closed surface with the tube graph's Euler characteristic: {bad or 'a case failed'}")


if __name__ == "__main__":
    main()
