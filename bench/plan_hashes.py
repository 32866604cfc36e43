"""Hash the setpoints of every example job and test fixture: a restructuring changes no plan.

Three sets, each planned offline (no ROS) and sampled as ``cnc-plan`` samples it (1 ms grid,
positions, velocities and accelerations of every joint, plus the events):

- ``config/jobs/*.yaml`` through ``cnc-plan`` itself (setpoints.npz and summary.json), and
  through the segmenting the planner node streams them with;
- ``test/bad_jobs/*``: the rejection each one gets (the reason text is hashed);
- ``bench/results/plan_fixtures.pkl.gz``: every (job, machine, start position) the unit and
  in-process tests handed to the planner, recorded by ``bench/plan_capture.py``.

Run from the workspace root:
    python bench/plan_hashes.py                      # print the table
    python bench/plan_hashes.py --save FILE          # ... and keep it
    python bench/plan_hashes.py --check FILE         # exit 1 if any hash differs from FILE
"""
from __future__ import annotations

import argparse
import gzip
import hashlib
import json
import pickle
import sys
import tempfile
from types import SimpleNamespace
from pathlib import Path

import numpy as np
import yaml

ROOT = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(ROOT / "src" / p) for p in ("cnc_msgs_py", "cnc_analysis", "cnc_planner", "cnc_servo_bridge")]

from cnc_msgs_py.job import JOB, decode_job, parse_job  # noqa: E402
from cnc_msgs_py.machine import MachineError, load_machine  # noqa: E402
from cnc_msgs_py.schema import REQUIRED, JobError, List, Obj  # noqa: E402
from cnc_planner.cli import plan_main  # noqa: E402
from cnc_planner.planning import plan_job  # noqa: E402
from cnc_planner.segments import plan_segments  # noqa: E402

PERIOD = 1e-3
FIXTURES = ROOT / "bench" / "results" / "plan_fixtures.pkl.gz"


def with_new_keys(value: object, spec: object) -> None:
    """A job pickled before keys of the schema existed (surface_speed, a move's feed_per_rev)
    given their defaults, as parse_job gives them today: the fixtures stay plannable."""
    if isinstance(spec, Obj) and isinstance(value, SimpleNamespace):
        for key, sub in spec.fields.items():
            if hasattr(value, key):
                with_new_keys(getattr(value, key), sub)
            elif sub.default is not REQUIRED:
                setattr(value, key, None if sub.default is None else sub.check(sub.default, key))
        for _, op, _ in getattr(getattr(value, "program", None), "operations", None) or []:
            with_new_keys(op, JOB)
    elif isinstance(spec, List) and isinstance(value, list):
        for item in value:
            with_new_keys(item, spec.item)


def plan_digest(plans) -> tuple[str, float, int]:
    """sha256 over every plan's sampled p, v, a and events; (digest, duration, samples)."""
    h = hashlib.sha256()
    duration, samples = 0.0, 0
    for plan in plans:
        t = np.arange(int(np.ceil(plan.duration / PERIOD)) + 1) * PERIOD
        for array in plan.sample(t):
            h.update(np.ascontiguousarray(array, dtype=np.float64).tobytes())
        h.update(json.dumps([[e.time, e.name, e.data] for e in plan.events], sort_keys=True, default=str).encode())
        duration += plan.duration
        samples += len(t)
    return h.hexdigest()[:16], duration, samples


def cnc_plan_digest(job_file: Path) -> tuple[str, float, int]:
    """Run ``cnc-plan`` on a job file and hash what it writes."""
    with tempfile.TemporaryDirectory() as out:
        if plan_main([str(job_file), "--out", out]) != 0:
            return "rejected", 0.0, 0
        h = hashlib.sha256()
        with np.load(Path(out) / "setpoints.npz") as npz:
            for key in sorted(npz.files):
                h.update(key.encode() + npz[key].tobytes())
            samples = len(npz["t"])
        summary = json.loads((Path(out) / "summary.json").read_text())
        h.update(json.dumps(summary, sort_keys=True).encode())
        return h.hexdigest()[:16], summary["duration_s"], samples


def outcome(call, *args) -> tuple[str, float, int]:
    try:
        return plan_digest(call(*args))
    except (JobError, MachineError) as err:  # the checkout's own path (a missing machine's) left out
        return "rejected:" + hashlib.sha256(str(err).replace(str(ROOT), "<root>").encode()).hexdigest()[:7], 0.0, 0


def rows() -> list[tuple[str, str, float, int]]:
    table = []
    for path in sorted((ROOT / "config" / "jobs").glob("*.yaml")):
        table.append((f"cnc-plan {path.name}", *cnc_plan_digest(path)))
        job = parse_job(yaml.safe_load(path.read_text()))
        table.append((f"segments {path.name}", *outcome(lambda j, m: list(plan_segments(j, m)),
                                                         job, load_machine(job.machine))))
    for path in sorted((ROOT / "test" / "bad_jobs").glob("*.*")):
        if path.name == "expected.yaml":
            continue
        def bad(p=path):
            text = p.read_text(encoding="utf-8")
            job = parse_job(decode_job(text if p.suffix == ".json" else json.dumps(yaml.safe_load(text))))
            return [plan_job(job, load_machine(job.machine))]
        table.append((f"bad {path.name}", *outcome(bad)))
    with gzip.open(FIXTURES, "rb") as f:
        fixtures = pickle.load(f)
    for _, job, _, _ in fixtures:
        with_new_keys(job, JOB)
    entry = {"plan_job": lambda j, m, s: [plan_job(j, m, s)], "plan_segments": lambda j, m, s: list(plan_segments(j, m, s))}
    for i, (name, job, machine, start) in enumerate(fixtures):
        table.append((f"fixture {i:03d} {name} {job.kind} on {machine.name}", *outcome(entry[name], job, machine, start)))
    return table


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--save", type=Path, help="write the table here")
    parser.add_argument("--check", type=Path, help="compare against a saved table; exit 1 on any difference")
    args = parser.parse_args()
    table = rows()
    text = "\n".join(f"{name:60s} {digest:18s} {duration:10.4f} s {samples:9d}" for name, digest, duration, samples in table)
    print(text)
    if args.save:
        args.save.write_text(text + "\n")
    if args.check:
        before = {line[:60].rstrip(): line[61:].split()[0] for line in args.check.read_text().splitlines() if line.strip()}
        after = {name: digest for name, digest, _, _ in table}
        changed = [name for name in before if before[name] != after.get(name)]
        print(f"\n{len(after)} plans hashed, {len(before)} in {args.check}: "
              f"{len(before) - len(changed)} equal, {len(changed)} differ")
        for name in changed:
            print(f"  differs: {name}: {before[name]} -> {after.get(name)}")
        return 1 if changed else 0
    return 0


if __name__ == "__main__":
    sys.exit(main())
