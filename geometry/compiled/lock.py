"""One compilation of a numba kernel among processes that start together.

numba compiles a kernel on its first call in a process and caches the
machine code on disk; a process that calls it while another is still
compiling it compiles it again (tens of seconds for the assembly kernels).
Workers of a test run, MPI ranks and parallel pipeline runs start together,
so :func:`locked` wraps a kernel whose first call in this process holds an
exclusive lock file next to numba's cache: the first process compiles and
writes the cache, the others wait and then load it (numba reads the cache
index when a call needs a new signature).  The lock is released by the
operating system if a process dies holding it.  Where file locks are not
available (no ``fcntl``), the call goes ahead unlocked.
"""

from __future__ import annotations

import os
import tempfile
from contextlib import contextmanager

__all__ = ["locked"]


@contextmanager
def _exclusive(name: str):
    try:
        import fcntl
    except ImportError:  # (Windows) compile unlocked, as without this module
        yield
        return
    from numba.core.config import CACHE_DIR

    folder = CACHE_DIR or tempfile.gettempdir()
    os.makedirs(folder, exist_ok=True)
    with open(os.path.join(folder, f"{name}.compile-lock"), "a") as handle:
        fcntl.flock(handle, fcntl.LOCK_EX)
        try:
            yield
        finally:
            fcntl.flock(handle, fcntl.LOCK_UN)


class _FirstCallLocked:
    """``kernel`` whose calls before it holds a compiled signature run under the kernel's lock file."""

    __slots__ = ("kernel",)

    def __init__(self, kernel):
        self.kernel = kernel

    def __call__(self, *args):
        if getattr(self.kernel, "signatures", True):  # compiled here already, or a plain function (no JIT)
            return self.kernel(*args)
        f = self.kernel.py_func
        with _exclusive(f"{f.__module__}.{f.__qualname__}".replace("<", "").replace(">", "")):
            return self.kernel(*args)


def locked(kernel) -> _FirstCallLocked:
    """``kernel`` (a numba dispatcher) as a callable whose first call in this process compiles it at most once
    among the processes that share numba's cache directory (see the module notes)."""
    return _FirstCallLocked(kernel)
