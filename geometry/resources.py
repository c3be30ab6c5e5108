"""Memory budget: estimates are checked against it before large work starts.

Building a paving of 10^6 tiles, a hierarchy of 40 levels or a space refined
ten times would exhaust the machine long after the user's mistake; instead,
every such entry point estimates its memory first and raises the calling
package's error (naming the estimate and the fix) when it exceeds the budget.

The budget is the memory available on this machine (``MemAvailable`` on
Linux, the physical memory elsewhere) unless set: ``with memory_budget(gib):``
around the work (a pipeline's ``max_memory_gib`` under ``[limits]`` does
this), ``set_memory_limit(gib)`` for the rest of the current context (the CLI
option ``--max-memory``, or else the environment variable ``IGA_MAX_MEMORY_GIB``,
which the ``iga`` command reads once at start: :func:`environment_limit`).
The budget is a context variable: a ``with`` block restores the caller's on
exit, and threads or asyncio tasks started elsewhere do not see it.
"""

from __future__ import annotations

import functools
import gc
import os
import sys
from contextlib import contextmanager
from contextvars import ContextVar

from .cache import memo
from .errors import SplineError
from .errors import show
from .numbers import is_real

__all__ = ["usable_cores", "available_memory", "memory_limit", "environment_limit", "memory_budget", "set_memory_limit", "check_memory", "peak_memory_mib", "GiB",
           "paused_gc", "bulk_build", "one_blas_thread"]

GiB = float(1 << 30)
_LIMIT: ContextVar[float | None] = ContextVar("memory_limit_bytes", default=None)  # None: available memory


def usable_cores() -> int:
    """CPU cores this process may run on: its affinity mask where the OS has one (``taskset``, cgroups,
    batch schedulers), not the machine's count."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except (AttributeError, OSError):  # no affinity on this platform
        return max(1, os.cpu_count() or 1)


@memo(1)
def _blas_controller():
    from threadpoolctl import ThreadpoolController

    return ThreadpoolController()  # finding the loaded BLAS libraries costs 0.4 ms: once per process


@contextmanager
def one_blas_thread():
    """BLAS held to one thread inside the block (the caller's setting restored after).

    Two uses: work that runs its own threads (BLAS's idle threads would spin between their calls), and
    results that must not depend on the thread count: a multi-threaded BLAS may split a product's sums
    differently from a single thread, so the same product differs in its last bits between a run on two
    threads and one on one.  Holding one thread wherever a reduction order matters makes the serial and
    the parallel paths compute the same numbers.
    """
    with _blas_controller().limit(limits=1, user_api="blas"):
        yield


def available_memory() -> float:
    """Bytes of memory this process may still use (an estimate; Linux ``MemAvailable``)."""
    try:
        with open("/proc/meminfo") as fh:
            for line in fh:
                if line.startswith("MemAvailable:"):
                    return float(line.split()[1]) * 1024
    except OSError:
        pass
    try:
        return float(os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES"))
    except (ValueError, OSError, AttributeError):  # not a POSIX system
        return 16 * GiB


def _bytes(gib: float | None) -> float | None:
    if gib is not None and not (is_real(gib) and 0 < gib < float("inf")):
        raise SplineError(f"the memory limit must be a positive number of GiB, got {show(gib)}")
    return None if gib is None else float(gib) * GiB


def set_memory_limit(gib: float | None) -> None:
    """Set the memory budget in GiB for the rest of the current context (None: the available memory)."""
    _LIMIT.set(_bytes(gib))


@contextmanager
def memory_budget(gib: float | None):
    """The memory budget in GiB inside a ``with`` block (None: leave the current one); restored on exit."""
    token = _LIMIT.set(_bytes(gib)) if gib is not None else None
    try:
        yield
    finally:
        if token is not None:
            _LIMIT.reset(token)


def memory_limit() -> float:
    """The memory budget in bytes (see the module notes)."""
    limit = _LIMIT.get()
    return limit if limit is not None else available_memory()


def environment_limit() -> float | None:
    """The budget in GiB the environment variable ``IGA_MAX_MEMORY_GIB`` sets, or None: read by the application
    edge (the ``iga`` command; a script may pass it to :func:`set_memory_limit`), never by library calls."""
    env = os.environ.get("IGA_MAX_MEMORY_GIB")
    if not env:
        return None
    try:
        value = float(env)
    except ValueError:
        value = -1.0
    if not value > 0:
        raise SplineError(f"IGA_MAX_MEMORY_GIB must be a positive number of GiB, got {show(env)}")
    return value


def check_memory(estimate: float, what: str, error=SplineError, hint: str = "") -> None:
    """Raise ``error`` when ``estimate`` (bytes) exceeds the budget, naming ``what`` and the estimate."""
    limit = memory_limit()
    if estimate > limit:
        raise error(
            f"{what} needs about {estimate / GiB:.3g} GiB, more than the {limit / GiB:.3g} GiB this run may use"
            f"{'; ' + hint if hint else ''}; raise the limit with --max-memory / max_memory_gib / "
            "IGA_MAX_MEMORY_GIB if the machine has the memory"
        )


def peak_memory_mib() -> float | None:
    """High-water mark of this process's resident memory in MiB, or None where the platform does not say."""
    try:
        import resource
    except ImportError:  # Windows
        return None
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    return peak / (1024 * 1024) if sys.platform == "darwin" else peak / 1024  # bytes on macOS, KiB on Linux


@contextmanager
def paused_gc():
    """Automatic garbage collection paused inside the block, restored on exit (also on an error).

    Building a large model creates hundreds of thousands of objects that live on (a 21^3 lattice: 280k), and
    each time their number grows by a quarter CPython walks all of them looking for reference cycles, which
    a build does not make: 0.46 s of that lattice's 2.7 s build went to 1,258 collections, 0.35 s to the
    four full ones (docs/performance.md).  Nothing is lost by pausing: the next collection after the block
    finds whatever cycles it left.  Nested blocks (a builder calling another) leave the collector paused
    until the outermost one ends; a block entered while collection was already off leaves it off.
    """
    was = gc.isenabled()
    gc.disable()
    try:
        yield
    finally:
        if was:
            gc.enable()


def bulk_build(fn):
    """Decorator: ``fn`` runs with automatic garbage collection paused (:func:`paused_gc`); for the
    entry points that build models of many patches (the pavings of :mod:`tiling.paving`)."""

    @functools.wraps(fn)
    def run(*args, **kwargs):
        with paused_gc():
            return fn(*args, **kwargs)

    return run
