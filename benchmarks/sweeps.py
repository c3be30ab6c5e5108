"""Round struts and helical fibres swept along composed axes (Elber 2017, Section 4 and Fig. 10).

    python benchmarks/sweeps.py [--figures]

Prints, for a body-centred and a cubic strut lattice in the duck and for the helical fibres of
Fig. 10, the struts, the sweep time, the tolerance beside the largest section error measured at
10^4 random points (distance to the true circle about the axis, in the axis's normal plane), and
the closedness of the welded surface; renders the bcc lattice to ``round_struts.png``.
"""

from __future__ import annotations

import time

import numpy as np

from geometry import primitives
from geometry.shapes import examples as shapes
from geometry.shapes.sweep import section_error
from tiling import library, regular, round_struts
from tiling.export import watertightness
from tiling.pictures import render_png

from _common import figures_dir


def _measured(struts, n=10_000, seed=0):
    rng = np.random.default_rng(seed)
    per = n // len(struts.struts.sweeps) + 1
    worst = 0.0
    for s in struts.struts.sweeps:
        lo, hi = s.axis.domain[0]
        worst = max(worst, float(section_error(s.surface, s.axis, s.radius, rng.random(per),
                                               lo + rng.random(per) * (hi - lo)).max()))
    return worst


def main():
    duck = shapes.duck()
    twisted = primitives.tapered(primitives.twisted(primitives.box((2.0, 2.0, 2.0), degrees=(2, 2, 2)), 0.8), 0.6)
    cases = [("bcc struts in the duck", duck, library.struts("bcc"), (2, 2, 1), 0.01),
             ("cubic struts in the duck", duck, library.struts("cubic"), (3, 3, 1), 0.01),
             ("Fig. 10 helical fibres", twisted, library.helix(), (3, 3, 2), 0.03)]
    print(f"{'case':28s} {'axes':>5s} {'sweeps':>6s} {'time s':>7s} {'tolerance':>10s} {'measured':>10s} closed")
    pictures = {}
    for name, D, tile, counts, radius in cases:
        ms = regular(D, tile, counts)
        t0 = time.perf_counter()
        struts = round_struts(ms, radius, tolerance=1e-3 * radius)
        dt = time.perf_counter() - t0
        closed = watertightness(struts)["closed"]
        print(f"{name:28s} {len(ms.patches):5d} {len(struts.struts.sweeps):6d} {dt:7.2f} "
              f"{struts.struts.tolerance:10.2e} {_measured(struts):10.2e} {closed}")
        pictures[name] = struts
    path = render_png(pictures["bcc struts in the duck"], figures_dir() / "round_struts.png", samples=4,
                      color_by="patch", window=(1000, 600))
    print(path)


if __name__ == "__main__":
    main()
