"""Helpers shared by the integration tests: paths and the console scripts."""
from __future__ import annotations

import dataclasses
import json
import os
import subprocess
import sys
from pathlib import Path

from hypothesis import strategies as st

from cnc_msgs_py.machine import SPINDLE, Machine

ROOT = Path(__file__).resolve().parents[1]
JOBS = ROOT / "config" / "jobs"
BIN = Path(sys.executable).parent


def domain_range() -> range:
    """The DDS domains this run may use: CNC_TEST_DOMAINS=LOW-HIGH, the user's ROS_DOMAIN_ID, or 1..100."""
    chosen = os.environ.get("CNC_TEST_DOMAINS") or (f"{os.environ['ROS_DOMAIN_ID']}-{os.environ['ROS_DOMAIN_ID']}"
                                                    if os.environ.get("ROS_DOMAIN_ID") else "1-100")
    low, _, high = chosen.partition("-")
    return range(int(low), int(high) + 1)


def cnc(tool: str, *args: str, timeout: float = 600) -> subprocess.CompletedProcess:
    """Run one of the project's console scripts as a user would."""
    return subprocess.run([str(BIN / tool), *map(str, args)], capture_output=True, text=True,
                          timeout=timeout, env=dict(os.environ))


def load_report(out: Path) -> dict:
    return json.loads((out / "report.json").read_text())


START_DELAY_S = 0.2  # from a job's first 'running' status to its first setpoint


def running_past(session, job_id: str, fraction: float) -> None:
    """Spin until the machine's (simulated) time has run ``fraction`` of the job."""
    def first_running() -> dict | None:
        return next((s for s in session.recorder.statuses if s["job_id"] == job_id and s["state"] == "running"), None)
    session.spin_until(lambda: first_running() is not None, 60, f"{job_id} never started")
    status = first_running()
    target = status["stamp_ns"] + int((START_DELAY_S + fraction * status["duration_s"]) * 1e9)
    session.spin_until(lambda: session.recorder.sim_ns >= target, 60, f"{job_id} never got to {fraction}")


LEFT_MATERIAL_MM = 0.08  # a hole's bottom rises by the overshoot of the deepest drive inside
# the tolerance (kinds/drill/bottom.py): 32 um on mill3, up to 80 um over drawn plants
OVERCUT_MM = 0.005  # cnc_analysis.verdict.OVERCUT_LIMIT: deeper than this is a miss
SHORT_LIMIT_MM = 0.2  # cnc_analysis.drilling.DEPTH_SHORT_LIMIT: a hole short by more is a miss
THREAD_SHORT_MM = 0.05  # cnc_analysis.threads.SHORT_LIMIT: a thread short by more is a miss


def assert_hole_depth(depth_mm: float, programmed_mm: float) -> None:
    """A drilled hole on feedback: never deeper than programmed (beyond the verdict's overcut
    limit), short of it by at most what the tolerance leaves."""
    assert programmed_mm - LEFT_MATERIAL_MM <= depth_mm <= programmed_mm + OVERCUT_MM, (depth_mm, programmed_mm)


def check_verified_properties(kind: str, report: dict, depth_mm: float = 5.0, depth_tol_mm: float = 0.05) -> None:
    """What we verify on feedback for a job kind's example (report.json of a recording, or
    of a predicted run): drilling safe and at depth, an air-cut in every vibrating
    revolution, thread chips broken with full depth on one helix, turning never into the
    part, a path completed with the tip on feedback within its chord tolerance."""
    if kind == "drill":
        drill = report["drill"]
        assert drill["safety_violations"] == 0
        for hole in drill["holes"]:  # never deeper; short by at most what the tolerance leaves
            assert depth_mm - max(depth_tol_mm, SHORT_LIMIT_MM) <= hole["depth_mm"] <= depth_mm + depth_tol_mm, hole
    elif kind == "vibration move":
        aircut = report["aircut"]["feedback"]
        assert aircut["revolutions"] >= 100
        assert aircut["revolutions_with_aircut"] == aircut["revolutions"]
    elif kind == "thread":
        thread = report["thread"]  # never over depth; short by at most what the tolerance leaves
        assert thread["overcut_mm"] <= OVERCUT_MM and thread["depth_error_mm"] <= THREAD_SHORT_MM, thread
        assert thread["helix_residual_mm"] < 0.01
        for cut in thread["passes"]:
            if cut["doc_mm"] > 0.05:
                assert cut["max_chip_revs"] <= 1.0, cut
    elif kind == "turn":
        assert report["turn"]["max_gouge_part_mm"] == 0
    elif kind == "path":
        assert report["kinematics"]["completed"] and report["kinematics"]["within_tolerance"]
    else:
        raise ValueError(f"no properties for job kind {kind!r}")


EXAMPLES = {  # job kind -> the example job of that kind in config/jobs
    "drill": "drill_row.yaml",
    "thread": "thread_m12.yaml",
    "vibration move": "lathe_feed_vibration.yaml",
    "turn": "turn_stepped.yaml",
    "path": "path_mill3.yaml",
}

LONG = [{"linear": {"x": 200.0}, "feed": 3000}, {"rapid": {"x": 0}}]  # 4 s of feed at 50 mm/s, then home
SHORT = [{"rapid": {"x": 5.0}}, {"rapid": {"x": 0.0}}]


def move_job(job_id: str, moves: list[dict]) -> str:
    """A mill3 move job as sent on job_goal (JSON)."""
    return json.dumps({"schema": "cnc_job/1", "job_id": job_id, "kind": "move", "machine": "mill3", "move": moves})


def log_uniform(lo: float, hi: float) -> st.SearchStrategy[float]:
    return st.floats(0.0, 1.0).map(lambda u: lo * (hi / lo) ** u)


@st.composite
def machines(draw, base: Machine) -> Machine:
    """The base machine with every positioning axis's jerk and drive drawn anew."""
    axes, drives = dict(base.axes), dict(base.drives)
    for name in base.joint_names:
        if name == SPINDLE:
            continue
        axes[name] = dataclasses.replace(axes[name], max_jerk=draw(log_uniform(50.0, 1e6)))
        drives[name] = dataclasses.replace(
            drives[name], kp=draw(st.floats(10.0, 150.0)), velocity_ff=draw(st.floats(0.0, 1.0)),
            accel_ff=draw(st.floats(0.0, 1.0)), velocity_lag=draw(log_uniform(2e-4, 1e-2)),
            resolution=draw(log_uniform(1e-8, 1e-5)), following_error_limit=draw(log_uniform(1e-3, 2e-2)))
    return dataclasses.replace(base, name=f"{base.name}_drawn", axes=axes, drives=drives)
