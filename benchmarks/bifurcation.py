"""Adaptive bifurcation in the duck (Massarwi et al. 2018, Section 5): layered parametric tilings with a heat solve.

    python benchmarks/bifurcation.py            # table, JSON, renders
    python benchmarks/bifurcation.py --no-png

Cases, each in a fresh subprocess (peak memory is per case, imports included):
  * parametric 1-2, 1-4a and 1-4b bifurcation tilings of the duck map with
    epsilon = 0.35 (Algorithm 1 layers; Fig. 15/17 analogues), then steady
    heat: 100 C on the tail layer's end faces, 20 C on the beak's, k = 20 W/(m K),
    degree elevated to 2 and refined once.
  * implicit bifurcation structures over Algorithm 1's subdivision of the duck
    (epsilon = 0.35), capped: the canonical one (Fig. 16(b) analogue) and a
    randomised one (alpha = 0.65, Fig. 16(c)): build and surface time, triangles,
    closedness, components; timed after a garbage collection (:func:`_common.settle`:
    the full collection the imports leave pending, 60-130 ms, is not the construction's).
The paper reports under 4 s and 104 MB for its Fig. 16(b) duck with
bifurcation (2018 hardware).  Writes benchmarks/out/bifurcation.json and,
with renders, bifurcation_duck_<kind>.png coloured by level and
implicit_bifurcation_duck*.png in benchmarks/out/figures (docs/ with --figures).
"""

from __future__ import annotations

import resource
import time

from _common import figures_dir, print_table, run_cases, save_json, settle

DOCS = figures_dir()  # benchmarks/out/figures; docs/ with --figures
CASES = ("1-2", "1-4a", "1-4b", "implicit", "implicit random")


def run_implicit(case: str, png: bool) -> dict:
    import pyvista  # noqa: F401  (imports are not the work measured)
    import vtkmodules.vtkFiltersCore  # noqa: F401  (nor the module of the contour filter, which pyvista loads on
    # its first contour: 10-15 ms of a cold surface)

    import tiling
    from geometry import primitives

    D = primitives.duck()
    alpha = 0.65 if "random" in case else 0.0
    settle()  # the collection the imports left pending is not the construction's
    t0 = time.perf_counter()
    s = tiling.implicit_bifurcation(D, 0.35, alpha=alpha, seed=0)
    t1 = time.perf_counter()
    mesh = s.surface()
    t2 = time.perf_counter()
    w = tiling.export.mesh_watertightness(mesh)
    row = {"case": f"{case} (Fig. 16{'c' if alpha else 'b'})", "tiles": len(s.cells), "build s": t1 - t0,
           "surface s": t2 - t1, "total s": t2 - t0, "triangles": w["triangles"], "closed": bool(w["closed"]),
           "components": w["components"], "peak MiB": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024}
    if png:
        s.render_png(DOCS / f"implicit_bifurcation_duck{'_random' if alpha else ''}.png", color_by="w")
        if not alpha:
            tiling.implicit_bifurcation(D, 0.35, cap=False).render_png(DOCS / "implicit_bifurcation_duck_open.png",
                                                                        color_by="w")
    return row


def run(case: str, png: bool) -> dict:
    import numpy as np

    import tiling
    from geometry import primitives
    from iga import HeatProblem

    if case.startswith("implicit"):
        return run_implicit(case, png)
    D = primitives.duck()
    t0 = time.perf_counter()
    ms = tiling.bifurcation(D, 0.35, case)
    t1 = time.perf_counter()
    s = (HeatProblem(ms, conductivity=20.0, degree_elevation=1, refine=1)
         .dirichlet("wmin", 100.0).dirichlet("wmax", 20.0).solve())
    t2 = time.perf_counter()
    w = tiling.export.watertightness(ms)
    row = {"case": f"parametric {case}", "layers": len(ms.info["levels"]), "levels": max(ms.info["levels"]),
           "tiles": ms.n_tiles, "patches": len(ms.patches),
           "branch interfaces": sum(i.kind == "branch" for i in ms.interfaces), "build s": t1 - t0,
           "heat s": t2 - t1, "DOFs": int(s.info["free_dofs"]), "heat flow W": float(-s.flux("wmin")),
           "balance": float(s.info["balance"]["relative_error"]), "closed": bool(w["closed"]),
           "components": w["components"], "peak MiB": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024}
    assert np.isfinite(row["heat flow W"]) and row["balance"] < 1e-8
    if png:
        tiling.pictures.render_png(ms, DOCS / f"bifurcation_duck_{case}.png", color_by="level")
    return row


def main():
    rows = run_cases(__file__, CASES, run, renders=True)
    if rows is None:  # (a child run of one case)
        return
    print_table([r for r in rows if "heat s" in r],
                [("case", "s"), ("layers", "d"), ("levels", "d"), ("tiles", "d"), ("patches", "d"),
                 ("branch interfaces", "d"), ("build s", ".3f"), ("heat s", ".2f"), ("DOFs", "d"),
                 ("heat flow W", ".4g"), ("balance", ".1e"), ("components", "d"), ("peak MiB", ".0f")])
    print()
    print_table([r for r in rows if "surface s" in r],
                [("case", "s"), ("tiles", "d"), ("build s", ".2f"), ("surface s", ".2f"), ("total s", ".2f"),
                 ("triangles", "d"), ("components", "d"), ("peak MiB", ".0f")])
    print("Massarwi et al. 2018: Fig. 16(b) under 4 s and 104 MB (2018 hardware)")
    save_json("bifurcation.json", rows)


if __name__ == "__main__":
    main()
