"""Process-level allocator setting for large assemblies (opt-in; the CLI and benchmarks use it).

Assembly and solve allocate and free arrays of hundreds of MB.  glibc serves
each one with a fresh ``mmap`` and unmaps it on free, so every large array
is page-faulted in again.  On virtual machines that hand freed pages back to
the host (free-page reporting), those faults dominate the time of a large
assembly (docs/performance.md has the figures).

:func:`retain_freed_memory` changes allocator behaviour for the whole process,
so the library never calls it on import; applications opt in (``iga`` does).
"""

from __future__ import annotations

import ctypes
import ctypes.util
import sys

_M_TRIM_THRESHOLD = -1
_M_MMAP_MAX = -4


def retain_freed_memory() -> bool:
    """Serve large arrays from the heap and keep freed memory for reuse (glibc only).

    Sets ``M_MMAP_MAX = 0`` and a 2 GiB ``M_TRIM_THRESHOLD``: freed blocks stay
    in the process and are reused without new page faults.  The resident
    size then stays near its peak until exit.  Returns True when applied,
    False where the C library is not glibc (nothing is changed).
    """
    if not sys.platform.startswith("linux"):
        return False
    name = ctypes.util.find_library("c")
    try:
        libc = ctypes.CDLL(name)
        mallopt = libc.mallopt
        _ = libc.gnu_get_libc_version  # glibc only: musl has no mallopt knobs worth setting
    except (OSError, AttributeError, TypeError):
        return False
    mallopt.argtypes = [ctypes.c_int, ctypes.c_int]
    return bool(mallopt(_M_MMAP_MAX, 0)) and bool(mallopt(_M_TRIM_THRESHOLD, 2**31 - 1))
