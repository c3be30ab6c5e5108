"""Throughput of exact batched composition, against splinepy where installed.

    python benchmarks/composition.py [--placements 1000] [--splinepy-samples 30]

Cases (all into one tricubic Bezier piece of a perturbed unit-cube map):
  * tri-quadratic trivariate tile -> degree (18, 18, 18), 6859 control points
  * bicubic surface tile          -> degree (27, 27)
  * cubic curve tile              -> degree 27
Our ``compose_many`` composes all placements in one vectorised batch (the least of three batches is
reported, the first beside it: splinepy's figure is the median of its calls).  When
the ``splinepy`` package is importable, a random sample of the same
placements is composed with ``splinepy.Bezier.compose`` in the same run; the
table reports per-composition times, the speed ratio and the largest
control-point difference.  Writes benchmarks/out/composition.{json,png}.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from _common import print_table, pyplot, save_json, save_plot

from geometry import BSpline, compose_many, knots as kn


def bezier(degrees, cp):
    return BSpline(degrees, [kn.uniform_knots(p, 1) for p in degrees], cp)


def make_case(rng, dim, p):
    grid = np.stack(np.meshgrid(*[np.linspace(0.1, 0.9, p + 1)] * dim, indexing="ij"), -1)
    pts = np.zeros(grid.shape[:-1] + (3,))
    pts[..., :dim] = grid
    if dim < 3:  # curve / surface tile: lift into the cube with a wavy third coordinate
        pts[..., 2] = 0.5 + 0.3 * rng.uniform(-1, 1, grid.shape[:-1])
    if dim < 2:
        pts[..., 1] = 0.5 + 0.3 * rng.uniform(-1, 1, grid.shape[:-1])
    pts += 0.05 * rng.uniform(-1, 1, pts.shape)
    return bezier((p,) * dim, np.clip(pts, 0, 1))


def splinepy_compose(outer: BSpline, inner: BSpline, M):
    import splinepy

    def sp_bezier(s, cps):
        # splinepy orders control points with the first parametric direction fastest
        flat = np.transpose(cps, tuple(reversed(range(s.dim))) + (s.dim,)).reshape(-1, cps.shape[-1])
        return splinepy.Bezier(degrees=list(s.degrees), control_points=flat)

    placed = inner.points @ M[:, :3].T + M[:, 3]
    so, si = sp_bezier(outer, outer.points), sp_bezier(inner, placed)
    t = time.perf_counter()
    res = so.compose(si)
    dt = time.perf_counter() - t
    return dt, np.asarray(res.control_points), list(res.degrees)


def ours_flat(s: BSpline):
    return np.transpose(s.points, tuple(reversed(range(s.dim))) + (s.dim,)).reshape(-1, 3)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--placements", type=int, default=1000)
    ap.add_argument("--splinepy-samples", type=int, default=30, help="placements also run through splinepy")
    args = ap.parse_args(argv)
    rng = np.random.default_rng(0)
    U = np.stack(np.meshgrid(*[np.linspace(0, 1, 4)] * 3, indexing="ij"), -1)
    outer = bezier((3, 3, 3), U + 0.04 * rng.uniform(-1, 1, U.shape))
    n = args.placements
    P = np.zeros((n, 3, 4))
    s = rng.uniform(0.05, 0.2, (n, 3))
    P[:, [0, 1, 2], [0, 1, 2]] = s
    P[:, :, 3] = rng.uniform(0, 1, (n, 3)) * (1 - s)
    try:
        import splinepy  # noqa: F401

        have_sp = True
    except ImportError:
        have_sp = False
        print("(splinepy not installed: pip install -e '.[bench]' to compare)")
    rows = []
    for label, dim, p in [("trivariate (2,2,2)", 3, 2), ("surface (3,3)", 2, 3), ("curve 3", 1, 3)]:
        tile = make_case(rng, dim, p)
        compose_many(outer, tile, P[:2])  # warm-up (allocations, caches)
        runs = []
        for _ in range(3):  # the least of three batches, as splinepy's median of warm calls; the first pays for
            t = time.perf_counter()  # its fresh output pages (33 MB at (18, 18, 18)), 30-40% more on this VM
            res = compose_many(outer, tile, P)
            runs.append((time.perf_counter() - t) / n)
        ours = min(runs)
        row = {"case": label, "result degrees": str(res[0].degrees), "control points": int(np.prod(res[0].shape)),
               "ours ms": ours * 1e3, "ours first ms": runs[0] * 1e3, "placements/s": 1 / ours}
        if have_sp:
            idx = rng.choice(n, min(n, args.splinepy_samples), replace=False)
            times, diffs = [], []
            for i in idx:
                dt, cps, degs = splinepy_compose(outer, tile, P[i])
                assert tuple(degs) == res[i].degrees, (degs, res[i].degrees)
                times.append(dt)
                diffs.append(np.abs(cps - ours_flat(res[i])).max())
            row.update({"splinepy ms": np.median(times) * 1e3, "speed-up": np.median(times) / ours,
                        "max |dCP|": float(max(diffs))})
        rows.append(row)
    cols = [("case", "s"), ("result degrees", "s"), ("control points", "d"), ("ours ms", ".3f"),
            ("ours first ms", ".3f"), ("placements/s", ".0f"), ("splinepy ms", ".3f"), ("speed-up", ".1f"),
            ("max |dCP|", ".1e")]
    print(f"\n{n} placements into a tricubic Bezier piece (times per composition)")
    print_table(rows, cols)
    save_json("composition.json", rows)
    plt = pyplot()
    if plt is not None:
        fig, ax = plt.subplots(figsize=(6, 3.5))
        x = np.arange(len(rows))
        ax.bar(x - 0.2, [r["ours ms"] for r in rows], 0.4, label="compose_many (batched)")
        if have_sp:
            ax.bar(x + 0.2, [r["splinepy ms"] for r in rows], 0.4, label="splinepy Bezier.compose")
        ax.set_xticks(x, [r["case"] for r in rows])
        ax.set_yscale("log")
        ax.set_ylabel("ms per composition")
        ax.legend()
        save_plot(fig, "composition.png")


if __name__ == "__main__":
    main()
