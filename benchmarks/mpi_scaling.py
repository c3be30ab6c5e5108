"""Strong scaling of the distributed assembly and solve on PETSc, on this machine's ranks.

    python benchmarks/mpi_scaling.py [--ranks 1,2,4] [--cases sink,lattice,elastic] [--repeat N] [--quick]
                                     [--estimate-only]

Needs the extra ``[mpi]`` (petsc4py, mpi4py and an ``mpiexec``).  Cases:
  * ``sink``: the circular heat sink of ``iga demo heat-sink`` at ``--refine 3`` (its pipeline, solver petsc;
    ``--quick``: ``--refine 1``);
  * ``lattice``: a 21 x 21 x 21 cross lattice in a twisted map at degree 2 (about 1M unknowns;
    ``--quick``: 6 x 6 x 6);
  * ``elastic``: that lattice's map with 15 x 15 x 15 crosses, elastic (aluminium, clamped at u = 0, a
    traction at u = 1; about 1.1M unknowns; ``--quick``: 4 x 4 x 4), GAMG with the rigid modes.
For each rank count the case runs under ``mpiexec -n R`` with ``solver="petsc"`` (CG + GAMG, tolerance
1e-8; R = 1 takes the same distributed path on one process): time per stage (model, spaces and regularity, assembly of the
rank's patches, constraints and Dirichlet data, matrix build + GAMG set-up, CG), iterations, and peak
memory per rank (max over ranks), and above a fixed floor against 1/R of the single rank's memory above
it; two floors: the memory after the imports with MPI, PETSc and numba's compiler initialised (every large
model loads numba, about 100 MiB; the smallest model alone would not), and the same program's peak
on the smallest model (``--floor``: its libraries, compiled kernels and MPI buffers, run beside each case).  From these runs, an
estimate for 10^7 and 10^8 unknowns on 16 and 128 ranks (:func:`estimate`: the replicated stages scale
with the unknowns, the distributed work with the unknowns per rank; memory ``a + b / R`` fitted to the two
largest rank counts, ``a`` the replicated part): a model, not a measurement.
``--repeat N`` runs every configuration N times and keeps the smallest time and peak of each column
(:func:`best_of`).  Writes benchmarks/out/mpi_scaling.json.
"""

from __future__ import annotations

import json
import resource
import sys
import time
from pathlib import Path

from _common import collect_rows, print_table, save_json


def run_case(case: str, size: str) -> None:
    """One case on the ranks of the current ``mpiexec`` (rank 0 prints the JSON row); ``size``: "full",
    "quick" or "floor" (the smallest model: the program's fixed memory, libraries and compiled kernels)."""
    t0 = time.perf_counter()
    import tempfile

    import tiling
    from geometry import primitives as pr
    from iga import HeatProblem
    from iga.distributed.solve import load_petsc, world
    from iga.app.pipeline import heat_sink_config, run_pipeline
    from tiling import library as L

    w = world()
    comm, rank, ranks = w if w else (None, 0, 1)
    load_petsc()  # PETSc initialised (as the distributed solve loads it): part of the floor every rank pays
    _load_compiler()  # numba and LLVM, as every large model loads them (the smallest one does not)
    t_import = time.perf_counter() - t0
    base = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024  # the interpreter, libraries, MPI, PETSc
    t0 = time.perf_counter()
    if case == "sink":  # the demo's pipeline, refined three times, on PETSc
        with tempfile.TemporaryDirectory() as tmp:
            cfg = heat_sink_config("circular", None, {"full": 3, "quick": 1, "floor": 0}[size], tmp)
            cfg["solver"].update(method="petsc", tol=1e-8)
            cfg["output"].update(vtu=False, png=False)
            s = run_pipeline(cfg, tmp)
        tm = {k[4:]: v for k, v in s["timings_s"].items() if k.startswith("iga.")}
        info, dofs, unknowns, t_all = s["solver"], s["dofs"], s["unknowns"], time.perf_counter() - t0
        t_model = s["timings_s"].get("deformation map", 0.0) + s["timings_s"].get("tiling", 0.0)
    else:
        D = pr.twisted(pr.box((1.0, 1.0, 1.0), degrees=(2, 2, 2)), 0.3, axis_point=(0.5, 0.5))
        if case == "elastic":  # the same lattice, aluminium, clamped at one end and pulled at the other
            from iga import ElasticityProblem

            n = {"full": 15, "quick": 4, "floor": 2}[size]
            prob = (ElasticityProblem(tiling.regular(D, L.cross(), (n, n, n)), 70e9, 0.33, degree_elevation=1)
                    .dirichlet("umin", 0.0).traction("umax", (1e6, 0.0, -2e5)))
        else:
            n = {"full": 21, "quick": 6, "floor": 2}[size]
            prob = (HeatProblem(tiling.regular(D, L.cross(), (n, n, n)), conductivity=20.0, degree_elevation=1)
                    .dirichlet("umin", 80.0).robin("umax", 50.0, 20.0))
        t_model = time.perf_counter() - t0
        s = prob.solve(solver="petsc", tol=1e-8)
        t_all = time.perf_counter() - t0
        tm, info, unknowns = s.record.timings, s.info["solver"], int(s.record.reduced_dofs)
        dofs = prob.ndof * (3 if case == "elastic" else 1)
        if "assembly_volume" not in tm:  # (elasticity times its assembly as one stage)
            tm = {**tm, "assembly_volume": tm["assembly"], "assembly_faces": 0.0}
    row = {"case": case, "floor": size == "floor", "ranks": ranks, "dofs": dofs, "unknowns": unknowns,
           "iterations": info["iterations"], "model s": t_model,
           "assembly s": tm["assembly_volume"] + tm["assembly_faces"], "constraints s": tm["constraints"],
           "matrix + setup s": info["setup_s"], "CG s": info["solve_s"], "total s": t_all,
           "reduction s": info.get("reduction_s", 0.0),
           "imports s": t_import, "imports MiB": base,
           "peak MiB": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024}
    if comm is not None:
        rows = comm.gather(row, root=0)
        if rank:
            return
        row = {k: (max(r[k] for r in rows) if isinstance(v, float) else v) for k, v in row.items()}
        row["peak MiB per rank"] = [round(r["peak MiB"]) for r in rows]
    else:
        row["peak MiB per rank"] = [round(row["peak MiB"])]
    print(json.dumps(row), flush=True)


def _load_compiler() -> None:
    """Import numba and compile one trivial function (LLVM initialised): about 100 MiB that every process
    running the compiled kernels pays once, whatever its model's size.  The large models load it in their
    assembly; the smallest model stays on the NumPy paths, so without this its peak would leave that fixed
    memory out of the floor and count it as memory that does not fall with R."""
    import importlib.util

    if importlib.util.find_spec("numba") is not None:
        import numba

        numba.njit(lambda x: x + 1)(1)


def _fit(by: dict) -> tuple[float, float]:
    """(a, b) of the peak memory per rank q(R) = a + b / R (b >= 0) through the two largest rank counts
    measured (the replicated part shows best where the shared-out part is small)."""
    lo, hi = sorted(by)[-2:]
    b = max((by[lo]["peak MiB"] - by[hi]["peak MiB"]) / (1.0 / lo - 1.0 / hi), 0.0)
    return by[hi]["peak MiB"] - b / hi, b


def _floors(rows, case: str) -> dict:
    """Per rank count: (memory after the imports and PETSc's initialisation, peak of the same program on the
    smallest model) in MiB; the second is the program's fixed memory (libraries, compiled kernels, MPI)."""
    imports = {r["ranks"]: r["imports MiB"] for r in rows if r["case"] == case}
    small = {r["ranks"]: r["peak MiB"] for r in rows if r["case"] == case and r.get("floor")}
    return {R: (imports[R], small.get(R, imports[R])) for R in imports}


def per_rank_check(rows) -> list[dict]:
    """Peak memory per rank above a fixed floor against 1/R of the single rank's (the target: within 20%),
    above either floor of :func:`_floors`."""
    out = []
    for case in sorted({r["case"] for r in rows}):
        by = {r["ranks"]: r for r in rows if r["case"] == case and not r.get("floor")}
        floors = _floors(rows, case)
        if 1 not in by:
            continue
        for which, k in (("imports", 0), ("smallest model", 1)):
            one = by[1]["peak MiB"] - floors[1][k]
            for R, r in sorted(by.items()):
                above = r["peak MiB"] - floors[R][k]
                out.append({"case": case, "floor": which, "ranks": R, "floor MiB": floors[R][k],
                            "above floor MiB": above, "1/R of one rank MiB": one / R, "ratio": above / (one / R)})
    return out


def estimate(rows) -> list[dict]:
    """Time and memory for 10^7 and 10^8 unknowns on 16 and 128 ranks (one core each) from the runs here.

    Time, from the run on 2 ranks (one core each): the stage every rank repeats (the model) scales with the
    unknowns N; the distributed work (assembly, the rank's constraints on its closure, its reduction and
    reduced matrix, GAMG set-up, CG; 2 x the slower rank's time) with N / R; CG iterations are taken as
    constant (GAMG).  Memory: q(R) = a + b / R (:func:`_fit`); above the program's fixed memory (its peak
    on the smallest model, :func:`_floors`) both scale with N.  A model, not a measurement.
    """
    out = []
    for case in sorted({r["case"] for r in rows}):
        by = {r["ranks"]: r for r in rows if r["case"] == case and not r.get("floor")}
        if 2 not in by or len(by) < 2:
            continue
        two = by[2]
        rep = two["model s"]
        work = 2 * (two["assembly s"] + two["constraints s"] + two["matrix + setup s"] + two["CG s"])
        a, b = _fit(by)
        base = max(f[1] for f in _floors(rows, case).values())  # the program's fixed memory does not grow
        for N in (1e7, 1e8):
            for R in (16, 128):
                s = N / two["unknowns"]
                out.append({"case": case, "unknowns": N, "ranks": R, "estimated s": rep * s + work * s / R,
                            "of which repeated on every rank s": rep * s,
                            "replicated GiB": max(a - base, 0.0) * s / 1024,
                            "memory per rank GiB": (base + max(a - base, 0.0) * s + b * s / R) / 1024})
    return out


def best_of(rows) -> list[dict]:
    """One row per (case, floor, ranks): the repeated runs' smallest time and peak memory in each column
    (``--repeat N``: peaks move by about 10% between identical runs, mostly in GAMG's set-up)."""
    out: dict = {}
    for r in rows:
        key = (r["case"], r.get("floor"), r["ranks"])
        if key not in out:
            out[key] = dict(r, repeats=1)
            continue
        best = out[key]
        best["repeats"] += 1
        for k, v in r.items():
            if isinstance(v, float):
                best[k] = min(best[k], v)
        if r["peak MiB"] <= best["peak MiB"]:
            best["peak MiB per rank"] = r["peak MiB per rank"]
    return list(out.values())


EST_COLUMNS = [("case", "s"), ("unknowns", ".0e"), ("ranks", "d"), ("estimated s", ".0f"),
               ("of which repeated on every rank s", ".0f"), ("replicated GiB", ".1f"), ("memory per rank GiB", ".1f")]


def main():
    if len(sys.argv) > 2 and sys.argv[1] == "--case":
        run_case(sys.argv[2], "floor" if "--floor" in sys.argv else "quick" if "--quick" in sys.argv else "full")
        return
    if "--estimate-only" in sys.argv:  # from the last run's measurements
        last = Path(__file__).parent / "out" / "mpi_scaling.json"
        if not last.is_file():
            raise SystemExit(f"--estimate-only reads the measurements of a previous run ({last}), and there is none: "
                             "run python benchmarks/mpi_scaling.py first")
        rows = json.loads(last.read_text())["measured"]
        est = estimate(rows)
        print_table(est, EST_COLUMNS)
        save_json("mpi_scaling.json", {"measured": rows, "estimate": est})
        return
    ranks = [1, 2, 4]
    repeat = 1
    for i, a in enumerate(sys.argv):
        if a == "--ranks":
            ranks = [int(v) for v in sys.argv[i + 1].split(",")]
        if a == "--repeat":
            repeat = int(sys.argv[i + 1])
    from iga.distributed.solve import launch_env, mpiexec as find_mpiexec

    mpiexec = find_mpiexec()  # a virtual environment's own, else the one on PATH
    if mpiexec is None:
        raise SystemExit("no mpiexec found (beside this Python or on PATH): install the [mpi] extra and an MPI "
                         "(e.g. apt install openmpi-bin, or mpich)")
    cases = ("sink", "lattice", "elastic")
    for i, a in enumerate(sys.argv):
        if a == "--cases":
            cases = tuple(sys.argv[i + 1].split(","))
    if set(cases) - {"sink", "lattice", "elastic"}:
        raise SystemExit(f"--cases takes sink, lattice and elastic (comma-separated), got {','.join(cases)}")
    quick = ["--quick"] if "--quick" in sys.argv else []
    jobs = [([mpiexec, "-n", str(R), sys.executable, __file__, "--case", case] + extra,
             f"{case}{' (smallest model)' if extra == ['--floor'] else ''} on {R} ranks")
            for case in cases for R in ranks for extra in (["--floor"], quick) for _ in range(repeat)]
    rows = collect_rows(jobs, lambda r: f"{r['case']} R={r['ranks']}: {r['unknowns']:,} unknowns, total "
                        f"{r['total s']:.1f} s, CG {r['CG s']:.1f} s ({r['iterations']} it), peak "
                        f"{r['peak MiB per rank']} MiB", env=launch_env())
    rows = best_of(rows)
    print_table(rows, [("case", "s"), ("floor", ""), ("ranks", "d"), ("unknowns", "d"), ("iterations", "d"), ("model s", ".2f"),
                       ("assembly s", ".2f"), ("constraints s", ".2f"), ("reduction s", ".2f"),
                       ("matrix + setup s", ".2f"), ("CG s", ".2f"),
                       ("total s", ".2f"), ("peak MiB", ".0f")])
    check = per_rank_check(rows)
    print("\nPeak memory per rank above a fixed floor, against 1/R of one rank's (target: within 20%):")
    print_table(check, [("case", "s"), ("floor", "s"), ("ranks", "d"), ("floor MiB", ".0f"), ("above floor MiB", ".0f"),
                        ("1/R of one rank MiB", ".0f"), ("ratio", ".2f")])
    est = estimate(rows)
    print("\nEstimate (a model from the per-rank figures above, not a measurement):")
    print_table(est, EST_COLUMNS)
    save_json("mpi_scaling.json", {"measured": rows, "memory per rank": check, "estimate": est})


if __name__ == "__main__":
    main()
