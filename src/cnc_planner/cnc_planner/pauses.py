"""What cnc-run does when its job holds at a program pause (M0/M1), having no operator to
press cycle start: resume it ``resume_after`` s of machine time later (each hold once), or
cancel it (None), saying so. Plain Python: the runner's session hears the statuses and the
machine time, and sends what this decides."""
from __future__ import annotations

from cnc_msgs_py.status import holds_passed
from cnc_msgs_py.units import NS


class Pauses:
    """The decision for one job's holds."""

    def __init__(self, job_id: str, resume_after: float | None) -> None:
        self.job_id, self.resume_after = job_id, resume_after
        self.handled = -1  # the holds passed (status detail) at the last one acted on
        self.since_ns: int | None = None  # machine time the current hold was first heard

    def due(self, held: dict | None, machine_ns: int) -> tuple[str, str] | None:
        """('resume' | 'cancel', what cnc-run says) when the job's latest status ``held`` (None:
        it is not held) asks for one now, at machine time ``machine_ns``; else None."""
        if held is None or holds_passed(held) <= self.handled:
            return None
        if self.resume_after is None:
            action = ("cancel", f"cnc-run: {self.job_id} {held['reason'].split(':')[0]}: canceled, as cnc-run "
                                f"resumes a held program only with --resume-after S")
        else:
            self.since_ns = held["stamp_ns"] if self.since_ns is None else self.since_ns
            if machine_ns < self.since_ns + round(self.resume_after * NS):
                return None
            action = ("resume", f"cnc-run: {self.job_id} resumed after {self.resume_after:g} s held (--resume-after)")
        self.handled, self.since_ns = holds_passed(held), None
        return action
