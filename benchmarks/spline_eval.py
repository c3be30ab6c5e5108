"""Evaluation throughput of a degree-3 trivariate with 20^3 control points.

    python benchmarks/spline_eval.py [--points 1000000] [--repeat 3]

Prints points/s for scattered random points (values, first derivatives, a
NURBS) and for a tensor grid of the same size (sum factorisation), and writes
benchmarks/out/spline_eval.json.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np

from geometry import BSpline, knots as kn


def best_of(fn, repeat):
    times = []
    for _ in range(repeat):
        t = time.perf_counter(); fn(); times.append(time.perf_counter() - t)
    return min(times)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--points", type=int, default=10**6)
    ap.add_argument("--repeat", type=int, default=3)
    args = ap.parse_args(argv)
    rng = np.random.default_rng(0)
    U = kn.uniform_knots(3, 17)
    cp = rng.random((20, 20, 20, 3))
    s = BSpline((3, 3, 3), [U, U, U], cp)
    r = BSpline((3, 3, 3), [U, U, U], cp, rng.uniform(0.5, 2, (20, 20, 20)))
    x = rng.random((args.points, 3))
    m = round(args.points ** (1 / 3))
    axes = [np.linspace(0, 1, m)] * 3
    rows = []
    for label, fn, n in [
        ("values, scattered", lambda: s.evaluate(x), len(x)),
        ("jacobian, scattered", lambda: s.jacobian(x), len(x)),
        ("NURBS values, scattered", lambda: r.evaluate(x), len(x)),
        (f"values, {m}^3 tensor grid", lambda: s.evaluate_grid(axes), m**3),
    ]:
        t = best_of(fn, args.repeat)
        rows.append({"case": label, "points": n, "seconds": t, "points_per_s": n / t})
    print(f"{'case':32s} {'points':>9s} {'seconds':>9s} {'points/s':>12s}")
    for row in rows:
        print(f"{row['case']:32s} {row['points']:9d} {row['seconds']:9.3f} {row['points_per_s']:12.3e}")
    out = Path(__file__).parent / "out"
    out.mkdir(exist_ok=True)
    (out / "spline_eval.json").write_text(json.dumps(rows, indent=2))


if __name__ == "__main__":
    main()
