"""Convergence study: manufactured solution on a curved patch, p = 1..4.

    python benchmarks/convergence.py [--degrees 1,2,3,4] [--max-refine 5]

Geometry: the exact NURBS quarter annulus shell (r in [1, 2], height 1).
Conductivity k = 1 + (x^2 + y^2) / 2 (variable), exact temperature
T = exp(x/2) sin(0.7 y + 0.3 z), source f = -div(k grad T), T = T_exact on
the whole boundary (L2-projected).  The solution space has degree p in every
direction and 2^r elements per direction.  Prints errors and rates per level
(rates over the last two refinements should be p + 1 in L2 and p in H1) and
A second study runs a smooth manufactured solution across a 3-level
hierarchy of T2 tiles (identity, branch and C0 constraints): its L2 rate
must be p + 1 = 3, which shows the constraints couple what must be coupled.
Writes benchmarks/out/convergence.{json,png}.
"""

from __future__ import annotations

import argparse
import sys
import time

import numpy as np

from _common import print_table, pyplot, save_json, save_plot

from iga import HeatProblem
from iga.manufactured import quarter_annulus

MS = quarter_annulus()
ANNULUS, k_var, T_exact, grad_exact, f_exact = MS.geometry, MS.conductivity, MS.temperature, MS.gradient, MS.source


def study(p: int, levels) -> list[dict]:
    rows = []
    for r in levels:
        t = time.perf_counter()
        prob = HeatProblem(ANNULUS, conductivity=k_var, source=f_exact, degree=p, refine=r)
        s = prob.dirichlet("boundary", T_exact).solve()
        row = {"p": p, "refine": r, "elements/dir": 2**r, "dofs": prob.ndof, "L2 error": s.l2_error(T_exact),
               "H1 error": s.h1_error(grad_exact), "seconds": time.perf_counter() - t}
        if rows:
            row["L2 rate"] = float(np.log2(rows[-1]["L2 error"] / row["L2 error"]))
            row["H1 rate"] = float(np.log2(rows[-1]["H1 error"] / row["H1 error"]))
        rows.append(row)
        print(f"p={p} r={r} dofs={prob.ndof} L2={row['L2 error']:.3e} H1={row['H1 error']:.3e}", flush=True)
    return rows


def hierarchy_study(tile="heat_sink_t2", counts=(2, 1), levels_of_refinement=(0, 1, 2, 3),
                    quadrature_extra=0) -> list[dict]:
    """Smooth manufactured solution across a 3-level hierarchy (identity, branch and C0 constraints).

    Row ``refine = -1`` is the patch test: a linear temperature, whose error should be round-off.
    """
    import tiling
    from geometry import primitives as pr
    from tiling import library as L

    D = pr.box((2.0, 1.0, 1.5), degrees=(1, 1, 1))
    ms = tiling.hierarchical(D, getattr(L, tile)(), counts, 3)

    def T(x):
        return np.sin(x[:, 0]) * np.cos(0.8 * x[:, 1]) * np.exp(0.3 * x[:, 2])

    def f(x):  # -lap T with k = 1
        return (1 + 0.64 - 0.09) * T(x)

    def linear(x):
        return 1 + 2 * x[:, 0] - x[:, 1] + 0.5 * x[:, 2]

    patch = HeatProblem(ms, quadrature_extra=quadrature_extra).dirichlet("boundary", linear).solve(tol=1e-12)
    rows = [{"tile": tile, "refine": -1, "dofs": patch.problem.ndof, "L2 error": patch.l2_error(linear),
             "patches": len(ms.patches)}]
    for r in levels_of_refinement:
        t = time.perf_counter()
        prob = HeatProblem(ms, source=f, refine=r, quadrature_extra=quadrature_extra)
        s = prob.dirichlet("boundary", T).solve(tol=1e-12)
        row = {"tile": tile, "p": 2, "refine": r, "dofs": prob.ndof, "patches": len(ms.patches),
               "L2 error": s.l2_error(T), "seconds": time.perf_counter() - t}
        if len(rows) > 1:
            row["L2 rate"] = float(np.log2(rows[-1]["L2 error"] / row["L2 error"]))
        rows.append(row)
        print(f"{tile} r={r} dofs={prob.ndof} L2={row['L2 error']:.3e}", flush=True)
    return rows


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--degrees", default="1,2,3,4")
    ap.add_argument("--max-refine", type=int, default=5)
    args = ap.parse_args(argv)
    rows = []
    for p in (int(v) for v in args.degrees.split(",")):
        rows += study(p, range(max(1, args.max_refine - 3), args.max_refine + 1))
    print("\nManufactured solution on the NURBS quarter annulus, variable k")
    print_table(rows, [("p", "d"), ("refine", "d"), ("dofs", "d"), ("L2 error", ".3e"), ("L2 rate", ".2f"),
                       ("H1 error", ".3e"), ("H1 rate", ".2f"), ("seconds", ".1f")])
    ok = True
    for p in sorted({r["p"] for r in rows}):
        last = [r for r in rows if r["p"] == p][-1]
        good = abs(last["L2 rate"] - (p + 1)) < 0.2 and abs(last["H1 rate"] - p) < 0.2
        ok &= good
        print(f"p={p}: last rates L2 {last['L2 rate']:.2f} (expect {p + 1}), H1 {last['H1 rate']:.2f} (expect {p})"
              f" -> {'optimal' if good else 'NOT within 0.2'}")
    hier = []
    for tile, counts, refs, qe in (("heat_sink_t2", (2, 1), (0, 1, 2, 3), 0),
                                   ("skinned_branching", (1, 1), (0, 1, 2), 1)):
        rows_t = hierarchy_study(tile, counts, refs, qe)
        patch, conv = rows_t[0], rows_t[1:]
        print(f"\nSmooth solution across a 3-level {tile} hierarchy ({patch['patches']} tiles, lowest tile degree 2, "
              f"quadrature_extra={qe}): L2 rate should be 3; patch test (linear T) error {patch['L2 error']:.1e}")
        print_table(conv, [("refine", "d"), ("dofs", "d"), ("L2 error", ".3e"), ("L2 rate", ".2f"),
                           ("seconds", ".1f")])
        ok &= abs(conv[-1]["L2 rate"] - 3) < 0.2 and patch["L2 error"] < 1e-9
        hier += rows_t
    save_json("convergence.json", {"annulus": rows, "hierarchy": hier})
    plt = pyplot()
    if plt is not None:
        fig, axs = plt.subplots(1, 2, figsize=(9, 3.8))
        for p in sorted({r["p"] for r in rows}):
            rr = [r for r in rows if r["p"] == p]
            h = [1 / r["elements/dir"] for r in rr]
            axs[0].loglog(h, [r["L2 error"] for r in rr], "o-", label=f"p={p}")
            axs[1].loglog(h, [r["H1 error"] for r in rr], "o-", label=f"p={p}")
        for ax, t in zip(axs, ["L2 error", "H1 seminorm error"]):
            ax.set_xlabel("h (parameter)")
            ax.set_title(t)
            ax.invert_xaxis()
            ax.legend()
        save_plot(fig, "convergence.png")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
