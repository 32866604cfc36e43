"""Plan one job over and over in one process: milliseconds and page faults per plan.

`make bench`'s planning rows keep the fastest of 3 runs in a process that has planned
other jobs first; this is the steady state, for comparing two versions of the planner on
one machine: run it at each alternately (the machine's speed drifts within minutes), e.g.

    python bench/plan_loop.py config/jobs/thread_m12.yaml
    PYTHONPATH=$(ls -d /path/to/other/checkout/src/*/ | paste -sd:) python bench/plan_loop.py ...

(the other checkout's kernels built in place: python setup.py build_ext --inplace in its
cnc_planner and cnc_servo_bridge). Each plan is timed as `make bench` times it: plan_job
and every setpoint sampled at 1 ms; the plan is dropped outside the timing.
"""
from __future__ import annotations

import argparse
import resource
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
if not any(p.rstrip("/").endswith("src/cnc_planner") for p in sys.path):  # else PYTHONPATH chose a checkout
    sys.path[:0] = [str(ROOT / "src" / p) for p in ("cnc_msgs_py", "cnc_analysis", "cnc_planner", "cnc_servo_bridge")]

from cnc_msgs_py.job import load_job_file, parse_job  # noqa: E402
from cnc_msgs_py.machine import load_machine  # noqa: E402
from cnc_planner.planning import plan_job  # noqa: E402
from cnc_servo_bridge.drive import warm_up  # noqa: E402


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("job", type=Path, help="job document (YAML or JSON)")
    parser.add_argument("--plans", type=int, default=300, help="plans timed, after 20 untimed")
    parser.add_argument("--glibc-defaults", action="store_true",
                        help="leave the allocator as glibc sets it (cnc-plan and the nodes keep freed memory)")
    args = parser.parse_args()
    if not args.glibc_defaults:
        from cnc_msgs_py.heap import keep_freed_memory
        keep_freed_memory()
    doc = load_job_file(args.job)
    machine, job = load_machine(doc["machine"]), parse_job(doc)
    warm_up()

    def one() -> float:
        start = time.perf_counter()
        plan = plan_job(job, machine)
        plan.sample(np.arange(int(np.ceil(plan.duration / 1e-3)) + 1) * 1e-3)
        return time.perf_counter() - start

    for _ in range(20):
        one()
    faults = resource.getrusage(resource.RUSAGE_SELF).ru_minflt
    times = np.sort([one() for _ in range(args.plans)])
    faults = (resource.getrusage(resource.RUSAGE_SELF).ru_minflt - faults) / args.plans
    print(f"{args.job.name}: {args.plans} plans, ms per plan mean {times.mean() * 1e3:.2f}, "
          f"p10 {times[args.plans // 10] * 1e3:.2f}, median {np.median(times) * 1e3:.2f}; "
          f"page faults per plan {faults:.1f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
