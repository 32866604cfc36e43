"""Work on the other core: a function run in a forked child process, its value handed back
through a pipe. The parent's memory is the child's (nothing to send but the value), and
the child leaves with os._exit, running none of the parent's exit handlers (rclpy's)."""
from __future__ import annotations

import os
import pickle
import signal
from collections.abc import Callable
from typing import Any


class Forked:
    """``fn()`` in a child process started now (at ``nice`` priority); ``result`` waits for it."""

    def __init__(self, fn: Callable[[], Any], nice: int = 0) -> None:
        self.read, write = os.pipe()
        self.pid = os.fork()
        if self.pid == 0:  # the child
            status = 1
            try:
                os.close(self.read)
                os.nice(nice)
                value = fn()
                with os.fdopen(write, "wb") as out:
                    pickle.dump(value, out)
                status = 0
            finally:
                os._exit(status)
        os.close(write)

    def result(self) -> tuple[bool, Any]:
        """(True, its value) once the child has returned it; (False, None) if it failed."""
        with os.fdopen(self.read, "rb") as source:
            data = source.read()
        _, status = os.waitpid(self.pid, 0)
        self.pid = 0
        return (True, pickle.loads(data)) if status == 0 else (False, None)

    def cancel(self) -> None:
        """Stop the child; its value is not wanted."""
        if self.pid:
            os.kill(self.pid, signal.SIGKILL)
            os.waitpid(self.pid, 0)
            os.close(self.read)
            self.pid = 0
