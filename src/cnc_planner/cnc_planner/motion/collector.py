"""Python's cyclic garbage collector held off while a plan is made.

Planning a long job allocates hundreds of thousands of objects (pieces, samplers, their
closures) that all live until the plan is dropped; each full collection walks every one
of them again, over and over as planning goes on. Reference counting frees what planning
discards, so the collector can wait: it runs once planning ends. ``paused`` nests and is
shared by threads (the planner plans on its intake thread while its stream samples).
"""
from __future__ import annotations

import gc
import threading
from collections.abc import Iterator
from contextlib import contextmanager

_lock = threading.Lock()
_depth = 0
_was_enabled = False


@contextmanager
def paused() -> Iterator[None]:
    """The collector off inside (if it was on when the first of nested pauses began)."""
    global _depth, _was_enabled
    with _lock:
        if _depth == 0:
            _was_enabled = gc.isenabled()
            gc.disable()
        _depth += 1
    try:
        yield
    finally:
        with _lock:
            _depth -= 1
            if _depth == 0 and _was_enabled:
                gc.enable()
