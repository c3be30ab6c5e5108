"""The transient heat stage of a pipeline (physics.kind = "transient-heat"): the configured
:class:`iga.TransientHeatProblem` stepped as [time] says, its ParaView series, the end state's VTU and
picture, a plot of the probes (or the watched point) against time, and the summary's figures.

With ``end = "steady"`` the steady problem is solved first: of its sample points that no Dirichlet condition
holds, the one whose temperature changes most from the initial one is watched, and the run stops once that
point has risen (or fallen) by ``fraction`` of its steady change (the warm-up time a heat-sink designer asks
for: the summary's ``settle_time_s``; on a sink heated through its base, its hottest point).
"""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np

from geometry import resources
from geometry.io.files import atomic_write

from iga.app.config_records import Config, Record
from iga.app.problems import heat_problem
from iga.discretisation.locate import Locator
from iga.errors import ProblemError
from iga.heat.coefficients import ScalarField
from iga.heat.transient import TransientHeatProblem
from iga.io.pictures import count, render_temperature
from iga.io.vtu import sampled_grid, save_vtu
from iga.tags import as_expression

__all__ = ["transient_stage"]

#: a run to the steady state has no end time of its own: it ends when the watched point settles
_FOREVER = 1e15


def transient_stage(cfg: Config, model, out: Path, ocfg: Record, stages):
    """Solve, write and summarise the transient run; returns (summary, end state, extra timings)."""
    tcfg, scfg, mat = cfg.time, cfg.solver, cfg.material
    probes = np.asarray(ocfg.probes, float).reshape(-1, 3)
    if len(probes):  # before the solve: a probe outside the model is a configuration error
        Locator(model)(probes, what="output.probes")
    watch = None
    if tcfg.end == "steady":
        stages.start("steady solve (the state to settle to)")
        steady = heat_problem(cfg, model).solve(solver=scfg.method, tol=scfg.tol, maxiter=scfg.maxiter)
        point = _watched_point(steady, tcfg.initial)
        watch = {"point": point, "steady_C": float(steady.probe(point)[0])}
        stages.done(f"(watched point {np.round(point[0], 5).tolist()}, {watch['steady_C']:.3f} C when steady)")
    stages.start("transient solve")
    prob = heat_problem(cfg, model, TransientHeatProblem, capacity=mat.capacity)
    prob.initial(tcfg.initial)
    until, t_end = None, tcfg.end
    if watch is not None:
        E = prob.probe_matrix(watch["point"])
        start = float(ScalarField(tcfg.initial, "time.initial", channels=False).values(
            watch["point"], {}, "the watched point")[0])
        target = start + tcfg.fraction * (watch["steady_C"] - start)
        rising = target >= start
        watch.update(start_C=start, target_C=target)

        seen = [(prob.start[0], start)]  # the watched point's last values: (time, temperature)

        def until(t, u):
            value = float((E @ u)[0])
            done = value >= target if rising else value <= target
            seen.append((t, value))
            del seen[:-3]
            if done:
                watch["settle_s"] = _crossing(seen, target)
            return done

        t_end = _FOREVER
    history = prob.solve(t_end, tcfg.step, tcfg.method, tcfg.tolerance, tcfg.theta,
                         solver=scfg.method, solver_tol=scfg.tol, keep=tcfg.every,
                         max_steps=tcfg.max_steps, until=until)
    r = history.record
    if watch is not None and r.stopped is None:
        raise ProblemError(f"the run did not settle: the watched point did not reach {100 * tcfg.fraction:g}% "
                           f"of its steady rise within time.max_steps = {tcfg.max_steps} steps")
    stages.done(f"({prob.ndof} DOFs, {r.steps} steps to {history.times[-1]:.4g} s, {r.prepared} prepared "
                f"{r.solver})")
    analysis_peak = resources.peak_memory_mib()
    final = history.final
    files = _series_outputs(history, final, ocfg, out, stages, watch)
    t0 = time.perf_counter()
    summary = _summary(cfg, history, final, probes, watch, files, analysis_peak)
    return summary, final, {"statistics": time.perf_counter() - t0,
                            **{f"iga.{k}": v for k, v in prob.timings.items()}}


#: a sample point is held by Dirichlet conditions where the free coefficients weigh less than this in its value
#: (the B-spline weights at a point sum to 1; a point on a held face has free weight 0 up to round-off)
_HELD_WEIGHT = 1e-6


def _watched_point(steady, initial) -> np.ndarray:
    """The sample point (1, 3) of the steady solution whose temperature rises (or falls) most from the initial
    one, among the points the Dirichlet conditions do not hold: a held point takes its steady value at the first
    step, so its rise says nothing about the part settling."""
    prob = steady.problem
    grid = steady.to_pyvista(samples=1)
    points = np.asarray(grid.points, float)
    held_faces = list(prob.faces_by_kind()["dirichlet"])
    free = np.ones(len(points), bool)
    if held_faces:
        held = np.zeros(prob.ndof, bool)
        held[np.concatenate([fd.dofs for fd in prob.faces(held_faces)])] = True
        E = prob.probe_matrix(points).tocsc()
        free = np.asarray(abs(E[:, np.flatnonzero(~held)]).sum(axis=1)).ravel() > _HELD_WEIGHT
        if not free.any():
            raise ProblemError("time.end = \"steady\" watches a point the Dirichlet conditions do not hold, and "
                               "they hold every sample point of this model; give time.end in seconds")
    start = ScalarField(initial, "time.initial", channels=False).values(points[free], {}, "the sample points")
    rise = np.abs(np.asarray(grid.point_data["temperature"], float)[free] - start)
    return points[free][int(np.argmax(rise))][None]


def _crossing(seen: list, target: float) -> float:
    """When the watched temperature crossed ``target`` inside the last step of ``seen`` (its last two or three
    (time, value) pairs): the root of the quadratic through the last three (the order of the time schemes),
    else of the line through the last two."""
    (t0, v0), (t1, v1) = seen[-2], seen[-1]
    if len(seen) == 3:
        ts, vs = np.array([p[0] for p in seen]), np.array([p[1] for p in seen]) - target
        roots = np.roots(np.polyfit(ts - t1, vs, 2)) + t1
        inside = [float(r.real) for r in roots if abs(r.imag) <= 1e-12 * abs(t1 - t0) and
                  t0 - 1e-12 * abs(t1 - t0) <= r.real <= t1 + 1e-12 * abs(t1 - t0)]
        if len(inside) == 1:
            return inside[0]
    return t0 + (t1 - t0) * (target - v0) / (v1 - v0) if v1 != v0 else t1


def _series_outputs(history, final, ocfg: Record, out: Path, stages, watch) -> dict:
    """The ParaView series, the end state's VTU and picture, and the plot against time; {kind: path}."""
    files = {}
    name = ocfg.name
    stages.start("VTU output")
    if ocfg.vtu:
        files["pvd"] = str(history.write_pvd(out / f"{name}.pvd", samples=ocfg.samples,
                                             tolerance=ocfg.tolerance, compress=ocfg.compress))
        grid = sampled_grid(final.problem.model, final, ocfg.samples, ocfg.tolerance)
        vtu = save_vtu(out / f"{name}.vtu", grid, ocfg.compress)
        files["vtu"] = str(vtu)
    stages.done()
    stages.start("render")
    if ocfg.png and ocfg.vtu:
        b = final.info["balance"]
        render_temperature(grid, out / f"{name}.png",
                           caption=f"{name} at t = {final.time:.4g} s: {count(final.info['patches'], 'patch')}, "
                                   f"{count(final.info['free_dofs'], 'unknown')}, {b['inflow_W']:.4g} W in, "
                                   f"{b['stored_W']:.4g} W stored")
        files["png"] = str(out / f"{name}.png")
    if ocfg.png:
        files["history_png"] = str(_plot_history(history, ocfg, out / f"{name}_history.png", watch))
    stages.done()
    return files


def _plot_history(history, ocfg: Record, path: Path, watch) -> Path:
    """Temperature against time at the probes (or the watched point), with the steady value and the
    settling time where known (atomic)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    points = np.asarray(ocfg.probes, float).reshape(-1, 3)
    labels = [f"probe {i}" for i in range(len(points))]
    if watch is not None:
        points = np.vstack([points, watch["point"]])
        labels.append("watched point")
    fig, ax = plt.subplots(figsize=(8, 4.5))
    t = history.times
    scale, unit = (60.0, "min") if t[-1] > 600 else (1.0, "s")
    if len(points):
        for series, label in zip(history.probe(points).T, labels):
            ax.plot(t / scale, series, label=label)
    else:  # nothing to watch: the heat content
        ax.plot(t / scale, history.heat_content(), label="heat content (J)")
    if watch is not None:
        ax.axhline(watch["steady_C"], ls="--", c="k", lw=0.8, label="steady")
        settle = watch["settle_s"] / scale
        ax.axvline(settle, ls=":", c="r", lw=0.8,
                   label=f"{100 * (watch['target_C'] - watch['start_C']) / (watch['steady_C'] - watch['start_C']):.0f}"
                         f"% of the rise at {settle:.3g} {unit}")
    ax.set(xlabel=f"time ({unit})", ylabel="temperature (C)" if len(points) else "J",
           title=f"{ocfg.name}: {count(history.problem.ndof, 'unknown')}, {history.record.method} in "
                 f"{count(history.record.steps, 'step')}")
    ax.legend()
    fig.tight_layout()
    return atomic_write(path, lambda tmp: fig.savefig(tmp, format="png", dpi=110), ".png", ProblemError)


def _summary(cfg, history, final, probes, watch, files, analysis_peak) -> dict:
    """The run's summary: the end state's heat figures and the time series."""
    bal, r = final.info["balance"], history.record
    lo, hi = final.temperature_range(cfg.output.samples)
    out = {
        "dofs": final.problem.ndof, "unknowns": final.info["free_dofs"],
        "temperature_C": {"min": lo, "max": hi, "mean": final.mean_temperature()},
        "inflow_W": bal["inflow_W"], "outflow_W": bal["outflow_W"], "stored_W": bal["stored_W"],
        "energy_balance_error": bal["relative_error"],
        "energy_identity": final.energy_balance().as_dict(),
        "connected_pieces": final.info["components"]["count"],
        "flux_W": {as_expression(bc["tag"]): final.flux(bc["tag"]) for bc in cfg.bc},
        "transient": {"method": r.method, "steps": r.steps, "rejected": r.rejected, "prepared_solvers": r.prepared,
                      "solver": r.solver, "iterations": r.iterations, "end_s": float(history.times[-1]),
                      "times_s": history.times.tolist(), "heat_content_J": history.heat_content().tolist(),
                      "timings_s": dict(r.timings)},
        "analysis_peak_memory_MiB": analysis_peak, "peak_memory_MiB": resources.peak_memory_mib(),
        "probes": {"points": probes.tolist(),
                   "temperature_C": history.probe(probes).T.tolist() if len(probes) else []},
        "files": files,
    }
    if watch is not None:
        out["transient"].update(settle_time_s=float(watch["settle_s"]), watched_point=watch["point"][0].tolist(),
                                watched_C=history.probe(watch["point"])[:, 0].tolist(),
                                steady_watched_C=watch["steady_C"], settled_fraction=cfg.time.fraction)
    return out
