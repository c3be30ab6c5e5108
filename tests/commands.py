"""Run the ``iga`` command, an example script or a documentation block inside the test process.

A new interpreter costs 3-4 s before the first line of a script runs (importing the toolkit, NumPy, SciPy, VTK and
loading the compiled kernels from numba's cache), more than most of the scripts themselves; the suite runs about
a hundred of them.  Here each runs as the interpreter would run it (``__main__``, its own namespace, ``sys.argv``,
the working folder), with its output captured, its exit status returned (``SystemExit`` and uncaught exceptions
as Python reports them) and every setting it makes in a ``ContextVar`` (the memory budget, progress display)
dropped when it returns.  The entry points themselves (``python -m iga``, the console script, the environment read
at start) keep their own tests in a new process (``test_pipeline.py``, ``test_products_primitives_io.py``,
``test_bad_input.py``).
"""

import contextlib
import contextvars
import io
import os
import runpy
import sys
import traceback
from dataclasses import dataclass
from pathlib import Path


@dataclass(frozen=True)
class Completed:
    """What a run left: its exit status and what it printed (as ``subprocess.CompletedProcess`` holds them)."""

    returncode: int
    stdout: str
    stderr: str


def _status(code) -> int:
    """The exit status of ``SystemExit(code)``: None is 0, an integer itself, anything else printed and 1."""
    if code is None or isinstance(code, int):
        return int(code or 0)
    print(code, file=sys.stderr)
    return 1


def _run(call, cwd, argv, env) -> Completed:
    out, err = io.StringIO(), io.StringIO()
    saved = os.getcwd(), sys.argv, {k: os.environ.get(k) for k in env}
    try:
        os.chdir(cwd if cwd is not None else saved[0])
        sys.argv = [str(a) for a in argv]
        os.environ.update({k: str(v) for k, v in env.items()})
        with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
            try:
                code = _status(contextvars.copy_context().run(call))
            except SystemExit as exc:
                code = _status(exc.code)
            except Exception:  # noqa: BLE001 -- reported as the interpreter reports it: a traceback and status 1
                traceback.print_exc()
                code = 1
    finally:
        os.chdir(saved[0])
        sys.argv = saved[1]
        for k, v in saved[2].items():
            os.environ.pop(k, None) if v is None else os.environ.__setitem__(k, v)
    return Completed(code, out.getvalue(), err.getvalue())


def iga_command(*args, cwd=None, env=None) -> Completed:
    """``iga ARGS`` (as ``python -m iga ARGS``) run in this process.  The allocator setting the command makes for
    its own process (:func:`iga.app.memory.retain_freed_memory`) is left out: it would outlive the call."""
    from iga.app import cli

    def call():
        held = cli.retain_freed_memory
        cli.retain_freed_memory = lambda: False
        try:
            return cli.main([str(a) for a in args])
        finally:
            cli.retain_freed_memory = held

    return _run(call, cwd, ["iga", *args], env or {})


def run_script(path: Path, *args, cwd=None) -> Completed:
    """``python PATH ARGS`` run in this process."""
    def call():
        runpy.run_path(str(path), run_name="__main__")

    return _run(call, cwd, [path, *args], {})


def run_code(code: str, cwd=None) -> Completed:
    """``python -c CODE`` run in this process, in a namespace of its own."""
    def call():
        exec(compile(code, "<string>", "exec"), {"__name__": "__main__"})

    return _run(call, cwd, ["-c"], {})
