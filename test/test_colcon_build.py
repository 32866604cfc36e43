"""The workspace builds with colcon like any ament_python workspace, and the installed
executables run as `ros2 run cnc_planner planner` and `ros2 run cnc_servo_bridge bridge`
would run them: a clean environment, `install/setup.bash` sourced, the executable started
from `<prefix>/lib/<package>/`.

The ROS 2 Python packages come from PyPI into the virtual environment, which stands in
for /opt/ros/jazzy: colcon (also from PyPI) runs with the environment's Python, so the
installed scripts' shebang is that Python, and setup.bash puts the installed packages
first on PYTHONPATH, ahead of the editable installs of this checkout.
"""
from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from cnc_msgs_py.discovery import DDS_VARIABLES
from support import ROOT

INSTALLED = {"cnc_planner": "planner", "cnc_servo_bridge": "bridge"}


@pytest.fixture(scope="module")
def install(tmp_path_factory) -> Path:
    """One colcon build of the workspace per module, into a temporary prefix."""
    base = tmp_path_factory.mktemp("colcon")
    colcon = Path(sys.executable).parent / "colcon"
    result = subprocess.run(
        [str(colcon), "--log-base", str(base / "log"), "build", "--base-paths", str(ROOT / "src"),
         "--build-base", str(base / "build"), "--install-base", str(base / "install")],
        capture_output=True, text=True, timeout=300, cwd=base, env=dict(os.environ))
    assert result.returncode == 0, result.stdout[-3000:] + result.stderr[-3000:]
    return base / "install"


def sourced(install: Path, command: str) -> list[str]:
    """`command` in bash after `source install/setup.bash`, exec'd so signals reach it."""
    return ["bash", "-c", f"source {install / 'setup.bash'} && exec {command}"]


def clean_env() -> dict[str, str]:
    """What a user's fresh shell holds, plus this test's DDS settings (localhost, own domain)."""
    return {"PATH": "/usr/bin:/bin", "HOME": os.environ["HOME"],
            **{k: v for k, v in os.environ.items() if k in DDS_VARIABLES}}


def test_colcon_build_installs_both_executables(install):
    for package, executable in INSTALLED.items():
        path = install / package / "lib" / package / executable
        assert path.is_file() and os.access(path, os.X_OK)
    assert (install / "cnc_msgs_py" / "share" / "cnc_msgs_py" / "config" / "machines" / "mill3.yaml").is_file()
    assert (install / "cnc_planner" / "share" / "ament_index" / "resource_index" / "packages" / "cnc_planner").is_file()


def test_sourced_install_imports_the_installed_packages(install):
    probe = ("import cnc_msgs_py, cnc_analysis, cnc_planner, cnc_servo_bridge as m; from cnc_msgs_py.discovery import LOCAL_PROFILE as x; "
             "assert x.is_file(); print(*(p.__file__ for p in (cnc_msgs_py, cnc_analysis, cnc_planner, m)), x)")
    result = subprocess.run(sourced(install, f"{sys.executable} -c '{probe}'"), capture_output=True, text=True,
                            timeout=60, env=clean_env())
    assert result.returncode == 0, result.stderr
    assert all(Path(f).is_relative_to(install) for f in result.stdout.split()), result.stdout


def test_installed_executables_run_a_job_over_topics(install, tmp_path):
    env = clean_env()
    share = {p: install / p / "share" / p / "config" for p in INSTALLED}
    nodes = [
        subprocess.Popen(sourced(install, f"{install}/cnc_servo_bridge/lib/cnc_servo_bridge/bridge --ros-args "
                                          f"-r __ns:=/cnc --params-file {share['cnc_servo_bridge'] / 'bridge.yaml'}"),
                         env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True),
        subprocess.Popen(sourced(install, f"{install}/cnc_planner/lib/cnc_planner/planner --ros-args -r __ns:=/cnc "
                                          f"-p use_sim_time:=true --params-file {share['cnc_planner'] / 'planner.yaml'}"),
                         env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True),
    ]
    try:
        submit = subprocess.run(
            sourced(install, f"{install}/cnc_msgs_py/lib/cnc_msgs_py/cnc-submit {share['cnc_planner'] / 'jobs' / 'drill_row.yaml'} "
                             "--namespace /cnc --timeout 120"),
            capture_output=True, text=True, timeout=180, env=env)
    finally:
        for node in nodes:
            node.terminate()
        logs = [node.communicate(timeout=30)[0] for node in nodes]
    assert submit.returncode == 0, submit.stderr + "\n".join(logs)
    final = json.loads(submit.stdout.strip().splitlines()[-1])
    assert final["job_id"] == "drill-row-demo" and final["state"] == "succeeded" and final["cycle_time_s"] > 0
    assert "active: drives enabled" in logs[0]  # the bridge brought itself up (autostart)
