"""Strong scaling of the distributed assembly and solve on PETSc (issue #21), on this machine's ranks.

    python benchmarks/mpi_scaling.py [--ranks 1,2] [--quick] [--estimate-only]

Needs the extra ``[mpi]`` (petsc4py, mpi4py and an ``mpiexec``).  Cases:
  * ``sink``: the circular heat sink of ``iga demo heat-sink`` at ``--refine 2`` (its pipeline, solver petsc);
  * ``lattice``: a 21 x 21 x 21 cross lattice in a twisted map at degree 2 (about 1M unknowns;
    ``--quick``: 6 x 6 x 6).
For each rank count the case runs under ``mpiexec -n R`` with ``solver="petsc"`` (CG + GAMG, tolerance
1e-8; R = 1 is PETSc on one process): time per stage (model, spaces and regularity, assembly of the
rank's patches, constraints and Dirichlet data, matrix build + GAMG set-up, CG), iterations, and peak
memory per rank (max over ranks).  From these runs, an estimate for 10^7 and 10^8 unknowns on 16 and 128
ranks (:func:`estimate`: the replicated stages scale with the unknowns, the distributed work with the
unknowns per rank; memory split into a replicated and a shared-out part): a model, not a measurement.
Writes benchmarks/out/mpi_scaling.json.
"""

from __future__ import annotations

import json
import resource
import sys
import time
from pathlib import Path

from _common import collect_rows, print_table, save_json


def run_case(case: str, quick: bool) -> None:
    """One case on the ranks of the current ``mpiexec`` (rank 0 prints the JSON row)."""
    t0 = time.perf_counter()
    import tempfile

    import tiling
    from geometry import primitives as pr
    from iga import HeatProblem
    from iga.distributed import world
    from iga.pipeline import heat_sink_config, run_pipeline
    from tiling import library as L

    w = world()
    comm, rank, size = w if w else (None, 0, 1)
    t_import = time.perf_counter() - t0
    base = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024  # the interpreter and libraries
    t0 = time.perf_counter()
    if case == "sink":  # the demo's pipeline, refined twice, on PETSc
        with tempfile.TemporaryDirectory() as tmp:
            cfg = heat_sink_config("circular", None, 2, tmp)
            cfg["solver"].update(method="petsc", tol=1e-8)
            cfg["output"].update(vtu=False, png=False)
            s = run_pipeline(cfg, tmp)
        tm = {k[4:]: v for k, v in s["timings_s"].items() if k.startswith("iga.")}
        info, dofs, unknowns, t_all = s["solver"], s["dofs"], s["unknowns"], time.perf_counter() - t0
        t_model = s["timings_s"].get("deformation map", 0.0) + s["timings_s"].get("tiling", 0.0)
    else:
        n = 6 if quick else 21
        D = pr.twisted(pr.box((1.0, 1.0, 1.0), degrees=(2, 2, 2)), 0.3, axis_point=(0.5, 0.5))
        prob = (HeatProblem(tiling.regular(D, L.cross(), (n, n, n)), conductivity=20.0, degree_elevation=1)
                .dirichlet("umin", 80.0).robin("umax", 50.0, 20.0))
        t_model = time.perf_counter() - t0
        s = prob.solve(solver="petsc", tol=1e-8)
        t_all = time.perf_counter() - t0
        tm, info, dofs, unknowns = prob.timings, s.info["solver"], prob.ndof, int(prob.reduced_dofs)
    row = {"case": case, "ranks": size, "dofs": dofs, "unknowns": unknowns,
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


def _fit(by: dict, q: str) -> tuple[float, float]:
    """(a, b) of q(R) = a + b / R through the runs on 1 and 2 ranks (b >= 0)."""
    b = max(2.0 * (by[1][q] - by[2][q]), 0.0)
    return by[1][q] - b, b


def estimate(rows) -> list[dict]:
    """Time and memory for 10^7 and 10^8 unknowns on 16 and 128 ranks (one core each) from the runs here.

    Time, from the run on 2 ranks (one core each): the stages every rank repeats (the model, the
    constraints, the replicated reduction) scale with the unknowns N; the distributed work (assembly, the
    rank's reduced matrix, GAMG set-up, CG; 2 x the slower rank's time) with N / R; CG iterations are taken
    as constant (GAMG).  Memory: q(R) = a + b / R fitted to the runs on 1 and 2 ranks (a: replicated, b:
    shared out), both scaled with N except the libraries' memory (measured after the imports).  A model,
    not a measurement.
    """
    out = []
    for case in sorted({r["case"] for r in rows}):
        by = {r["ranks"]: r for r in rows if r["case"] == case}
        if 1 not in by or 2 not in by:
            continue
        two = by[2]
        rep = two["model s"] + two["constraints s"] + two["reduction s"]
        work = 2 * (two["assembly s"] + two["matrix + setup s"] - two["reduction s"] + two["CG s"])
        a, b = _fit(by, "peak MiB")
        base = max(r["imports MiB"] for r in by.values())  # the libraries do not grow with the model
        for N in (1e7, 1e8):
            for R in (16, 128):
                s = N / two["unknowns"]
                out.append({"case": case, "unknowns": N, "ranks": R, "estimated s": rep * s + work * s / R,
                            "of which repeated on every rank s": rep * s,
                            "memory per rank GiB": (base + (a - base) * s + b * s / R) / 1024})
    return out


def main():
    if len(sys.argv) > 2 and sys.argv[1] == "--case":
        run_case(sys.argv[2], "--quick" in sys.argv)
        return
    if "--estimate-only" in sys.argv:  # from the last run's measurements
        last = Path(__file__).parent / "out" / "mpi_scaling.json"
        if not last.is_file():
            raise SystemExit(f"--estimate-only reads the measurements of a previous run ({last}), and there is none: "
                             "run python benchmarks/mpi_scaling.py first")
        rows = json.loads(last.read_text())["measured"]
        est = estimate(rows)
        print_table(est, [("case", "s"), ("unknowns", ".0e"), ("ranks", "d"), ("estimated s", ".0f"),
                          ("of which repeated on every rank s", ".0f"), ("memory per rank GiB", ".1f")])
        save_json("mpi_scaling.json", {"measured": rows, "estimate": est})
        return
    ranks = [1, 2]
    for i, a in enumerate(sys.argv):
        if a == "--ranks":
            ranks = [int(v) for v in sys.argv[i + 1].split(",")]
    from iga.distributed import launch_env, mpiexec as find_mpiexec

    mpiexec = find_mpiexec()  # a virtual environment's own, else the one on PATH
    if mpiexec is None:
        raise SystemExit("no mpiexec found (beside this Python or on PATH): install the [mpi] extra and an MPI "
                         "(e.g. apt install openmpi-bin, or mpich)")
    quick = ["--quick"] if "--quick" in sys.argv else []
    jobs = [([mpiexec, "-n", str(R), sys.executable, __file__, "--case", case] + quick, f"{case} on {R} ranks")
            for case in ("sink", "lattice") for R in ranks]
    rows = collect_rows(jobs, lambda r: f"{r['case']} R={r['ranks']}: {r['unknowns']:,} unknowns, total "
                        f"{r['total s']:.1f} s, CG {r['CG s']:.1f} s ({r['iterations']} it), peak "
                        f"{r['peak MiB per rank']} MiB", env=launch_env())
    print_table(rows, [("case", "s"), ("ranks", "d"), ("unknowns", "d"), ("iterations", "d"), ("model s", ".2f"),
                       ("assembly s", ".2f"), ("constraints s", ".2f"), ("reduction s", ".2f"),
                       ("matrix + setup s", ".2f"), ("CG s", ".2f"),
                       ("total s", ".2f"), ("peak MiB", ".0f")])
    est = estimate(rows)
    print("\nEstimate (a model from the per-rank figures above, not a measurement):")
    print_table(est, [("case", "s"), ("unknowns", ".0e"), ("ranks", "d"), ("estimated s", ".0f"),
                      ("of which repeated on every rank s", ".0f"), ("memory per rank GiB", ".1f")])
    save_json("mpi_scaling.json", {"measured": rows, "estimate": est})


if __name__ == "__main__":
    main()
