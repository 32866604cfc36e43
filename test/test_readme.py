"""Every example in the README and in docs/ runs, so the pages cannot rot: job fragments
validate and plan inside their example jobs, the machine description parses, the Python
snippets run against real nodes and a real recording, the shell examples name real make
targets, console scripts and files, and every relative link leads to a file and heading."""
from __future__ import annotations

import importlib
import json
import re
import subprocess
import sys
from pathlib import Path

import pytest
import yaml

from cnc_msgs_py.job import KINDS, load_job_file, parse_job
from cnc_msgs_py.machine import load_machine, parse_drive, parse_machine
from cnc_msgs_py.plant import parse_plant
from cnc_planner.planning import plan_job
from cnc_planner.runner import Session

from support import BIN, JOBS, ROOT

PAGES = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
# (page, language, text) of every fenced block, pages in the order above.
BLOCKS = [(page, lang, text) for page in PAGES
          for lang, text in re.findall(r"```(\w+)\n(.*?)```", page.read_text(), re.S)]
# The example job each kind's fragment belongs to.
EXAMPLE = {"move": "move_mill3", "drill": "drill_row", "turn": "turn_stepped", "thread": "thread_m12",
           "path": "path_5ax_tilt", "vibration": "lathe_feed_vibration", "program": "program_mill3",
           "sync": "sync_lathe"}
YAML = [(page, yaml.safe_load(text)) for page, lang, text in BLOCKS if lang == "yaml"]
JOB_BLOCKS = [(page, doc) for page, doc in YAML if "axes" not in doc and "drive" not in doc]
# A plant file, or a description's drive entries (with their tolerance), without the axes.
DRIVE_BLOCKS = [(page, doc) for page, doc in YAML if "drive" in doc and "axes" not in doc]
PYTHON = [text for _, lang, text in BLOCKS if lang == "python"]
SHELL = [text for _, lang, text in BLOCKS if lang == "sh"]


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


@pytest.mark.parametrize("page, fragment", DRIVE_BLOCKS, ids=lambda x: x.name if isinstance(x, Path) else "+".join(x))
def test_plant_and_drive_fragments_parse(page, fragment):
    """A plant file parses over mill3; a description's drive entries parse as drives."""
    if any("tolerance" in spec for spec in fragment["drive"].values()):
        for joint, spec in fragment["drive"].items():
            assert parse_drive(spec, f"drive.{joint}").tolerance.kp[0] > 0
    else:
        assert parse_plant(fragment, load_machine("mill3")).drives.keys() == {"x", "y", "z", "spindle"}


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


def test_shell_examples_name_real_targets_scripts_and_files():
    targets = set(re.findall(r"^([\w-]+):", (ROOT / "Makefile").read_text(), re.M))
    for text in SHELL:
        for line in text.splitlines():
            words = line.split("#")[0].split()
            if words and words[0] == "make":
                assert words[1] in targets, line
            if words and words[0].startswith("cnc-"):
                assert (BIN / words[0]).is_file(), line
            for word in words:
                if re.fullmatch(r"(config|bench)/[\w./-]+\.\w+", word):
                    assert (ROOT / word).is_file(), line


def anchors(page: Path) -> set[str]:
    """GitHub's anchors for a page's headings: lower case, punctuation dropped, spaces to '-'."""
    text = re.sub(r"```.*?```", "", page.read_text(), flags=re.S)
    return {re.sub(r"[^\w\- ]", "", title.lower()).replace(" ", "-")
            for title in re.findall(r"^#+ (.+)$", text, re.M)}


@pytest.mark.parametrize("page", PAGES, ids=lambda p: p.name)
def test_relative_links_lead_to_a_file_and_heading(page):
    for target in re.findall(r"\]\(([^)\s]+)\)", page.read_text()):
        if re.match(r"\w+://", target):
            continue
        path, _, anchor = target.partition("#")
        linked = (page.parent / path).resolve() if path else page
        assert linked.exists(), f"{page.name}: {target}"
        if anchor:
            assert anchor in anchors(linked), f"{page.name}: {target}"


def test_named_source_files_and_objects_exist():
    """`cnc_pkg/module.py` paths and `cnc_pkg.module.Name` objects the pages name, so a
    module that moves takes its pages along."""
    text = "".join(page.read_text() for page in PAGES)
    for package, rest in re.findall(r"`(cnc_\w+)/([\w/]+\.(?:py|c))`", text):
        assert (ROOT / "src" / package / package / rest).is_file(), f"{package}/{rest}"
    for dotted in re.findall(r"`(cnc_\w+(?:\.\w+)+)`", text):
        obj = importlib.import_module(dotted.split(".")[0])
        for name in dotted.split(".")[1:]:
            if not hasattr(obj, name):  # a submodule not imported yet
                importlib.import_module(f"{obj.__name__}.{name}")
            obj = getattr(obj, name)
