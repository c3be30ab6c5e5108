"""Stability of exact composition at high degree: the circularity experiment of Elber 2017, Fig. 13.

    python benchmarks/composition_stability.py [--max-order 10] [--points 20000]

A unit-cube polynomial trivariate T of tri-order d (the identity map of
[0,1]^3 written at degree d-1, so T(S) = S mathematically) and a rational
cylinder surface S of unit size (axis at x = y = 0.5, radius
0.5, height 1) of bi-order d are composed; the error in circularity of T(S) is
the largest deviation of the distance from the axis from 0.5, measured at
random points of the composed surface.  Orders start at 3 because an exact
rational circle needs degree >= 2.  Prints a table, writes
benchmarks/out/composition_stability.{json,png}.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from _common import print_table, pyplot, save_json, save_plot

from geometry import BSpline, compose, knots as kn, primitives as pr


def cylinder(order: int) -> BSpline:
    """Rational cylinder surface of bi-order ``order``: u around (4 quadrants), v along z."""
    p, U, P, w = pr.arc(0.5, 2 * np.pi, exact=True)
    P = P + [0.5, 0.5, 0.0]
    cp = np.stack([P, P + [0, 0, 1.0]], axis=1)  # (n, 2, 3)
    W = np.stack([w, w], axis=1)
    s = BSpline((p, 1), [U, kn.uniform_knots(1, 1)], cp, W)
    return s.elevate(0, order - 1 - p).elevate(1, order - 2)


def unit_cube(order: int) -> BSpline:
    return pr.box(degrees=(order - 1,) * 3)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--max-order", type=int, default=10)
    ap.add_argument("--points", type=int, default=20000)
    args = ap.parse_args(argv)
    rng = np.random.default_rng(0)
    x = rng.random((args.points, 2))
    rows = []
    for d in range(3, args.max_order + 1):
        S, T = cylinder(d), unit_cube(d)
        t = time.perf_counter()
        C = compose(T, S)
        dt = time.perf_counter() - t
        v = C(x)
        dev = np.abs(np.hypot(v[:, 0] - 0.5, v[:, 1] - 0.5) - 0.5).max()
        dev_in = np.abs(np.hypot(*(S(x)[:, :2] - 0.5).T) - 0.5).max()
        rows.append({"order d": d, "T(S) degrees": str(C.degrees), "control points": int(np.prod(C.shape)),
                     "circularity error": float(dev), "input S error": float(dev_in), "seconds": dt})
    print("Circularity of T(S): unit-cube trivariate T and rational cylinder S, both of order d")
    print_table(rows, [("order d", "d"), ("T(S) degrees", "s"), ("control points", "d"),
                       ("circularity error", ".2e"), ("input S error", ".2e"), ("seconds", ".2f")])
    save_json("composition_stability.json", rows)
    worst = max(r["circularity error"] for r in rows)
    print(f"largest deviation {worst:.2e} ({'below' if worst < 1e-12 else 'ABOVE'} 1e-12)")
    plt = pyplot()
    if plt is not None:
        fig, ax1 = plt.subplots(figsize=(6, 3.8))
        ds = [r["order d"] for r in rows]
        ax1.plot(ds, [r["circularity error"] for r in rows], "o-", color="tab:red", label="circularity error")
        ax1.set_xlabel("order d")
        ax1.set_ylabel("max | |x - axis| - r |", color="tab:red")
        ax2 = ax1.twinx()
        ax2.plot(ds, [int(r["T(S) degrees"].strip("()").split(",")[0]) + 1 for r in rows], "s--", color="tab:blue")
        ax2.set_ylabel("order of T(S)", color="tab:blue")
        ax1.set_title("Elber 2017, Fig. 13: exact composition stays circular")
        save_plot(fig, "composition_stability.png")


if __name__ == "__main__":
    main()
