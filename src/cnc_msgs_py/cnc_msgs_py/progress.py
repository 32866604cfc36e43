"""Progress of a running job on a terminal or in a log (ROS-free), for cnc-run and cnc-submit.

``Progress`` takes every ``cnc_status/1`` document of a job (as dicts, the way cnc-run's
progress callback and CncClient.on_progress hand them over) and shows it:

- on a terminal, a tqdm bar redrawn in place: percent, simulated time vs the job's planned
  time, holes or passes done (from the status's phase counts), phase;
- otherwise plain lines, at most one per 10 % of progress, or one per 5 s of wall time on
  a job that advances slowly, plus one line for every other state (accepted, final).

The counts in ``detail`` are how many of each phase mark the job has passed; the status's
``count`` names the one a machinist counts, its unit and the job's total (the planner's
kind of job says which: ``S1`` per hole, ``pass`` per roughing pass, ``thread_pass`` per
thread pass), which turns it into 'hole 3/5' without this display knowing any kind.
"""
from __future__ import annotations

import sys
import time
from typing import Callable, TextIO

from tqdm import tqdm

LINE_STEP = 0.1  # plain lines: at most one per 10 % of progress ...
LINE_PERIOD_S = 5.0  # ... or one per 5 s (wall) while a slow job advances
REDRAW_PERIOD_S = 0.1  # terminal: tqdm redraws the bar at most this often
PHASE_WIDTH = 11  # room kept for the phase ('thread_pass'), so that the bar keeps its length
# tqdm's bar of simulated seconds; the elapsed time is as wide as the total, for the same reason.
BAR_FORMAT = "  {{desc}} {{percentage:3.0f}}%|{{bar}}| sim {{n:{width}.2f}}/{{total:.2f}} s{{postfix}}"


def counts_text(status: dict) -> str:
    """'hole 3/5', 'pass 2/8' from a status's phase counts and what it counts, or ''."""
    count = status.get("count") or {}
    if not count:
        return ""
    done, total = int((status.get("detail") or {}).get(count["event"], 0)), int(count["total"])
    return f"{count['unit']} {done:{len(str(total))}d}/{total}"


def status_text(status: dict) -> str:
    """One status as a line without a bar (the non-terminal form)."""
    job_id = status.get("job_id", "")
    state = status.get("state", "")
    if state != "running":
        reason = f" ({status['reason']})" if status.get("reason") else ""
        cycle = status.get("cycle_time_s")
        extra = f", {cycle:.2f} s" if state == "succeeded" and cycle is not None else ""
        return f"  {job_id}: {state}{reason}{extra}"
    times = f"sim {status.get('elapsed_s', 0.0):.2f}/{status.get('duration_s', 0.0):.2f} s"
    fields = [f"{100 * status.get('progress', 0.0):5.1f}%", times, counts_text(status),
              status.get("phase", "")]
    return f"  {job_id}: " + "  ".join(f for f in fields if f)


class Progress:
    """A progress callback for cnc-run: call it with every status document of the job.

    Args:
        stream: where to write (default stdout).
        tty: draw a bar in place; default: whether ``stream`` is a terminal.
        clock: wall clock (monotonic seconds) of the plain lines' 5 s period, replaceable in tests.
        width: line width on a terminal; default: the terminal's, followed as it is resized.
    """

    def __init__(self, stream: TextIO | None = None, *, tty: bool | None = None,
                 clock: Callable[[], float] = time.monotonic, width: int | None = None) -> None:
        self.stream = stream or sys.stdout
        if tty is None:
            isatty = getattr(self.stream, "isatty", None)
            tty = bool(isatty and isatty())
        self.tty = tty
        self.clock = clock
        self.width = width
        self._bar: tqdm | None = None  # the job's bar while it is on screen (terminal)
        self._last_time: float | None = None
        self._last_step = -1  # the 10 % step of the last plain line
        self._last_progress = -1.0
        self._held = ""  # the hold last shown: a held job's status comes every 0.5 s, shown once

    def __call__(self, status: dict) -> None:
        if status.get("state") == "held":
            if status.get("reason") != self._held:
                self.close()
                self._line(status_text(status))
                self._held = status.get("reason", "")
            return
        self._held = ""
        if status.get("state") != "running":
            self.close()
            self._line(status_text(status))
        elif self.tty:
            self._draw(status)
        else:
            self._log(status)

    def close(self) -> None:
        """End the bar, left on screen with its last figures (before anything else is printed)."""
        if self._bar is not None:
            self._bar.close()
            self._bar = None

    def _draw(self, status: dict) -> None:
        duration = float(status.get("duration_s", 0.0))
        done = float(status.get("progress", 0.0)) * duration  # simulated seconds, as the plan counts them
        after = ", ".join(f for f in (counts_text(status),
                                      f"{status.get('phase', ''):{PHASE_WIDTH}}") if f.strip())
        if self._bar is None:
            self._bar = tqdm(total=duration, initial=done, desc=status.get("job_id", ""), postfix=after,
                             file=self.stream, ncols=self.width, dynamic_ncols=self.width is None,
                             mininterval=REDRAW_PERIOD_S, miniters=0,
                             bar_format=BAR_FORMAT.format(width=len(f"{duration:.2f}")))
            return
        self._bar.set_postfix_str(after, refresh=False)
        self._bar.update(done - self._bar.n)

    def _log(self, status: dict) -> None:
        now = self.clock()
        progress = float(status.get("progress", 0.0))
        step = int(progress / LINE_STEP + 1e-9)
        slow = self._last_time is not None and now - self._last_time >= LINE_PERIOD_S and progress > self._last_progress
        if step > self._last_step or slow:
            self._line(status_text(status))
            self._last_step = max(step, self._last_step)
            self._last_progress = progress
            self._last_time = now

    def _line(self, text: str) -> None:
        self.stream.write(text + "\n")
        self.stream.flush()
