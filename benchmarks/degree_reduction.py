"""Lower-order approximation, Massarwi et al. 2018, Fig. 10 setting: tile degrees (3, 3, 2) in a (1, 1, 2) map.

    python benchmarks/degree_reduction.py

The cross tile (seven trivariates) at degrees (3, 3, 2), its inside bent so
that it is not affine, paved 1 x 1 x 2 into a curved map of degrees
(1, 1, 2): composed patches of degrees (12, 12, 8).  Each is reduced to
degree 2 and 3 (geometry.composition.reduction): deviation (reported on 17^3 points per
piece, and measured at 10^4 random points), control points before and after,
time; then steady heat with a manufactured temperature on the exact and on
the reduced models (L2 errors, time).  Writes benchmarks/out/degree_reduction.json.
"""

from __future__ import annotations

import time

import numpy as np

from _common import print_table, save_json

import tiling
from geometry import BSpline, MultiPatch, primitives as pr
from geometry.composition.reduction import reduce_model
from iga import HeatProblem
from tiling import library as L


def main():
    D = pr.box((1.0, 1.0, 2.0)).elevate_to((1, 1, 2))  # a curved map of degrees (1, 1, 2)
    cp = D.control_points.copy()
    cp[..., 0] += 0.3 * np.sin(cp[..., 2])
    cp[..., 1] += 0.1 * cp[..., 2] ** 2
    ms = tiling.regular(BSpline(D.degrees, D.knots, cp), L.bent_cross(), (1, 1, 2))
    t0 = time.perf_counter()
    ms.compose_all()
    t_comp = time.perf_counter() - t0
    T = lambda x: np.sin(x[:, 0]) * np.cos(x[:, 1]) * np.exp(0.5 * x[:, 2])  # noqa: E731
    f = lambda x: 1.75 * T(x)  # noqa: E731
    t0 = time.perf_counter()
    exact_err = HeatProblem(ms, source=f, degree_elevation=1).dirichlet("boundary", T).solve(tol=1e-12).l2_error(T)
    t_exact = time.perf_counter() - t0
    rng = np.random.default_rng(0)
    rows = [{"model": "exact (12, 12, 8)", "control points": sum(int(np.prod(p.composed.shape)) for p in ms.patches),
             "time s": t_comp, "heat L2 error": exact_err, "heat s": t_exact}]
    for q in (2, 3):
        t0 = time.perf_counter()
        red, rep = reduce_model(ms, q, check=17)
        t_red = time.perf_counter() - t0
        measured = 0.0
        for p, r in zip(ms.patches, red):
            x = p.composed.domain[:, 0] + rng.random((10_000 // len(red) + 1, 3)) * np.ptp(p.composed.domain, axis=1)
            measured = max(measured, float(np.linalg.norm(p.composed.evaluate(x)[:, :3] - r.evaluate(x)[:, :3],
                                                          axis=1).max()))
        t0 = time.perf_counter()
        err = (HeatProblem(MultiPatch.from_splines(red), source=f, degree_elevation=4 - q)
               .dirichlet("boundary", T).solve(tol=1e-12).l2_error(T))
        rows.append({"model": f"reduced to {q}", "control points": rep["control_points"][1], "time s": t_red,
                     "deviation": rep["deviation"], "deviation at 1e4 random": measured,
                     "heat L2 error": err, "heat s": time.perf_counter() - t0})
    print_table(rows, [("model", "s"), ("control points", "d"), ("time s", ".3f"), ("deviation", ".2e"),
                       ("deviation at 1e4 random", ".2e"), ("heat L2 error", ".2e"), ("heat s", ".2f")])
    print("(heat: manufactured T = sin x cos y exp(z/2), analysis degree 4 on every model)")
    save_json("degree_reduction.json", rows)


if __name__ == "__main__":
    main()
