"""Every executable answers like a command-line tool (issue 27): ``--help`` prints its usage
and exits 0, ``--version`` prints its package's version, an unknown argument is an error
(exit 2), and none of them starts a node: a node that started would spin until killed, so
each run must end by itself within the timeout, and the nodes' start-up lines (logged by
rclpy at INFO) must not appear. Both answer before the heavy imports (issue 43): what a
script imported is read from Python's own import log, not timed (bench/startup.py times them)."""
from __future__ import annotations

import os
import subprocess
from importlib.metadata import entry_points, version

import pytest

from support import BIN, cnc

PACKAGES = ("cnc_msgs_py", "cnc_analysis", "cnc_planner", "cnc_servo_bridge")
SCRIPTS = sorted((ep.name, ep.dist.name) for ep in entry_points(group="console_scripts")
                 if ep.dist is not None and ep.dist.name in PACKAGES)
NODES = {"planner", "cnc-planner", "bridge", "cnc-bridge"}
ENDS_BY_ITSELF_S = 60  # generous: the bound only catches a node spinning instead of answering
HEAVY = {"rclpy", "numpy", "yaml", "matplotlib", "jinja2", "rosbags", "cnc_analysis", "cnc_planner.planning"}
# the bridge's entry point is its node's module, which imports rclpy and numpy at its top
IMPORTED_BY_ITS_MODULE = {"cnc-identify": {"cnc_analysis"}}  # its own package's empty __init__ and cli module


def test_every_package_script_is_found():
    assert {name for name, _ in SCRIPTS} >= {"cnc-run", "cnc-plan", "cnc-analyze", "cnc-cell", "cnc-submit",
                                              *NODES}


@pytest.mark.parametrize("script, package", SCRIPTS)
def test_help_prints_usage_and_starts_no_node(script, package):
    result = cnc(script, "--help", timeout=ENDS_BY_ITSELF_S)
    assert result.returncode == 0, result.stderr
    assert result.stdout.startswith(f"usage: {script} "), result.stdout[:200]
    assert "--version" in result.stdout
    assert "[INFO]" not in result.stderr, result.stderr
    if script in NODES:
        for part in ("--ros-args", "-r __ns:=/cnc", "--params-file", "parameters:", "machine (default mill3)"):
            assert part in result.stdout, part


@pytest.mark.parametrize("script, package", SCRIPTS)
def test_version_prints_the_package_version(script, package):
    result = cnc(script, "--version", timeout=ENDS_BY_ITSELF_S)
    assert result.returncode == 0, result.stderr
    assert result.stdout.strip() == f"{script} {version(package)}"


@pytest.mark.parametrize("flag", ["--help", "--version"])
@pytest.mark.parametrize("script, package", SCRIPTS)
def test_help_and_version_answer_before_the_heavy_imports(script, package, flag):
    result = subprocess.run([str(BIN / script), flag], capture_output=True, text=True, timeout=ENDS_BY_ITSELF_S,
                            env={**os.environ, "PYTHONPROFILEIMPORTTIME": "1"})
    assert result.returncode == 0, result.stderr[-2000:]
    imported = {line.rsplit("|", 1)[-1].strip() for line in result.stderr.splitlines()
                if line.startswith("import time:")}
    assert imported, "no import log: PYTHONPROFILEIMPORTTIME was not honoured"
    assert not (HEAVY - IMPORTED_BY_ITS_MODULE.get(script, set())) & imported


@pytest.mark.parametrize("script", sorted(NODES))
def test_a_node_refuses_an_argument_that_is_not_ros(script):
    result = cnc(script, "--bogus", "--ros-args", "-p", "machine:=mill3", timeout=ENDS_BY_ITSELF_S)
    assert result.returncode == 2
    assert "unrecognized arguments: --bogus" in result.stderr
    assert "[INFO]" not in result.stderr
