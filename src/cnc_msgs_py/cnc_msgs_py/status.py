"""Status documents (``cnc_status/1``) on job_status, cancel requests on job_cancel and
resume requests (a held program, M0/M1) on job_resume."""
from __future__ import annotations

import json
from dataclasses import asdict, dataclass, field

STATUS_SCHEMA = "cnc_status/1"
STATES = ("accepted", "rejected", "running", "held", "succeeded", "aborted", "canceled")
# held: a program stands at a pause (M0, M1), its axes at rest, until a job_resume for its
# job_id arrives (its reason says at which line and how); a cancel ends it as any running job
FINAL_STATES = ("rejected", "succeeded", "aborted", "canceled")


def holds_passed(status: dict) -> int:
    """How many program pauses (M0/M1, the ``hold`` marks its detail counts) a status has
    passed: what tells one hold of a program from the next."""
    return status["detail"].get("hold", 0)


@dataclass
class Status:
    """One job's state. ``progress`` is 0..1 of plan time; ``cycle_time_s`` once final.

    ``detail`` counts the phase marks (job_events names) the job has passed; ``count`` says
    which of them a machinist counts and how many the whole job has, e.g.
    {"event": "S1", "unit": "hole", "total": 50} (empty for kinds without),
    so a display shows "hole 3/50" without knowing the job's kind.
    """

    job_id: str
    state: str
    reason: str = ""
    progress: float = 0.0
    phase: str = ""
    elapsed_s: float = 0.0
    duration_s: float = 0.0
    cycle_time_s: float | None = None
    detail: dict = field(default_factory=dict)
    count: dict = field(default_factory=dict)
    stamp_ns: int = 0  # the machine's (bridge's) time when the status was issued
    schema: str = STATUS_SCHEMA

    @property
    def final(self) -> bool:
        return self.state in FINAL_STATES

    def encode(self) -> str:
        return json.dumps(asdict(self))

    @classmethod
    def decode(cls, text: str) -> "Status":
        doc = json.loads(text)
        if doc.get("schema") != STATUS_SCHEMA or doc.get("state") not in STATES:
            raise ValueError(f"not a {STATUS_SCHEMA} document: {text[:80]}")
        return cls(**doc)


def encode_cancel(job_id: str) -> str:
    """job_cancel carries the bare job_id."""
    return job_id


def decode_cancel(text: str) -> str:
    return text.strip()


def encode_resume(job_id: str) -> str:
    """job_resume carries the bare job_id, as job_cancel does."""
    return job_id


decode_resume = decode_cancel
