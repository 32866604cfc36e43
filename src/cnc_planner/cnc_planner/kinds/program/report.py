"""The ``program`` section of report.json: each operation of a G-code program judged by its
own kind's judge on its share of the recording, imported only to report. The section's
verdict fails where any operation's does, so a program is never a silent success."""
from __future__ import annotations

import json
from dataclasses import replace
from types import SimpleNamespace

import numpy as np

from cnc_msgs_py.machine import Machine

from cnc_analysis.recording import Run
from cnc_analysis.verdict import verdict

from cnc_planner.kinds.program import HOLD, OPERATION, kinds, operations_at


def _operation_run(run: Run, part: np.ndarray, t0: float, t1: float, doc: dict) -> Run:
    """The recording as one operation's judge must see it: only the operation's share of the
    feedback and commands (a judge may look past its window, where the next operation cuts),
    and the operation's own goal (a judge may read the goal as sent, in mm)."""
    sent = (run.command_t >= t0 - 1e-9) & (run.command_t < t1 - 1e-9)
    return replace(run, feedback_t=run.feedback_t[part], feedback=run.feedback[part],
                   feedback_velocity=run.feedback_velocity[part], command_t=run.command_t[sent],
                   command=run.command[sent], command_velocity=run.command_velocity[sent],
                   goals=[json.dumps(doc)])


def program_section(run: Run, job: SimpleNamespace, machine: Machine, window: np.ndarray) -> dict:
    """One section per operation, judged by its kind's own judge on its share of the feedback:
    from its start to the next operation's or a hold point's (M0/M1: the machine stood there,
    held, until resumed), whichever comes first."""
    registry = kinds()
    t = run.feedback_t
    begin = t[window][0] if window.any() else 0.0

    def marks(name: str) -> list[float]:
        return sorted(e["stamp_ns"] / 1e9 for e in run.events
                      if e.get("name") == name and "stamp_ns" in e and e["stamp_ns"] / 1e9 >= begin - 1e-9)
    starts, holds = marks(OPERATION), marks(HOLD)
    sections = []
    operations = operations_at(job, machine, run.feedback_at(window)) if window.any() else job.program.operations
    for index, (line, op, doc) in enumerate(operations):
        entry = {"index": index, "line": line, "kind": op.kind}
        if index < len(starts):
            t1 = starts[index + 1] if index + 1 < len(starts) else np.inf
            t1 = min([t1] + [h for h in holds if h > starts[index] + 1e-9])
            part = window & (t >= starts[index] - 1e-9) & (t < t1 - 1e-9)
            entry["duration_s"] = float(t[part][-1] - t[part][0]) if part.any() else 0.0
            section = registry[op.kind].report
            if section is not None and part.any():
                own = _operation_run(run, part, starts[index], t1, doc)
                judged = section.judge(own, op, machine, np.ones(len(own.feedback_t), dtype=bool))
                if judged is not None:  # (None: nothing of the kind's to judge, as a move at one rpm)
                    entry[section.key] = judged
        sections.append(entry)
    failures = [f"operation {e['index']} (line {e['line']}, {e['kind']}): {s['verdict']['says']}"
                for e in sections for s in e.values()
                if isinstance(s, dict) and isinstance(s.get("verdict"), dict) and s["verdict"].get("passed") is False]
    judged = sum(1 for e in sections for s in e.values() if isinstance(s, dict) and "verdict" in s)
    return {"operations": sections,
            "verdict": verdict("every operation's own verdict on its share of the feedback", failures,
                               f"{judged} of {len(sections)} operations judged, every verdict passed")}
