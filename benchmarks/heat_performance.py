"""Assembly and solve performance: unit-cube Poisson, p = 2 and 3.

    python benchmarks/heat_performance.py [--sizes 30k,110k,475k] [--degrees 2,3] [--million]
                                          [--malloc retain|default|both] [--repeat 5] [--numpy]

Each case runs in a fresh subprocess (so timings and peak memory are per
case): the unit cube as one trivariate patch with N^3 elements of degree p
(DOFs (N+p)^3), -lap T = 1, T = 0 on the boundary.  First one
``HeatProblem(...).solve(solver="amg-cg", tol=1e-8)``, what a script pays:
"total s" (assembly + Dirichlet elimination + AMG set-up + CG), with its
parts and the process's peak memory at that point.  Then ``--repeat`` more
assemblies of a new problem of the same size ("warm", median): the cost once
one-time tables exist and freed memory is reused.  The "CSR floor" is the
time SciPy needs to build a CSR matrix with the same nnz from COO triplets,
the floor for any assembly that produces such a matrix (fastest of
``--repeat`` runs, so that it is compared warm with the warm assembly).
The floor runs come after the warm assemblies rather than between them:
interleaved, each allocation of one disturbs the other's reuse of freed
memory (at 1M unknowns both became 30% slower and the first floor paid
for fresh pages).  The JSON keeps every run.

``--malloc retain`` (default) applies :func:`iga.app.memory.retain_freed_memory`
in the case's process, as the ``iga`` CLI does; ``default`` keeps glibc's
behaviour; ``both`` runs every case both ways.  ``--numpy`` disables the
compiled (numba) assembly and elimination, to measure the NumPy/SciPy path.
``--million`` adds the 1M-unknown p = 2 case.  Writes
benchmarks/out/heat_performance.{json,png}.
"""

from __future__ import annotations

import argparse
import json
import resource
import sys
import time

import numpy as np

from _common import collect_rows, print_table, pyplot, save_json, save_plot

SIZES = {"30k": 31, "110k": 48, "475k": 78, "1M": 100}  # (N + p) per direction, p = 2; p = 3 uses one less element


def run_case(p: int, n_per_dir: int, tol: float, malloc: str = "retain", repeat: int = 5,
             numpy_only: bool = False) -> dict:
    if malloc == "retain":
        from iga.app.memory import retain_freed_memory

        retain_freed_memory()
    import scipy.sparse as sp

    from geometry import primitives as pr
    from iga import HeatProblem
    from iga.assembly import compiled as fast_assembly

    if numpy_only:
        fast_assembly.AVAILABLE = False
    N = n_per_dir - p
    cube = pr.box(degrees=(p,) * 3, elements=(N,) * 3)
    t = time.perf_counter()
    prob = HeatProblem(cube, source=1.0).dirichlet("boundary", 0.0)
    sol = prob.solve(solver="amg-cg", tol=tol)
    total = time.perf_counter() - t
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024**2  # GiB (Linux reports KiB)
    info, tm = sol.info["solver"], sol.record.timings
    cold = tm["assembly_volume"] + tm["assembly_faces"]
    del sol
    times = []
    K = None
    for _ in range(repeat):
        K = None  # drop the previous matrix first, as a script re-assembling would: its memory is reused
        t = time.perf_counter()
        K, f, _ = HeatProblem(cube, source=1.0).dirichlet("boundary", 0.0).assemble()
        times.append(time.perf_counter() - t)
    warm = float(np.median(times))
    nnz = K.nnz
    rows = np.repeat(np.arange(K.shape[0], dtype=np.int32), np.diff(K.indptr))
    floors = []
    for _ in range(max(repeat, 2)):  # fastest of several: the first one pays for fresh memory, as "cold" does
        t = time.perf_counter()
        sp.csr_matrix((K.data, (rows, K.indices)), shape=K.shape)
        floors.append(time.perf_counter() - t)
    floor = min(floors)
    return {"p": p, "malloc": malloc, "compiled": "yes" if (not numpy_only and fast_assembly.AVAILABLE) else "no", "dofs": prob.ndof,
            "nnz": int(nnz), "assembly cold s": cold, "assembly warm s": warm, "CSR floor s": floor,
            "warm/floor": warm / floor, "warm runs s": times, "floor runs s": floors,
            "elimination s": tm["constraints"], "AMG setup s": info["setup_s"],
            "CG s": info["solve_s"], "iterations": info["iterations"], "residual": info["residual"],
            "total s": total, "peak GiB": peak}


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--sizes", default="30k,110k,475k")
    ap.add_argument("--degrees", default="2,3")
    ap.add_argument("--million", action="store_true", help="add 1M unknowns at p = 2")
    ap.add_argument("--tol", type=float, default=1e-8)
    ap.add_argument("--malloc", choices=("retain", "default", "both"), default="retain",
                    help="allocator setting per case (see iga.app.memory)")
    ap.add_argument("--repeat", type=int, default=5, help="warm assemblies per case (median reported)")
    ap.add_argument("--numpy", action="store_true", help="disable the compiled (numba) assembly and elimination")
    ap.add_argument("--case", help=argparse.SUPPRESS)  # internal: "p,n" run in this process
    args = ap.parse_args(argv)
    if args.case:
        p, n = (int(v) for v in args.case.split(","))
        print(json.dumps(run_case(p, n, args.tol, args.malloc, args.repeat, args.numpy)))
        return
    cases = [(p, SIZES[s] - (p - 2)) for p in (int(v) for v in args.degrees.split(",")) for s in args.sizes.split(",")]
    if args.million:
        cases.append((2, SIZES["1M"]))
    mallocs = ("retain", "default") if args.malloc == "both" else (args.malloc,)
    jobs = [([sys.executable, __file__, "--case", f"{p},{n}", "--tol", str(args.tol), "--malloc", malloc, "--repeat",
              str(args.repeat)] + (["--numpy"] if args.numpy else []), f"case p={p} n={n}")
            for (p, n), malloc in ((c, m) for c in cases for m in mallocs)]
    rows = collect_rows(jobs, lambda r: f"p={r['p']} dofs={r['dofs']} malloc={r['malloc']}: total {r['total s']:.2f} "
                        f"s, warm assembly {r['assembly warm s']:.2f} s")
    print("\nUnit-cube Poisson, one patch, AMG-CG (pyamg smoothed aggregation) to", args.tol)
    print_table(rows, [("p", "d"), ("malloc", "s"), ("compiled", "s"), ("dofs", "d"), ("nnz", "d"),
                       ("assembly cold s", ".2f"), ("assembly warm s", ".2f"), ("CSR floor s", ".3f"),
                       ("warm/floor", ".1f"), ("elimination s", ".2f"), ("AMG setup s", ".2f"), ("CG s", ".2f"),
                       ("iterations", "d"), ("total s", ".1f"), ("peak GiB", ".2f")])
    save_json("heat_performance.json", rows)
    plt = pyplot()
    if plt is not None and rows:
        fig, ax = plt.subplots(figsize=(6, 4))
        for p in sorted({r["p"] for r in rows}):
            rr = [r for r in rows if r["p"] == p and r["malloc"] == mallocs[0]]
            ax.loglog([r["dofs"] for r in rr], [r["assembly warm s"] for r in rr], "o-", label=f"assembly p={p}")
            ax.loglog([r["dofs"] for r in rr], [r["total s"] for r in rr], "s--", label=f"total (one solve) p={p}")
        ax.set_xlabel("unknowns")
        ax.set_ylabel("seconds")
        ax.legend()
        save_plot(fig, "heat_performance.png")


if __name__ == "__main__":
    main()
