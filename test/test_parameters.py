"""Both nodes' parameters carry descriptors (what `ros2 param describe` shows), and a set
outside the range, of a read-only parameter, or of a configure-time parameter while the
bridge is configured is refused with the reason, over the standard parameter services."""
from __future__ import annotations

import subprocess
import sys

import pytest
from rcl_interfaces.msg import ParameterDescriptor, SetParametersResult
from rclpy.parameter import Parameter, parameter_value_to_python
from rclpy.parameter_client import AsyncParameterClient

from cnc_planner.planner_node import PARAMETERS as PLANNER_PARAMETERS
from cnc_planner.runner import Session
from cnc_servo_bridge.bridge_node import PARAMETERS as BRIDGE_PARAMETERS

NODES = {"cnc_servo_bridge": BRIDGE_PARAMETERS, "cnc_planner": PLANNER_PARAMETERS}


class Parameters:
    """A node's parameter services, answered while the session spins."""

    def __init__(self, session: Session, node: str) -> None:
        self.session = session
        self.client = AsyncParameterClient(session.recorder, f"/cnc/{node}")
        session.spin_until(self.client.services_are_ready, 30, f"no parameter services on {node}")

    def _result(self, future):
        self.session.spin_until(future.done, 30, "no answer from the parameter service")
        return future.result()

    def describe(self, names: list[str]) -> dict[str, ParameterDescriptor]:
        return {d.name: d for d in self._result(self.client.describe_parameters(names)).descriptors}

    def set(self, name: str, value: object) -> SetParametersResult:
        return self._result(self.client.set_parameters([Parameter(name, value=value)])).results[0]

    def get(self, name: str) -> object:
        return parameter_value_to_python(self._result(self.client.get_parameters([name])).values[0])


def test_every_parameter_is_described_and_bad_sets_are_refused_with_the_reason(tmp_path):
    with Session("mill3", tmp_path / "bag") as session:
        described = {node: Parameters(session, node).describe(list(table)) for node, table in NODES.items()}
        for node, table in NODES.items():
            assert set(described[node]) == set(table), node
            for name, descriptor in described[node].items():
                assert descriptor.description and descriptor.additional_constraints, f"{node}.{name}"
        bridge, planner = described["cnc_servo_bridge"], described["cnc_planner"]
        period = bridge["servo_period"]
        assert period.description.endswith("[s]") and not period.read_only
        assert (period.floating_point_range[0].from_value, period.floating_point_range[0].to_value) == (1e-4, 0.01)
        assert "read at configure" in period.additional_constraints
        assert bridge["autostart"].read_only and planner["machine"].read_only
        points = planner["chunk_points"]
        assert (points.integer_range[0].from_value, points.integer_range[0].to_value) == (1, 10000)
        assert planner["lookahead"].description.endswith("[s]") and not planner["lookahead"].read_only

        bridge_params, planner_params = Parameters(session, "cnc_servo_bridge"), Parameters(session, "cnc_planner")
        refused = bridge_params.set("underrun_timeout", 100.0)
        assert not refused.successful and "out of range" in refused.reason and "60" in refused.reason
        refused = bridge_params.set("machine", "lathe")
        assert not refused.successful
        assert refused.reason == "machine: read at configure; deactivate and cleanup the bridge first"
        refused = planner_params.set("lookahead", 10.0)
        assert not refused.successful and "out of range" in refused.reason
        refused = planner_params.set("machine", "lathe")
        assert not refused.successful and "read-only" in refused.reason
        assert planner_params.get("lookahead") == 0.3 and bridge_params.get("machine") == "mill3"
        assert bridge_params.set("underrun_timeout", 2.0).successful  # in range, a run-time parameter
        assert bridge_params.get("underrun_timeout") == 2.0


@pytest.mark.parametrize("module, argument, named", [
    ("cnc_servo_bridge.bridge_node", "servo_period:=0.5", "servo_period"),
    ("cnc_planner.planner_node", "chunk_points:=0", "chunk_points"),
])
def test_a_node_started_with_a_value_out_of_range_exits_with_one_line_naming_it(module, argument, named):
    result = subprocess.run([sys.executable, "-m", module, "--ros-args", "-p", argument],
                            capture_output=True, text=True, timeout=60)
    assert result.returncode == 2
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and f"parameter '{named}'" in lines[0] and "out of range" in lines[0], result.stderr
