"""keep_freed_memory: freed arrays stay in the process for the next ones, within bounds.

Each case runs in a fresh interpreter (the allocator's thresholds are process-wide) and
reads the resident set from /proc before and after freeing a block it has touched."""
from __future__ import annotations

import json
import platform
import subprocess
import sys

import pytest

from cnc_msgs_py.heap import MMAP_THRESHOLD, TRIM_THRESHOLD

pytestmark = pytest.mark.skipif(platform.libc_ver()[0] != "glibc", reason="the thresholds are glibc's")

MIB = 1 << 20
SCRIPT = """
import json, sys
import numpy as np
from cnc_msgs_py.heap import keep_freed_memory

def rss():
    for line in open("/proc/self/status"):
        if line.startswith("VmRSS:"):
            return int(line.split()[1]) * 1024

kept = keep_freed_memory() if sys.argv[1] == "keep" else None
blocks = [np.ones(int(sys.argv[2]) // 8) for _ in range(int(sys.argv[3]))]  # touched: resident
held = rss()
del blocks
freed = rss()
again = np.ones(int(sys.argv[2]) // 8)
print(json.dumps({"kept": kept, "returned": held - freed, "grew_again": rss() - freed}))
"""


def freeing(mode: str, size: int, count: int = 1) -> dict:
    """Touch ``count`` arrays of ``size`` bytes, free them, then touch one again."""
    out = subprocess.run([sys.executable, "-c", SCRIPT, mode, str(size), str(count)], capture_output=True, text=True,
                         check=True, timeout=60)
    return json.loads(out.stdout)


def test_glibcs_defaults_give_a_freed_block_back_and_fault_it_in_again():
    """The premise: without the setting an 8 MiB array is unmapped when freed, and the
    next one costs its pages again."""
    result = freeing("default", 8 * MIB)
    assert result["returned"] > 7 * MIB
    assert result["grew_again"] > 7 * MIB


def test_a_freed_block_below_the_thresholds_stays_for_the_next_array():
    result = freeing("keep", 8 * MIB)
    assert result["kept"] is True
    assert result["returned"] < MIB
    assert result["grew_again"] < MIB


def test_a_block_above_the_mapping_threshold_still_goes_back_to_the_system():
    size = MMAP_THRESHOLD + 16 * MIB
    assert size < TRIM_THRESHOLD  # so that it is the mapping, not the trim, that returns it
    result = freeing("keep", size)
    assert result["returned"] > size - MIB


def test_at_most_the_trim_threshold_of_free_memory_stays():
    size, count = MMAP_THRESHOLD // 2, 2 * TRIM_THRESHOLD // MMAP_THRESHOLD + 1  # heap blocks, 80 MiB
    result = freeing("keep", size, count)
    assert size * count - TRIM_THRESHOLD > 8 * MIB  # what must go back, at least
    assert result["returned"] >= size * count - TRIM_THRESHOLD
