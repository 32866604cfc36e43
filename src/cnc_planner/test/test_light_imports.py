"""The planning core loads no judge, recording, plotting or page code (issue 43): a kind's
report section, page and figures are found only to report (cnc_planner.kinds.kind), so the
planner node and cnc-plan start with what planning uses. Each import runs in a fresh
interpreter: this test's own process has long loaded everything."""
from __future__ import annotations

import json
import subprocess
import sys

import pytest

HEAVY = ("matplotlib", "rosbags", "jinja2", "cnc_analysis")  # what only reporting needs


def loaded_after(module: str) -> list[str]:
    """Which of HEAVY a fresh interpreter holds once ``module`` is imported."""
    code = (f"import sys, json, {module}; "
            f"print(json.dumps(sorted(m for m in {HEAVY!r} if m in sys.modules)))")
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60, check=True)
    return json.loads(result.stdout)


@pytest.mark.parametrize("module", [
    "cnc_planner.planning", "cnc_planner.kinds",
    "cnc_planner.planner_node",  # the node (rclpy with it): what it plans with, not what reports
    "cnc_planner.executive", "cnc_planner.cli",  # cnc-plan's own module: its tools import their work when run
])
def test_planning_loads_no_judge_plots_or_page(module):
    assert loaded_after(module) == []
