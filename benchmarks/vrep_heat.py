"""Heat on the winged-duck V-model: an aluminium body, steel wings, bridges between them.

    python benchmarks/vrep_heat.py [--body 10 10 12] [--wing 10 20 1] [--solver auto] [--no-png]

The winged duck of :func:`tiling.vrep.examples.winged_duck` (Hong and Elber 2021, Fig. 16 analogue; none of
the papers analyses a V-model micro-structure): the wing tips held at 80 C, every other free face cooled by
convection (h = 2 W/(m^2 K), 20 C: a still gas, so that the heat reaches the body).  Conductivity from the maps' channels: k = 205 in the body, 54 in the
wings, blended along the union bridges.  Stage lines and bars on stderr (progress), then a table: trivariates,
DOFs, free unknowns, solver iterations, the time of each stage, peak memory, the energy balance and the
range of the temperature's control values (which bound it).  Renders vrep_winged_duck_heat.png (benchmarks/out/figures; docs/ with --figures); writes benchmarks/out/vrep_heat.json.
"""

from __future__ import annotations

import argparse
import resource
import time

from _common import figures_dir, print_table, save_json

DOCS = figures_dir()  # benchmarks/out/figures; docs/ with --figures
H = 2.0  # film coefficient W/(m^2 K)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--body", type=int, nargs=3, default=(10, 10, 12), help="body tiles per knot span")
    ap.add_argument("--wing", type=int, nargs=3, default=(10, 20, 1), help="wing tiles per knot span")
    ap.add_argument("--solver", default="auto", help="HeatProblem.solve backend (default auto)")
    ap.add_argument("--figures", action="store_true", help="write the picture into docs/ (make_figures.py does)")
    ap.add_argument("--no-png", action="store_true", help="skip the render")
    args = ap.parse_args()

    from geometry import progress
    from iga import HeatProblem
    from tiling.vrep import vrep_microstructure
    from tiling.vrep.examples import WINGED_DUCK_TIPS, winged_duck

    progress.enable(True)
    st = progress.Stages(3)
    st.start("winged duck V-model micro-structure")
    res = vrep_microstructure(winged_duck(tuple(args.body), tuple(args.wing)), margin=0.03)
    ms = res.microstructure
    st.done(f"({len(ms.patches):,} trivariates, {res.bridges.bridges} bridging)")
    tips = {f for tag in WINGED_DUCK_TIPS for f in ms.tags[tag]}
    ms.tags["cooled"] = [f for f in ms.tags["boundary"] if f not in tips]
    st.start("spaces, regularity proof")
    pb = HeatProblem(ms, conductivity="k")
    for tag in WINGED_DUCK_TIPS:
        pb.dirichlet(tag, 80.0)
    pb.robin("cooled", H, 20.0)
    st.done(f"({pb.ndof:,} DOFs)")
    st.start(f"assembly and solve ({args.solver})")
    t0 = time.perf_counter()
    s = pb.solve(args.solver)
    solve_s = time.perf_counter() - t0
    st.done(f"({s.info['solver'].get('iterations', '-')} iterations)")
    lo, hi = float(s.u.min()), float(s.u.max())  # control values: they bound the temperature (convex hull)
    bal = s.info["balance"]
    row = {"trivariates": len(ms.patches), "bridging TVs": res.bridges.bridges, "DOFs": pb.ndof,
           "free": s.info["free_dofs"], "solver": s.info["solver"]["method"],
           "iterations": s.info["solver"].get("iterations", 0), "build s": st.timings[
               "winged duck V-model micro-structure"], "set-up s": st.timings["spaces, regularity proof"],
           "solve s": solve_s, "peak MiB": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024,
           "balance": bal["relative_error"], "heat W": bal["inflow_W"], "T min": lo, "T max": hi,
           "solver info": s.info["solver"], "timings": s.info["timings"]}
    print_table([row], [("trivariates", "d"), ("bridging TVs", "d"), ("DOFs", "d"), ("free", "d"), ("solver", "s"),
                        ("iterations", "d"), ("build s", ".1f"), ("set-up s", ".1f"), ("solve s", ".1f"),
                        ("peak MiB", ".0f"), ("balance", ".1e"), ("heat W", ".1f"), ("T min", ".2f"),
                        ("T max", ".2f")])
    save_json("vrep_heat.json", row)
    if not args.no_png:
        from iga.app.pipeline import render_temperature
        from iga.io.vtu import write_vtu
        from _common import out_dir

        vtu = write_vtu(out_dir() / "vrep_winged_duck_heat.vtu", s, samples=2)
        # the body stays within a degree of the 20 C air while the wing tips are at 80 C: on a linear scale it
        # is one colour; the rise above the air on a log scale shows where the heat goes
        render_temperature(vtu, DOCS / "vrep_winged_duck_heat.png", "rise above 20 C air (K)",
                           above=20.0)
    # the discrete solution need not keep the maximum principle exactly (no discrete maximum principle for
    # these elements): control values may undershoot 20 C slightly; more than 1% of the range is an error
    if not (bal["relative_error"] < 1e-8 and 20.0 - 0.6 <= lo <= hi <= 80.0 + 0.6):
        raise SystemExit("the winged duck's heat balance or temperature range is off")


if __name__ == "__main__":
    main()
