"""The layout follows the methods (issue 24), checked on the source so that it stays so.

- no source module longer than 600 lines: one concept each;
- the judge (cnc_analysis), the drive emulation (cnc_servo_bridge) and the schemas
  (cnc_msgs_py) import nothing of cnc_planner, and the bridge holds no analyser;
- outside the per-kind packages, at most 3 places compare something with a job kind's
  name: everything else finds a kind through the registries.
"""
from __future__ import annotations

import ast
from pathlib import Path

import pytest

from cnc_msgs_py.job import KINDS as KIND_NAMES
from cnc_planner.kinds import KINDS

from support import ROOT

SRC = ROOT / "src"
PACKAGES = ("cnc_msgs_py", "cnc_analysis", "cnc_servo_bridge", "cnc_planner")
MAX_LINES = 600
MAX_KIND_SWITCHES = 3


def modules(package: str, tests: bool = False) -> list[Path]:
    root = SRC / package
    return sorted(p for p in root.rglob("*.py") if tests or "test" not in p.relative_to(root).parts[:1])


def imported(path: Path) -> set[str]:
    names = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            names |= {a.name for a in node.names}
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            names.add(node.module)
    return names


@pytest.mark.parametrize("package", PACKAGES)
def test_no_module_is_longer_than_one_concept(package):
    long = {str(p.relative_to(SRC)): n for p in modules(package) if (n := len(p.read_text().splitlines())) > MAX_LINES}
    assert long == {}


@pytest.mark.parametrize("package", ("cnc_msgs_py", "cnc_analysis", "cnc_servo_bridge"))
def test_only_the_planner_imports_the_planner(package):
    found = {str(p.relative_to(SRC)): sorted(m for m in imported(p) if m.split(".")[0] == "cnc_planner")
             for p in modules(package, tests=True)}
    assert {k: v for k, v in found.items() if v} == {}


def test_the_bridge_emulates_drives_and_judges_nothing():
    for path in modules("cnc_servo_bridge"):
        assert not {m.split(".")[0] for m in imported(path)} & {"cnc_analysis", "rosbags"}, path


def _kind_comparisons(path: Path) -> list[int]:
    """Lines comparing something with a kind's name ('drill' == x, x in ('turn', ...))."""
    lines = []
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Compare):
            for side in (node.left, *node.comparators):
                values = side.elts if isinstance(side, (ast.Tuple, ast.List, ast.Set)) else [side]
                if any(isinstance(v, ast.Constant) and v.value in KIND_NAMES for v in values):
                    lines.append(node.lineno)
                    break
    return lines


def test_kinds_are_looked_up_not_switched_on():
    switches = {}
    for package in PACKAGES:
        for path in modules(package):
            if "kinds" in path.relative_to(SRC).parts:
                continue
            if found := _kind_comparisons(path):
                switches[str(path.relative_to(SRC))] = found
    assert sum(map(len, switches.values())) <= MAX_KIND_SWITCHES, switches


def test_every_kind_has_its_folder_and_every_folder_is_a_kind():
    folders = {p.name for p in (SRC / "cnc_planner" / "cnc_planner" / "kinds").iterdir()
               if (p / "__init__.py").is_file()}
    assert folders == set(KINDS) == set(KIND_NAMES)
