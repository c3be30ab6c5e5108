"""Micro-structures in V-rep Boolean models: the orthogonal cylinders of Hong and Elber 2021, Figs. 13-14.

    python benchmarks/vrep.py [--no-png]

Three solid cylinders A (along x, radius 1), B (along y, radius 1), C (along z, radius 0.8), 4 long, each
paved with the cross tile (7 trivariates) per knot span of its map (3 x 3 spans across, 1 along) with counts
chosen per case so that the trivariates kept come near those of the paper's Table 1 (COUNTS); priorities
A > B > C unless the case says otherwise.  Cases: A u B (Fig. 13(b)), (A u B) - C (Fig. 13(c)), A - B - C (Fig. 13(d)) and A n B n C with
the three priority orders (Fig. 14).  For each: tiles per class, trivariates kept (tiles x 7 + bridges),
one-to-one bridges and collision handling, time, peak memory, and the paper's Table 1 figures for the
same model (its tile and counts differ, so the comparison is of the order of magnitude).  In unions the
bridges here run to the trimming surface (Section 3.2); matching anchoring faces across it (Sections
3.4-3.6, issue #20) is not built, so the paper's union bridges are not the same object.
Each case runs in its own subprocess; renders go to docs/vrep_<case>.png (coloured by tile).
Writes benchmarks/out/vrep.json.
"""

from __future__ import annotations

import resource
import time
from pathlib import Path

from _common import print_table, run_cases, save_json

DOCS = Path(__file__).resolve().parent.parent / "docs"
CASES = ("AuB", "(AuB)-C", "A-B-C", "AnBnC A>B>C", "AnBnC B>C>A", "AnBnC C>A>B")
TABLE1 = {"AuB": (1400, 28, 35), "(AuB)-C": (826, 98, 38), "A-B-C": (384, 48, 17), "AnBnC A>B>C": (208, 40, 18)}
COUNTS = {"AuB": (1, 1, 12), "(AuB)-C": (1, 1, 12), "A-B-C": (1, 1, 12), "AnBnC": (2, 2, 7)}


def run(case: str, png: bool) -> dict:
    import pyvista  # noqa: F401  (imports are not the work measured)

    from geometry.shapes import cylinder
    from tiling import library as L
    from tiling.vrep import Primitive, vrep_microstructure

    order = case.split()[-1].split(">") if ">" in case else ["A", "B", "C"]
    pr = {name: 3 - order.index(name) for name in "ABC"}
    counts = COUNTS[case.split()[0]]
    A = Primitive(cylinder(1.0, 4.0, 0), L.cross(), counts, pr["A"], "A")
    B = Primitive(cylinder(1.0, 4.0, 1), L.cross(), counts, pr["B"], "B")
    C = Primitive(cylinder(0.8, 4.0, 2), L.cross(), counts, pr["C"], "C")
    model = {"AuB": A | B, "(AuB)-C": (A | B) - C, "A-B-C": A - B - C}.get(case.split()[0], A & B & C)
    t0 = time.perf_counter()
    res = vrep_microstructure(model)
    t = time.perf_counter() - t0
    ms = res.microstructure
    row = {"case": case, "trivariates": len(ms.patches), "bridges": res.bridges.get("bridges", 0),
           "anchoring faces": res.bridges.get("anchoring faces", 0), "collisions": res.bridges.get("collisions", 0),
           "swapped": res.bridges.get("swapped", 0), "repelled": res.bridges.get("repelled", 0),
           "eliminated": res.bridges.get("eliminated", 0), "time s": t,
           "peak MiB": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024,
           "tiles kept": {n: c["inside"] + c["to-be-bridged"] for n, c in res.counts().items()}}
    if case in TABLE1:
        row["paper trivariates"], row["paper bridges"], row["paper s"] = TABLE1[case]
        row["speed-up"] = row["paper s"] / t
    if png:
        from tiling.export import render_png

        name = case.replace(" ", "_").replace(">", "").replace("(", "").replace(")", "")
        render_png(ms, DOCS / f"vrep_{name}.png", samples=2, color_by="tile")
    return row


def main():
    rows = run_cases(__file__, CASES, run, renders=True)
    if rows is None:
        return
    print_table(rows, [("case", "s"), ("trivariates", "d"), ("bridges", "d"), ("collisions", "d"),
                       ("eliminated", "d"), ("time s", ".1f"), ("peak MiB", ".0f"), ("paper trivariates", "d"),
                       ("paper bridges", "d"), ("paper s", "d"), ("speed-up", ".0f")])
    print("(the paper's times are on an Intel i7-7700K at 4.2 GHz; ours on this 2-core VM)")
    save_json("vrep.json", rows)


if __name__ == "__main__":
    main()
