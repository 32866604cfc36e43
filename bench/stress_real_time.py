"""Stress: the real-time tests, many times in a row, beside two busy processes and the rest
of the suite (the load under which a fresh-clone `make test` once saw a first chunk arrive
17 ms late and the bridge die). Not part of `make test`; `make stress` runs it.

Usage: python bench/stress_real_time.py [--runs 50]
Prints one line per run and a summary; writes bench/results/stress_real_time.txt.
Every helper process is bounded in time and stopped by its own id at the end.
"""
from __future__ import annotations

import argparse
import os
import re
import signal
import subprocess
import sys
import tempfile
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

from publish import write_result

ROOT = Path(__file__).resolve().parents[1]
_RAISED_AT = re.compile(r"^\S+\.py:\d+: ")  # pytest's "file.py:123: ErrorType" under a traceback
REAL_TIME_TESTS = ["test/test_real_time.py", "test/test_node_survival.py"]
PYTEST = [sys.executable, "-m", "pytest", "-q", "-p", "no:warnings", "-p", "no:cacheprovider"]
BUSY = "import time\nend = time.monotonic() + {limit}\nwhile time.monotonic() < end:\n    pass\n"


class RestOfSuite:
    """The rest of the test suite, run again each time it ends, so that every real-time run
    has it alongside; each finished round's summary and failed tests are kept. Each round
    runs in a process group of its own, killed whole when it ends or is stopped: killing
    pytest alone left the nodes of the run it was in alive, still talking in their domain."""

    def __init__(self, command: list[str], env: dict[str, str]) -> None:
        self.command, self.env = command, env
        self.outcomes: list[str] = []
        self.proc: subprocess.Popen | None = None
        self.log = tempfile.TemporaryFile("w+")

    def keep_running(self) -> None:
        if self.proc is not None and self.proc.poll() is None:
            return
        if self.proc is not None:
            self.outcomes.append(self._outcome())
            self._kill_group()  # whatever the round left behind
        self.log.seek(0)
        self.log.truncate()
        self.proc = subprocess.Popen(self.command, cwd=ROOT, env=self.env, stdout=self.log, stderr=subprocess.STDOUT,
                                     start_new_session=True)

    def stop(self) -> None:
        """Kill an unfinished round (not counted) with every process it started."""
        if self.proc is not None and self.proc.poll() is None:
            self._kill_group()
            self.proc.wait()
        elif self.proc is not None:
            self.outcomes.append(self._outcome())
            self._kill_group()

    def _kill_group(self) -> None:
        try:
            os.killpg(self.proc.pid, signal.SIGKILL)
        except ProcessLookupError:  # nothing of the round is left
            pass

    def _outcome(self) -> str:
        self.log.seek(0)
        output = self.log.read().strip().splitlines() or ["(no output)"]
        failed = [line for line in output if line.startswith("FAILED ")]
        outcome = "; ".join(dict.fromkeys([output[-1]] + failed))  # each failure once
        if failed or "failed" in output[-1]:
            outcome += "\n" + failure_report(output)
        return outcome


def failure_report(output: list[str], log_lines: int = 30) -> str:
    """Why, not only which: from pytest's failure report, each failed test's header, its
    error lines (E ...) and where they were raised, and the first warnings and errors of
    each captured log (where the trouble begins; the log's tail says little)."""
    start = next((k for k, line in enumerate(output) if "= FAILURES =" in line), None)
    if start is None:
        return "\n".join(output[-log_lines:])
    kept, log_left = [], 0
    for line in output[start:]:
        if line.startswith("=") and "short test summary" in line:
            break
        if line.startswith("_") or line.startswith("E ") or _RAISED_AT.match(line):
            kept.append(line)
        elif line.startswith("-") and "Captured" in line:
            kept.append(line)
            log_left = log_lines
        elif log_left and ("[ERROR]" in line or "[WARN]" in line):
            kept.append(line)
            log_left -= 1
    return "\n".join(kept)


@contextmanager
def stress_load(env: dict[str, str], limit: float) -> Iterator[RestOfSuite]:
    """Two busy processes and the rest of the suite (started now, in DDS domains 1-100) for
    as long as the block runs; each stopped by its own id at the end."""
    busy = [subprocess.Popen([sys.executable, "-c", BUSY.format(limit=limit)]) for _ in range(2)]
    rest = RestOfSuite(PYTEST + [f"--ignore={t}" for t in REAL_TIME_TESTS], dict(env, CNC_TEST_DOMAINS="1-100"))
    rest.keep_running()
    try:
        yield rest
    finally:
        for proc in busy:
            proc.kill()
            proc.wait()
        rest.stop()


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=50)
    parser.add_argument("--limit", type=float, default=7200.0, help="longest the load runs (s)")
    args = parser.parse_args()
    env = dict(os.environ, ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST")
    # the two suites run at once: each its own DDS domains (test/conftest.py), or they hear each other
    real_time_env = dict(env, CNC_TEST_DOMAINS="211-230")
    lines, failed = [], 0
    with stress_load(env, args.limit) as rest:
        for run in range(1, args.runs + 1):
            rest.keep_running()
            start = time.monotonic()
            result = subprocess.run(PYTEST + REAL_TIME_TESTS, cwd=ROOT, env=real_time_env, capture_output=True, text=True)
            tail = (result.stdout.strip().splitlines() or ["(no output)"])[-1]
            failed += result.returncode != 0
            line = (f"run {run:3d}: exit {result.returncode}  {time.monotonic() - start:6.1f} s  "
                    f"rest of suite round {len(rest.outcomes) + 1} alongside  {tail}")
            print(line, flush=True)
            lines.append(line)
            if result.returncode != 0:
                lines.append(failure_report(result.stdout.splitlines()))
    lines += [f"rest of suite, round {k}: {outcome}" for k, outcome in enumerate(rest.outcomes, 1)]
    summary = (f"{args.runs - failed} of {args.runs} runs passed (2 busy processes; the rest of the suite "
               f"alongside every run, restarted whenever it ended: {len(rest.outcomes)} rounds ended)")
    print(summary)
    write_result("stress_real_time.txt", "\n".join(lines + [summary]))
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
