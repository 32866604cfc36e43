"""A section's verdict in report.json: whether the recorded feedback did what the job asked.

Every kind's section carries one, {"passed", "criterion", "says"}: the criterion names the
rule and its limits, ``says`` what the feedback did (each failure, or the figures that
passed). cnc-run and cnc-analyze exit 4 when any section's verdict has ``passed`` false, so
a run whose feedback misses is never a silent success. The limits themselves live with the
analysers that measure the figures (drilling, threads, aircut), one place each.
"""
from __future__ import annotations

# m: deeper into the part than programmed by more than this fails a verdict, for a hole, a
# thread or a turned contour alike: the planner leaves material on every drive inside the
# description's tolerance, so only an encoder's rounding and noise are allowed.
OVERCUT_LIMIT = 5e-6


def verdict(criterion: str, failures: list[str], passed: str) -> dict:
    """The verdict of a section: passed when ``failures`` (one phrase per miss) is empty;
    ``says`` joins the failures, or is ``passed`` (the figures that held)."""
    return {"passed": not failures, "criterion": criterion, "says": "; ".join(failures) if failures else passed}
