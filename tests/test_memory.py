"""iga.app.memory: the pages of streamed arrays (read back from the kernel's own account, /proc/self/smaps)."""

from __future__ import annotations

import sys

import numpy as np
import pytest

from iga.app.memory import streamed_empty
from iga.assembly.vector_csr import VectorCSR


def _vm_flags(a: np.ndarray) -> list[str]:
    """The VmFlags of the mapping that holds the middle of ``a`` (/proc/self/smaps)."""
    address = a.ctypes.data + a.nbytes // 2
    inside = False
    for line in open("/proc/self/smaps"):
        head = line.split()[0]
        if "-" in head and not head.endswith(":"):
            lo, hi = (int(x, 16) for x in head.split("-"))
            inside = lo <= address < hi
        elif inside and head == "VmFlags:":
            return line.split()[1:]
    raise AssertionError("no mapping holds the array")


linux = pytest.mark.skipif(not sys.platform.startswith("linux"), reason="madvise and smaps are Linux's")


@linux
def test_large_streamed_arrays_ask_for_small_pages():
    a = streamed_empty(3 << 21, np.int32)  # 24 MiB
    assert a.shape == (3 << 21,) and a.dtype == np.int32
    assert "nh" in _vm_flags(a)  # MADV_NOHUGEPAGE reached the kernel
    a[:] = 7  # and the memory is ordinary, writable memory
    assert int(a[-1]) == 7


@linux
def test_small_arrays_are_left_as_numpy_makes_them():
    a = streamed_empty(1000)
    assert a.shape == (1000,) and a.dtype == float
    big = np.empty(3 << 21)  # NumPy's own large array keeps its huge-page request
    assert "nh" not in _vm_flags(big)


@linux
def test_heat_operator_arrays_use_small_pages_and_elastic_ones_do_not():
    heat = VectorCSR(np.array([0, 1000]), np.array([5 << 20]), components=1)
    elastic = VectorCSR(np.array([0, 1000]), np.array([5 << 20]), components=3)
    assert "nh" in _vm_flags(heat.data) and "nh" in _vm_flags(heat.indices)
    assert "nh" not in _vm_flags(elastic.data)


def _malloc_info() -> tuple[int, int]:
    """(heap bytes, bytes in mappings of their own) of glibc's allocator (``mallinfo2()``: arena, hblkhd)."""
    import ctypes
    import ctypes.util

    class Info(ctypes.Structure):
        _fields_ = [(n, ctypes.c_size_t) for n in
                    "arena ordblks smblks hblks hblkhd usmblks fsmblks uordblks fordblks keepcost".split()]

    libc = ctypes.CDLL(ctypes.util.find_library("c"))
    if not hasattr(libc, "mallinfo2"):
        pytest.skip("the C library has no mallinfo2 (glibc 2.33 or later)")
    libc.mallinfo2.restype = Info
    info = libc.mallinfo2()
    return int(info.arena), int(info.hblkhd)


@linux
def test_returned_memory_gives_large_arrays_their_own_mappings_again():
    from iga.app.memory import retain_freed_memory, return_freed_memory

    # each array is larger than the whole heap, so no free block of the heap can serve it: it either grows the
    # heap or gets a mapping of its own, whatever the tests before left in this process
    try:
        if not retain_freed_memory():
            pytest.skip("not glibc: no allocator settings to change")
        heap, mapped = _malloc_info()
        kept = np.ones((heap >> 3) + (5 << 20))  # the heap grows: nothing new is mapped
        assert _malloc_info()[1] - mapped < kept.nbytes
        del kept
    finally:
        assert return_freed_memory()  # large blocks unmapped again, for the rest of this process too
    heap, mapped = _malloc_info()
    own = np.ones((heap >> 3) + (6 << 20))  # a mapping of its own, unmapped when freed
    assert _malloc_info()[1] - mapped >= own.nbytes
    del own
    assert _malloc_info()[1] - mapped < 1 << 20
