"""Spline-aware preconditioners against AMG-CG, same run, same tolerance.

    python benchmarks/preconditioners.py [--geometry twisted,cube] [--quick] [--no-micro | --micro-only]

Each (case, method) runs in a fresh subprocess, so peak memory is per method
(the process's peak: assembly included).  Methods: ``amg-cg`` (pyamg smoothed
aggregation, today's default above 2,000 unknowns), ``fd-cg`` (fast
diagonalization, Sangalli and Tani 2016: one patch only), ``gmg-cg``
(geometric multigrid on knot-insertion prolongations, Galerkin coarse
operators, Chebyshev-Jacobi smoothing).

* One patch: -lap T = 1, T = 0 on the boundary, degree p = 2, 3, 4, sizes up
  to 1M unknowns (p = 2) and 456k (p = 3), on the unit cube (where fast
  diagonalization is exact) and on a twisted cube (0.6 rad: a curved
  geometry, so it is a preconditioner, not a solver).
* Micro-structures: the 3-level T2 heat sink (refine 1) and a 10 x 10 x 10
  cross lattice in a twisted map (degree 2, refine 1): 80 C on the base
  (sink) or one side (lattice), convection on the fins (sink) or on the
  opposite side (lattice); the temperatures of every method are
  compared with AMG-CG's.
"solve" is the structure (Kronecker factors or multigrid levels, built by iga) + the solver's set-up + the
iterations; assembly is excluded (it is the same for all).
Writes benchmarks/out/preconditioners.json.
"""

from __future__ import annotations

import json
import resource
import sys
import time

import numpy as np

from _common import out_dir, print_table, run_child, save_json

METHODS = ("amg-cg", "fd-cg", "gmg-cg")
SIZES = {2: (31, 48, 78, 100), 3: (31, 48, 77), 4: (31, 48)}  # (N + p) per direction: 30k .. 1M unknowns
TOL = 1e-8


def _patch(geometry: str, p: int, n: int):
    from geometry import primitives as pr

    N = n - p
    if geometry == "cube":
        return pr.box(degrees=(p,) * 3, elements=(N,) * 3)
    return pr.refined(pr.twisted(pr.box((1.0, 1.0, 1.0), degrees=(p,) * 3), 0.6, axis_point=(0.5, 0.5)), (N,) * 3)


def _problem(case: str):
    from geometry import primitives as pr
    from iga import HeatProblem
    import tiling
    from tiling import library as L

    kind, *rest = case.split(":")
    if kind == "patch":
        geometry, p, n = rest[0], int(rest[1]), int(rest[2])
        return HeatProblem(_patch(geometry, p, n), source=1.0).dirichlet("boundary", 0.0)
    if kind == "sink":
        ms = tiling.hierarchical(pr.box((0.06, 0.06, 0.03)), L.heat_sink_t2(), (4, 4), levels=3)
        return HeatProblem(ms, conductivity=200.0, refine=1).dirichlet("branch-in", 80.0).robin("exterior", 50.0, 20.0)
    twisted = pr.twisted(pr.box((1.0, 1.0, 1.0), degrees=(2, 2, 2)), 0.3, axis_point=(0.5, 0.5))
    ms = tiling.regular(twisted, L.cross(), (10, 10, 10))
    return (HeatProblem(ms, conductivity=20.0, degree_elevation=1, refine=1)
            .dirichlet("umin", 80.0).robin("umax", 50.0, 20.0))


def run_one(case: str, method: str) -> dict:
    from iga.app.memory import retain_freed_memory

    retain_freed_memory()
    problem = _problem(case)
    t0 = time.perf_counter()
    s = problem.solve(solver=method, tol=TOL, maxiter=2000)
    wall = time.perf_counter() - t0
    info = s.info["solver"]
    np.save(out_dir() / f"_u_{case.replace(':', '_')}_{method}.npy", s.u)
    structure = s.record.timings.get("solver_structure", 0.0)  # Kronecker factors / multigrid levels (iga side)
    return {"case": case, "method": method, "dofs": int(s.record.reduced_dofs), "iterations": info["iterations"],
            "structure s": structure, "setup s": info["setup_s"], "iterate s": info["solve_s"],
            "solve s": structure + info["setup_s"] + info["solve_s"],
            "wall s": wall, "levels": info.get("mg_levels", ""),
            "peak MiB": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024}


def main():
    if len(sys.argv) > 3 and sys.argv[1] == "--one":
        print(json.dumps(run_one(sys.argv[2], sys.argv[3])))
        return
    geometries = ["twisted"]
    for i, a in enumerate(sys.argv):
        if a == "--geometry":
            geometries = sys.argv[i + 1].split(",")
    quick = "--quick" in sys.argv
    cases = [f"patch:{g}:{p}:{n}" for g in geometries for p, ns in SIZES.items() for n in (ns[:2] if quick else ns)]
    if "--no-micro" not in sys.argv:
        cases += ["sink", "lattice"]
    if "--micro-only" in sys.argv:
        cases = ["sink", "lattice"]
    rows = []
    for case in cases:
        for method in METHODS:
            if method == "fd-cg" and not case.startswith("patch"):
                continue  # one patch only
            row = run_child([sys.executable, __file__, "--one", case, method], f"{case} {method}")
            if row is None:
                continue
            ref = out_dir() / f"_u_{case.replace(':', '_')}_amg-cg.npy"
            if ref.exists():
                a, b = np.load(ref), np.load(out_dir() / f"_u_{case.replace(':', '_')}_{method}.npy")
                row["max |T - T_amg| / max |T|"] = float(np.abs(a - b).max() / max(np.abs(a).max(), 1e-300))
            base = next((r for r in rows if r["case"] == case and r["method"] == "amg-cg"), None)
            row["speed-up vs amg"] = base["solve s"] / row["solve s"] if base else 1.0
            rows.append(row)
            print(f"{case:22s} {method:7s} dofs {row['dofs']:>9,}  it {row['iterations']:>4}  "
                  f"solve {row['solve s']:7.2f} s  x{row['speed-up vs amg']:.1f}  peak {row['peak MiB']:.0f} MiB",
                  flush=True)
    for f in out_dir().glob("_u_*.npy"):
        f.unlink()
    print(f"\nSame tolerance {TOL:g} for every method; solve = structure + set-up + iterations.")
    print_table(rows, [("case", "s"), ("method", "s"), ("dofs", "d"), ("iterations", "d"), ("structure s", ".2f"),
                       ("setup s", ".2f"),
                       ("iterate s", ".2f"), ("solve s", ".2f"), ("speed-up vs amg", ".1f"), ("levels", ""),
                       ("max |T - T_amg| / max |T|", ".1e"), ("peak MiB", ".0f")])
    save_json("preconditioners.json", rows)


if __name__ == "__main__":
    main()
