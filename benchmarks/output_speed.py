"""The output stage against the analysis: both demo sinks at refine 0, 1, 2.

For each case (``iga demo heat-sink --variant V --refine R`` as a pipeline, picture on): the analysis (map,
tiling, assembly and solve), the VTU output (sampling the model on conforming grids, then writing), the
render and the statistics, from the pipeline's own stage timings; then, on the written grid, the writer alone
as the pipeline writes it (raw appended arrays) beside zlib at level 1 and at VTK's default level, with the
file sizes.  Target: VTU output at most the analysis time on every row.  Every case runs twice in one process:
the table is the second run (warm: numba's kernels loaded, VTK imported); the first run's analysis and VTU
times are its last columns (what one ``iga demo`` process pays once).

    python benchmarks/output_speed.py [--refine 0,1,2]

Writes benchmarks/out/output_speed.json.
"""

from __future__ import annotations

import argparse
import os
import tempfile
import time
from pathlib import Path

from _common import print_table, save_json, settle


def _writer(grid, path: Path, compress, level=None) -> float:
    import vtk

    w = vtk.vtkXMLUnstructuredGridWriter()
    w.SetFileName(str(path))
    w.SetInputData(grid)
    w.SetDataModeToAppended()
    w.EncodeAppendedDataOff()
    w.SetHeaderTypeToUInt64()
    if compress:
        w.SetCompressorTypeToZLib()
        if level is not None:
            w.SetCompressionLevel(level)
    else:
        w.SetCompressorTypeToNone()
    t0 = time.perf_counter()
    if not w.Write():
        raise SystemExit(f"VTK could not write {path}")
    return time.perf_counter() - t0


def case(variant: str, refine: int) -> dict:
    import pyvista as pv

    from iga.app.pipeline import heat_sink_config, run_pipeline

    with tempfile.TemporaryDirectory() as tmp:
        cfg = heat_sink_config(variant, refine=refine, out=tmp)
        s = run_pipeline(cfg, tmp)
        t = s["timings_s"]
        analysis = t["deformation map"] + t["tiling"] + t["assembly and solve"]
        grid = pv.read(s["files"]["vtu"])
        writes = {}
        for label, compress, level in (("raw", False, None), ("zlib 1", True, 1), ("zlib default", True, None)):
            path = Path(tmp) / f"w_{label.replace(' ', '_')}.vtu"
            writes[label] = (_writer(grid, path, compress, level), os.path.getsize(path) / 2**20)
    return {"case": f"{variant} refine {refine}", "unknowns": s["unknowns"], "points": grid.n_points,
            "analysis s": analysis, "VTU output s": t["VTU output"], "VTU / analysis": t["VTU output"] / analysis,
            "render s": t["render"], "statistics s": t["statistics"],
            "write raw s": writes["raw"][0], "raw MiB": writes["raw"][1],
            "write zlib-1 s": writes["zlib 1"][0], "zlib-1 MiB": writes["zlib 1"][1],
            "write zlib s": writes["zlib default"][0], "zlib MiB": writes["zlib default"][1]}


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--refine", default="0,1,2", help="refinements, comma-separated")
    args = ap.parse_args()
    from iga.app.memory import retain_freed_memory

    retain_freed_memory()  # the allocator setting of the ``iga`` command, whose run this measures
    cases = [(variant, int(r)) for r in args.refine.split(",") for variant in ("circular", "vertical")]
    # a first pass loads what each stage imports and compiles once per process (numba and its cached kernels,
    # VTK): shown as the first run's times, then every case again, warm
    first = {}
    for variant, refine in cases:
        row = case(variant, refine)
        first[row["case"]] = (row["analysis s"], row["VTU output s"])
        print(f"  first run, {row['case']}: analysis {row['analysis s']:.2f} s, VTU {row['VTU output s']:.2f} s",
              flush=True)
    rows = []
    for variant, refine in cases:
        settle()
        rows.append(case(variant, refine))
        rows[-1]["first run: analysis s"], rows[-1]["first run: VTU s"] = first[rows[-1]["case"]]
        print(f"  {rows[-1]['case']}: analysis {rows[-1]['analysis s']:.2f} s, VTU {rows[-1]['VTU output s']:.2f} s",
              flush=True)
    print("\nThe output stage against the analysis (target: VTU / analysis <= 1)")
    print_table(rows, [("case", "s"), ("unknowns", ",d"), ("points", ",d"), ("analysis s", ".2f"),
                       ("VTU output s", ".2f"), ("VTU / analysis", ".2f"), ("render s", ".2f"),
                       ("statistics s", ".2f"), ("write raw s", ".2f"), ("raw MiB", ".0f"), ("write zlib-1 s", ".2f"),
                       ("zlib-1 MiB", ".0f"), ("write zlib s", ".2f"), ("zlib MiB", ".0f"),
                       ("first run: analysis s", ".2f"), ("first run: VTU s", ".2f")])
    save_json("output_speed.json", rows)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
