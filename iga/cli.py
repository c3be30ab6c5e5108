"""The ``iga`` command line.

Subcommands
-----------
``iga demo heat-sink --out DIR``  the seed's heat-sink analysis (VTU, PNG, JSON summary)
``iga run CONFIG.toml``           a pipeline described in a TOML file
``iga info FILE.npz``             describe the splines stored in a file
"""

from __future__ import annotations

import argparse
import sys

from geometry.errors import ToolkitError

NOT_YET = "not yet available: {what} lands with the {issue} issue of the project plan."


def _cmd_demo(args) -> int:
    print(NOT_YET.format(what=f"the {args.name} demo", issue="heat-sink (end-to-end)"))
    return 0


def _cmd_run(args) -> int:
    print(NOT_YET.format(what="running TOML pipelines", issue="heat-sink (end-to-end)"), file=sys.stderr)
    return 2


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
        description="Run a built-in demonstration: 'heat-sink' builds the seed's hierarchical heat sink, "
        "solves steady heat transfer and writes VTU, PNG and a JSON summary into --out.",
    )
    demo.add_argument("name", choices=["heat-sink"], help="which demonstration to run")
    demo.add_argument("--out", default="heat-sink-out", help="output folder (created if missing)")
    demo.add_argument("--variant", choices=["circular", "vertical"], default="circular", help="heat-sink variant")
    demo.add_argument("--levels", type=int, default=None, help="hierarchy levels (default: the seed's)")
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
    try:
        return int(args.func(args))
    except ToolkitError as exc:
        print(f"iga: error: {exc}", file=sys.stderr)
        return 1


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
