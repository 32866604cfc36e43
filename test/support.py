"""Helpers shared by the integration tests: paths and the console scripts."""
from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
JOBS = ROOT / "config" / "jobs"
BIN = Path(sys.executable).parent


def cnc(tool: str, *args: str, timeout: float = 600) -> subprocess.CompletedProcess:
    """Run one of the project's console scripts as a user would."""
    return subprocess.run([str(BIN / tool), *map(str, args)], capture_output=True, text=True,
                          timeout=timeout, env=dict(os.environ))


def load_report(out: Path) -> dict:
    return json.loads((out / "report.json").read_text())
