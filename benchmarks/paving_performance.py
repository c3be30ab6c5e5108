"""Tiling performance: wall time and peak memory, including exact composition.

    python benchmarks/paving_performance.py

Cases (each in a fresh subprocess, so peak memory is per case):
  * the Fig. 11(b) circular heat sink: tile T1, 16 x 1 copies, 3 levels
  * a 10 x 10 x 10 regular paving of the cross tile into a tricubic map
  * a large hierarchy: tile T2 on 8 x 8 cells of a flat box, 4 levels (5,440 patches, 5,376 branch links)
  * a large lattice: 21 x 21 x 21 cross tiles in a twisted map (64,827 patches; the 1M-unknown model of
    ``mpi_scaling.py``)
All are paved and every patch is composed exactly into the map
(``Microstructure.compose_all``, batched per tile patch).  Massarwi et al. 2018 report
under 5 s per example (2018 hardware, single thread).  Writes
benchmarks/out/paving_performance.json.
"""

from __future__ import annotations

import resource
import time

import numpy as np

from _common import print_table, run_cases, save_json
from heat_sink_maps import circular_map

import tiling
from tiling import library as L


def tricubic_map():
    from geometry import BSpline, primitives as pr

    b = pr.box((1.0, 1.0, 1.0), degrees=(3, 3, 3))
    cp = b.control_points.copy()
    cp[..., 2] += 0.15 * np.sin(np.pi * cp[..., 0]) * np.sin(np.pi * cp[..., 1])
    return BSpline(b.degrees, b.knots, cp)


def run(case: str) -> dict:
    t0 = time.perf_counter()
    from geometry import primitives as pr

    if case == "fig11b":
        ms = tiling.hierarchical(circular_map(), L.heat_sink_t1(), (4, 1), 3, scale=0.5)
    elif case == "T2 8x8, 4 levels":
        ms = tiling.hierarchical(pr.box((1.0, 1.0, 0.25)), L.heat_sink_t2(), (8, 8), 4)
    elif case == "cross 21^3":
        twisted = pr.twisted(pr.box((1.0, 1.0, 1.0), degrees=(2, 2, 2)), 0.3, axis_point=(0.5, 0.5))
        ms = tiling.regular(twisted, L.cross(), (21, 21, 21))
    else:
        ms = tiling.regular(tricubic_map(), L.cross(), (10, 10, 10))
    t1 = time.perf_counter()
    composed = ms.compose_all()
    t2 = time.perf_counter()
    cps = sum(int(np.prod(c.shape)) for c in composed)
    return {"case": case, "tiles": ms.n_tiles, "patches": len(ms.patches), "interfaces": len(ms.interfaces),
            "composed control points": cps, "degrees": str(composed[0].degrees), "paving s": t1 - t0,
            "composition s": t2 - t1, "total s": t2 - t0,
            "peak MiB": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024}


def main():
    rows = run_cases(__file__, ("fig11b", "cross10", "T2 8x8, 4 levels", "cross 21^3"), run)
    if rows is None:  # (a child run of one case)
        return
    print_table(rows, [("case", "s"), ("tiles", "d"), ("patches", "d"), ("interfaces", "d"),
                       ("composed control points", "d"), ("degrees", "s"), ("paving s", ".2f"),
                       ("composition s", ".2f"), ("total s", ".2f"), ("peak MiB", ".0f")])
    save_json("paving_performance.json", rows)


if __name__ == "__main__":
    main()
