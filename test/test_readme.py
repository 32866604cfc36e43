"""Every example in the README and in docs/ runs, so the pages cannot rot: job fragments
validate and plan inside their example jobs, the machine description parses, and the Python
snippets run against real nodes and a real recording."""
from __future__ import annotations

import json
import re
import subprocess
import sys
from pathlib import Path

import pytest
import yaml

from cnc_msgs_py.job import KINDS, load_job_file, parse_job
from cnc_msgs_py.machine import load_machine, parse_machine
from cnc_planner.jobs import plan_job
from cnc_planner.runner import Session

from support import JOBS, ROOT

PAGES = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
# (page, language, text) of every fenced block, pages in the order above.
BLOCKS = [(page, lang, text) for page in PAGES
          for lang, text in re.findall(r"```(\w+)\n(.*?)```", page.read_text(), re.S)]
# The example job each kind's fragment belongs to.
EXAMPLE = {"move": "move_mill3", "drill": "drill_row", "turn": "turn_stepped", "thread": "thread_m12",
           "path": "path_5ax_tilt", "vibration": "lathe_feed_vibration"}
YAML = [(page, yaml.safe_load(text)) for page, lang, text in BLOCKS if lang == "yaml"]
JOB_BLOCKS = [(page, doc) for page, doc in YAML if "axes" not in doc]
PYTHON = [text for _, lang, text in BLOCKS if lang == "python"]


@pytest.mark.parametrize("page, fragment", JOB_BLOCKS, ids=lambda x: x.name if isinstance(x, Path) else "+".join(x))
def test_job_fragment_validates_and_plans_in_its_example(page, fragment):
    kind = next((k for k in fragment if k in EXAMPLE), fragment.get("kind"))
    doc = load_job_file(JOBS / f"{EXAMPLE[kind]}.yaml")
    if "schema" in fragment:  # the common keys: a whole header with its kind's block
        doc = {**fragment, kind: doc[kind]}
    else:
        doc.update(fragment)
    job = parse_job(doc)
    assert plan_job(job, load_machine(job.machine)).duration > 0


def test_every_kind_page_has_an_executed_example():
    pages = {page.name for page, _ in JOB_BLOCKS}
    assert {f"{kind}.md" for kind in KINDS} <= pages


def test_machine_description_example_parses():
    machine_doc = next(doc for _, doc in YAML if "axes" in doc)
    machine = parse_machine(machine_doc)
    assert machine.joint_names == ("x", "spindle") and machine.home_position[0] == 0.0


def test_python_examples_run_against_nodes_and_a_recording(tmp_path):
    client_example, bag_example = PYTHON
    with Session("mill3", tmp_path / "bag") as session:
        script = client_example + "\nprint(json.dumps(status))\n"
        result = subprocess.run([sys.executable, "-c", "import json\n" + script], cwd=ROOT, capture_output=True,
                                text=True, timeout=180)
        assert result.returncode == 0, result.stderr[-2000:]
        status = json.loads(result.stdout.strip().splitlines()[-1])
        assert status["job_id"] == "drill-row-demo" and status["state"] == "succeeded"
        session.settle(status)
    script = bag_example.replace('"runs/<stamp>/bag"', repr(str(tmp_path / "bag"))) + "\nprint(msg)\n"
    result = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=120)
    assert result.returncode == 0 and result.stdout.strip(), result.stderr[-2000:]
