"""Memory of large assemblies: process-level allocator settings (opt-in; the CLI and benchmarks use one,
the distributed solve the other) and the page size of streamed arrays.

Assembly and solve allocate and free arrays of hundreds of MB.  glibc serves
each one with a fresh ``mmap`` and unmaps it on free, so every large array
is page-faulted in again.  On virtual machines that hand freed pages back to
the host (free-page reporting), those faults dominate the time of a large
assembly (docs/performance.md has the figures).

:func:`retain_freed_memory` changes allocator behaviour for the whole process,
so the library never calls it on import; applications opt in (``iga`` does, on
one process).  :func:`return_freed_memory` unmaps large arrays when freed
again: a distributed solve, whose point is memory per rank, sets it once
PETSc is loaded, as loading Debian's PETSc turns unmapping off.
:func:`streamed_empty` concerns one array only: the heat operator's CSR
arrays take it (:class:`iga.assembly.vector_csr.VectorCSR`).
"""

from __future__ import annotations

import ctypes
import ctypes.util
import mmap
import sys

import numpy as np

from geometry.cache import memo

_M_TRIM_THRESHOLD = -1
_M_MMAP_THRESHOLD = -3
_M_MMAP_MAX = -4


def retain_freed_memory() -> bool:
    """Serve large arrays from the heap and keep freed memory for reuse (glibc only).

    Sets ``M_MMAP_MAX = 0`` and a 2 GiB ``M_TRIM_THRESHOLD``: freed blocks stay
    in the process and are reused without new page faults.  The resident
    size then stays near its peak until exit.  Returns True when applied,
    False where the C library is not glibc (nothing is changed).
    """
    return _mallopt(0, None, 2**31 - 1)


def return_freed_memory() -> bool:
    """Give blocks of 16 MiB and more mappings of their own, unmapped when freed, and return a free heap top
    above 16 MiB to the system (glibc only: ``M_MMAP_MAX = 65536``, ``M_MMAP_THRESHOLD`` and
    ``M_TRIM_THRESHOLD`` 16 MiB): the resident size follows the large arrays in use, while smaller blocks
    are still reused from the heap without new page faults.  Returns True when applied, False where the C
    library is not glibc.

    The distributed solve sets this after loading PETSc (:func:`iga.distributed.solve.load_petsc`): Debian's
    PETSc 3.18 loads SuperLU_DIST, whose loader sets ``M_MMAP_MAX = 0`` and ``M_TRIM_THRESHOLD = -1`` for
    the whole process, so no freed array went back; on each of 4 ranks of the 21^3 cross lattice 293 MiB
    lay freed in the heap when GAMG's set-up began.  Measured on 4 ranks (docs/performance.md): the
    lattice's peak per rank 938-945 -> 870-876 MiB with 16 MiB (the same with glibc's 128 KiB, where every
    slab of the assembly is faulted in afresh, or 32 MiB); the refined demo sink's 539-541 MiB with 16 MiB
    or less, 580-599 MiB with 32 MiB, as its rank's matrices are smaller.
    """
    return _mallopt(65536, 16 << 20, 16 << 20)


def _mallopt(mmap_max: int, mmap_threshold: int | None, trim_threshold: int) -> bool:
    """glibc's ``M_MMAP_MAX``, ``M_MMAP_THRESHOLD`` (None: left as it is) and ``M_TRIM_THRESHOLD``; False
    (nothing changed) off glibc."""
    libc = _libc()
    try:
        mallopt = libc.mallopt
        _ = libc.gnu_get_libc_version  # glibc only: musl has no mallopt knobs worth setting
    except AttributeError:  # (None off Linux, too)
        return False
    mallopt.argtypes = [ctypes.c_int, ctypes.c_int]
    done = bool(mallopt(_M_MMAP_MAX, mmap_max)) and bool(mallopt(_M_TRIM_THRESHOLD, trim_threshold))
    return done and (mmap_threshold is None or bool(mallopt(_M_MMAP_THRESHOLD, mmap_threshold)))


_MADV_NOHUGEPAGE = 15
_SMALL_PAGES_BYTES = 1 << 24  # 16 MiB: smaller arrays are left to NumPy's default


@memo(1)
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
