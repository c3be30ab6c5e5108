"""The ``iga`` command line.

Subcommands
-----------
``iga demo heat-sink --out DIR``  the heat-sink analysis of Massarwi et al. 2018 (VTU, PNG, JSON summary)
``iga run CONFIG.toml``           a pipeline described in a TOML file
``iga info FILE.npz``             describe the splines stored in a file
"""

from __future__ import annotations

import argparse
import sys

from geometry.errors import ToolkitError

def _cmd_demo(args) -> int:
    from .pipeline import heat_sink_config, run_pipeline

    cfg = heat_sink_config(args.variant, args.levels, args.refine, args.out)
    s = run_pipeline(cfg, progress=None)
    print(f"{args.variant} heat sink: {s['tiles']} tiles on {s['levels']} levels, {s['dofs']} DOFs "
          f"({s['unknowns']} unknowns)")
    t = s["temperature_C"]
    print(f"temperature {t['min']:.2f} .. {t['max']:.2f} C (mean {t['mean']:.2f}); inflow {s['inflow_W']:.4g} W, "
          f"outflow {s['outflow_W']:.4g} W, balance error {s['energy_balance_error']:.1e}")
    print(f"wrote {', '.join(s['files'].values())} and {args.out}/summary.json")
    return 0


def _cmd_run(args) -> int:
    import tomllib
    from pathlib import Path

    from .errors import ProblemError
    from .pipeline import run_pipeline

    path = Path(args.config)
    if not path.is_file():
        raise ProblemError(f"config file {path} does not exist")
    try:
        cfg = tomllib.loads(path.read_text())
    except tomllib.TOMLDecodeError as exc:
        raise ProblemError(f"{path} is not valid TOML: {exc}") from None
    s = run_pipeline(cfg, base_dir=path.parent, progress=None)
    print(f"{s['tiles']} tiles, {s['dofs']} DOFs; temperature {s['temperature_C']['min']:.3f} .. "
          f"{s['temperature_C']['max']:.3f}; balance error {s['energy_balance_error']:.1e}; "
          f"summary in {Path(s['files'].get('vtu', path)).parent / 'summary.json'}")
    return 0


def _cmd_info(args) -> int:
    from geometry.io import load_all

    for i, s in enumerate(load_all(args.file)):
        dom = ", ".join(f"[{a:g}, {b:g}]" for a, b in s.domain)
        print(f"{i}: {s!r}")
        print(f"   domain {dom}; elements {s.n_elements}; bounding box {s.bounding_box().round(6).tolist()}")
    return 0


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="iga",
        description="Exact B-spline micro-structures and isogeometric heat-transfer analysis.",
        epilog="Run 'iga COMMAND --help' for the options of one command.",
    )
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    demo = sub.add_parser(
        "demo",
        help="run a built-in demonstration (heat-sink)",
        description="Run a built-in demonstration: 'heat-sink' builds the hierarchical heat sink of Massarwi et al. 2018 (Section 8), "
        "solves steady heat transfer and writes VTU, PNG and a JSON summary into --out.",
    )
    demo.add_argument("name", choices=["heat-sink"], help="which demonstration to run")
    demo.add_argument("--out", default="heat-sink-out", help="output folder (created if missing)")
    demo.add_argument("--variant", choices=["circular", "vertical"], default="circular", help="heat-sink variant")
    demo.add_argument("--levels", type=int, default=None, help="hierarchy levels (default: the paper's, 3 circular, 2 vertical)")
    demo.add_argument("--refine", type=int, default=0, help="uniform h-refinement rounds of every tile space")
    demo.set_defaults(func=_cmd_demo)
    run = sub.add_parser(
        "run",
        help="run a pipeline described in a TOML file",
        description="Run a pipeline (deformation map, tile, paving, materials, boundary conditions, solver, "
        "outputs) described in a TOML file; see the README for the schema.",
    )
    run.add_argument("config", help="path to the CONFIG.toml file")
    run.set_defaults(func=_cmd_run)
    info = sub.add_parser("info", help="describe the splines in a saved .npz file",
                          description="Print degrees, sizes, channels, domain and bounding box of saved splines.")
    info.add_argument("file", help="a file written by geometry.save / geometry.save_all")
    info.set_defaults(func=_cmd_info)
    return parser


def main(argv=None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    if not getattr(args, "func", None):
        parser.print_help()
        return 0
    from .memory import retain_freed_memory

    retain_freed_memory()  # a whole-process choice, so the application (not the library) makes it
    try:
        return int(args.func(args))
    except ToolkitError as exc:
        print(f"iga: error: {exc}", file=sys.stderr)
        return 1


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
