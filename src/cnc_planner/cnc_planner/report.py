"""report.json from a recording alone: what cnc-run writes and cnc-analyze recomputes.

The job document travels on job_goal and is recorded, so the method sections re-derive
what they need (hole positions, R plane, stock) from it with the planner's own code and
judge the recorded feedback (and, for comparison, the recorded commands).
"""
from __future__ import annotations

import json
from types import SimpleNamespace

import numpy as np

from cnc_msgs_py.job import parse_job
from cnc_msgs_py.machine import SPINDLE, Machine, MachineError, load_machine
from cnc_msgs_py.schema import JobError
from cnc_msgs_py.units import to_mm
from cnc_servo_bridge import analysis
from cnc_servo_bridge.aircut import analyze_aircut
from cnc_servo_bridge.drill_analysis import analyze_drilling, obstacle_clearance
from cnc_servo_bridge.drive import DriveModel
from cnc_servo_bridge.recording import Run
from cnc_servo_bridge.thread_analysis import analyze_thread

from .drilling import lower_bound_time
from .executive import event_doc
from .clamps import OBSTACLE_MARGIN
from .jobs import drill_cycle, plan_job, tilted, tilted_frame
from .kinematics import Kinematics
from .path_report import path_section
from .timeline import Event, Plan
from .turning import max_gouge, plan_naive, plan_roughing

FINAL = ("rejected", "succeeded", "aborted", "canceled")


def final_status(run: Run, job_id: str | None = None) -> dict:
    """The last final status of the job (or of the last job in the run)."""
    finals = [s for s in run.statuses if s["state"] in FINAL]
    if job_id is not None:
        finals = [s for s in finals if s["job_id"] == job_id]
    return finals[-1] if finals else {"job_id": job_id or "", "state": "unknown", "reason": "no final status recorded"}


def last_job(run: Run) -> tuple[str | None, SimpleNamespace | None]:
    if not run.goals:
        return None, None
    try:
        doc = json.loads(run.goals[-1])
    except json.JSONDecodeError:
        return None, None
    job_id = doc.get("job_id") if isinstance(doc, dict) else None
    try:
        return job_id, parse_job(doc)
    except JobError:
        return job_id, None


def build_report(run: Run, machine: Machine | None = None) -> dict:
    """The figures of a run's last job, judged on feedback; ``machine``: the description
    it ran on, if not the one the job names in config (a drawn one, in tests)."""
    job_id, job = last_job(run)
    status = final_status(run, job_id)
    axes = tuple(j for j in run.joints if j != SPINDLE)
    report = {
        "job_id": status["job_id"],
        "state": status["state"],
        "reason": status.get("reason", ""),
        "cycle_time_s": analysis.cycle_time(run, axes),
        "planned_time_s": status.get("cycle_time_s"),
        "max_following_error": analysis.following_error(run),
        "setpoints": int(len(run.command_t)),
        "chunks": len(run.chunks),
        "chunks_lost": analysis.chunks_lost(run),
        "feedback_samples": int(len(run.feedback_t)),
        "alarms": sorted(set(run.alarms)),
    }
    if job is None or status["state"] == "rejected" or len(run.feedback_t) == 0:
        return report
    try:
        machine = machine or load_machine(job.machine)
    except MachineError:
        return report
    window = job_window(run, status["job_id"])
    if job.kind == "drill":
        report["drill"] = drill_section(run, job, machine, window)
    if job.kind == "turn":
        report["turn"] = turn_section(run, job, machine, window)
    if job.kind == "path":
        report["kinematics"] = path_section(run, job, machine, window)
    if job.kind == "thread":
        report["thread"] = thread_section(run, job, machine, window)
    elif job.vibration is not None and job.kind != "drill":  # a drill job judges each hole
        report["aircut"] = aircut_section(run)
    return report


def job_window(run: Run, job_id: str) -> np.ndarray:
    """Feedback samples from the job's first setpoint to the end of the recording."""
    starts = [e["stamp_ns"] for e in run.events if e.get("job_id") == job_id and e["name"] == "job_start"]
    t0 = (starts[-1] / 1e9) if starts else run.feedback_t[0]
    return run.feedback_t >= t0 - 1e-9


def predicted_run(doc: dict, plan: Plan, machine: Machine, period: float = 1e-3) -> Run:
    """A run as the bridge would record it, predicted offline: the plan's setpoints, the
    drive model's feedback to them and the plan's events, so that build_report judges a
    prediction with the very code that judges recordings. A prediction, not a recording:
    no DDS, no timing, no lost samples."""
    t, feedback = simulated_feedback(plan, machine, period)
    p, v, _ = plan.sample(t)
    job_id = str(doc.get("job_id", ""))
    final = {"job_id": job_id, "state": "succeeded", "reason": "", "cycle_time_s": plan.duration}
    events = [event_doc(job_id, 0, e) for e in plan.events]
    if not any(e.name == "job_start" for e in plan.events):
        events.insert(0, event_doc(job_id, 0, Event(0.0, "job_start")))
    return Run(joints=plan.joints, feedback_t=t, feedback=feedback, feedback_velocity=np.zeros_like(feedback),
               command_t=t, command=p, command_velocity=v, goals=[json.dumps(doc)], statuses=[final],
               events=events)


def simulated_feedback(plan, machine: Machine, period: float = 1e-3) -> tuple[np.ndarray, np.ndarray]:
    """What the bridge's drives would report for a plan, offline (same drive model)."""
    t = np.arange(int(np.ceil(plan.duration / period)) + 1) * period
    p, v, a = plan.sample(t)
    fb, _ = DriveModel(machine, period, plan.joints).simulate(p, v, a)
    return t, fb


def drill_section(run: Run, job: SimpleNamespace, machine: Machine, window: np.ndarray) -> dict:
    kin = Kinematics(machine, job.setup, job.tool)
    start = {j: float(run.feedback[window][0, run.column(j)]) for j in run.joints}
    cycle = drill_cycle(job, machine, kin, (start["x"], start["y"]))
    # A tilted setup drills in program coordinates (tool along program Z): analyse there,
    # from the cycle's start (the first S1): before it the rotaries turn from wherever
    # the machine stood, where the program's R plane means nothing yet.
    frame = tilted(kin) and machine.layout != "mill3"
    if frame:
        begin = run.feedback_t[window][0]
        s1 = [e["stamp_ns"] / 1e9 for e in run.events
              if e.get("name") == "S1" and "stamp_ns" in e and e["stamp_ns"] / 1e9 >= begin - 1e-9]
        if s1:
            window = window & (run.feedback_t >= min(s1) - 1e-9)
    t = run.feedback_t[window]
    fb = run.feedback[window]

    def xyz(joints, feedback: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        if not frame:
            return tuple(feedback[:, list(joints).index(j)] for j in "xyz")  # type: ignore[return-value]
        tips, _ = kin.fk_many({j: feedback[:, i] for i, j in enumerate(joints) if j != SPINDLE})
        return tips[:, 0], tips[:, 1], tips[:, 2]

    surfaces = [cycle.planes(i)[0] for i in range(len(cycle.holes))]
    result = analyze_drilling(t, *xyz(run.joints, fb), cycle.holes, cycle.r_z, cycle.xy_tolerance, surfaces)
    modes = {e["hole"]: e["mode"] for e in run.events if e.get("name") == "S1"}
    for hole in result["holes"]:
        hole["mode"] = modes.get(hole["index"])
        hole["job_index"] = cycle.order[hole["index"]] if cycle.order else hole["index"]
    conventional = SimpleNamespace(**{**vars(job), "drill": SimpleNamespace(**{**vars(job.drill), "overlap": "off"})})
    conv_plan = plan_job(conventional, machine, start)
    ct, cfb = simulated_feedback(conv_plan, machine)
    if frame:
        keep = ct >= min(e.time for e in conv_plan.events if e.name == "S1") - 1e-9
        ct, cfb = ct[keep], cfb[keep]
    conv = analyze_drilling(ct, *xyz(conv_plan.joints, cfb), cycle.holes, cycle.r_z, cycle.xy_tolerance, surfaces)
    if job.vibration is not None:
        hole_aircuts(run, result["holes"], surfaces)
    if job.drill.peck is not None:
        result["pecks"] = peck_reentries(run, window)
    if job.drill.obstacles:
        result["obstacles"] = obstacle_section(job, kin, *xyz(run.joints, fb))
    result["conventional_cycle_time_s"] = conv["cycle_time_s"]
    if job.drill.order == "shortest":  # planning the other order costs a plan: only when asked
        result["order"] = order_section(job, machine, start, result["cycle_time_s"], xyz)
    if frame:  # from the cycle's start, over the first hole; in the tilted frame's limits
        result["lower_bound_s"] = lower_bound_time(tilted_frame(job, machine, kin).machine, cycle)
    else:
        result["lower_bound_s"] = lower_bound_time(machine, cycle, (start["x"], start["y"]))
    return result


def peck_reentries(run: Run, window: np.ndarray) -> dict:
    """Pecks on feedback: how close the fast re-entry after each retract came to the
    previous bottom (must stay above it), and how many retracts went up."""
    t, z = run.feedback_t[window], run.feedback[window][:, run.column("z")]
    marks = [e for e in run.events if e.get("name") in ("reentry", "peck")]
    closest = np.inf
    count = 0
    for entry, feed in zip(marks[0::2], marks[1::2]):
        fast = (t >= entry["stamp_ns"] / 1e9) & (t <= feed["stamp_ns"] / 1e9)
        if fast.any():
            closest = min(closest, float(np.min(z[fast]) - entry["previous_bottom"]))
            count += 1
    return {"reentries": count, "min_reentry_height_mm": to_mm(closest) if count else None}


def obstacle_section(job: SimpleNamespace, kin: Kinematics, x: np.ndarray, y: np.ndarray,
                     z: np.ndarray) -> list[dict]:
    """Per obstacle, the tip's lowest height above its top while the tool was over it, on
    feedback (axis x, y, z in; judged in program coordinates, as the obstacles are given)."""
    tips, _ = kin.fk_many({"x": x, "y": y, "z": z})
    px, py, pz = tips[:, 0], tips[:, 1], tips[:, 2]
    radius = (job.tool.diameter or 0.0) / 2.0
    lows = obstacle_clearance(px, py, pz, job.drill.obstacles, radius)
    return [{"index": k, "top_mm": to_mm(o[4]), "min_clearance_mm": None if low is None else to_mm(low),
             "required_mm": to_mm(OBSTACLE_MARGIN)} for k, (o, low) in enumerate(zip(job.drill.obstacles, lows))]


def order_section(job: SimpleNamespace, machine: Machine, start: dict, cycle_time: float, xyz) -> dict:
    """Cycle time of both hole orders: the short tour drilled (on feedback) and the order
    given (planned and run through the drive model)."""
    given = SimpleNamespace(**{**vars(job), "drill": SimpleNamespace(**{**vars(job.drill), "order": "given"})})
    plan = plan_job(given, machine, start)
    t, fb = simulated_feedback(plan, machine)
    cycle = drill_cycle(given, machine, Kinematics(machine, job.setup, job.tool))
    given_time = analyze_drilling(t, *xyz(plan.joints, fb), cycle.holes, cycle.r_z, cycle.xy_tolerance)["cycle_time_s"]
    return {"drilled": "shortest", "shortest_cycle_time_s": cycle_time, "given_cycle_time_s": given_time}


def turn_section(run: Run, job: SimpleNamespace, machine: Machine, window: np.ndarray) -> dict:
    t = job.turn
    args = dict(stock=[tuple(p) for p in t.stock], profile=[tuple(p) for p in t.profile],
                depth_of_cut=t.depth_of_cut, clearance=t.clearance, origin=tuple(t.origin),
                finish_allowance=t.finish_allowance, finish_allowance_z=t.finish_allowance_z)
    ours = plan_roughing(**args, finishing_pass=t.finishing_pass)
    naive = plan_naive(**args, finishing_pass=t.finishing_pass)
    kin = Kinematics(machine, job.setup, job.tool)

    def tips(positions: np.ndarray) -> np.ndarray:
        radius, z = kin.tip_radius_z(positions[:, run.column("x")], positions[:, run.column("z")])
        return np.stack([z, radius], axis=1)

    tip_zx = tips(run.feedback[window])
    commanded = tips(run.command[run.command_t >= run.feedback_t[window][0]])
    return {
        **ours.to_dict(),
        "naive_path_mm": to_mm(naive.path_length),
        "naive_air_feed_mm": to_mm(naive.air_feed_length),
        "path_feedback_mm": to_mm(float(np.sum(np.linalg.norm(np.diff(tip_zx, axis=0), axis=1)))),
        # How far the tip went into the finishing allowances (radial and axial) on feedback, into
        # the final profile itself on feedback (must be 0), and into the allowances in the setpoints.
        "max_gouge_mm": to_mm(max_gouge(tip_zx, args["profile"], t.finish_allowance, t.finish_allowance_z)),
        "max_gouge_part_mm": to_mm(max_gouge(tip_zx, args["profile"], 0.0)),
        "max_gouge_commanded_mm": to_mm(max_gouge(commanded, args["profile"], t.finish_allowance,
                                                  t.finish_allowance_z)),
        "cycle_time_s": analysis.cycle_time(run, ("x", "z")),
    }


def thread_section(run: Run, job: SimpleNamespace, machine: Machine, window: np.ndarray) -> dict:
    """Passes, chips, depth and helix accuracy of a thread, on feedback and on commands,
    judged in program coordinates (the thread block's), whatever the setup and tool length."""
    thread = json.loads(run.goals[-1])["thread"]
    kin = Kinematics(machine, job.setup, job.tool)

    def judge(t: np.ndarray, positions: np.ndarray) -> dict:
        radius, z = kin.tip_radius_z(positions[:, run.column("x")], positions[:, run.column("z")])
        return analyze_thread(t, radius, z, positions[:, run.column(SPINDLE)], thread)

    feedback = judge(run.feedback_t[window], run.feedback[window])
    inside = run.command_t >= run.feedback_t[window][0]
    try:
        commanded = judge(run.command_t[inside], run.command[inside])
    except ValueError as err:
        # A drive without feed-forward is commanded well ahead of the groove it cuts: its
        # commands need not trace a helix at all. The feedback is what is judged.
        return {**feedback, "commanded": {"error": str(err)}}
    return {**feedback, "commanded": {k: commanded[k] for k in ("max_chip_revs", "helix_residual_mm", "depth_error_mm")}}


def _feeds(run: Run) -> list[tuple[dict, float]]:
    """Every vibrated feed of the run: its start event and its end time (s)."""
    starts = [e for e in run.events if e.get("name") == "vibration_feed"]
    ends = [e["stamp_ns"] / 1e9 for e in run.events if e.get("name") == "vibration_end"]
    return list(zip(starts, ends))


def _feed_aircut(run: Run, times: np.ndarray, positions: np.ndarray, start: dict, end: float,
                 below: float | None = None) -> dict | None:
    """analyze_aircut of one vibrated feed (from where its progress first passes ``below``,
    m along the feed, if given), or None if not even one revolution was recorded."""
    inside = (times >= start["stamp_ns"] / 1e9) & (times <= end)
    cols = [run.column(j) for j in start["joints"]]
    progress = (positions[:, cols] - np.array(start["start"])) @ np.array(start["direction"])
    if below is not None:
        cut = inside & (progress > below)
        inside &= np.arange(len(times)) >= (int(np.argmax(cut)) if cut.any() else len(times))
    spindle = positions[inside, run.column(SPINDLE)]
    if len(spindle) < 2 or abs(spindle[-1] - spindle[0]) < 2 * np.pi:
        return None  # not even one revolution recorded: nothing to judge
    return analyze_aircut(spindle, progress[inside]).to_dict()


def hole_aircuts(run: Run, holes: list[dict], surfaces: list[float]) -> None:
    """Per hole, the air-cut share and the longest chip below the surface, on the commands
    and on the feedback (the vibrated feed starts at R, in the air)."""
    rows = {h["index"]: h for h in holes}
    for start, end in _feeds(run):
        row = rows.get(start.get("hole"))
        if row is None:
            continue
        above = start["start"][0] - surfaces[row["index"]]  # the feed runs down Z from R
        row["aircut"] = {}
        for source, times, positions in (("commanded", run.command_t, run.command),
                                         ("feedback", run.feedback_t, run.feedback)):
            found = _feed_aircut(run, times, positions, start, end, above)
            row["aircut"][source] = None if found is None else {
                k: found[k] for k in ("revolutions", "revolutions_with_aircut", "aircut_fraction", "max_chip_revs")}


def aircut_section(run: Run) -> dict:
    """Air-cuts of every vibrating feed, on the commands and on the feedback."""
    out = {}
    for source, times, positions in (("commanded", run.command_t, run.command),
                                     ("feedback", run.feedback_t, run.feedback)):
        totals = {"revolutions": 0, "revolutions_with_aircut": 0, "max_chip_revs": 0.0}
        for start, end in _feeds(run):
            report = _feed_aircut(run, times, positions, start, end)
            if report is None:
                continue
            totals["revolutions"] += report["revolutions"]
            totals["revolutions_with_aircut"] += report["revolutions_with_aircut"]
            totals["max_chip_revs"] = max(totals["max_chip_revs"], report["max_chip_revs"])
        out[source] = totals
    return {
        "revolutions": out["feedback"]["revolutions"],
        "revolutions_with_aircut": out["feedback"]["revolutions_with_aircut"],
        "max_chip_revs": out["feedback"]["max_chip_revs"],
        "commanded": out["commanded"],
        "feedback": out["feedback"],
    }
