"""How fast can the spindle turn while the drive's feedback still breaks the chip every revolution?

For each vibration on the lathe's z axis (F = 0.1 mm/rev, Q = 1.2, a 1 mm feed), a binary
search finds the highest spindle speed, up to the axis limit check_vibration enforces, at
which DriveModel.simulate of the command air-cuts in every analysed revolution, once with
the plain waveform as the command and once with the servo-lag pre-compensated command;
and, as the bound for both, at which the planned waveform itself does. Everything is
judged while the waveform moves (up to the end of the motion), paired with the spindle
angle at each servo instant.

Two drives: the lathe as configured (z with velocity feed-forward), and the same lathe
with z's velocity feed-forward off, where the position loop alone must drive the axis.
With feed-forward the loop passes the vibration at a gain >= 1 up to ~75 Hz and only
delays it (~1.5 ms), while the z jerk limit caps a 0.12 mm vibration near 32 Hz; a delay
shifts where the air-cut falls but removes none, so there the axis limit binds with or
without compensation. Without feed-forward the loop attenuates the vibration from a few
Hz on, and compensation is what keeps the chip breaking up to the axis limit. With D < 1
near the limit the ramp onto the waveform (not the drive) costs the first air-cuts: the
"motion" column.

Usage: python bench/vibration_speed.py   (writes bench/results/vibration_speed.txt too)
"""
from __future__ import annotations

import dataclasses
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
from cnc_planner.vibration.waveform import (  # noqa: E402
    Vibration, VibrationError, VibrationFeed, check_vibration,
)
from cnc_analysis.aircut import analyze_aircut  # noqa: E402
from cnc_servo_bridge.drive import DriveModel  # noqa: E402
from publish import write_result  # noqa: E402

F = 1e-4  # m/rev
REVS = 10  # feed length in revolutions
SERVO_PERIOD = 1e-3
RPM_RESOLUTION = 0.01  # relative width at which the binary search stops
CASES = [
    ("D=1.5", Vibration(D=1.5, Q=1.2)),
    ("D=2.5", Vibration(D=2.5, Q=1.2)),
    ("E=2 R=1 (D=0.5)", Vibration(D=None, Q=1.2, E=2, R=1)),
]


def lathe(velocity_ff: float | None = None) -> Machine:
    machine = load_machine("lathe")
    if velocity_ff is None:
        return machine
    z = dataclasses.replace(machine.drives["z"], velocity_ff=velocity_ff)
    return dataclasses.replace(machine, drives={**machine.drives, "z": z})


def axis_limit_rpm(vib: Vibration, machine: Machine) -> float:
    """Highest spindle speed check_vibration accepts (to 0.1 rpm)."""
    lo, hi = 1.0, to_rpm(machine.axis("spindle").max_velocity)
    while hi - lo > 0.1:
        mid = (lo + hi) / 2
        try:
            check_vibration(vib, F, rpm(mid), machine.axis("z"))
            lo = mid
        except VibrationError:
            hi = mid
    return lo


def air_cuts_every_rev(vib: Vibration, speed_rpm: float, machine: Machine, judged: str) -> bool:
    """Whether `judged` air-cuts in every analysed revolution while the feed moves: "motion"
    (the waveform itself), "plain" (feedback of the waveform as the command) or
    "compensated" (feedback of the pre-compensated command)."""
    def drive() -> DriveModel:
        return DriveModel(machine, SERVO_PERIOD, joints=("z",))

    omega, z = rpm(speed_rpm), machine.axis("z")
    motion = VibrationFeed(REVS * F, F, vib, omega, z, servo_period=SERVO_PERIOD)
    command = VibrationFeed(
        REVS * F, F, vib, omega, z, servo_period=SERVO_PERIOD,
        drive_model_factory=drive if judged == "compensated" else None,
    )
    t = np.arange(round(command.duration / SERVO_PERIOD) + 1) * SERVO_PERIOD
    s, v, a = command.sample(t)
    if judged != "motion":
        s = drive().simulate(s[:, None], v[:, None], a[:, None])[0][:, 0]
    moving = t <= motion.duration
    report = analyze_aircut(omega * t[moving], s[moving])
    return report.revolutions > 0 and report.revolutions_with_aircut == report.revolutions


def max_air_cut_rpm(vib: Vibration, machine: Machine, judged: str, limit: float) -> float:
    """Binary search up to the axis limit (0 if even a twentieth of it fails)."""
    if air_cuts_every_rev(vib, limit, machine, judged):
        return limit
    lo, hi = limit / 20, limit
    if not air_cuts_every_rev(vib, lo, machine, judged):
        return 0.0
    while hi - lo > RPM_RESOLUTION * hi:
        mid = (lo + hi) / 2
        lo, hi = (mid, hi) if air_cuts_every_rev(vib, mid, machine, judged) else (lo, mid)
    return lo


def row(job: tuple[str, Vibration, float | None]) -> str:
    name, vib, velocity_ff = job
    machine = lathe(velocity_ff)
    limit = axis_limit_rpm(vib, machine)
    motion, plain, comp = (
        max_air_cut_rpm(vib, machine, judged, limit) for judged in ("motion", "plain", "compensated")
    )
    ratio = f"{comp / plain:6.2f}" if plain else "   inf"
    return f"{name:<16} {vib.Q:4.2f} {limit:8.0f} {motion:8.0f} {plain:8.0f} {comp:12.0f} {ratio}"


def main() -> None:
    start = time.perf_counter()
    header = (
        f"{'vibration':<16} {'Q':>4} {'limit':>8} {'motion':>8} {'plain':>8} "
        f"{'compensated':>12} {'ratio':>6}\n"
        f"{'':<16} {'':>4} {'rpm':>8} {'rpm':>8} {'rpm':>8} {'rpm':>12}"
    )
    z = lathe().drives["z"]
    sections = [
        (f"lathe z as configured (kp {z.kp:g}/s, velocity_ff {z.velocity_ff:g}, "
         f"accel_ff {z.accel_ff:g}, velocity lag {z.velocity_lag * 1e3:g} ms)", None),
        ("the same with z's velocity feed-forward off (velocity_ff 0)", 0.0),
    ]
    jobs = [(name, vib, ff) for _, ff in sections for name, vib in CASES]
    with ProcessPoolExecutor(max_workers=2) as pool:
        rows = list(pool.map(row, jobs))
    lines = [
        f"Highest spindle speed at which the z feedback air-cuts every revolution "
        f"(F = {F * 1e3:g} mm/rev, {REVS * F * 1e3:g} mm feed, servo {SERVO_PERIOD * 1e3:g} ms)",
        "limit: max spindle speed within the z axis velocity/acceleration/jerk limits "
        "(check_vibration)",
        "motion: the planned waveform itself air-cuts every revolution (bounds the feedback)",
        "plain / compensated: feedback of the waveform as command / of the pre-compensated command",
        "ratio: compensated / plain",
        "",
    ]
    for i, (title, _) in enumerate(sections):
        lines += [title, header, *rows[i * len(CASES):(i + 1) * len(CASES)], ""]
    lines.append(f"({time.perf_counter() - start:.0f} s)")
    text = "\n".join(lines)
    print(text)
    write_result("vibration_speed.txt", text)


if __name__ == "__main__":
    main()
