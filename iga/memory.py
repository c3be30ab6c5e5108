"""Memory of large assemblies: a process-level allocator setting (opt-in; the CLI and benchmarks use it)
and the page size of streamed arrays.

Assembly and solve allocate and free arrays of hundreds of MB.  glibc serves
each one with a fresh ``mmap`` and unmaps it on free, so every large array
is page-faulted in again.  On virtual machines that hand freed pages back to
the host (free-page reporting), those faults dominate the time of a large
assembly (docs/performance.md has the figures).

:func:`retain_freed_memory` changes allocator behaviour for the whole process,
so the library never calls it on import; applications opt in (``iga`` does).
:func:`streamed_empty` concerns one array only: the heat operator's CSR
arrays take it (:class:`iga.vector_csr.VectorCSR`).
"""

from __future__ import annotations

import ctypes
import ctypes.util
import mmap
import sys
from functools import lru_cache

import numpy as np

_M_TRIM_THRESHOLD = -1
_M_MMAP_MAX = -4


def retain_freed_memory() -> bool:
    """Serve large arrays from the heap and keep freed memory for reuse (glibc only).

    Sets ``M_MMAP_MAX = 0`` and a 2 GiB ``M_TRIM_THRESHOLD``: freed blocks stay
    in the process and are reused without new page faults.  The resident
    size then stays near its peak until exit.  Returns True when applied,
    False where the C library is not glibc (nothing is changed).
    """
    libc = _libc()
    try:
        mallopt = libc.mallopt
        _ = libc.gnu_get_libc_version  # glibc only: musl has no mallopt knobs worth setting
    except AttributeError:  # (None off Linux, too)
        return False
    mallopt.argtypes = [ctypes.c_int, ctypes.c_int]
    return bool(mallopt(_M_MMAP_MAX, 0)) and bool(mallopt(_M_TRIM_THRESHOLD, 2**31 - 1))


_MADV_NOHUGEPAGE = 15
_SMALL_PAGES_BYTES = 1 << 24  # 16 MiB: smaller arrays are left to NumPy's default


@lru_cache(maxsize=1)
def _libc():
    """The C library (``ctypes.CDLL``), or None off Linux or where it cannot be loaded."""
    if not sys.platform.startswith("linux"):
        return None
    try:
        return ctypes.CDLL(ctypes.util.find_library("c"), use_errno=True)
    except (OSError, TypeError):
        return None


def _madvise():
    """libc's ``madvise`` (None where :func:`_libc` has no C library or it has no ``madvise``)."""
    fn = getattr(_libc(), "madvise", None)
    if fn is not None:
        fn.argtypes = [ctypes.c_void_p, ctypes.c_size_t, ctypes.c_int]
        fn.restype = ctypes.c_int
    return fn


def streamed_empty(n: int, dtype=float) -> np.ndarray:
    """``np.empty(n, dtype)`` for a large array that is written once in order and then streamed (the arrays
    of a sparse matrix), mapped in ordinary 4 KiB pages.

    NumPy asks Linux for transparent huge pages on every array of 4 MiB or more (``madvise(MADV_HUGEPAGE)``).
    Where a huge page must be assembled when first written, on a virtual machine that has handed its free
    memory back to the host, that first write is several times slower: measured on this Firecracker VM,
    800 MiB never touched before filled at 0.35-0.38 GB/s with huge pages and 2.1-2.2 GB/s without
    (docs/performance.md).  A streamed array gains nothing from huge pages (its pages are read in order),
    so this one asks for small pages (``MADV_NOHUGEPAGE``) before anything is written.  Arrays under
    16 MiB, and systems without the call, are left as NumPy makes them.
    """
    a = np.empty(n, dtype)
    fn = _madvise()
    if fn is not None and a.nbytes >= _SMALL_PAGES_BYTES:
        page = mmap.PAGESIZE
        start = -(-a.ctypes.data // page) * page
        stop = (a.ctypes.data + a.nbytes) // page * page
        fn(start, stop - start, _MADV_NOHUGEPAGE)  # a failure leaves the pages as NumPy asked for them
    return a
