"""Speed of the drive model's compiled kernel (DriveModel.run/simulate) against DriveModel.step.

The planner's safety searches call ``simulate`` on short windows thousands of times, and
the bridge calls ``run`` on blocks of a few to a few hundred servo periods, so both the
cost per call and the cost per period matter. Per case: microseconds per ``simulate``
call, nanoseconds per servo period and joint, and the same periods stepped one at a time
with ``step`` (the numpy reference the kernel equals). Best of five; CPU time, so other
work on the machine weighs less. Run from the workspace root:  python bench/drive_kernel.py
(about half a minute). Writes bench/results/drive_kernel.txt.
"""
from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(ROOT / "src" / p) for p in ("cnc_msgs_py", "cnc_analysis", "cnc_planner", "cnc_servo_bridge")]

from cnc_msgs_py.machine import load_machine  # noqa: E402
from cnc_servo_bridge.drive import DriveModel, warm_up  # noqa: E402
from publish import write_result  # noqa: E402

PERIOD = 1e-3
# (joints, servo periods per call, calls per timing)
CASES = [(("z",), 10, 5000), (("z",), 1000, 500), (("x", "y", "z"), 100, 2000), (("x", "y", "z"), 100_000, 5)]


def best_cpu_s(action, repeats: int = 5) -> float:
    """Smallest CPU time of ``action`` over ``repeats`` runs."""
    best = float("inf")
    for _ in range(repeats):
        start = time.process_time()
        action()
        best = min(best, time.process_time() - start)
    return best


def stepped(drive: DriveModel, p: np.ndarray, v: np.ndarray, a: np.ndarray) -> None:
    """The same periods through the numpy reference, one ``step`` per period."""
    drive.reset(p[0])
    for row in range(len(p)):
        drive.step(p[row], v[row], a[row])


def main() -> int:
    machine = load_machine("mill3")
    warm_up()
    rng = np.random.default_rng(0)
    lines = [f"{'joints':<8}{'periods/call':>13}{'us/call':>10}{'ns/period/joint':>17}"
             f"{'step ns/period/joint':>22}{'speed-up':>10}", "-" * 80]
    for joints, n, calls in CASES:
        drive = DriveModel(machine, PERIOD, joints)
        p = np.cumsum(rng.normal(0, 1e-5, (n, len(joints))), axis=0)
        v, a = np.gradient(p, PERIOD, axis=0), np.zeros_like(p)
        kernel = best_cpu_s(lambda: [drive.simulate(p, v, a) for _ in range(calls)]) / calls
        rows = min(n, 2000)  # the numpy reference is slow: time a slice of the same reference
        step = best_cpu_s(lambda: stepped(drive, p[:rows], v[:rows], a[:rows]), 3) / rows
        per_period = kernel / n
        lines.append(f"{','.join(joints):<8}{n:>13}{kernel * 1e6:>10.1f}{per_period / len(joints) * 1e9:>17.1f}"
                     f"{step / len(joints) * 1e9:>22.0f}{step / per_period:>10.0f}")
    lines += ["", NOTES]
    text = "\n".join(lines)
    print(text)
    write_result("drive_kernel.txt", text)
    return 0


NOTES = """\
us/call: one DriveModel.simulate call (reset, argument checks, the kernel) per reference
  window; ns/period/joint: that divided by periods and joints. step: DriveModel.step (numpy,
  one call per period, all joints at once) over up to 2000 periods of the same reference;
  speed-up: step time per period / kernel time per period. CPU time (process_time), best
  of five, 2 CPUs shared with other work. The kernel is the C function
  cnc_servo_bridge/_drive_kernel.c, compiled by the package's setup.py at install."""


if __name__ == "__main__":
    sys.exit(main())
