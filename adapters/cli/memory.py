"""Give the C heap's free memory back to the operating system (glibc's ``malloc_trim``).

A daemon that runs all day frees as much as it allocates, but glibc keeps freed chunks in its arenas
(one per thread that allocated: Zenoh's, the writer's, numpy's temporaries), so the resident size
creeps up by fragmentation although nothing leaks. Trimming now and then keeps it flat; measured on
the lab under 100 observations a second: 80 -> 89 MB over 40,000 observations untrimmed, flat at
81 MB trimmed every few seconds.

Example::

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


def free_memory_releaser() -> Callable[[], None] | None:
    """A function that trims the C heap, or None when the C library is not glibc."""
    name = ctypes.util.find_library("c")
    try:
        libc = ctypes.CDLL(name or "libc.so.6")
        trim = libc.malloc_trim
    except (OSError, AttributeError):
        log.debug("No malloc_trim in the C library %r: the heap is not trimmed", name)
        return None
    trim.argtypes = [ctypes.c_size_t]
    trim.restype = ctypes.c_int

    def release() -> None:
        trim(0)

    return release
