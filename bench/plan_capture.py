"""pytest plugin: record every job the test suite plans, as fixtures for bench/plan_hashes.py.

Run once (``PYTHONPATH=bench pytest -p plan_capture src/*/test test/...``) with
``CNC_CAPTURE_PLANS=FILE``: each distinct (entry point, validated job, machine, start
position) that a test hands to the planner is pickled to FILE, so a restructuring can
replay exactly the plans the tests exercise and show they did not change.
"""
from __future__ import annotations

import gzip
import hashlib
import os
import pickle

import cnc_planner.planning as _planning
import cnc_planner.segments as _segments

_seen: dict[str, bytes] = {}


def _recording(name: str, fn):
    def wrapper(job, machine, start_position=None, *args, **kwargs):
        try:
            blob = pickle.dumps((name, job, machine, start_position))
            _seen.setdefault(hashlib.sha256(blob).hexdigest(), blob)
        except Exception:  # noqa: BLE001 (an unpicklable stand-in machine: not a fixture)
            pass
        return fn(job, machine, start_position, *args, **kwargs)
    return wrapper


_planning.plan_job = _recording("plan_job", _planning.plan_job)
_segments.plan_segments = _recording("plan_segments", _segments.plan_segments)


def pytest_sessionfinish(session, exitstatus):
    path = os.environ.get("CNC_CAPTURE_PLANS")
    if path:
        with gzip.open(path, "wb") as f:
            pickle.dump([pickle.loads(b) for b in _seen.values()], f)
        print(f"\nplan_capture: {len(_seen)} planner calls -> {path}")
