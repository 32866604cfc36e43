"""A goal sent again is answered with what its job came to, never run twice."""
from __future__ import annotations

from cnc_msgs_py.status import Status

from cnc_planner import goal_ledger
from cnc_planner.goal_ledger import GoalLedger


def test_a_repeat_is_answered_with_its_jobs_latest_status():
    ledger = GoalLedger()
    goal = '{"job_id": "a", "kind": "move"}'
    key = ledger.key(goal)
    assert not ledger.is_repeat(key)
    ledger.receive(key)
    assert ledger.is_repeat(ledger.key(goal))
    assert ledger.answer(key) is None  # still being prepared: the first copy's status will come
    accepted = Status("a", "accepted", duration_s=3.0)
    ledger.admitted(key, accepted)
    ledger.published(accepted)
    assert ledger.answer(key) is accepted
    running = Status("a", "running", progress=0.5)
    ledger.published(running)
    assert ledger.answer(key) is running


def test_another_goal_under_the_same_job_id_is_no_repeat_and_its_rejection_stays_its_own():
    ledger = GoalLedger()
    first, second = '{"job_id": "a", "x": 1}', '{"job_id": "a", "x": 2}'
    k1, k2 = ledger.key(first), ledger.key(second)
    assert k1 != k2
    ledger.receive(k1)
    ledger.admitted(k1, accepted := Status("a", "accepted"))
    ledger.published(accepted)
    assert not ledger.is_repeat(k2)
    ledger.receive(k2)
    rejected = Status("a", "rejected", reason="job_id: 'a' was already used in this planner's lifetime")
    ledger.admitted(k2, rejected)
    ledger.published(rejected)
    assert ledger.answer(k1) is accepted  # the job that holds the id is unaffected
    assert ledger.answer(k2) is rejected  # and the repeat of the rejected goal hears its rejection


def test_goals_that_are_not_json_are_keyed_by_their_text():
    ledger = GoalLedger()
    for text in ["", "{not json", "\ud800"]:  # a lone surrogate, as a broken client may send
        key = ledger.key(text)
        ledger.receive(key)
        ledger.admitted(key, rejected := Status("", "rejected", reason="not JSON"))
        assert ledger.answer(ledger.key(text)) is rejected


def test_only_the_newest_goals_and_jobs_are_kept(monkeypatch):
    monkeypatch.setattr(goal_ledger, "KEPT", 3)
    ledger = GoalLedger()
    keys = [ledger.key(f'{{"job_id": "j{i}"}}') for i in range(5)]
    for i, key in enumerate(keys):
        ledger.receive(key)
        ledger.admitted(key, accepted := Status(f"j{i}", "accepted"))
        ledger.published(accepted)
    assert [ledger.is_repeat(k) for k in keys] == [False, False, True, True, True]
    assert ledger.answer(keys[4]).job_id == "j4"
    ledger.published(Status("j2", "running"))  # a job heard of again is the newest once more
    ledger.published(Status("j5", "accepted"))
    assert ledger.answer(keys[2]).state == "running" and ledger.answer(keys[3]) is None
