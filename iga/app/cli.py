"""The ``iga`` command line.

Subcommands
-----------
``iga demo heat-sink --out DIR``  the heat-sink analysis of Massarwi et al. 2018 (VTU, PNG, JSON summary;
                                 ``--stress`` adds its thermal stress)
``iga run CONFIG.toml``           a pipeline described in a TOML file
``iga info FILE``                describe a file the toolkit wrote (splines, meshes, IGES, summary.json)
``iga homogenize --tile NAME``   effective conductivity (and stiffness) of a library tile

Global options: ``--version``, ``--quiet`` (no progress display),
``--max-memory GIB`` (the memory budget of the run).  Every error the command
meets is printed as one line on stderr, with exit status 1.
"""

from __future__ import annotations

import argparse
import difflib
import re
import sys
import warnings
from pathlib import Path

import numpy as np

from geometry.numbers import TINY
from geometry import progress, resources
from tiling.library import TILES
from geometry.errors import ToolkitError

from iga.distributed.solve import launched
from iga.errors import ProblemError
from iga.app.memory import retain_freed_memory
from geometry.errors import show


def _plural(n: int, word: str) -> str:
    return f"{n} {word}" + ("" if n == 1 else ("es" if word.endswith(("ch", "sh", "s", "x")) else "s"))


def _version() -> str:
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version("iga-microstructures")
    except PackageNotFoundError:  # running from a source tree that was not installed
        return "unknown (not installed)"


def _cmd_demo(args) -> int:
    from iga.app.pipeline import heat_sink_config, run_pipeline

    cfg = heat_sink_config(args.variant, args.levels, args.refine, args.out, stress=args.stress,
                           transient=args.transient)
    s = run_pipeline(cfg)
    if args.transient:
        return _transient_lines(args, s)
    print(f"{args.variant} heat sink: {_plural(s['tiles'], 'tile')} on {_plural(s['levels'], 'level')}, "
          f"{s['dofs']} DOFs ({s['unknowns']} unknowns)")
    t = s["temperature_C"]
    print(f"temperature {t['min']:.2f} .. {t['max']:.2f} C (volume mean {t['mean']:.2f}); inflow {s['inflow_W']:.4g} W, "
          f"outflow {s['outflow_W']:.4g} W, balance error {s['energy_balance_error']:.1e}")
    if "elasticity" in s:
        print(_elastic_line(s["elasticity"]))
    print(f"wrote {', '.join(s['files'].values())} and {Path(args.out) / 'summary.json'}")
    return 0


def _transient_lines(args, s: dict) -> int:
    tr = s["transient"]
    minutes = tr["settle_time_s"] / 60
    print(f"{args.variant} heat sink switched on at 20 C: {_plural(s['tiles'], 'tile')}, {s['dofs']} DOFs, "
          f"{tr['method']} in {tr['steps']} steps ({tr['rejected']} rejected, {tr['prepared_solvers']} solver "
          f"preparations)")
    print(f"hottest point {tr['watched_C'][0]:.2f} -> {tr['watched_C'][-1]:.2f} C, 95% of its steady rise (to "
          f"{tr['steady_watched_C']:.2f} C) after {minutes:.1f} min; then {s['inflow_W']:.4g} W in, "
          f"{s['stored_W']:.4g} W still stored, balance error {s['energy_balance_error']:.1e}")
    print(f"wrote {', '.join(s['files'].values())} and {Path(args.out) / 'summary.json'}")
    return 0


def _newton_note(s: dict) -> str:
    """``; Newton: n iterations`` for a nonlinear run (radiation, k(T)), else nothing."""
    n = (s.get("solver") or {}).get("newton_iterations")
    return f"; Newton: {n} iterations" if n is not None else ""


def _elastic_line(e: dict) -> str:
    return (f"elasticity: {e['dofs']} DOFs; largest displacement {e['max_displacement_m']:.3g} m, von Mises up to "
            f"{e['max_von_mises_Pa']:.3g} Pa; work balance error {e['work']['relative_error']:.1e}")


def _read_config(path: Path) -> dict:
    import tomllib

    if path.is_dir():
        raise ProblemError(f"config file {path} is a folder; give the path of a .toml file")
    if not path.is_file():
        raise ProblemError(f"config file {path} does not exist")
    try:
        return tomllib.loads(path.read_text())
    except tomllib.TOMLDecodeError as exc:
        raise ProblemError(f"{path} is not valid TOML: {exc}") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise ProblemError(f"cannot read config file {path}: {exc}") from None


def _cmd_optimize(args) -> int:
    cfg = _read_config(Path(args.config))
    if "design" not in cfg:
        raise ProblemError(f"iga optimize needs a [design] section in {args.config} (variables = \"channel:k\", "
                           "bounds = [54, 205], ...); see the pipeline reference, or use iga run")
    return _cmd_run(args, cfg)


def _cmd_run(args, cfg: dict | None = None) -> int:
    from iga.app.pipeline import run_pipeline

    path = Path(args.config)
    cfg = _read_config(path) if cfg is None else cfg
    s = run_pipeline(cfg, base_dir=path.parent)
    from iga.distributed.solve import is_root

    if not is_root():  # under mpiexec rank 0 reports
        return 0
    where = f"outputs and summary.json in {Path(next(iter(s['files'].values()), path)).parent}"
    if "temperature_C" in s:
        t = s["temperature_C"]
        print(f"{_plural(s['tiles'], 'tile')}, {s['dofs']} DOFs; temperature {t['min']:.3f} .. {t['max']:.3f}; "
              f"balance error {s['energy_balance_error']:.1e}{_newton_note(s)}; {where}")
    d = s["design"] if "design" in s else s.get("elasticity", {}).get("design")  # (heat's, or elasticity's)
    if d is not None:
        print(f"design: {d['objective']} {d['initial']:.4g} -> {d['final']:.4g} ({100 * d['improvement']:.1f}% "
              f"lower) in {len(d['steps'])} iterations, {d['analyses']} analyses; {d['message']}")
    if "adapt" in s:
        a = s["adapt"]
        print(f"adaptive: {len(a['steps'])} steps to {a['patches']} patches, estimate {a['estimate']:.3g}; "
              f"{a['reason']}")
    if "elasticity" in s:
        print(f"{_plural(s['tiles'], 'tile')}, {_elastic_line(s['elasticity'])}; {where}")
    if "temperature_C" not in s and "elasticity" not in s:  # a model without analysis (physics.kind = 'none')
        extra = ""
        if "surface" in s:
            w = s["surface"]
            extra = (f"; surface of {w['triangles']:,} triangles, {'closed' if w['closed'] else 'open'}"
                     if w.get("triangles") else f"; {w.get('lines', 0):,} lines")
        print(f"{_plural(s['tiles'], 'tile')} (no analysis){extra}; {where}")
    return 0


def _cmd_homogenize(args) -> int:
    from iga.homogenisation.cells import effective_conductivity, effective_stiffness
    from iga.homogenisation.macro import CUBIC_MARGIN, cubic_constants

    import inspect

    if args.youngs is None and args.poisson is not None:
        raise ProblemError("--poisson applies to the effective stiffness, which --youngs asks for; give --youngs E "
                           "(Pa) too, or leave --poisson out")
    kwargs = {}
    for item in args.arg or []:
        key, sep, value = item.partition("=")
        if not sep or not key:
            raise ProblemError(f"--arg {item!r}: give name=number, e.g. --arg arm=0.3")
        if key in kwargs:
            raise ProblemError(f"--arg {key} is given twice ({key}={kwargs[key]:g} and {item}); give each tile "
                               "parameter once")
        try:  # a whole number stays an integer (a count), anything else is a float
            kwargs[key] = int(value) if re.fullmatch(r"[+-]?\d+", value.strip()) else float(value)
        except ValueError:
            raise ProblemError(f"--arg {item!r}: give name=number, e.g. --arg arm=0.3") from None
    family = TILES[args.tile]
    params = inspect.signature(family).parameters
    unknown = [k for k in kwargs if k not in params]
    if unknown and not any(p.kind is p.VAR_KEYWORD for p in params.values()):
        raise ProblemError(f"tile {args.tile!r} does not take {unknown}; its parameters are {list(params)}")
    try:
        tile = family(**kwargs)
    except TypeError as exc:
        raise ProblemError(f"tile {args.tile!r} refused {kwargs}: {exc}") from None
    k = effective_conductivity(tile, args.conductivity, refine=args.refine, diagnostics=True)
    np.set_printoptions(precision=6, suppress=True)
    print(f"{args.tile}{kwargs or ''}: volume fraction {k.volume_fraction:.6g}; effective conductivity "
          f"(k = {args.conductivity:g}), symmetry error {k.symmetry_error:.1e}:")
    print(k.tensor)
    print(f"(cell problems: {k.unknowns} unknowns, condition number about {k.condition:.2g})")
    if args.out is not None:
        if not str(args.out).endswith(".vtu"):
            raise ProblemError(f"--out {args.out!r}: the cell fields are written as a .vtu file; give a name ending "
                               "in .vtu")
        print(f"cell fields (corrector, cell_flux_x/y/z, conductivity): {k.write_vtu(args.out)}")
    if args.youngs is not None:
        nu = 0.3 if args.poisson is None else args.poisson
        c = effective_stiffness(tile, args.youngs, nu, refine=args.refine, diagnostics=True)
        scale = 10.0 ** np.floor(np.log10(max(np.abs(c.tensor).max(), TINY)))
        print(f"effective stiffness (E = {args.youngs:g}, nu = {nu:g}; Voigt xx yy zz yz xz xy, "
              f"engineering shears) in units of {scale:g} Pa, symmetry error {c.symmetry_error:.1e}:")
        print(np.round(c.tensor / scale, 6) + 0.0)
        (c11, c12, c44), departure = (v[0] for v in cubic_constants(c.tensor))
        if departure <= CUBIC_MARGIN:  # a lattice designer's figures: the constants and Zener's anisotropy ratio
            print(f"cubic symmetry (to {departure:.1e}): C11 = {c11:.6g}, C12 = {c12:.6g}, C44 = {c44:.6g} Pa; "
                  f"Zener ratio 2 C44 / (C11 - C12) = {2 * c44 / (c11 - c12):.4g} (1: isotropic); iga.stiffness_table "
                  "tabulates them for a macro model")
    return 0


def _cmd_info(args) -> int:
    from geometry import check_regular
    from geometry.io.gismo import read_gismo
    from geometry.maps.scale import scale_bounds
    from geometry.io.files import load_all

    from iga.io.describe import describe

    path = Path(args.file)
    if not path.is_file():
        raise ProblemError(f"{path} does not exist or is not a file")
    lines = describe(path)  # meshes, IGES and summaries; None for spline files
    if lines is not None:
        print("\n".join(lines))
        return 0
    if path.suffix.lower() == ".xml":
        g = read_gismo(path)
        splines = g.patches
        print(f"{path.name}: G+Smo XML, {_plural(len(splines), 'patch')}, {_plural(len(g.interfaces), 'interface')}, "
              f"{_plural(len(g.boundary), 'boundary side')}, {_plural(len(g.branches), 'branch interface')}")
        for c in g.conditions:
            print(f"   {c.kind} {c.expression}{' (h ' + c.coefficient + ')' if c.coefficient else ''} on "
                  f"{_plural(len(c.faces), 'side')}")
        for label, expr in g.functions.items():
            print(f"   {label} = {expr}")
    else:  # anything else is read as our .npz archive (its loader says what is wrong with other files)
        splines = load_all(path)
        print(f"{path.name}: {_plural(len(splines), 'spline')}")
    for i, s in enumerate(splines):
        dom = ", ".join(f"[{a:g}, {b:g}]" for a, b in s.domain)
        knots = "; ".join(f"{len(np.unique(U)) - 1} span{'s' if len(np.unique(U)) > 2 else ''}" for U in s.knots)
        line = f"{i}: {show(s)}\n   domain {dom}; {knots}; bounding box {s.bounding_box().round(6).tolist()}"
        if s.dim == 3:
            r = check_regular(s, max_depth=6)
            line += f"; regularity: {r.status}"
            line += "".join(f"\n   {t}" for t in scale_bounds(s).summary())
        print(line)
    return 0


class _Formatter(argparse.ArgumentDefaultsHelpFormatter):
    """Shows defaults, except None (those options say in words what they default to)."""

    def _get_help_string(self, action):
        return action.help if action.default is None else super()._get_help_string(action)


def _add_demo(sub) -> None:
    """The ``demo`` command and its ``heat-sink`` demonstration."""
    demo = sub.add_parser("demo", help="run a built-in demonstration (heat-sink)",
                          description="Run a built-in demonstration; 'iga demo heat-sink --help' lists its options.")
    demo.set_defaults(func=lambda _: demo.print_help() or 0)
    demos = demo.add_subparsers(dest="name", metavar="NAME")
    hs = demos.add_parser(
        "heat-sink", help="the hierarchical heat sink of Massarwi et al. 2018 (Section 8)", formatter_class=_Formatter,
        description="Build the hierarchical heat sink of Massarwi et al. 2018 (Section 8, Figs. 11 and 18), solve "
        "steady heat transfer (inlet flux 1515.8 W/m^2 on the heated face, convection h = 5 W/(m^2 K) to air "
        "at 30 C elsewhere, conductivity graded from aluminium to steel) and write heat_sink.vtu, heat_sink.png "
        "and summary.json into --out.")
    hs.add_argument("--out", default="heat-sink-out", help="output folder (created if missing)")
    hs.add_argument("--variant", choices=["circular", "vertical"], default="circular",
                    help="circular: tile T1 around a twisted ring; vertical: tile T2 on a box")
    hs.add_argument("--levels", type=int, default=None,
                    help="hierarchy levels (default: the paper's, 3 circular, 2 vertical)")
    hs.add_argument("--refine", type=int, default=0, help="uniform h-refinement rounds of every tile space")
    hs.add_argument("--stress", action="store_true",
                    help="add the thermal stress of the graded sink (aluminium to steel; free to expand): a stress "
                         "VTU and a von Mises picture")
    hs.add_argument("--transient", action="store_true",
                    help="switch the sink on in air at 20 C and follow it warming up (rho c 2.4e6 J/(m^3 K), "
                         "adaptive BDF2) until its hottest point reaches 95%% of its steady rise: a ParaView time "
                         "series (heat_sink.pvd) and the warm-up curve (heat_sink_history.png)")
    hs.add_argument("--quiet", action="store_true", default=argparse.SUPPRESS,
                    help="no progress display on stderr (as 'iga --quiet demo ...')")
    hs.set_defaults(func=_cmd_demo)


def _add_homogenize(sub) -> None:
    hom = sub.add_parser("homogenize", help="effective conductivity (and stiffness) of a library tile",
                         formatter_class=_Formatter,
                         description="Solve the periodic cell problems of a library tile in the unit cell and print "
                         "its effective conductivity tensor, and with --youngs its effective stiffness (Voigt).")
    hom.add_argument("--tile", required=True, choices=sorted(TILES),
                     help="a library tile")
    hom.add_argument("--arg", action="append", metavar="NAME=VALUE", help="a tile parameter, e.g. arm=0.3 (repeatable)")
    hom.add_argument("--conductivity", type=float, default=1.0, help="the solid's conductivity (W/(m K))")
    hom.add_argument("--youngs", type=float, default=None, help="Young's modulus (Pa): also the effective stiffness")
    hom.add_argument("--poisson", type=float, default=None, help="Poisson's ratio (with --youngs; default 0.3)")
    hom.add_argument("--refine", type=int, default=0, help="refinement rounds of the cell problems' spaces")
    hom.add_argument("--out", default=None, metavar="FILE.vtu",
                     help="also write the cell fields: the correctors and the cell's heat flux for unit gradients")
    hom.set_defaults(func=_cmd_homogenize)


class _Parser(argparse.ArgumentParser):
    """argparse with a "did you mean" for a mistyped option or command (difflib's close matches among every
    option and command of the ``iga`` command)."""

    def error(self, message):
        words = [w for w in re.findall(r"(--?[\w-]+|'[\w-]+')", message.split(":", 1)[-1])]
        known = sorted(_all_names(self._root()))
        hints = []
        for w in words:
            w = w.strip("'")
            if w in known:
                continue
            close = difflib.get_close_matches(w, known, n=1, cutoff=0.6)
            if close:
                hints.append(f"{w}: did you mean {close[0]}?")
        super().error(message + ("; " + "; ".join(hints) if hints else ""))

    def _root(self):
        return getattr(self, "root", self)


def _all_names(parser) -> set:
    """Every option string and subcommand name of ``parser`` and its subparsers."""
    out = set()
    for action in parser._actions:
        out.update(action.option_strings)
        if isinstance(action, argparse._SubParsersAction):
            for name, sub in action.choices.items():
                out.add(name)
                out |= _all_names(sub)
    return out


def _one_line_warning(message, category, filename, lineno, file=None, line=None):
    """A warning reaches a command-line user as one ``iga: warning:`` line, without Python's source line."""
    print(f"iga: warning: {message}", file=sys.stderr)


def _config_command(sub, name: str, func, summary: str, description: str, needs: str) -> None:
    """A subcommand that runs a pipeline from CONFIG.toml (``needs``: what the file must hold, said in the help)."""
    cmd = sub.add_parser(name, help=summary, formatter_class=_Formatter, description=description)
    cmd.add_argument("config", help=f"path to the CONFIG.toml file{needs}")
    cmd.add_argument("--quiet", action="store_true", default=argparse.SUPPRESS,
                     help=f"no progress display on stderr (as 'iga --quiet {name} ...')")
    cmd.set_defaults(func=func)


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of the ``iga`` command (subcommands demo, run, info)."""
    parser = _Parser(
        prog="iga",
        description="Exact B-spline micro-structures and their isogeometric heat-transfer and elasticity analysis.",
        epilog="Run 'iga COMMAND --help' for the options of one command.",
    )
    parser.add_argument("--version", action="version", version=f"iga {_version()}")
    parser.add_argument("--quiet", action="store_true", help="no progress display on stderr")
    parser.add_argument("--max-memory", type=float, metavar="GIB", default=None,
                        help="memory budget in GiB for the size checks (default: IGA_MAX_MEMORY_GIB if set, else "
                             "the memory available now)")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    _add_demo(sub)
    _config_command(sub, "run", _cmd_run, "run a pipeline described in a TOML file",
                    "Run a pipeline (deformation map, tile, paving, materials, boundary conditions, solver, "
                    "outputs) described in a TOML file; see the README, section Pipelines, for the schema. Outputs go "
                    "to [output] dir (default 'out', relative to the config file).", "")
    _config_command(sub, "optimize", _cmd_optimize,
                    "design a pipeline's material channel by gradient ([design] section)",
                    "Run a pipeline whose [design] section names the map's channel that the conductivity reads "
                    "(variables = \"channel:k\"), its bounds and the output to minimise: SLSQP over the channel's "
                    "control values, each step an exact analysis and one adjoint (iga.optimize). Writes the final "
                    "design's VTU and picture, NAME_design.png (the objective per iteration) and summary.json "
                    "(every iteration).", " (with a [design] section)")
    _add_homogenize(sub)
    info = sub.add_parser("info", help="describe a file the toolkit wrote (splines, meshes, IGES, summary)",
                          description="Print degrees, sizes, channels, knot spans, domain, bounding box and "
                          "regularity of saved splines (for G+Smo XML also the topology and conditions); cells, "
                          "arrays and their ranges of a VTU/VTP/STL/OBJ/PLY mesh; the entities of an IGES file; "
                          "the key figures of a pipeline's summary.json.")
    info.add_argument("file", help="a .npz (geometry.save), a G+Smo .xml, a .vtu/.vtp/.stl/.obj/.ply mesh, an "
                                   ".igs file or a summary.json")
    info.set_defaults(func=_cmd_info)
    for sp_action in [a for a in parser._actions if isinstance(a, argparse._SubParsersAction)]:
        stack = list(sp_action.choices.values())
        while stack:  # every subparser suggests among the whole command's names
            p = stack.pop()
            p.root = parser
            stack += [c for a in p._actions if isinstance(a, argparse._SubParsersAction) for c in a.choices.values()]
    return parser


def main(argv=None) -> int:
    """Run the ``iga`` command with ``argv``; returns the exit status (0, or 1 after a one-line error)."""
    parser = build_parser()
    args = parser.parse_args(argv)
    if not getattr(args, "func", None):
        parser.print_help()
        return 0
    if not launched():  # a whole-process choice, so the application (not the library) makes it; an MPI rank
        retain_freed_memory()  # returns freed memory instead (iga.distributed.solve.load_petsc)
    progress.enable(False if args.quiet else None)  # bars on a terminal only
    with warnings.catch_warnings():  # restored on return: main() may be called from a script
        warnings.showwarning = _one_line_warning
        return _main(args)


def _main(args) -> int:
    try:
        # the environment is read here, at the edge, once: library calls only see the budget set
        resources.set_memory_limit(args.max_memory if args.max_memory is not None else resources.environment_limit())
        if getattr(args, "name", None) == "heat-sink":
            for name in ("levels", "refine"):
                v = getattr(args, name)
                if v is not None and v < (1 if name == "levels" else 0):
                    raise ProblemError(f"--{name} must be {'>= 1' if name == 'levels' else '>= 0'}, got {v}")
        return int(args.func(args))
    except ToolkitError as exc:
        print(f"iga: error: {exc}", file=sys.stderr)
        return 1
    except MemoryError:
        print("iga: error: out of memory; reduce the model (counts, levels, refine) or lower --max-memory so that "
              "the size checks refuse it early", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        print("iga: interrupted", file=sys.stderr)
        return 130
    except BrokenPipeError:  # the reader went away (``iga info FILE | head``): stop quietly
        sys.stderr.close()
        return 0
    except OSError as exc:  # the file system refused a name the user gave (too long, not allowed, full disk)
        where = f"{exc.filename}: " if exc.filename else ""
        print(f"iga: error: {where}{exc.strerror or exc}; choose another output name or folder", file=sys.stderr)
        return 1
    except ValueError as exc:  # e.g. a NUL character in a path of the configuration
        print(f"iga: error: {exc}; check the names and paths in the command and the configuration", file=sys.stderr)
        return 1


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
