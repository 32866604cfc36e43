"""What every executable of the workspace answers like a command-line tool: --help, --version.

The one place that answers them, for the tools (cnc-run, cnc-plan, cnc-submit, ...) and the
nodes (run_node): from argparse alone, before anything heavy is imported (rclpy, the planner,
the judge, matplotlib), so that each answers in well under 0.3 s (bench/startup.py). A tool
builds its parser and parses first, and imports what its work needs after that.
"""
from __future__ import annotations

import argparse
import sys
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from .parameters import Param

ROS_ARGS, END_OF_ROS_ARGS = "--ros-args", "--"

ROS_USAGE = """ROS arguments (after --ros-args, as with `ros2 run`):
  -r __ns:=/cnc             the machine's namespace (default: none; the tools use /cnc)
  -p NAME:=VALUE            set a parameter
  --params-file FILE        parameters from a YAML file (config/<node>.yaml)
  --log-level LEVEL         debug, info, warn, error or fatal
DDS: ROS_DOMAIN_ID, ROS_AUTOMATIC_DISCOVERY_RANGE, ROS_DISCOVERY_SERVER as usual."""


class _Version(argparse.Action):
    """--version: the installed package's version, looked up only when asked for
    (importlib.metadata scans every installed distribution: 20-50 ms of each start)."""

    def __init__(self, option_strings: list[str], prog: str, package: str, **kwargs: Any) -> None:
        super().__init__(option_strings, dest=argparse.SUPPRESS, default=argparse.SUPPRESS, nargs=0,
                         help="show program's version number and exit")
        self.prog, self.package = prog, package

    def __call__(self, parser: argparse.ArgumentParser, *_: Any) -> None:
        from importlib.metadata import version

        sys.stdout.write(f"{self.prog} {version(self.package)}\n")
        parser.exit()


def tool_parser(prog: str, package: str, **kwargs) -> argparse.ArgumentParser:
    """An ArgumentParser for ``prog`` with ``--version`` (the installed package's version)."""
    parser = argparse.ArgumentParser(prog=prog, **kwargs)
    parser.add_argument("--version", action=_Version, prog=prog, package=package)
    return parser


def add_program_options(parser: argparse.ArgumentParser) -> None:
    """The options cnc-run, cnc-plan and cnc-submit share for a job file (read by
    ``gcode.document.job_from_args``)."""
    parser.add_argument("--machine", help="the machine a program (or job) runs on when it names none")
    parser.add_argument("--tools", help="a LinuxCNC tool.tbl for a G-code program (default: the machine's own)")
    parser.add_argument("--spindle", type=float, metavar="RPM",
                        help="a G-code program begins with the spindle turning (M3) at RPM, as after an "
                             "operator's MDI S<RPM> M3 (default: stopped)")


def node_parser(prog: str, description: str, package: str, parameters: dict[str, Param]) -> argparse.ArgumentParser:
    """A node's own arguments (--help, --version) and, in its help, ROS's and the parameters."""
    rows = []
    for name, param in parameters.items():
        default = param.default if isinstance(param.default, (bool, int, float, str)) else "unset"
        unit = f" [{param.unit}]" if param.unit else ""
        bounds = f", {param.range[0]:g}..{param.range[1]:g}" if param.range else ""
        rows.append(f"  {name} (default {default}{bounds}){unit}: {param.description}")
    epilog = ROS_USAGE + "\n\nparameters:\n" + "\n".join(rows)
    return tool_parser(prog, package, description=description, epilog=epilog,
                       usage=f"{prog} [-h] [--version] [--ros-args ...]",
                       formatter_class=argparse.RawDescriptionHelpFormatter)


def without_ros_args(argv: list[str]) -> list[str]:
    """``argv`` without its ROS arguments: each ``--ros-args`` section up to ``--`` or the
    end, as rclpy.utilities.remove_ros_args cuts them (without loading rclpy to do it;
    rclpy.init then reads the sections themselves)."""
    kept, in_ros = [], False
    for arg in argv:
        if arg == ROS_ARGS:
            in_ros = True
        elif in_ros and arg == END_OF_ROS_ARGS:
            in_ros = False
        elif not in_ros:
            kept.append(arg)
    return kept
