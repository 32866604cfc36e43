"""cnc-run's answer to a held program (cnc_planner.pauses): with --resume-after S, each hold
is resumed once, S of machine time after it was first heard; without, the job is canceled
at its first hold, and cnc-run says which."""
from cnc_msgs_py.units import NS

from cnc_planner.pauses import Pauses


def held(hold: int, stamp_s: float, line: int = 7) -> dict:
    return {"job_id": "p", "state": "held", "reason": f"held at line {line} (M0): resume by publishing 'p' ...",
            "detail": {"hold": hold}, "stamp_ns": round(stamp_s * NS)}


def test_each_hold_is_resumed_once_after_the_machine_time_asked():
    pauses = Pauses("p", 0.5)
    assert pauses.due(None, 0) is None
    assert pauses.due(held(1, 2.0), round(2.0 * NS)) is None
    assert pauses.due(held(1, 2.1), round(2.49 * NS)) is None  # timed from the first held status heard
    assert pauses.due(held(1, 2.2), round(2.5 * NS)) == ("resume", "cnc-run: p resumed after 0.5 s held (--resume-after)")
    assert pauses.due(held(1, 2.3), round(9.0 * NS)) is None  # the same hold's late statuses: done
    assert pauses.due(held(2, 4.0), round(4.2 * NS)) is None  # the next hold waits its own 0.5 s
    assert pauses.due(held(2, 4.1), round(4.5 * NS))[0] == "resume"


def test_without_resume_after_the_first_hold_cancels_and_says_where():
    pauses = Pauses("p", None)
    assert pauses.due(held(1, 1.0, line=9), round(1.0 * NS)) == (
        "cancel", "cnc-run: p held at line 9 (M0): canceled, as cnc-run resumes a held program only with --resume-after S")
    assert pauses.due(held(1, 1.1), round(1.1 * NS)) is None
