"""Bad job documents never move the machine (issue 7, "Bad input").

The corpus in test/bad_jobs/ (one document per file, expected.yaml names what each
rejection must start with) goes (a) through the planner's Executive without ROS, each
against the machine it names, and (b) over real topics into one mill3 planner + bridge:
every document is rejected naming the field, no setpoint is published for any of them,
the planner keeps running, and a valid job afterwards runs normally.
"""
from __future__ import annotations

import json
import math
from functools import lru_cache
from pathlib import Path

import pytest
import yaml

from cnc_msgs_py.job import MAX_LIST
from cnc_msgs_py.machine import load_machine
from cnc_planner.executive import Executive
from cnc_planner.planning import INTERNAL

CORPUS = Path(__file__).resolve().parent / "bad_jobs"
EXPECTED = yaml.safe_load((CORPUS / "expected.yaml").read_text())
MACHINES = ("mill3", "lathe")
VALID_ID = "valid-after-bad"  # duplicate_job_id.yaml reuses it
VALID = {
    "schema": "cnc_job/1", "job_id": VALID_ID, "kind": "move", "machine": "mill3",
    "move": [{"linear": {"x": 10}, "feed": 3000}, {"rapid": {"x": 0}}],
}


def expectation(name: str) -> tuple[str, bool]:
    """(prefix the reason starts with, whether it is submitted after the valid job)."""
    entry = EXPECTED[name]
    if isinstance(entry, dict):
        return entry["prefix"], bool(entry.get("after_valid"))
    return entry, False


def message(path: Path) -> str:
    """The job_goal text for a corpus file: JSON files as they are, YAML as JSON."""
    text = path.read_text(encoding="utf-8")
    if path.suffix == ".json":
        return text
    return json.dumps(yaml.safe_load(text))


def huge_list_message() -> str:
    """One hole more than the configured maximum (generated: too big to keep as a file)."""
    doc = {"schema": "cnc_job/1", "job_id": "bad-holes-beyond-max", "kind": "drill", "machine": "mill3",
           "spindle_rpm": 3000, "drill": {"holes": [[0, 0]] * (MAX_LIST + 1), "depth": 5, "feed": 1200}}
    return json.dumps(doc, separators=(",", ":"))


HUGE_PREFIX = "drill.holes"


def target_machine(text: str) -> str:
    """The machine a document names, if it is one we have (else mill3 answers it)."""
    try:
        doc = json.loads(text)
    except (ValueError, RecursionError):
        return "mill3"
    machine = doc.get("machine") if isinstance(doc, dict) else None
    return machine if machine in MACHINES else "mill3"


@lru_cache(maxsize=None)
def machine(name: str):
    return load_machine(name)


def names_field(reason: str, prefix: str) -> bool:
    """The reason starts with the prefix; a field path must end there ('x' is not 'x_y')."""
    if not reason.startswith(prefix):
        return False
    if " " in prefix or prefix == "":  # a whole-document reason, not a field path
        return True
    return reason[len(prefix):len(prefix) + 1] in (":", ".", "[")


def check_rejection(status, prefix: str) -> None:
    assert status.state == "rejected", f"accepted: {status}"
    assert names_field(status.reason, prefix), f"expected {prefix!r}, got {status.reason!r}"
    assert "\n" not in status.reason and "\r" not in status.reason
    assert INTERNAL not in status.reason, status.reason  # a planner bug, not a check
    json.dumps(status.reason).encode("utf-8")  # publishable as it is


FILES = sorted(EXPECTED)


def test_corpus_is_complete():
    on_disk = {p.name for p in CORPUS.iterdir() if p.name != "expected.yaml"}
    assert on_disk == set(EXPECTED), on_disk ^ set(EXPECTED)
    assert len(on_disk) >= 60


@pytest.mark.parametrize("name", FILES)
def test_bad_document_is_rejected(name):
    prefix, after_valid = expectation(name)
    text = message(CORPUS / name)
    executive = Executive(machine(target_machine(text)))
    if after_valid:
        assert executive.submit(json.dumps(VALID)).state == "accepted"
    check_rejection(executive.submit(text), prefix)
    assert len(executive.queue) == (1 if after_valid else 0)  # nothing queued for the bad one


def test_list_beyond_the_maximum_is_rejected():
    status = Executive(machine("mill3")).submit(huge_list_message())
    check_rejection(status, HUGE_PREFIX)
    assert f"maximum {MAX_LIST}" in status.reason


def test_rejected_job_keeps_the_executive_usable():
    """After every bad document in turn, the same executive takes and plans a valid job."""
    executive = Executive(machine("mill3"))
    for name in FILES:
        prefix, after_valid = expectation(name)
        if not after_valid:
            assert executive.submit(message(CORPUS / name)).state == "rejected"
    status = executive.submit(json.dumps(VALID))
    assert status.state == "accepted" and math.isfinite(status.duration_s) and status.duration_s > 0
    assert [j.job_id for j in executive.queue] == [VALID_ID]


# --- over real topics ---------------------------------------------------------------------------
def test_bad_jobs_over_topics_publish_nothing_and_the_next_job_runs(tmp_path):
    from cnc_planner.runner import Session
    from cnc_analysis.recording import read_run

    before = [n for n in FILES if not expectation(n)[1]]
    after = [n for n in FILES if expectation(n)[1]]
    messages = [(n, message(CORPUS / n)) for n in before] + [("<holes beyond max>", huge_list_message())]
    # The same documents through a ROS-free mill3 executive: the reasons to expect on the topic.
    local = Executive(machine("mill3"))
    wanted = {n: local.submit(text).reason for n, text in messages}

    with Session("mill3", tmp_path / "bag") as session:
        statuses = session.recorder.statuses

        def rejected() -> list[dict]:
            return [s for s in statuses if s["state"] == "rejected"]

        for k, (name, text) in enumerate(messages):
            session.submit(text)
            session.spin_until(lambda: len(rejected()) > k, 20, f"no status for {name}")
            got = rejected()[k]
            assert got["reason"] == wanted[name], name
            if name in EXPECTED and target_machine(text) == "mill3":
                assert names_field(got["reason"], expectation(name)[0]), (name, got["reason"])
        assert all(s["state"] == "rejected" for s in statuses), [s for s in statuses if s["state"] != "rejected"]
        assert session.procs["planner"].poll() is None and session.procs["bridge"].poll() is None

        session.submit(json.dumps(VALID))
        final = session.wait(VALID_ID, 60)
        assert final["state"] == "succeeded", final
        for name in after:  # its id is now taken
            session.submit(message(CORPUS / name))
            session.spin_until(lambda: len(rejected()) > len(messages), 20, f"no status for {name}")
            assert names_field(rejected()[-1]["reason"], expectation(name)[0])
        session.settle(final)
        assert session.procs["planner"].poll() is None

    run = read_run(tmp_path / "bag")
    starts = [e["stamp_ns"] for e in run.events if e["name"] == "job_start"]
    assert [e["job_id"] for e in run.events if e["name"] == "job_start"] == [VALID_ID]
    assert run.chunks, "the valid job published no setpoints"
    # Not one chunk before the valid job's first: every setpoint belongs to it.
    assert run.chunks[0].stamp_ns == starts[0]
    assert all(c.stamp_ns >= starts[0] for c in run.chunks)
    points = sum(c.points for c in run.chunks)
    assert points == pytest.approx(final["duration_s"] * 1000, abs=2)
    # The valid job ran: the axis went to x = 10 mm and came back.
    x = run.column("x")
    assert run.feedback[:, x].max() == pytest.approx(0.010, abs=1e-4)
    assert abs(run.feedback[-1, x]) < 1e-6
