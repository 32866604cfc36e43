"""The workspace builds with colcon like any ament_python workspace, installing the
executables that `ros2 run cnc_planner planner` and `ros2 run cnc_servo_bridge bridge` run."""
from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

from support import ROOT


def test_colcon_build_installs_both_executables(tmp_path):
    colcon = Path(sys.executable).parent / "colcon"
    result = subprocess.run(
        [str(colcon), "--log-base", str(tmp_path / "log"), "build", "--base-paths", str(ROOT / "src"),
         "--build-base", str(tmp_path / "build"), "--install-base", str(tmp_path / "install")],
        capture_output=True, text=True, timeout=300, cwd=tmp_path, env=dict(os.environ))
    assert result.returncode == 0, result.stdout[-3000:] + result.stderr[-3000:]
    install = tmp_path / "install"
    for package, executable in (("cnc_planner", "planner"), ("cnc_servo_bridge", "bridge")):
        path = install / package / "lib" / package / executable
        assert path.is_file() and os.access(path, os.X_OK)
    assert (install / "cnc_msgs_py" / "share" / "cnc_msgs_py" / "config" / "machines" / "mill3.yaml").is_file()
    assert (install / "cnc_planner" / "share" / "ament_index" / "resource_index" / "packages" / "cnc_planner").is_file()
