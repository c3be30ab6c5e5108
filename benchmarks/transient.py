"""The circular demo heat sink switched on: 1,000 BDF2 steps of transient conduction against one steady solve.

The sink of ``iga demo heat-sink`` (Massarwi et al. 2018, Fig. 11; aluminium graded to steel, 1515.8 W/m^2 on
the inner ring, h = 5 W/(m^2 K) to air), starting at the ambient 20 C with rho c = 2.4e6 J/(m^3 K)
(aluminium).  Measured: the steady solve (assembly, constraints, solve), the transient setup (assembly, mass
form, constraints, initial state), the first step (it prepares the step's solver), the mean of the other
steps and their spread over the run (flat: no step slows down as the run goes on), the resident memory
after the setup, after 50 steps (the factors and the allocator's arenas are in place by then: at 73,920
unknowns 599 MiB after the first step, 714 MiB from step 50 to step 400 with no kept states) and at the end
(flat: only the kept states grow, 16 bytes per coefficient each, one in 50 steps here), and how far the
hottest point got towards its steady rise.

Targets: a step after the first at most 0.3x a steady solve; memory flat over the steps.

    python benchmarks/transient.py            # refine 0 (the demo's), 1,000 steps
    python benchmarks/transient.py --refine 1 --steps 200
"""

from __future__ import annotations

import argparse
import resource
import time

import numpy as np

from _common import out_dir, print_table, pyplot, save_json, save_plot, settle


def rss_mib() -> float:
    """Resident memory now (MiB), from /proc (the high-water mark would hide a drop)."""
    with open("/proc/self/statm") as f:
        return int(f.read().split()[1]) * resource.getpagesize() / 2**20


def sink_model(refine: int):
    from iga.app.config import validate
    from iga.app.pipeline import heat_sink_config
    from iga.app.pipeline_build import build, build_maps

    cfg = validate(heat_sink_config("circular", None, refine, str(out_dir())), out_dir())
    return build(cfg, build_maps(cfg)).model


def conditions(problem):
    return problem.neumann("branch-in", 1515.8).robin("exterior", 5.0, 20.0)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--refine", type=int, default=0)
    ap.add_argument("--steps", type=int, default=1000)
    ap.add_argument("--dt", type=float, default=10.0, help="step (s)")
    args = ap.parse_args(argv)

    from iga import HeatProblem, TransientHeatProblem
    from iga.heat.stepping import TimeStepper

    ms = sink_model(0)
    conditions(HeatProblem(ms, conductivity="k", refine=args.refine)).solve()  # the compiled kernels loaded
    settle()
    t0 = time.perf_counter()
    steady = conditions(HeatProblem(ms, conductivity="k", refine=args.refine)).solve()
    t_steady = time.perf_counter() - t0
    grid = steady.to_pyvista(samples=1)
    hottest = np.asarray(grid.points)[int(np.argmax(grid.point_data["temperature"]))][None]

    problem = conditions(TransientHeatProblem(ms, conductivity="k", capacity=2.4e6, refine=args.refine))
    problem.initial(20.0)
    settle()
    t0 = time.perf_counter()
    stepper = TimeStepper(problem, "bdf2", None, "auto", 1e-10)
    t_setup = time.perf_counter() - t0
    mem_setup = rss_mib()
    times, mems = [], []

    def on_step(n, t, seconds):
        times.append(seconds)
        if n % 50 == 0 or n == args.steps:  # the allocator settles within the first 50 steps (measured)
            mems.append((n, rss_mib()))

    history = stepper.run(args.steps * args.dt, args.dt, None, 50, args.steps + 1, on_step)
    T_hot = history.probe(hottest)[:, 0]
    rise = (T_hot - 20.0) / (float(steady.probe(hottest)[0]) - 20.0)
    steps = np.array(times)
    later = steps[1:]
    quarter = max(1, len(later) // 4)
    rows = [
        {"quantity": "unknowns", "value": f"{problem.ndof:,}", "target": ""},
        {"quantity": "steady solve (s)", "value": f"{t_steady:.3f}", "target": ""},
        {"quantity": "transient setup (s)", "value": f"{t_setup:.3f}", "target": ""},
        {"quantity": "first step (s)", "value": f"{steps[0]:.4f}", "target": ""},
        {"quantity": "later steps, mean (s)", "value": f"{later.mean():.4f}",
         "target": f"<= {0.3 * t_steady:.4f} (0.3 x steady)"},
        {"quantity": "later step / steady solve", "value": f"{later.mean() / t_steady:.3f}", "target": "<= 0.3"},
        {"quantity": "first / last quarter of steps, mean (s)",
         "value": f"{later[:quarter].mean():.4f} / {later[-quarter:].mean():.4f}", "target": "flat"},
        {"quantity": f"{args.steps} steps, total (s)", "value": f"{steps.sum():.2f}", "target": ""},
        {"quantity": "memory: setup / step 50 / end (MiB)",
         "value": f"{mem_setup:.0f} / {mems[0][1]:.0f} / {mems[-1][1]:.0f}", "target": "flat after step 50"},
        {"quantity": f"hottest point's rise at {args.steps * args.dt:g} s", "value": f"{100 * rise[-1]:.1f}% of "
         "steady", "target": ""},
        {"quantity": "prepared solver", "value": stepper.record.solver, "target": ""},
    ]
    print_table(rows, [("quantity", "<40"), ("value", ">22"), ("target", "<30")])
    save_json(f"transient_r{args.refine}.json", {"rows": rows, "step_s": steps.tolist(), "memory_mib": mems,
                                                  "times_s": history.times.tolist(), "hottest_C": T_hot.tolist()})
    plt = pyplot()
    if plt is not None:
        fig, (a1, a2) = plt.subplots(1, 2, figsize=(11, 4))
        a1.plot(history.times / 60, T_hot)
        a1.axhline(float(steady.probe(hottest)[0]), ls="--", c="k", lw=0.8, label="steady")
        a1.set(xlabel="time (min)", ylabel="hottest point (C)", title="the demo sink switched on at 20 C")
        a1.legend()
        a2.plot(np.arange(1, len(steps) + 1), steps * 1e3, lw=0.6)
        a2.axhline(0.3 * t_steady * 1e3, ls="--", c="r", lw=0.8, label="0.3 x steady solve")
        a2.set(xlabel="step", ylabel="time per step (ms)", yscale="log", title=f"{problem.ndof:,} unknowns")
        a2.legend()
        save_plot(fig, f"transient_r{args.refine}.png")


if __name__ == "__main__":
    main()
