"""Progress of a running job on a terminal or in a log (ROS-free).

``Progress`` takes every ``cnc_status/1`` document of a job (as dicts, the way cnc-run's
progress callback hands them over) and shows it:

- on a terminal, one line redrawn in place with ``\\r``: a bar, percent, holes or passes
  done (from the status's phase counts), simulated time vs the job's planned time, phase;
- otherwise plain lines, at most one per 10 % of progress, or one per 5 s of wall time on
  a job that advances slowly, plus one line for every other state (accepted, final).

The counts in ``detail`` are how many of each phase mark the job has passed: ``S1`` per
hole (its positioning move has begun), ``pass`` per roughing pass, ``thread_pass`` per
thread pass. ``totals`` (the same names, counted on the plan) turns them into ``3/5``.
"""
from __future__ import annotations

import shutil
import sys
import time
from typing import Callable, TextIO

# detail key -> what a machinist calls it (singular, plural)
UNITS = (("S1", "hole", "holes"), ("thread_pass", "thread pass", "thread passes"),
         ("pass", "pass", "passes"))
LINE_STEP = 0.1  # plain lines: at most one per 10 % of progress ...
LINE_PERIOD_S = 5.0  # ... or one per 5 s (wall) while a slow job advances
REDRAW_PERIOD_S = 0.1  # terminal: redraw the bar at most this often
BAR_WIDTH = 30
MIN_BAR = 10
PHASE_WIDTH = 11  # room kept for '  ' + the phase (a longer one than 'job_start' is cut at the end)


def counts_text(detail: dict | None, totals: dict | None = None) -> str:
    """'hole 3/5', 'pass 2/8', 'thread pass 4' from a status's phase counts, or ''."""
    detail = detail or {}
    totals = totals or {}
    parts = []
    for key, one, _many in UNITS:
        total = totals.get(key)
        done = detail.get(key)
        if done is None and not total:
            continue
        done = int(done or 0)
        parts.append(f"{one} {done:{len(str(int(total)))}d}/{int(total)}" if total else f"{one} {done}")
    return "  ".join(parts)


def bar(fraction: float, width: int = BAR_WIDTH) -> str:
    """A bar of ``width`` cells: '[#########...............]'."""
    fraction = min(1.0, max(0.0, float(fraction)))
    full = int(round(fraction * width))
    return "[" + "#" * full + "." * (width - full) + "]"


def status_text(status: dict, totals: dict | None = None) -> str:
    """One status as a line without a bar (the non-terminal form)."""
    job_id = status.get("job_id", "")
    state = status.get("state", "")
    if state != "running":
        reason = f" ({status['reason']})" if status.get("reason") else ""
        cycle = status.get("cycle_time_s")
        extra = f", {cycle:.2f} s" if state == "succeeded" and cycle is not None else ""
        return f"  {job_id}: {state}{reason}{extra}"
    fields = [f"{100 * status.get('progress', 0.0):5.1f}%", _times(status), counts_text(status.get("detail"), totals),
              status.get("phase", "")]
    return f"  {job_id}: " + "  ".join(f for f in fields if f)


def bar_text(status: dict, totals: dict | None = None, width: int = 80) -> str:
    """One running status as the terminal's bar line, within ``width`` - 1 characters:
    the bar shrinks first, then the phase and the rest are cut."""
    progress = status.get("progress", 0.0)
    head = f"  {status.get('job_id', '')} "
    # Fields of steady width, so that the bar keeps its length from one redraw to the next.
    tail = "  ".join(f for f in (f" {100 * progress:3.0f}%", counts_text(status.get("detail"), totals),
                                 _times(status, steady=True)) if f)
    cells = max(MIN_BAR, min(BAR_WIDTH, width - 1 - len(head) - len(tail) - 2 - PHASE_WIDTH))
    phase = status.get("phase", "")
    return (head + bar(progress, cells) + tail + (f"  {phase}" if phase else ""))[: max(10, width - 1)]


def _times(status: dict, steady: bool = False) -> str:
    duration = f"{status.get('duration_s', 0.0):.2f}"
    return f"sim {status.get('elapsed_s', 0.0):{len(duration) if steady else 0}.2f}/{duration} s"


class Progress:
    """A progress callback for cnc-run: call it with every status document of the job.

    Args:
        stream: where to write (default stdout).
        tty: draw a bar in place; default: whether ``stream`` is a terminal.
        totals: phase counts of the whole plan, e.g. {"S1": 5}, for 'hole 3/5'.
        clock: wall clock (monotonic seconds), replaceable in tests.
        width: line width on a terminal; default: the terminal's.
    """

    def __init__(self, stream: TextIO | None = None, *, tty: bool | None = None, totals: dict | None = None,
                 clock: Callable[[], float] = time.monotonic, width: int | None = None) -> None:
        self.stream = stream or sys.stdout
        if tty is None:
            isatty = getattr(self.stream, "isatty", None)
            tty = bool(isatty and isatty())
        self.tty = tty
        self.totals = dict(totals or {})
        self.clock = clock
        self.width = width or shutil.get_terminal_size((80, 24)).columns
        self._drawn = 0  # characters of the bar line on screen (terminal), 0 = none
        self._last_time: float | None = None
        self._last_step = -1  # the 10 % step of the last plain line
        self._last_progress = -1.0

    def __call__(self, status: dict) -> None:
        if status.get("state") == "running":
            self._running(status)
        else:
            self._line(status_text(status, self.totals))

    def close(self) -> None:
        """End a bar left on the line (before anything else is printed)."""
        if self._drawn:
            self.stream.write("\n")
            self.stream.flush()
            self._drawn = 0

    def _running(self, status: dict) -> None:
        now = self.clock()
        progress = float(status.get("progress", 0.0))
        if self.tty:
            if self._last_time is not None and now - self._last_time < REDRAW_PERIOD_S and progress < 1.0:
                return
            text = bar_text(status, self.totals, self.width)
            self.stream.write("\r" + text + " " * max(0, self._drawn - len(text)))
            self.stream.flush()
            self._drawn = len(text)
            self._last_time = now
            return
        step = int(progress / LINE_STEP + 1e-9)
        slow = self._last_time is not None and now - self._last_time >= LINE_PERIOD_S and progress > self._last_progress
        if step > self._last_step or slow:
            self._line(status_text(status, self.totals))
            self._last_step = max(step, self._last_step)
            self._last_progress = progress
            self._last_time = now

    def _line(self, text: str) -> None:
        if self._drawn:
            self.stream.write("\r" + text + " " * max(0, self._drawn - len(text)) + "\n")
            self._drawn = 0
        else:
            self.stream.write(text + "\n")
        self.stream.flush()


def job_totals(doc: dict) -> dict:
    """Phase counts of a whole job from its document, cheaply ({} when unknown or invalid):
    the count its kind shows (cnc_planner.kinds), e.g. {"S1": holes} for drilling. The
    planner rejects an invalid job itself; this only labels the progress."""
    try:
        from cnc_msgs_py.job import parse_job

        from cnc_planner.kinds import KINDS

        job = parse_job(doc)
        count = KINDS[job.kind].progress
        return {} if count is None else {count.event: count.total(job)}
    except Exception:  # noqa: BLE001 - labels only; the planner reports what is wrong
        return {}
