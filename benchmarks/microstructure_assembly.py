"""Micro-structure heat assembly: where the time goes on a regular paving.

    python benchmarks/microstructure_assembly.py [--tiles 4,4,2] [--refine 2] [--repeat 4]

A regular paving of the ``cross`` tile into a rational triquadratic box map
(2 x 2 x 2 elements, random weights; every Gauss point needs the map's value
and Jacobian), ``HeatProblem(..., refine=R)`` with k = 2 and f = 1,
Dirichlet on ``umin``.  Prints patches, unknowns, nnz, the cold and warm
(median of ``--repeat``) assembly times, and the warm times of the parts that
dominate: the deformation map's values and Jacobian at the Gauss points
(``BSpline.value_and_jacobian``), and the rest.  Writes
benchmarks/out/microstructure_assembly.json.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from _common import print_table, save_json

import tiling
from geometry import BSpline, primitives as pr
from tiling import library


def model(tiles):
    box = pr.box(degrees=(2, 2, 2), elements=(2, 2, 2), size=(2, 2, 1))
    w = np.random.default_rng(1).uniform(0.8, 1.25, box.coefficients.shape[:-1])
    D = BSpline(box.degrees, box.knots, box.coefficients, w)
    return tiling.regular(D, library.cross(0.3), tuple(tiles))


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--tiles", default="4,4,2", help="tiles per direction")
    ap.add_argument("--refine", type=int, default=2, help="knot-span bisections of every patch's space")
    ap.add_argument("--repeat", type=int, default=4, help="warm assemblies (median reported)")
    args = ap.parse_args(argv)
    from iga import HeatProblem
    from iga.app.memory import retain_freed_memory

    retain_freed_memory()
    m = model(int(v) for v in args.tiles.split(","))
    spent = {"map": 0.0}
    value_and_jacobian = BSpline.value_and_jacobian

    def timed(self, params):  # the deformation map's share of the assembly
        t = time.perf_counter()
        out = value_and_jacobian(self, params)
        spent["map"] += time.perf_counter() - t
        return out

    BSpline.value_and_jacobian = timed

    def assemble():
        spent["map"] = 0.0
        t = time.perf_counter()
        K, _, _ = HeatProblem(m, conductivity=2.0, source=1.0, refine=args.refine).dirichlet("umin", 0.0).assemble()
        return time.perf_counter() - t, spent["map"], K

    cold, _, K = assemble()
    runs = [assemble()[:2] for _ in range(args.repeat)]
    warm = float(np.median([r[0] for r in runs]))
    map_s = float(np.median([r[1] for r in runs]))
    row = {"patches": len(m.patches), "unknowns": K.shape[0], "nnz": int(K.nnz), "cold s": cold, "warm s": warm,
           "map value+Jacobian s": map_s, "rest s": warm - map_s, "warm runs s": [r[0] for r in runs]}
    print_table([row], [("patches", "d"), ("unknowns", "d"), ("nnz", "d"), ("cold s", ".2f"), ("warm s", ".2f"),
                        ("map value+Jacobian s", ".2f"), ("rest s", ".2f")])
    print("wrote", save_json("microstructure_assembly.json", row))


if __name__ == "__main__":
    main()
