"""Regenerate every picture the README shows (``docs/*.png``, ``docs/tiles/``): the one command that writes
tracked pictures; the benchmarks by themselves write theirs to ``benchmarks/out/figures``.

    python benchmarks/make_figures.py [--only NAME[,NAME...]]

Runs the demo (both heat sinks, the circular sink's thermal stress and its warm-up) and the picture-producing
benchmarks with ``--figures``; each in its own process, one after another (minutes in all).
"""

from __future__ import annotations

import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

HERE = Path(__file__).resolve().parent
DOCS = HERE.parent / "docs"
BENCHMARKS = ("tile_gallery", "bifurcation", "capped_models", "random_tiling", "vrep", "vrep_heat", "elasticity",
              "sweeps", "trimmed_tiles", "fig4_knot", "design", "adaptive")


def _demo(variant: str, option: str | None, picture: str, source: str) -> None:
    with tempfile.TemporaryDirectory() as tmp:
        cmd = [sys.executable, "-m", "iga", "--quiet", "demo", "heat-sink", "--variant", variant, "--out", tmp]
        subprocess.run(cmd + ([option] if option else []), check=True)
        shutil.copyfile(Path(tmp) / source, DOCS / picture)
    print(f"docs/{picture}")


def main() -> int:
    only = None
    if "--only" in sys.argv:
        only = set(sys.argv[sys.argv.index("--only") + 1].split(","))
    jobs = {"heat_sink_circular": lambda: _demo("circular", None, "heat_sink_circular.png", "heat_sink.png"),
            "heat_sink_vertical": lambda: _demo("vertical", None, "heat_sink_vertical.png", "heat_sink.png"),
            "heat_sink_stress": lambda: _demo("circular", "--stress", "heat_sink_stress.png", "heat_sink_stress.png"),
            "heat_sink_warm_up": lambda: _demo("circular", "--transient", "heat_sink_warm_up.png",
                                               "heat_sink_history.png")}
    for name in BENCHMARKS:
        jobs[name] = lambda name=name: subprocess.run([sys.executable, str(HERE / f"{name}.py"), "--figures"],
                                                      check=True, cwd=HERE)
    unknown = sorted((only or set()) - set(jobs))
    if unknown:
        raise SystemExit(f"unknown figure sources {unknown}; choose from {sorted(jobs)}")
    for name, job in jobs.items():
        if only is None or name in only:
            print(f"== {name}", flush=True)
            job()
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
