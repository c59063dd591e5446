"""Keep a long-running process's heap from growing with freed memory: glibc's mmap threshold.

glibc's malloc serves a request of at least ``M_MMAP_THRESHOLD`` bytes (128 KiB at start) with
its own ``mmap``, returned to the system on ``free``; but when such a block is freed it raises
the threshold to the block's size (up to 32 MiB), so that later blocks of that size come from
the heap instead. numpy allocates its arrays with malloc, and the online engine frees
window-sized ones (the τ estimate's copy of the window, its solver's matrices, the newest
pairs joined for a fit) several times a second, on two threads: once the threshold has risen
they fragment the heaps, and the memory the allocator holds grows while the memory in use
does not (``bench/bench_soak.py --mode engine``: the process's RSS rose 25–130 MiB an hour of
stream at 2×5 kHz, the heap in use stayed flat). Pinning the threshold (which also turns its
adjustment off) keeps those arrays in mappings of their own, given back when freed.
"""

from __future__ import annotations

import ctypes
import ctypes.util
import functools
from dataclasses import dataclass

__all__ = ["MMAP_THRESHOLD", "HeapInfo", "heap_info", "pin_mmap_threshold"]

#: Bytes from which glibc's malloc maps a block of its own (glibc's initial value).
MMAP_THRESHOLD = 128 * 1024
#: ``mallopt``'s parameter number for the threshold (glibc's malloc.h).
_M_MMAP_THRESHOLD = -3


def pin_mmap_threshold(threshold: int = MMAP_THRESHOLD) -> bool:
    """Fix glibc's mmap threshold of this process at ``threshold`` bytes (module notes).

    Returns whether it was set: False where the C library is not glibc (nothing is changed).
    """
    mallopt = getattr(_libc(), "mallopt", None)
    if mallopt is None:
        return False
    mallopt.argtypes = [ctypes.c_int, ctypes.c_int]
    mallopt.restype = ctypes.c_int
    return bool(mallopt(_M_MMAP_THRESHOLD, threshold))


@functools.cache
def _libc() -> ctypes.CDLL | None:
    # Once per process: find_library runs ldconfig, and every CDLL builds its function-pointer
    # class anew (a soak sampling heap_info once a second held 61 KiB more in ten minutes).
    name = ctypes.util.find_library("c")
    try:
        return ctypes.CDLL(name) if name else None
    except OSError:
        return None


class _Mallinfo2(ctypes.Structure):
    _fields_ = [
        (field, ctypes.c_size_t)
        for field in (
            "arena",
            "ordblks",
            "smblks",
            "hblks",
            "hblkhd",
            "usmblks",
            "fsmblks",
            "uordblks",
            "fordblks",
            "keepcost",
        )
    ]


@dataclass(frozen=True)
class HeapInfo:
    """glibc's malloc, all arenas (``mallinfo2``).

    Attributes
    ----------
    in_use : int
        Bytes allocated and not freed (heaps and own mappings).
    held : int
        Bytes the allocator holds from the system (heaps and own mappings): ``in_use`` plus
        what it keeps after ``free``.
    mapped_blocks : int
        Blocks served by a mapping of their own.
    """

    in_use: int
    held: int
    mapped_blocks: int


def heap_info() -> HeapInfo | None:
    """The state of glibc's malloc in this process; None without ``mallinfo2`` (glibc < 2.33)."""
    libc = _libc()
    mallinfo2 = getattr(libc, "mallinfo2", None)
    if mallinfo2 is None:
        return None
    mallinfo2.restype = _Mallinfo2
    info = mallinfo2()
    return HeapInfo(
        in_use=int(info.uordblks + info.hblkhd),
        held=int(info.arena + info.hblkhd),
        mapped_blocks=int(info.hblks),
    )
