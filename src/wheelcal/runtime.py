"""Process-level settings that make the fits fast: the allocator and BLAS threads.

Layer 1 (beside ``model``): any layer may call it.

A fit allocates a few arrays of 0.5–15 MB per iteration (the Jacobian of a
90 s / 200 Hz recording is 6.5 MB).  glibc serves blocks above 128 kB by
``mmap`` and returns them to the system on ``free``, so every iteration
page-faults its arrays in again: measured here, 35–40 % of a fit's time on a
virtual machine.  :func:`tune_allocator` raises glibc's mmap and trim thresholds
(``mallopt``) so such blocks stay in the heap and are reused.  It is a no-op
where glibc is absent.  The cost: a process keeps up to ~100 MB it has freed.

The CLI, the batch and study workers and the test suite call it; a program that
uses the library directly may call it too.
"""

from __future__ import annotations

import ctypes
import ctypes.util
import functools

_M_TRIM_THRESHOLD = -1
_M_MMAP_THRESHOLD = -3
#: glibc caps the mmap threshold at 32 MB on 64-bit systems.
_MMAP_THRESHOLD_BYTES = 32 * 1024 * 1024
_TRIM_THRESHOLD_BYTES = 128 * 1024 * 1024


@functools.cache
def tune_allocator() -> bool:
    """Keep large arrays in the heap between fit iterations; True if it took effect."""
    name = ctypes.util.find_library("c")
    if not name:
        return False
    try:
        libc = ctypes.CDLL(name)
        mallopt = libc.mallopt
    except (OSError, AttributeError):
        return False
    mallopt.argtypes = [ctypes.c_int, ctypes.c_int]
    ok_mmap = mallopt(_M_MMAP_THRESHOLD, _MMAP_THRESHOLD_BYTES)
    ok_trim = mallopt(_M_TRIM_THRESHOLD, _TRIM_THRESHOLD_BYTES)
    return bool(ok_mmap and ok_trim)


def worker_init() -> None:
    """Initializer for worker processes: the allocator tuned and one BLAS thread."""
    from threadpoolctl import threadpool_limits

    tune_allocator()
    threadpool_limits(1)
