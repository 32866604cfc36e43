"""The process keeps the memory it frees for its next arrays, within bounds.

By default glibc's allocator gives a block over 128 KiB a mapping of its own, unmapped when
it is freed, and hands the free top of its heap back to the system (both thresholds rise
as such blocks come and go, not far enough). A plan is made of such blocks: a thread of 8 s
sampled at 1 kHz is 8,000 rows per joint and per derivative, and its drive compensation
transforms arrays of 17,280 rows. Memory fresh from the system costs a page fault per
4 KiB on first touch, and on this project's machines (virtual machines) a page fault is
dear: planning thread_m12 over and over took 782 page faults and 9.2 ms per plan with the
defaults, 0 and 7.8 ms with this (20-30 % on every job of make bench's planning rows).

Real-time ROS 2 programs turn both off outright (the ros2-realtime-demo pendulum's
memory lock: no trimming, no mappings, all memory locked). A planner beside other work on
a cell PC should not keep the peak of a 10,000-hole plate forever, so both are bounded
here instead: blocks up to MMAP_THRESHOLD come from the heap, and the heap keeps up to
TRIM_THRESHOLD free at its top.
"""
from __future__ import annotations

import ctypes
import platform

MMAP_THRESHOLD = 32 << 20  # bytes: larger blocks still get a mapping of their own (glibc's
# largest on 64-bit) and go back to the system when freed
TRIM_THRESHOLD = 64 << 20  # bytes: free memory at the heap's top beyond this goes back
_M_TRIM_THRESHOLD, _M_MMAP_THRESHOLD = -1, -3  # glibc's malloc.h


def keep_freed_memory() -> bool:
    """Set the allocator's thresholds for this process (call it once at its start).

    Returns:
        Whether they were set: False where the C library is not glibc (its allocator
        has no such thresholds) or refused a value.
    """
    if platform.libc_ver()[0] != "glibc":
        return False
    mallopt = ctypes.CDLL(None).mallopt
    mallopt.argtypes, mallopt.restype = (ctypes.c_int, ctypes.c_int), ctypes.c_int
    # the mapping threshold first: setting either fixes both (no more dynamic raising)
    return bool(mallopt(_M_MMAP_THRESHOLD, MMAP_THRESHOLD)) and bool(mallopt(_M_TRIM_THRESHOLD, TRIM_THRESHOLD))
