"""cnc-identify refuses what it cannot identify as one machine, with a one-line reason and
exit 2: bags of different machines, a bag whose job names none, a bag that is not there."""
from __future__ import annotations

import json

from cnc_analysis.identify_cli import main
from cnc_analysis.recording import RECORDED, TYPESTORE, BagWriter


def _goal_bag(path, *goals: dict) -> None:
    """A bag holding nothing but job goals."""
    writer = BagWriter(path, {"/cnc/job_goal": RECORDED["job_goal"]})
    for i, goal in enumerate(goals):
        message = TYPESTORE.types["std_msgs/msg/String"](data=json.dumps(goal))
        writer.write("/cnc/job_goal", i + 1, TYPESTORE.serialize_cdr(message, "std_msgs/msg/String"))
    writer.close()


def _refused(capsys, *args) -> str:
    assert main([*map(str, args)]) == 2
    error = capsys.readouterr().err.strip()
    assert error.startswith("cnc-identify: ") and "\n" not in error
    return error


def test_bags_of_different_machines_are_refused(tmp_path, capsys):
    _goal_bag(tmp_path / "mill", {"job_id": "a", "machine": "mill3"})
    _goal_bag(tmp_path / "lathe", {"job_id": "b", "machine": "lathe"})
    error = _refused(capsys, tmp_path / "mill", tmp_path / "lathe", "--out", tmp_path / "fit")
    assert "different machines" in error and "mill3" in error and "lathe" in error
    assert not (tmp_path / "fit").exists()


def test_a_bag_that_names_no_machine_is_refused(tmp_path, capsys):
    _goal_bag(tmp_path / "bag", {"job_id": "a"})
    assert "names no machine" in _refused(capsys, tmp_path / "bag", "--out", tmp_path / "fit")
    _goal_bag(tmp_path / "empty")
    assert "no job_goal recorded" in _refused(capsys, tmp_path / "empty", "--out", tmp_path / "fit")


def test_a_missing_bag_is_refused(tmp_path, capsys):
    assert "no recording at" in _refused(capsys, tmp_path / "nothing", "--out", tmp_path / "fit")
