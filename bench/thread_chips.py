"""Thread cutting with and without the chip-breaking vibration, judged on the drive's feedback.

The issue-9 example job (start_z 4, end_z -16, major radius 6, pitch 1.75, depth 1.07 mm,
6 passes + 1 spring pass, infeed 29.5 deg; vibration D 1.5, Q 1.2, phase shift 180 deg) is
planned, sampled every servo period, run through DriveModel.simulate (what the bridge
publishes) and read back with analyze_thread from positions only.

Table 1, at 600 rpm: cycle time, mean time between synchronised passes (from one pass
leaving its helix to the next locking on, as analyze_thread finds them on feedback),
longest chip of the cutting passes, air-cut share, helix residual, depth error and
overcut, with and without the vibration, on the shipped lathe and on the "fair"
description of bench-peer (every max_jerk 1e6, bench/peer/ours.py), against which
LinuxCNC G76 takes 9.224 s with 0.164 s between passes (bench/results/peer.txt).

Table 2: the highest spindle speed at which the feedback still breaks the chip within one
revolution on every cutting pass, reaches full depth within 0.02 mm and stays within
0.01 mm of the helix; binary search from 300 rpm up to the speed check_thread accepts
(the axes' limits for the vibration). For the lathe as configured and with the x/z
velocity feed-forward off, each with the drive-compensated command and the plain one.

Usage: python bench/thread_chips.py   (writes bench/results/thread_chips.txt too)
"""
from __future__ import annotations

import dataclasses
import math
import re
import sys
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
for package in ("cnc_msgs_py", "cnc_analysis", "cnc_planner", "cnc_servo_bridge"):
    sys.path.insert(0, str(ROOT / "src" / package))

from cnc_msgs_py.machine import Machine, load_machine  # noqa: E402
from cnc_msgs_py.units import rpm, to_rpm  # noqa: E402
from cnc_planner.motion.builder import PlanBuilder  # noqa: E402
from cnc_planner.kinds.thread.checks import WAVE_LIMIT_SHARE, check_thread  # noqa: E402
from cnc_planner.kinds.thread.planning import plan_thread  # noqa: E402
from cnc_planner.kinds.thread.spec import ThreadError, ThreadSpec, ThreadVibration  # noqa: E402
from cnc_servo_bridge.drive import DriveModel  # noqa: E402
from cnc_analysis.threads import analyze_thread  # noqa: E402
from publish import write_result  # noqa: E402

SERVO_PERIOD = 1e-3
LOW_RPM = 300.0
RPM_RESOLUTION = 0.01  # relative width at which the binary search stops
THREAD = {"start_z": 4.0, "end_z": -16.0, "major_radius": 6.0, "pitch": 1.75, "depth": 1.07,
          "passes": 6, "infeed_angle": 29.5, "spring_passes": 1}
FAIR_JERK = 1e6  # m/s^3, rad/s^3: bench/peer/ours.py TRAPEZOID_JERK
VIBRATION = ThreadVibration(D=1.5, Q=1.2, phase_shift=math.pi, D_step=0.0)


def spec(speed_rpm: float, vibration: ThreadVibration | None = VIBRATION) -> ThreadSpec:
    return ThreadSpec(start_z=4e-3, end_z=-16e-3, major_radius=6e-3, pitch=1.75e-3, depth=1.07e-3,
                      spindle_speed=rpm(speed_rpm), passes=6, infeed_angle=math.radians(29.5),
                      spring_passes=1, vibration=vibration)


def lathe(velocity_ff: float | None = None) -> Machine:
    machine = load_machine("lathe")
    if velocity_ff is None:
        return machine
    drives = {j: dataclasses.replace(machine.drives[j], velocity_ff=velocity_ff) for j in ("x", "z")}
    return dataclasses.replace(machine, drives={**machine.drives, **drives})


def fair() -> Machine:
    """The lathe with every max_jerk 1e6, as bench/peer/ours.py writes its trapezoid variant."""
    machine = load_machine("lathe")
    axes = {name: dataclasses.replace(axis, max_jerk=FAIR_JERK) for name, axis in machine.axes.items()}
    return dataclasses.replace(machine, axes=axes)


def cut(thread: ThreadSpec, machine: Machine, compensate: bool = True) -> tuple[float, dict]:
    """Cycle time and the analysis of the feedback."""
    builder = PlanBuilder(machine, {"x": 7e-3, "z": 4e-3})
    plan_thread(builder, thread, servo_period=SERVO_PERIOD, compensate=compensate)
    plan = builder.build()
    t = np.arange(0.0, plan.duration + SERVO_PERIOD / 2, SERVO_PERIOD)
    feedback = DriveModel(machine, SERVO_PERIOD).simulate(*plan.sample(t))[0]
    return plan.duration, analyze_thread(t, feedback[:, 0], feedback[:, 1], feedback[:, 2], THREAD)


def good(report: dict) -> bool:
    return report["chips_broken"] and report["full_depth"] and report["helix_residual_mm"] < 0.01


def accepted_rpm(machine: Machine) -> float:
    """The highest speed check_thread accepts for the vibration (it names it when refusing)."""
    try:
        check_thread(spec(to_rpm(machine.axis("spindle").max_velocity)), machine)
    except ThreadError as err:
        return float(re.search(r"max spindle speed (\d+) rpm", str(err)).group(1))
    return to_rpm(machine.axis("spindle").max_velocity)


def breaks(speed_rpm: float, machine: Machine, compensate: bool) -> bool:
    try:
        return good(cut(spec(speed_rpm), machine, compensate)[1])
    except ThreadError:
        return False


def highest_rpm(job: tuple[str, float | None, bool]) -> str:
    name, velocity_ff, compensate = job
    machine = lathe(velocity_ff)
    limit = accepted_rpm(machine)
    if breaks(limit, machine, compensate):
        best = limit
    elif not breaks(LOW_RPM, machine, compensate):
        best = 0.0
    else:
        lo, hi = LOW_RPM, limit
        while hi - lo > RPM_RESOLUTION * hi:
            mid = (lo + hi) / 2
            lo, hi = (mid, hi) if breaks(mid, machine, compensate) else (lo, mid)
        best = lo
    command = "compensated" if compensate else "plain"
    shown = f"{best:.0f}" if best else f"none >= {LOW_RPM:.0f}"
    return f"{name:<26} {command:<12} {limit:>10.0f} {shown:>14}"


def row(job: tuple[str, str, ThreadVibration | None]) -> str:
    name, machine, vibration = job
    duration, report = cut(spec(600.0, vibration), fair() if machine == "fair" else lathe())
    cutting = [p for p in report["passes"] if p["cutting"]]
    air = 100 * float(np.mean([p["aircut_share"] for p in cutting]))
    passes = report["passes"]
    between = np.mean([b["t_start"] - a["t_end"] for a, b in zip(passes, passes[1:])])
    return (f"{machine:<6} {name:<18} {duration:8.3f} {between:9.3f} {report['max_chip_revs']:10.2f} {air:8.1f} "
            f"{report['helix_residual_mm'] * 1e3:10.2f} {report['depth_error_mm'] * 1e3:10.2f} "
            f"{report['overcut_mm'] * 1e3:10.2f}")


def main() -> None:
    start = time.perf_counter()
    with ProcessPoolExecutor(max_workers=2) as pool:
        comparison = pool.map(row, [(name, machine, vibration) for machine in ("lathe", "fair")
                                    for name, vibration in (("with vibration", VIBRATION),
                                                            ("without (G76-like)", None))])
        speeds = pool.map(highest_rpm, [
            ("lathe as configured", None, True), ("lathe as configured", None, False),
            ("x/z velocity_ff off", 0.0, True), ("x/z velocity_ff off", 0.0, False),
        ])
        comparison, speeds = list(comparison), list(speeds)
    lines = [
        "Thread chips: issue-9 example (start_z 4, end_z -16, major radius 6, pitch 1.75, depth 1.07 mm,",
        "6 passes + 1 spring, infeed 29.5 deg; vibration D 1.5, Q 1.2, phase shift 180 deg), judged on",
        f"the drive model's feedback (servo {SERVO_PERIOD * 1e3:g} ms) by analyze_thread.",
        "",
        "At 600 rpm (between: mean s from a pass leaving its helix to the next on it; chip and air-cut",
        "over the cutting passes; residual, error and overcut in um). lathe: as shipped; fair: every",
        "max_jerk 1e6, where LinuxCNC G76 takes 9.224 s, 0.164 s between passes (bench/results/peer.txt).",
        f"{'':<25} {'cycle s':>8} {'between s':>9} {'chip revs':>10} {'air-cut%':>8} {'helix um':>10} "
        f"{'depth um':>10} {'overcut um':>10}",
        *comparison,
        "",
        "Highest spindle speed at which the feedback breaks the chip (<= 1 rev) on every cutting pass,",
        "reaches full depth (+-0.02 mm) and holds the helix (residual < 0.01 mm). accepted: the highest",
        f"speed check_thread accepts (vibration within {WAVE_LIMIT_SHARE:.0%} of the x/z limits); "
        f"search from {LOW_RPM:.0f} rpm.",
        f"{'drive':<26} {'command':<12} {'accepted':>10} {'feedback rpm':>14}",
        *speeds,
        "",
        f"({time.perf_counter() - start:.0f} s)",
    ]
    text = "\n".join(lines)
    print(text)
    write_result("thread_chips.txt", text)


if __name__ == "__main__":
    main()
