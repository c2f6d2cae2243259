"""Give the C heap's free memory back to the operating system (glibc's ``malloc_trim``).

A daemon that runs all day frees as much as it allocates, but glibc keeps freed chunks in its arenas
(one per thread that allocated: Zenoh's, the writer's, numpy's temporaries), so the resident size
creeps up by fragmentation although nothing leaks. Two measures keep it flat:

- a fixed mmap threshold (:func:`fix_heap_thresholds`): glibc raises its threshold each time a large
  block is freed, up to 32 MB, after which RocksDB's 1 MB memtable arena blocks, map windows and Zenoh
  buffers are carved from the main heap between long-lived objects and never given back. Fixed at
  128 KiB, large blocks are mapped and unmapped on their own. Measured on the lab at 30 moves a second
  for 7 minutes in the writer: +0.6 MB/min with the default, +0.1 MB/min fixed;
- trimming now and then (:func:`free_memory_releaser`): 80 -> 89 MB over 40,000 observations untrimmed,
  flat at 81 MB trimmed every few seconds.

Example::

    fix_heap_thresholds()                 # once, at start
    release = free_memory_releaser()      # None where the C library has no malloc_trim
    if release is not None:
        release()
"""

from __future__ import annotations

import ctypes
import ctypes.util
import logging
from collections.abc import Callable

log = logging.getLogger(__name__)

_M_TRIM_THRESHOLD = -1
_M_MMAP_THRESHOLD = -3
LARGE_BLOCK = 128 * 1024
"""Blocks from this size on are mapped on their own and unmapped when freed."""


def _libc() -> ctypes.CDLL | None:
    name = ctypes.util.find_library("c")
    try:
        return ctypes.CDLL(name or "libc.so.6")
    except OSError:
        return None


def fix_heap_thresholds(large_block: int = LARGE_BLOCK) -> bool:
    """Fix glibc's mmap and trim thresholds at ``large_block`` bytes (no dynamic raising); False where
    the C library has no ``mallopt`` (not glibc)."""
    libc = _libc()
    mallopt = getattr(libc, "mallopt", None)
    if mallopt is None:
        log.debug("No mallopt in the C library: heap thresholds left as they are")
        return False
    mallopt.argtypes = [ctypes.c_int, ctypes.c_int]
    mallopt.restype = ctypes.c_int
    ok = bool(mallopt(_M_MMAP_THRESHOLD, large_block)) and bool(mallopt(_M_TRIM_THRESHOLD, large_block))
    log.debug("Heap thresholds fixed at %d bytes: %s", large_block, ok)
    return ok


def free_memory_releaser() -> Callable[[], None] | None:
    """A function that trims the C heap, or None when the C library is not glibc."""
    libc = _libc()
    trim = getattr(libc, "malloc_trim", None)
    if trim is None:
        log.debug("No malloc_trim in the C library: the heap is not trimmed")
        return None
    trim.argtypes = [ctypes.c_size_t]
    trim.restype = ctypes.c_int

    def release() -> None:
        trim(0)

    return release
