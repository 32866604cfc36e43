"""cnc-run's progress display: a bar redrawn in place on a terminal, sparse lines in a log."""
from __future__ import annotations

import io
import pytest

from cnc_msgs_py.progress import Progress, counts_text, status_text

HOLES = {"event": "S1", "unit": "hole", "total": 5}  # what the planner's statuses say they count
PASSES = {"event": "pass", "unit": "pass", "total": 8}
THREAD_PASSES = {"event": "thread_pass", "unit": "thread pass", "total": 7}


class Clock:
    def __init__(self) -> None:
        self.t = 0.0

    def __call__(self) -> float:
        return self.t


@pytest.fixture
def clock(monkeypatch) -> Clock:
    """A wall clock the test moves, for the plain lines and for tqdm's redraw interval alike."""
    clock = Clock()
    monkeypatch.setattr("tqdm.std.time", clock)
    return clock


def running(progress: float, duration: float = 10.0, count: dict | None = None, **detail: int) -> dict:
    return {"job_id": "j1", "state": "running", "progress": progress, "phase": "S2",
            "elapsed_s": progress * duration, "duration_s": duration, "detail": detail, "count": count or {}}


def bar_line(status: dict, width: int = 80) -> str:
    """The bar a terminal of ``width`` columns shows for one running status."""
    out = io.StringIO()
    show = Progress(out, tty=True, width=width)
    show(status)
    show.close()
    return out.getvalue().split("\r")[-1].rstrip()


def test_counts_name_holes_and_passes_against_the_plan():
    assert counts_text({"detail": {"S1": 3, "S2": 3, "job_start": 1}, "count": HOLES}) == "hole 3/5"
    assert counts_text({"detail": {"pass": 2}, "count": PASSES}) == "pass 2/8"
    assert counts_text({"detail": {"thread_pass": 4}, "count": THREAD_PASSES}) == "thread pass 4/7"
    assert counts_text({"detail": {}, "count": HOLES}) == "hole 0/5"  # nothing passed yet, but the total is known
    assert counts_text({"detail": {"rapid": 2}, "count": {}}) == ""  # a kind that counts nothing
    assert counts_text({"detail": {"S1": 2}}) == ""  # a status without a count (an older planner)


def test_lines_carry_progress_counts_and_simulated_vs_job_time():
    line = status_text(running(0.45, count=HOLES, S1=3))
    assert "45.0%" in line and "hole 3/5" in line and "sim 4.50/10.00 s" in line and "S2" in line
    assert status_text({"job_id": "j1", "state": "rejected", "reason": "drill.depth: must be > 0"}) == \
        "  j1: rejected (drill.depth: must be > 0)"
    assert "succeeded, 3.55 s" in status_text({"job_id": "j1", "state": "succeeded", "cycle_time_s": 3.552})
    assert len(bar_line(running(0.3, **{"pass": 1}), width=40)) <= 40
    # On an 80-column terminal the whole line fits: the bar gives way.
    line = bar_line({**running(0.83, duration=12.72, count=THREAD_PASSES, thread_pass=6), "job_id": "thread-m12-demo"},
                    width=80)
    assert len(line) <= 80 and line.startswith("  thread-m12-demo  83%|"), line
    assert line.endswith("| sim 10.56/12.72 s, thread pass 6/7, S2"), line
    cells = line[line.index("|") + 1:line.rindex("|")]
    assert len(cells) >= 5 and cells.startswith("#####"), line


def test_bar_keeps_its_length_as_time_counts_and_phase_change():
    early = bar_line(running(0.05, duration=12.72, count=HOLES, S1=1))
    late = bar_line({**running(0.95, duration=12.72, count=HOLES, S1=5), "phase": "job_start"})
    assert "sim  0.64/12.72 s" in early and "sim 12.08/12.72 s" in late
    assert early.index("| sim") == late.index("| sim")


def test_terminal_redraws_one_line_in_place_and_ends_it(clock):
    out = io.StringIO()
    show = Progress(out, tty=True, clock=clock, width=100)
    show({"job_id": "j1", "state": "accepted"})
    for k in range(20):
        clock.t += 0.5
        show(running(k / 20, count=PASSES, **{"pass": k // 3}))
    show({"job_id": "j1", "state": "succeeded", "cycle_time_s": 10.0})
    text = out.getvalue()
    lines = text.split("\n")
    assert lines[0] == "  j1: accepted"
    # Every running status redrew the same line (20 carriage returns, no new lines), and the
    # final state left the bar with its last figures, once more, before its own line.
    assert lines[1].count("\r") == 21 and "pass 6/8" in lines[1]
    assert lines[1].split("\r")[-1].rstrip().endswith("| sim  9.50/10.00 s, pass 6/8, S2")
    assert lines[2] == "  j1: succeeded, 10.00 s"
    assert lines[3] == "" and len(lines) == 4


def test_terminal_redraw_is_throttled(clock):
    out = io.StringIO()
    show = Progress(out, tty=True, clock=clock, width=80)
    for k in range(100):
        clock.t += 0.01
        show(running(k / 100))
    assert 5 <= out.getvalue().count("\r") <= 11  # ~ one per 0.1 s
    show.close()
    assert out.getvalue().endswith("\n")


def test_log_gets_at_most_one_line_per_ten_percent():
    out, clock = io.StringIO(), Clock()
    show = Progress(out, tty=False, clock=clock)
    show({"job_id": "j1", "state": "accepted"})
    for k in range(200):  # a status every 0.5 % of the job, 0.1 s apart
        clock.t += 0.1
        show(running(k / 200, count=HOLES, S1=k // 40))
    show({"job_id": "j1", "state": "succeeded", "cycle_time_s": 10.0})
    lines = out.getvalue().splitlines()
    assert "\r" not in out.getvalue()
    assert lines[0] == "  j1: accepted" and lines[-1] == "  j1: succeeded, 10.00 s"
    assert len(lines) == 2 + 10  # 0 %, 10 %, ... 90 %
    assert all("hole" in line for line in lines[1:-1])


def test_slow_jobs_still_show_a_line_every_five_seconds():
    out, clock = io.StringIO(), Clock()
    show = Progress(out, tty=False, clock=clock)
    for k in range(60):  # 30 s of wall time within the first 3 % of the job
        clock.t += 0.5
        show(running(k / 2000))
    lines = out.getvalue().splitlines()
    assert 6 <= len(lines) <= 7  # the first, then one per 5 s


def test_a_held_program_shows_each_hold_once():
    """A held job's status comes every 0.5 s while it waits: one line per hold, not per status
    (a hold at the same line again, in a loop, is a new one)."""
    out = io.StringIO()
    show = Progress(out, tty=False, clock=Clock())
    m0 = {"job_id": "j1", "state": "held", "reason": "held at line 9 (M0): resume by publishing 'j1' on job_resume"}
    m1 = {**m0, "reason": "held at line 20 (M1): resume by publishing 'j1' on job_resume"}
    for status in (m0, m0, m0, running(0.5), m1, m1, running(0.7), m1):
        show(status)
    held = [line for line in out.getvalue().splitlines() if "held" in line]
    assert held == [f"  j1: held ({m0['reason']})"] + 2 * [f"  j1: held ({m1['reason']})"]
