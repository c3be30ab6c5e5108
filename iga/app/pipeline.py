"""End-to-end pipeline: map -> tile -> paving -> materials -> heat problem -> outputs.

Used by ``iga run CONFIG.toml`` and by ``iga demo heat-sink`` (a built-in
configuration).  The configuration is checked whole by :func:`iga.app.config.validate`
before any work starts; the paving and the analysis then check their memory
estimates, and the probes are located in the model before the solve.
Outputs go to ``[output] dir`` (relative to the configuration file): the
sampled VTU, optionally the exact Bezier VTU, a PNG render and
``summary.json``; each is written atomically, and a failed run leaves no
output folder it created behind.
"""

from __future__ import annotations

import json
import time
from dataclasses import asdict
from pathlib import Path

import numpy as np

from geometry import resources
from geometry import progress as display
from geometry.io.iges import write_iges
from geometry.io.files import atomic_write, check_folder, offscreen_plotter, save_screenshot
from iga.io.pictures import count, render_temperature
from iga.adaptivity.loop import adaptive_solve
from iga.design import optimize
from iga.outputs import Compliance, HeatFlow, MeanTemperature, TemperatureNorm, VonMisesNorm
from iga.app.problems import heat_problem
from iga.app.pipeline_transient import transient_stage
from tiling.export import boundary_splines, mesh_watertightness, write_mesh, write_surfaces

from iga.app.config import validate
from iga.app.config_records import Config, Record
from iga.app.config_model import surface_reason
from iga.app.pipeline_build import build, build_maps, macro_material
from iga.errors import ProblemError
from iga.io.gismo import export_gismo
from iga.discretisation.locate import Locator
from iga.app.maps import MAPS, circular_heat_sink_map, heat_sink_config, vertical_heat_sink_map
from iga.distributed import solve as distributed
from iga.tags import as_expression
from iga.io.vtu import sampled_grid, save_vtu, write_pieces, write_vtu

__all__ = ["run_pipeline", "heat_sink_config", "circular_heat_sink_map", "vertical_heat_sink_map", "MAPS",
           "render_temperature"]


def _mesh_volume(written) -> float | None:
    """Volume of the sampled grid written (or of the ``.pvtu`` read back) as ParaView integrates it, or None."""
    import pyvista as pv

    return None if written is None else float((pv.read(written) if isinstance(written, Path) else written).volume)


def _volumes(exact: float, mesh: float | None) -> dict:
    """The model's volume (Gauss rule on the exact geometry) and the sampled VTU's, with its relative error."""
    out = {"exact": exact}
    if mesh is not None:
        out.update({"vtu": mesh, "vtu_relative_error": mesh / exact - 1.0})
    return out


def _output_folder(path: Path) -> bool:
    """Create the output folder; returns whether it was created (so a failed run can remove it)."""
    if path.exists() and not path.is_dir():
        raise ProblemError(f"output.dir {path} exists and is not a folder; choose another output folder")
    created = not path.exists()
    try:
        path.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise ProblemError(f"cannot create output folder {path}: {exc.strerror}") from None
    return created


def run_pipeline(config: dict, base_dir: str | Path = ".", progress: bool | None = None) -> dict:
    """Run a configured pipeline; returns the summary (also written as ``summary.json``).

    ``progress``: stage lines and bars on stderr (None: leave the current
    setting of :mod:`geometry.progress`, off unless an application turned it on).
    """
    cfg = validate(config, base_dir)
    out = cfg.output.path
    created = False
    root = distributed.is_root()  # under mpiexec rank 0 alone prints and writes
    try:
        with (resources.memory_budget(cfg.limits.max_memory_gib),
              display.enabled((display.active() if progress is None else progress) and root)):
            created = _output_folder(out) if root else False
            return _run(cfg, out, root)
    except BaseException:
        if created and out.is_dir() and not any(out.iterdir()):
            out.rmdir()  # a failed run leaves no empty folder behind
        raise


def _write_outputs(ocfg: Record, out: Path, sol, stages) -> tuple[dict, object]:
    """The VTU files and the picture asked for; returns ({kind: path}, the grid written, a .pvtu path or None)."""
    files = {}
    stages.start("VTU output")
    name = ocfg.name
    vtu = out / f"{name}.vtu"
    written, grid = None, None
    world = distributed.solve_world(sol)
    if world and ocfg.get("pieces"):  # a distributed solve: every rank writes its patches, rank 0 the .pvtu index
        vtu = write_pieces(out / f"{name}.pvtu", sol, world[0], samples=ocfg.samples, tolerance=ocfg.tolerance)
        files["vtu"] = str(vtu)
        written = vtu if ocfg.vtu else None
    elif ocfg.vtu:
        check_folder(vtu, ProblemError)
        grid = sampled_grid(sol.problem.model, sol, ocfg.samples, ocfg.tolerance)
        save_vtu(vtu, grid, ocfg.compress)
        files["vtu"] = str(vtu)
        written = grid
    if ocfg.bezier:  # exact Bezier hexahedra (VTK 79) beside the sampled file
        exact = out / f"{name}_bezier.vtu"
        write_vtu(exact, sol, cells="bezier")
        files["bezier_vtu"] = str(exact)
    stages.done()
    stages.start("render")
    if ocfg.png:
        b = sol.info["balance"]
        render_temperature(grid if grid is not None else vtu, out / f"{name}.png",
                           caption=f"{name}: {count(sol.info['patches'], 'patch')}, "
                           f"{count(sol.info['free_dofs'], 'unknown')}, {b['inflow_W']:.4g} W in")
        files["png"] = str(out / f"{name}.png")
    stages.done()
    return files, written


def render_mesh(mesh, png_path: Path, scalars: str | None = None, title: str | None = None):
    """Offscreen render of a surface ``mesh`` (triangles and lines), plain or coloured by ``scalars`` (atomic)."""
    pl = offscreen_plotter((1200, 850))
    if scalars is None:
        pl.add_mesh(mesh, color="#c9a66b", smooth_shading=True, line_width=2, ambient=0.3)
    else:
        pl.add_mesh(mesh, scalars=scalars, cmap="viridis", smooth_shading=True, line_width=2, ambient=0.3,
                    scalar_bar_args={"title": title or scalars, "vertical": True, "position_x": 0.86})
    save_screenshot(pl, png_path, ProblemError, "iso", 0.85)


def _surface_outputs(built, out: Path, ocfg: Record, stages, root: bool) -> dict:
    """The outputs of a model without volume (an implicit structure, a polygon paving, a paving of surface or curve
    tiles): its mesh as ``NAME.vtp`` (with ``vtu``) and the exports, a render, and the summary of the
    construction and of the surface's closedness."""
    stages.start("surface output")
    files, mesh, s = {}, built.mesh, built.structure
    if root:
        names = (["vtp"] if ocfg.vtu else []) + [k for k in ocfg.exports
                                                    if k not in ("iges",) and (k != "vtp" or not ocfg.vtu)]
        for kind in names:
            files[kind] = str(write_mesh(out / f"{ocfg.name}.{kind}", mesh))
        if "iges" in ocfg.exports:  # surface and curve tiles: their exact B-spline geometry
            files["iges"] = str(write_iges(out / f"{ocfg.name}.igs", boundary_splines(s), name=ocfg.name))
        if ocfg.png:
            png = out / f"{ocfg.name}.png"
            if hasattr(s, "render_png"):
                s.render_png(png, color_by="w")
            else:
                render_mesh(mesh, png, "w" if "w" in mesh.point_data else None)
            files["png"] = str(png)
    w = {**mesh_watertightness(mesh), "lines": int(mesh.n_lines)}  # (no triangles: not closed, 0 components)
    stages.done()
    n = len(s.cells) if hasattr(s, "cells") else int(np.prod(s.counts)) if hasattr(s, "counts") else \
        getattr(s, "n_tiles", built.info.get("tiles", 0))
    return {"tiles": n, "levels": getattr(s, "levels", 1), "interfaces": len(getattr(s, "interfaces", [])),
            "surface": {k: bool(v) if isinstance(v, (bool, np.bool_)) else int(v) if isinstance(v, np.integer) else v
                        for k, v in w.items()},
            "construction": {k: v for k, v in getattr(s, "stats", {}).items() if isinstance(v, (int, float, str))},
            **built.info, "files": files, "peak_memory_MiB": resources.peak_memory_mib()}


def _exports(ocfg: Record, out: Path, ms, problem) -> dict:
    """The exports named in ``[output] exports``: the boundary surface as STL/OBJ/PLY/VTP, the exact boundary as
    IGES, the heat problem as G+Smo XML; {name: path}."""
    files = {}
    for kind in ocfg.exports:
        path = out / f"{ocfg.name}.{'igs' if kind == 'iges' else 'xml' if kind == 'gismo' else kind}"
        if kind in ("stl", "obj", "ply", "vtp"):
            write_surfaces(path, ms)
        elif kind == "iges":
            write_iges(path, boundary_splines(ms), name=ocfg.name)
        elif problem is not None:
            export_gismo(problem, path)
        else:  # validation refuses this; kept as a message should it be reached another way
            raise ProblemError("output.exports 'gismo' writes the heat problem; give physics.kind = 'heat'")
        files[kind] = str(path)
    return files


def _counts(ms) -> dict:
    """Tiles, patches, levels and interfaces of the micro-structure a model came from."""
    return {"tiles": ms.n_tiles, "patches": len(ms.patches), "levels": ms.levels,
            "tiles_per_level": ms.tiles_per_level(), "interfaces": len(ms.interfaces)}


def _summary(cfg, prob, sol, trange, mesh_volume, probes, files, analysis_peak) -> dict:
    """The run's summary (``summary.json``) of the heat analysis, counts and timings left to the caller."""
    bal, identity = sol.info["balance"], sol.energy_balance()  # (its pass also gives the mean temperature)
    return {
        "dofs": prob.ndof, "unknowns": sol.info["free_dofs"],
        "temperature_C": {"min": trange[0], "max": trange[1], "mean": sol.mean_temperature()},
        "inflow_W": bal["inflow_W"], "outflow_W": bal["outflow_W"], "energy_balance_error": bal["relative_error"],
        # the field's energy against the loads' and supports' work (Solution.energy_balance): independent of the
        # heat-flow balance above, which sums consistent flows
        "energy_identity": identity.as_dict(),
        "connected_pieces": sol.info["components"]["count"],
        "flux_W": {as_expression(bc["tag"]): sol.flux(bc["tag"]) for bc in cfg.bc},
        "solver": sol.info["solver"],
        "volume_m3": _volumes(sol.volume(), mesh_volume),
        "analysis_peak_memory_MiB": analysis_peak,
        "peak_memory_MiB": resources.peak_memory_mib(),
        "probes": {"points": probes.tolist(), "temperature_C": sol.probe(probes).tolist() if len(probes) else []},
        "files": files,
    }


def _heat_stage(cfg, model, out: Path, ocfg: Record, stages):
    """The heat analysis, its VTU files, picture and exports; returns (summary, solution, extra timings)."""
    scfg = cfg.solver
    stages.start("assembly and solve")
    prob = heat_problem(cfg, model)
    probes = np.asarray(ocfg.probes, float).reshape(-1, 3)
    if len(probes):  # before the solve: a probe outside the model is a configuration error
        Locator(prob.model)(probes, what="output.probes")
    adapted = designed = None
    if cfg.design is not None:  # exact analyses of the same micro-structure, redesigned
        designed = _design(prob, cfg.design, scfg.method)
        sol = designed[1].solution
        prob, model = sol.problem, sol.problem.model
    elif cfg.adapt is not None:  # solve, estimate, split where the estimate is largest, until the tolerance
        a = cfg.adapt
        adapted = adaptive_solve(prob, a.tolerance, a.max_unknowns, a.marking, a.refine, scfg.method,
                                 max_steps=a.max_steps, tol=scfg.tol,
                                 goal=[HeatFlow(t) for t in a.goal] if a.goal else None)
        sol = adapted.solution
        prob = sol.problem
        model = prob.model
    else:
        sol = prob.solve(solver=scfg.method, tol=scfg.tol, maxiter=scfg.maxiter)
    stages.done(f"({prob.ndof} DOFs, {sol.info['free_dofs']} unknowns)")
    # high-water mark of the analysis alone (map, tiling, assembly, solve), before VTK is loaded for output
    analysis_peak = resources.peak_memory_mib()
    files, written = _write_outputs(ocfg, out, sol, stages)
    files.update(_exports(ocfg, out, model, prob))
    t0 = time.perf_counter()
    tmin, tmax = sol.temperature_range(ocfg.samples)
    summary = _summary(cfg, prob, sol, (tmin, tmax), _mesh_volume(written), probes, files, analysis_peak)
    if designed is not None:
        summary["design"] = _design_summary(designed, ocfg, out, files)
    if adapted is not None:
        summary["adapt"] = {"reached": adapted.reached, "reason": adapted.reason,
                            "estimate": float(adapted.estimate.relative), "patches": len(model.patches),
                            "steps": [asdict(h) for h in adapted.history]}
    return summary, sol, {"statistics": time.perf_counter() - t0, **{f"iga.{k}": v for k, v in prob.timings.items()}}


#: the output of each [design] objective, from the section (heat: over the model or a tag's faces)
_OBJECTIVES = {"temperature_norm": lambda d: TemperatureNorm(d.p, d.tag),
               "mean_temperature": lambda d: MeanTemperature(d.tag),
               "compliance": lambda d: Compliance(),
               "von_mises_norm": lambda d: VonMisesNorm(d.p)}


def _design(prob, d: Record, method: str) -> tuple:
    """(the objective, the :class:`iga.optimiser.DesignResult`): the [design] section ``d`` run on ``prob`` (heat
    or elastic) by :func:`iga.design.optimize`: the map's channel, its control points (the solid volume kept) or a
    field-graded paving's field (the same)."""
    objective = _OBJECTIVES[d.objective](d)
    if d.variables == "map":
        result = optimize(prob, objective, "map", d.move, maxiter=d.iterations, solver=method, hold=tuple(d.hold),
                          axes=d.axes)
    elif d.variables == "parameters":
        result = optimize(prob, objective, "parameters", d.bounds, maxiter=d.iterations, solver=method,
                          hold=tuple(d.hold))
    else:
        result = optimize(prob, objective, d.variables, d.bounds, d.mean, d.iterations, solver=method,
                          keep_fraction=bool(d.get("keep_fraction")))
    return objective, result


def _design_summary(design: tuple, ocfg: Record, out: Path, files: dict) -> dict:
    """The summary's ``design`` of :func:`_design`'s (objective, result): the objective before and after and every
    iteration; its picture into ``files``."""
    objective, designed = design
    if ocfg.png:
        files["design_png"] = str(_plot_design(designed, out / f"{ocfg.name}_design.png"))
    return {"objective": objective.name, "initial": designed.initial, "final": designed.objective,
            "improvement": designed.improvement, "success": designed.success, "message": designed.message, "analyses": designed.evaluations,
            "steps": [asdict(h) for h in designed.history]}


def _plot_design(result, path: Path) -> Path:
    """The objective against the SLSQP iterations of a design run (atomic)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(7, 4))
    ax.plot([0] + [h.iteration for h in result.history], [result.initial] + [h.objective for h in result.history],
            "o-")
    ax.set(xlabel="iteration", ylabel="objective", title=f"design: {result.initial:.4g} -> {result.objective:.4g} "
           f"({100 * result.improvement:.1f}% lower)")
    fig.tight_layout()
    out = atomic_write(path, lambda tmp: fig.savefig(tmp, format="png", dpi=110), ".png", ProblemError)
    plt.close(fig)
    return out


def _run(cfg: Config, out: Path, root: bool = True) -> dict:
    ocfg, kind = cfg.output, cfg.physics.kind
    # another MPI rank assembles and solves its share and writes its VTU piece; rank 0 writes the rest
    ocfg = ocfg.replace(pieces=ocfg.vtu) if root else ocfg.replace(pieces=ocfg.vtu, vtu=False, bezier=False, png=False)
    heat, elastic = kind in ("heat", "thermo-elastic"), kind in ("elasticity", "thermo-elastic")
    transient = kind == "transient-heat"
    surface = surface_reason(cfg) is not None
    stages = display.Stages(4 if surface else 3 + 3 * heat + 2 * elastic + (kind == "none")
                            + (3 + (cfg.time.end == "steady") if transient else 0))
    stages.start("deformation map")
    maps = build_maps(cfg)
    stages.done(f"({len(maps)} primitives)" if isinstance(maps, dict) else
                f"(degrees {maps.degrees}, channels {list(maps.channels)})")
    stages.start("tiling")
    built = build(cfg, maps)
    model, ms = built.model, built.structure
    stages.done(f"({built.mesh.n_cells} cells, a surface)" if surface else
                f"({ms.n_tiles} tiles, {len(ms.interfaces)} interfaces)")
    summary, sol, timings = {}, None, {}
    if surface:
        summary = _surface_outputs(built, out, ocfg, stages, root)
    elif heat or transient:
        stage = transient_stage if transient else _heat_stage
        summary, sol, timings = stage(cfg, model, out, ocfg, stages)
        summary = {**_counts(ms), **built.info, **summary}
    else:
        summary = {**_counts(ms), **built.info, "files": _exports(ocfg, out, model, None), "peak_memory_MiB": None}
        if kind == "none" and ocfg.vtu and root:  # the model alone: its geometry and channels
            stages.start("VTU output")
            vtu = out / f"{ocfg.name}.vtu"
            write_vtu(vtu, model, samples=ocfg.samples, tolerance=ocfg.tolerance, compress=ocfg.compress)
            summary["files"]["vtu"] = str(vtu)
            stages.done()
    if elastic:
        summary["elasticity"] = _elastic_stage(cfg, model, sol, out, ocfg, stages)
        summary["files"].update(summary["elasticity"].pop("files"))
        summary["peak_memory_MiB"] = resources.peak_memory_mib()
    stages.start("summary")
    summary["timings_s"] = {**stages.timings, **timings}
    if root:
        atomic_write(out / "summary.json", lambda tmp: Path(tmp).write_text(json.dumps(summary, indent=2)),
                     ".json", ProblemError)
    stages.done()
    return summary


def _support_names(supports: list) -> list:
    """The summary's name of each [[support]]: its ``name``, else its tag (as written), else ``support[i]``."""
    return [s["name"] or (as_expression(s["tag"]) if s["tag"] is not None else f"support[{i}]")
            for i, s in enumerate(supports)]


def _elastic_stage(cfg, ms, heat_solution, out: Path, ocfg: Record, stages) -> dict:
    """The elastic (or thermo-elastic, on the heat solution) analysis of the [physics] section, its stress VTU
    and render; returns its summary (with its files)."""
    from iga.elasticity.problem import ElasticityProblem

    ph, scfg = cfg.physics, cfg.solver
    stages.start("elastic analysis")
    material = macro_material(ph.macro, ph.youngs, ph.poisson) if ph.get("macro") else None
    p = ElasticityProblem(ms, *((None, None) if material else (ph.youngs, ph.poisson)), material=material,
                          degree_elevation=scfg.degree_elevation, refine=scfg.refine, degree=scfg.degree,
                          quadrature_extra=scfg.quadrature_extra)
    names = _support_names(ph.support)
    for s, name in zip(ph.support, names):
        if s["tag"] is not None:
            p.dirichlet(s["tag"], s["value"], s["components"])
            continue
        kind, where = s["select"]
        where = where if kind in ("edge", "corner") else np.asarray(where, float)
        if s["stiffness"] is not None:  # springs on the selected components
            p.spring(where, [s["stiffness"] if c in s["components"] else 0.0 for c in "xyz"], name=name)
        else:
            p.hold(where, s["value"], s["components"], name=name)
    for i, ld in enumerate(ph.load):
        if ld["kind"] == "point":
            p.point_load(ld["point"], ld["value"], name=f"load[{i}]")
        else:
            (p.traction if ld["kind"] == "traction" else p.pressure)(ld["tag"], ld["value"])
    if ph.hold_rigid:
        p.hold_rigid()
    if ph.kind == "thermo-elastic":
        p.thermal(heat_solution, ph.expansion, ph.reference)
    design = _design(p, cfg.design, scfg.method) if cfg.design is not None else None
    es = design[1].solution if design else p.solve(solver=scfg.method, tol=scfg.tol, maxiter=scfg.maxiter)
    ms = es.problem.model  # (a design's: its map redesigned)
    stages.done(f"({es.info['dofs']} DOFs, {es.info['free_dofs']} unknowns)")
    stages.start("stress output")
    grid = sampled_grid(ms, es, ocfg.samples, ocfg.tolerance)  # (the summary's maxima and the picture)
    files = {}
    if (world := distributed.solve_world(es)) and ocfg.get("pieces"):  # every rank its piece, rank 0 the index
        files["stress_vtu"] = str(write_pieces(out / f"{ocfg.name}_stress.pvtu", es, world[0], samples=ocfg.samples,
                                               tolerance=ocfg.tolerance))
    elif ocfg.vtu:
        vtu = out / f"{ocfg.name}_stress.vtu"
        save_vtu(vtu, grid, ocfg.compress)
        files["stress_vtu"] = str(vtu)
    if ocfg.vtu and ocfg.png:
        umax = float(np.abs(grid.point_data["displacement"]).max())
        size = float(np.ptp(grid.points, axis=0).max())
        warp = 0.05 * size / umax if umax > 0 else None  # the deformation shown at 5% of the model's size
        render_temperature(grid, out / f"{ocfg.name}_stress.png", "von Mises stress (Pa)", scalars="von_mises",
                           warp=warp, cmap="viridis", fmt="%.3g")
        files["stress_png"] = str(out / f"{ocfg.name}_stress.png")
    stages.done()
    return {"dofs": es.info["dofs"], "unknowns": es.info["free_dofs"], "solver": es.info["solver"],
            "max_displacement_m": float(np.linalg.norm(grid.point_data["displacement"], axis=1).max()),
            "max_von_mises_Pa": float(grid.point_data["von_mises"].max()),
            "reactions_N": {name: es.reaction(s["tag"] if s["tag"] is not None else name).tolist()
                            for s, name in zip(ph.support, names)},
            **({"max_von_mises_note": "a point load's stress is infinite at its point: the largest von Mises stress "
                "sampled grows under refinement"} if any(ld["kind"] == "point" for ld in ph.load) else {}),
            "applied_N": es.info["applied_N"], "work": es.info["work"],
            **({"design": _design_summary(design, ocfg, out, files)} if design else {}),
            "timings_s": {k: float(v) for k, v in es.info["timings"].items()}, "files": files}
