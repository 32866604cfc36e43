"""The drill section of report.json: every hole judged on feedback (depth, X/Y still below
R, retract mode), pecks, clamps, air-cuts per hole, and the cycle against the conventional
cycle, the other hole order and the lower bound.

Its verdict fails the run on feedback that moved X/Y while the tip was below R, a hole
deeper or shallower than programmed beyond cnc_analysis.drilling's limits, a peck's fast
re-entry below the previous bottom, the tool below an obstacle's top while over it, or a
vibrated hole's chip longer than its waveform's window."""
from __future__ import annotations

from types import SimpleNamespace

import numpy as np

from cnc_msgs_py.machine import SPINDLE, Machine
from cnc_msgs_py.units import to_mm

from cnc_analysis.drilling import DEPTH_SHORT_LIMIT, analyze_drilling, drilling_failures, obstacle_clearance
from cnc_analysis.recording import Run
from cnc_analysis.verdict import OVERCUT_LIMIT, verdict

from cnc_planner import planning
from cnc_planner.baselines import baseline
from cnc_planner.kinds.drill.block import drill_cycle
from cnc_planner.kinds.drill.bound import lower_bound_time
from cnc_planner.kinds.drill.clamps import OBSTACLE_MARGIN
from cnc_planner.kinds.drill.tilted import tilted, tilted_frame
from cnc_planner.kinematics import Kinematics
from cnc_planner.prediction import simulated_feedback
from cnc_planner.vibration.report import CHIP_CRITERION, chip_failures, feed_aircut, feeds


def _frame(kin: Kinematics, machine: Machine) -> bool:
    """A tilted setup drills in program coordinates (tool along program Z): analysed there."""
    return tilted(kin) and machine.layout != "mill3"


def _tips(kin: Kinematics, frame: bool):
    """The tool tip's x, y, z of feedback (samples x joints, in ``joints``' order)."""
    def xyz(joints, feedback: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        if not frame:
            return tuple(feedback[:, list(joints).index(j)] for j in "xyz")  # type: ignore[return-value]
        tips, _ = kin.fk_many({j: feedback[:, i] for i, j in enumerate(joints) if j != SPINDLE})
        return tips[:, 0], tips[:, 1], tips[:, 2]
    return xyz


@baseline
def other_cycles(job: SimpleNamespace, machine: Machine, start: dict[str, float]) -> dict:
    """The cycles the drilled one is compared with, planned from ``start`` and timed on the
    drive model's feedback: the conventional cycle (overlap off) and, for a job drilled in
    the short tour, the order given. The recording changes neither (cnc_planner.baselines)."""
    kin = Kinematics(machine, job.setup, job.tool)
    cycle = drill_cycle(job, machine, kin, (start["x"], start["y"]))
    frame = _frame(kin, machine)
    xyz = _tips(kin, frame)
    surfaces = [cycle.planes(i)[0] for i in range(len(cycle.holes))]
    conventional = SimpleNamespace(**{**vars(job), "drill": SimpleNamespace(**{**vars(job.drill), "overlap": "off"})})
    conv_plan = planning.plan_job(conventional, machine, start)
    ct, cfb = simulated_feedback(conv_plan, machine)
    if frame:
        keep = ct >= min(e.time for e in conv_plan.events if e.name == "S1") - 1e-9
        ct, cfb = ct[keep], cfb[keep]
    conv = analyze_drilling(ct, *xyz(conv_plan.joints, cfb), cycle.holes, cycle.r_z, cycle.xy_tolerance, surfaces)
    out = {"conventional_cycle_time_s": conv["cycle_time_s"]}
    if job.drill.order == "shortest":  # planning the other order costs a plan: only when asked
        out["given_cycle_time_s"] = given_order_time(job, machine, start, xyz)
    return out


def drill_section(run: Run, job: SimpleNamespace, machine: Machine, window: np.ndarray) -> dict:
    kin = Kinematics(machine, job.setup, job.tool)
    start = run.feedback_at(window)
    cycle = drill_cycle(job, machine, kin, (start["x"], start["y"]))
    # A tilted setup is analysed from the cycle's start (the first S1): before it the
    # rotaries turn from wherever the machine stood, where the program's R plane means
    # nothing yet.
    frame = _frame(kin, machine)
    if frame:
        begin = run.feedback_t[window][0]
        s1 = [e["stamp_ns"] / 1e9 for e in run.events
              if e.get("name") == "S1" and "stamp_ns" in e and e["stamp_ns"] / 1e9 >= begin - 1e-9]
        if s1:
            window = window & (run.feedback_t >= min(s1) - 1e-9)
    t = run.feedback_t[window]
    fb = run.feedback[window]
    xyz = _tips(kin, frame)
    surfaces = [cycle.planes(i)[0] for i in range(len(cycle.holes))]
    result = analyze_drilling(t, *xyz(run.joints, fb), cycle.holes, cycle.r_z, cycle.xy_tolerance, surfaces)
    modes = {e["hole"]: e["mode"] for e in run.events if e.get("name") == "S1"}
    for hole in result["holes"]:
        hole["mode"] = modes.get(hole["index"])
        hole["job_index"] = cycle.order[hole["index"]] if cycle.order else hole["index"]
    depths = [surface - cycle.planes(i)[2] for i, surface in enumerate(surfaces)]
    failures = drilling_failures(result, depths)
    if job.vibration is not None:
        failures += chip_failures(hole_aircuts(run, result["holes"], surfaces))
    if job.drill.peck is not None:
        result["pecks"] = peck_reentries(run, window)
        low = result["pecks"]["min_reentry_height_mm"]
        if low is not None and low < 0:
            failures.append(f"a peck's fast re-entry went {-low:.4f} mm below the previous bottom")
    if job.drill.obstacles:
        result["obstacles"] = obstacle_section(job, kin, *xyz(run.joints, fb))
        hits = [o for o in result["obstacles"] if o["min_clearance_mm"] is not None and o["min_clearance_mm"] < 0]
        if hits:
            failures.append(f"the tip went {-hits[0]['min_clearance_mm']:.4f} mm below the top of obstacle "
                            f"{hits[0]['index']} while over it")
    drilled = [h["depth_mm"] for h in result["holes"] if h.get("depth_mm") is not None]
    result["verdict"] = verdict(criterion(job), failures, (
        f"no X/Y motion below R on feedback; {len(drilled)} holes {min(drilled, default=0):.4f}-"
        f"{max(drilled, default=0):.4f} mm deep for {', '.join(f'{to_mm(d):g}' for d in sorted(set(depths)))} mm"))
    others = other_cycles(job, machine, start)  # last: planned meanwhile (cnc_planner.baselines)
    result["conventional_cycle_time_s"] = others["conventional_cycle_time_s"]
    if job.drill.order == "shortest":
        result["order"] = {"drilled": "shortest", "shortest_cycle_time_s": result["cycle_time_s"],
                           "given_cycle_time_s": others["given_cycle_time_s"]}
    if frame:  # from the cycle's start, over the first hole; in the tilted frame's limits
        result["lower_bound_s"] = lower_bound_time(tilted_frame(job, machine, kin).machine, cycle)
    else:
        result["lower_bound_s"] = lower_bound_time(machine, cycle, (start["x"], start["y"]))
    return result


def criterion(job: SimpleNamespace) -> str:
    """What the drill section's verdict holds the feedback to, with its limits."""
    rules = [f"on feedback: no X/Y motion while the tip is below R; every hole within +{to_mm(OVERCUT_LIMIT):g}/"
             f"-{to_mm(DEPTH_SHORT_LIMIT):g} mm of its depth"]
    if job.drill.peck is not None:
        rules.append("every peck's fast re-entry above the previous bottom")
    if job.drill.obstacles:
        rules.append("the tip above every obstacle's top while over it")
    if job.vibration is not None:
        rules.append(CHIP_CRITERION.removeprefix("on feedback: "))
    return "; ".join(rules)


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


def given_order_time(job: SimpleNamespace, machine: Machine, start: dict, xyz) -> float:
    """The cycle time of the holes in the order given (planned and run through the drive
    model), for a job drilled in its short tour."""
    given = SimpleNamespace(**{**vars(job), "drill": SimpleNamespace(**{**vars(job.drill), "order": "given"})})
    plan = planning.plan_job(given, machine, start)
    t, fb = simulated_feedback(plan, machine)
    cycle = drill_cycle(given, machine, Kinematics(machine, job.setup, job.tool))
    return analyze_drilling(t, *xyz(plan.joints, fb), cycle.holes, cycle.r_z, cycle.xy_tolerance)["cycle_time_s"]


def hole_aircuts(run: Run, holes: list[dict], surfaces: list[float]) -> list[tuple[dict, dict | None]]:
    """Per hole, the air-cut share and the longest chip below the surface, on the commands
    and on the feedback (the vibrated feed starts at R, in the air); returns each hole's
    feed (its start event) with its air-cuts on feedback, for the verdict."""
    rows = {h["index"]: h for h in holes}
    judged = []
    for start, end in feeds(run):
        row = rows.get(start.get("hole"))
        if row is None:
            continue
        above = start["start"][0] - surfaces[row["index"]]  # the feed runs down Z from R
        row["aircut"] = {}
        for source, times, positions in (("commanded", run.command_t, run.command),
                                         ("feedback", run.feedback_t, run.feedback)):
            found = feed_aircut(run, times, positions, start, end, above)
            row["aircut"][source] = None if found is None else {
                k: found[k] for k in ("revolutions", "revolutions_with_aircut", "aircut_fraction", "max_chip_revs")}
        judged.append((start, row["aircut"]["feedback"]))
    return judged
