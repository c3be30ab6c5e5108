"""End-to-end pipeline: map -> tile -> paving -> materials -> heat problem -> outputs.

Used by ``iga run CONFIG.toml`` and by ``iga demo heat-sink`` (a built-in
configuration).  The configuration is a dictionary (the TOML file's
content); every key is checked, unknown or missing keys raise
:class:`iga.ProblemError` naming the key.  Schema (README, "Pipelines"):

    [map]      primitive = "circular_heat_sink" | "vertical_heat_sink" | "box" | "annulus"
               args = {...}            keyword arguments of the primitive (optional)
               file = "map.npz"        a saved trivariate instead of a primitive
    [map.grading]  channel, near, far, face, mode     optional graded channel on the map
    [tile]     library = "heat_sink_t1" | ... (tiling.library names), args = {...}
    [paving]   scheme = "hierarchical" | "regular", counts = [..], levels, scale
    [material] conductivity = number or channel name, source = number
    [[bc]]     kind = "dirichlet" | "neumann" | "robin", tag, value | (h, ambient)
    [solver]   method, tol, refine, degree_elevation
    [output]   dir, name, vtu, png, samples, probes = [[x, y, z], ...]
"""

from __future__ import annotations

import json
import os
import resource
import sys
import time
from math import pi
from pathlib import Path

import numpy as np

from geometry import BSpline, load, primitives as pr
from geometry.io import atomic_write

from .errors import ProblemError

SCHEMA = {
    "map": {"primitive", "args", "file", "grading"},
    "map.grading": {"channel", "near", "far", "face", "mode"},
    "tile": {"library", "args"},
    "paving": {"scheme", "counts", "levels", "scale"},
    "material": {"conductivity", "source"},
    "bc": {"kind", "tag", "value", "h", "ambient"},
    "solver": {"method", "tol", "refine", "degree_elevation"},
    "output": {"dir", "name", "vtu", "bezier", "png", "samples", "probes"},
}
REQUIRED = {"map": set(), "tile": {"library"}, "paving": {"scheme", "counts"}, "bc": {"kind", "tag"}}


def circular_heat_sink_map(r_in=0.02, r_out=0.06, height=0.03, twist=pi / 8) -> BSpline:
    """Twisted cylindrical shell (m): u around the axis, v along it, w radial (Massarwi et al. 2018, Fig. 11(a))."""
    shell = pr.annulus(r_in, r_out, height, angle=2 * pi, exact=True)  # (angle, radius, z)
    return pr.twisted(shell, twist).permute([0, 2, 1])  # (angle, z, radius): right-handed


def vertical_heat_sink_map(width=0.06, depth=0.06, height=0.03) -> BSpline:
    """Box base of the vertical heat sink (m), w upwards (Massarwi et al. 2018, Fig. 11(c)-(d))."""
    return pr.box((width, depth, height), degrees=(2, 2, 2))


MAPS = {"circular_heat_sink": circular_heat_sink_map, "vertical_heat_sink": vertical_heat_sink_map,
        "box": pr.box, "annulus": pr.annulus}


def heat_sink_config(variant: str = "circular", levels: int | None = None, refine: int = 0, out: str = "heat-sink-out"):
    """The heat-sink analysis of Massarwi et al. 2018 (Section 8, Figs. 11 and 18) as a pipeline configuration.

    Aluminium (205 W/(m K)) at the heated face graded to stainless steel
    (54 W/(m K)) away from it; inlet flux 1515.8 W/m^2 on the inner ring
    (circular) or the bottom face (vertical); convection h = 5 W/(m^2 K) to
    air at 30 C on every other external face.
    """
    if variant not in ("circular", "vertical"):
        raise ProblemError(f"variant must be 'circular' or 'vertical', got {variant!r}")
    circ = variant == "circular"
    return {
        "map": {"primitive": "circular_heat_sink" if circ else "vertical_heat_sink",
                "grading": {"channel": "k", "near": 205.0, "far": 54.0, "face": "wmin"}},
        "tile": {"library": "heat_sink_t1" if circ else "heat_sink_t2"},
        "paving": {"scheme": "hierarchical", "counts": [4, 1] if circ else [4, 4],
                   "levels": levels if levels is not None else (3 if circ else 2), "scale": 0.5},
        "material": {"conductivity": "k"},
        "bc": [{"kind": "neumann", "tag": "branch-in", "value": 1515.8},
               {"kind": "robin", "tag": "exterior", "h": 5.0, "ambient": 30.0}],
        "solver": {"method": "auto", "tol": 1e-10, "refine": refine},
        "output": {"dir": out, "name": "heat_sink", "vtu": True, "png": True},
    }


def _check(section: str, table, where: str):
    if not isinstance(table, dict):
        raise ProblemError(f"config key {where!r} must be a table, got {type(table).__name__}")
    unknown = set(table) - SCHEMA[section]
    if unknown:
        raise ProblemError(f"unknown config key {where}.{sorted(unknown)[0]!r}; allowed keys: {sorted(SCHEMA[section])}")
    missing = REQUIRED.get(section, set()) - set(table)
    if missing:
        raise ProblemError(f"missing required config key {where}.{sorted(missing)[0]!r}")


class Progress:
    """Stage display on a terminal (stderr); silent when stderr is not a TTY."""

    def __init__(self, stages: int, enabled: bool | None = None):
        self.n = stages
        self.i = 0
        self.on = sys.stderr.isatty() if enabled is None else enabled
        self.t = time.perf_counter()
        self.timings = {}

    def start(self, name: str):
        self.i += 1
        self.name = name
        self.t = time.perf_counter()
        if self.on:
            print(f"[{self.i}/{self.n}] {name} ...", end="", file=sys.stderr, flush=True)

    def done(self, detail: str = ""):
        dt = time.perf_counter() - self.t
        self.timings[self.name] = dt
        if self.on:
            print(f" {dt:.2f} s {detail}", file=sys.stderr, flush=True)


def _build_map(cfg, base: Path) -> BSpline:
    _check("map", cfg, "map")
    if "file" in cfg:
        D = load(base / cfg["file"])
    else:
        name = cfg.get("primitive")
        if name not in MAPS:
            raise ProblemError(f"config key map.primitive must be one of {sorted(MAPS)}, got {name!r}")
        D = MAPS[name](**cfg.get("args", {}))
    if "grading" in cfg:
        from tiling.materials import graded_channel

        g = cfg["grading"]
        _check("map.grading", g, "map.grading")
        D = graded_channel(D, g.get("channel", "k"), g.get("near", 205.0), g.get("far", 54.0), g.get("face", "wmin"),
                           g.get("mode", "parameter"))
    return D


def _atomic_json(path: Path, data):
    atomic_write(path, lambda tmp: Path(tmp).write_text(json.dumps(data, indent=2)), ".json", ProblemError)


def render_temperature(vtu_path: Path, png_path: Path, title: str = "temperature (C)"):
    """Offscreen render of a written .vtu coloured by temperature, with a scalar bar (atomic)."""
    import pyvista as pv

    try:
        pv.vtk_verbosity("off")
    except AttributeError:
        pass
    mesh = pv.read(vtu_path).extract_surface(algorithm="dataset_surface")
    pl = pv.Plotter(off_screen=True, window_size=[1100, 850])
    pl.add_mesh(mesh, scalars="temperature", cmap="inferno", smooth_shading=True,
                scalar_bar_args={"title": title, "vertical": True, "fmt": "%.2f"})
    pl.camera_position = "iso"
    pl.set_background("white")
    try:
        atomic_write(png_path, lambda tmp: pl.screenshot(tmp), ".png", ProblemError)
    finally:
        pl.close()


def run_pipeline(config: dict, base_dir: str | Path = ".", progress: bool | None = None) -> dict:
    """Run a configured pipeline; returns the summary (also written as summary.json)."""
    import tiling
    from tiling import library as L

    from . import HeatProblem, write_vtu

    if not isinstance(config, dict):
        raise ProblemError("the configuration must be a table of sections")
    unknown = set(config) - {"map", "tile", "paving", "material", "bc", "solver", "output"}
    if unknown:
        raise ProblemError(f"unknown config section {sorted(unknown)[0]!r}")
    for sec in ("map", "tile", "paving", "bc"):
        if sec not in config:
            raise ProblemError(f"missing required config section {sec!r}")
    base = Path(base_dir)
    out_cfg = dict(config.get("output", {}))
    _check("output", out_cfg, "output")
    out = Path(out_cfg.get("dir", "out"))
    out = out if out.is_absolute() else base / out
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise ProblemError(f"cannot create output folder {out}: {exc.strerror}") from None
    if not os.access(out, os.W_OK):
        raise ProblemError(f"output folder {out} is not writable")
    name = out_cfg.get("name", "result")
    prog = Progress(6, progress)

    prog.start("deformation map")
    D = _build_map(config["map"], base)
    prog.done(f"({D.degrees}, channels {list(D.channels)})")

    prog.start("tiling")
    tcfg = config["tile"]
    _check("tile", tcfg, "tile")
    maker = getattr(L, tcfg["library"], None)
    if maker is None or tcfg["library"].startswith("_") or not callable(maker):
        raise ProblemError(f"config key tile.library: unknown tile {tcfg['library']!r}")
    tile = maker(**tcfg.get("args", {}))
    pcfg = config["paving"]
    _check("paving", pcfg, "paving")
    if pcfg["scheme"] == "hierarchical":
        ms = tiling.hierarchical(D, tile, pcfg["counts"], pcfg.get("levels", 2), pcfg.get("scale"))
    elif pcfg["scheme"] == "regular":
        ms = tiling.regular(D, tile, pcfg["counts"])
    else:
        raise ProblemError(f"config key paving.scheme must be 'hierarchical' or 'regular', got {pcfg['scheme']!r}")
    prog.done(f"({ms.n_tiles} tiles, {len(ms.interfaces)} interfaces)")

    prog.start("assembly and solve")
    mcfg = config.get("material", {})
    _check("material", mcfg, "material")
    scfg = config.get("solver", {})
    _check("solver", scfg, "solver")
    prob = HeatProblem(ms, conductivity=mcfg.get("conductivity", 1.0), source=mcfg.get("source", 0.0),
                       refine=scfg.get("refine", 0), degree_elevation=scfg.get("degree_elevation", 0))
    bcs = config["bc"] if isinstance(config["bc"], list) else [config["bc"]]
    for i, bc in enumerate(bcs):
        _check("bc", bc, f"bc[{i}]")
        kind = bc["kind"]
        if kind == "dirichlet":
            prob.dirichlet(bc["tag"], bc.get("value", 0.0))
        elif kind == "neumann":
            prob.neumann(bc["tag"], bc.get("value", 0.0))
        elif kind == "robin":
            if "h" not in bc or "ambient" not in bc:
                raise ProblemError(f"config bc[{i}] (robin) needs keys 'h' and 'ambient'")
            prob.robin(bc["tag"], bc["h"], bc["ambient"])
        else:
            raise ProblemError(f"config key bc[{i}].kind must be dirichlet, neumann or robin, got {kind!r}")
    sol = prob.solve(solver=scfg.get("method", "auto"), tol=scfg.get("tol", 1e-10))
    prog.done(f"({prob.ndof} DOFs, {sol.info['free_dofs']} unknowns)")
    # high-water mark of the analysis alone (map, tiling, assembly, solve), before VTK is loaded for output
    analysis_peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024

    files = {}
    prog.start("VTU output")
    vtu = out / f"{name}.vtu"
    if out_cfg.get("vtu", True):
        write_vtu(vtu, sol, samples=out_cfg.get("samples", 3))
        files["vtu"] = str(vtu)
    if out_cfg.get("bezier", False):  # exact Bezier hexahedra (VTK 79) beside the sampled file
        exact = out / f"{name}_bezier.vtu"
        write_vtu(exact, sol, cells="bezier")
        files["bezier_vtu"] = str(exact)
    prog.done()
    prog.start("render")
    if out_cfg.get("png", True) and "vtu" in files:
        render_temperature(vtu, out / f"{name}.png")
        files["png"] = str(out / f"{name}.png")
    prog.done()

    prog.start("summary")
    import pyvista as pv

    T = pv.read(vtu).point_data["temperature"] if "vtu" in files else sol.u
    bal = sol.info["balance"]
    probes = out_cfg.get("probes", [])
    summary = {
        "dofs": prob.ndof, "unknowns": sol.info["free_dofs"], "tiles": ms.n_tiles, "patches": len(ms.patches),
        "levels": ms.levels, "tiles_per_level": ms.tiles_per_level(), "interfaces": len(ms.interfaces),
        "temperature_C": {"min": float(np.min(T)), "max": float(np.max(T)), "mean": float(np.mean(T))},
        "inflow_W": bal["inflow_W"], "outflow_W": bal["outflow_W"], "energy_balance_error": bal["relative_error"],
        "flux_W": {bc["tag"]: sol.flux(bc["tag"]) for bc in bcs},
        "solver": sol.info["solver"], "timings_s": {**prog.timings, **{f"iga.{k}": v for k, v in prob.timings.items()}},
        "analysis_peak_memory_MiB": analysis_peak,
        "peak_memory_MiB": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024,
        "probes": {"points": probes, "temperature_C": sol.probe(np.asarray(probes, float)).tolist() if probes else []},
        "files": files,
    }
    _atomic_json(out / "summary.json", summary)
    prog.done()
    return summary
