"""NodesHeard: a session's view of its nodes from their diagnostics (pids, readiness)."""
from types import SimpleNamespace

from cnc_msgs_py import topics
from cnc_msgs_py.heard import NodesHeard


def status(name: str, namespace: str, **values: str) -> SimpleNamespace:
    return SimpleNamespace(name=name, hardware_id=namespace,
                           values=[SimpleNamespace(key=k, value=v) for k, v in values.items()])


def test_a_planner_counts_ready_only_under_its_namespace_once_it_says_so():
    heard = NodesHeard("/cnc")
    heard.hear([status("cnc_servo_bridge: drives", "/cnc", pid="11")])
    heard.hear([status("cnc_planner: executive", "/cnc", pid="12", ready=topics.NOT_READY)])
    assert heard.pids == {11, 12} and heard.ready == set() and heard.planner_heartbeats == 1
    heard.hear([status("cnc_planner: executive", "/cell2", pid="13", ready=topics.READY)])  # another machine's
    assert heard.pids == {11, 12} and heard.ready == set() and heard.planner_heartbeats == 2
    heard.hear([status("cnc_planner: executive", "/cnc", pid="12", ready=topics.READY)])
    assert heard.ready == {12} and heard.planner_heartbeats == 3


def test_diagnostics_without_a_pid_name_no_process():
    heard = NodesHeard("/cnc")
    heard.hear([status("some_driver", "/cnc", ready=topics.READY)])
    assert heard.pids == set() and heard.ready == set() and heard.planner_heartbeats == 0
