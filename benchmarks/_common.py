"""Small helpers shared by the benchmark scripts (tables, output folder, plots)."""

from __future__ import annotations

import json
import re
import subprocess
import sys
import time
from pathlib import Path

OUT = Path(__file__).parent / "out"
DOCS = Path(__file__).resolve().parent.parent / "docs"


def out_dir() -> Path:
    OUT.mkdir(exist_ok=True)
    return OUT


def figures_dir() -> Path:
    """Where a benchmark's pictures go: ``benchmarks/out/figures``, or the README's ``docs/`` when the
    script runs with ``--figures`` (as ``benchmarks/make_figures.py`` runs it: the one command that
    regenerates the tracked pictures), so that running a benchmark never changes the working tree."""
    if "--figures" in sys.argv:
        return DOCS
    path = out_dir() / "figures"
    path.mkdir(exist_ok=True)
    return path


def settle() -> None:
    """Collect garbage before a timed call: the full collection that importing numpy, SciPy, pyvista and the
    toolkit leaves pending (100-185k tracked objects, 60-130 ms on this VM) belongs to the imports, which a
    benchmark does not time, not to whichever call happens to trigger it (docs/performance.md).  Collections
    that the timed work itself triggers still count."""
    import gc

    gc.collect()


def run_child(cmd: list, label: str, env: dict | None = None) -> dict | None:
    """Run a benchmark child process ``cmd`` (environment ``env``, default this one's) whose last stdout line
    is a JSON row (the last line that opens with ``{``: a library may leave terminal codes after it, as
    VTK's output window does at exit under Open MPI); the row, or None after printing ``label`` and the end
    of its stderr when it failed."""
    out = subprocess.run(cmd, capture_output=True, text=True, env=env)
    text = re.sub(r"\x1b\[[0-9;]*[A-Za-z]", "", out.stdout)
    rows = [line for line in text.splitlines() if line.lstrip().startswith("{")]
    if out.returncode or not rows:
        print(f"{label} failed:\n{out.stderr[-2000:]}{out.stdout[-500:] if not rows else ''}")
        return None
    return json.loads(rows[-1].strip())


def collect_rows(jobs, describe, env: dict | None = None) -> list[dict]:
    """Run each child ``(cmd, label)`` of ``jobs`` (:func:`run_child`, environment ``env``) and keep the rows of
    those that succeed, printing ``describe(row)`` for each as it arrives (long benchmarks show their progress)."""
    rows = []
    for cmd, label in jobs:
        row = run_child(cmd, label, env)
        if row is not None:
            rows.append(row)
            print(describe(row), flush=True)
    return rows


def run_cases(script: str, cases, run, renders: bool = False) -> list[dict] | None:
    """Each case of a benchmark in a fresh subprocess of ``script``, so that peak memory is per case.

    Called as ``script --case NAME [--png]`` (the child), prints ``run(NAME)`` (``run(NAME, png)`` when
    ``renders``) as JSON and returns None.  Otherwise (the parent) runs every case, then, with
    ``renders`` and without ``--no-png``, once more with ``--png`` so that rendering is not timed, and
    returns the rows (failed cases print their error and are left out).
    """
    if len(sys.argv) > 2 and sys.argv[1] == "--case":
        args = (sys.argv[2], "--png" in sys.argv) if renders else (sys.argv[2],)
        print(json.dumps(run(*args)))
        return None
    png = renders and "--no-png" not in sys.argv
    rows = []
    for case in cases:
        row = run_child([sys.executable, script, "--case", case], f"case {case}")
        if row is None:
            continue
        rows.append(row)
        if png:
            figures = ["--figures"] if "--figures" in sys.argv else []
            subprocess.run([sys.executable, script, "--case", case, "--png"] + figures, check=True,
                           capture_output=True)
    return rows


def print_table(rows: list[dict], columns: list[tuple[str, str]]) -> None:
    """Print ``rows`` with ``columns`` = [(key, format spec)], header from the keys."""
    widths = [max(len(k), 12) for k, _ in columns]
    print("  ".join(k.rjust(w) for (k, _), w in zip(columns, widths)))
    for row in rows:
        cells = []
        for (k, fmt), w in zip(columns, widths):
            v = row.get(k, "")
            cells.append((format(v, fmt) if v != "" and v is not None else "-").rjust(w))
        print("  ".join(cells))


def save_json(name: str, data) -> Path:
    path = out_dir() / name
    path.write_text(json.dumps(data, indent=2))
    return path


def save_plot(fig, name: str) -> Path:
    """Lay out ``fig``, write it to benchmarks/out/``name`` (PNG, 120 dpi) and say where."""
    path = out_dir() / name
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    print(f"plot: {path}")
    return path


def pyplot():
    """matplotlib.pyplot with a non-interactive backend, or None if matplotlib is missing."""
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:  # the 'bench' extra is not installed
        print("(matplotlib not installed: pip install -e '.[bench]' for plots)")
        return None
    return plt


def timed(fn):
    """(fn(), its wall time in s), after :func:`settle`."""
    settle()
    t0 = time.perf_counter()
    out = fn()
    return out, time.perf_counter() - t0
