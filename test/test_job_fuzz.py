"""Property tests of job validation: no document, however broken, crashes the planner.

Random JSON-like documents and mutations of the example jobs in config/jobs (a key
dropped, a type changed, NaN/inf/huge/negative numbers injected, unknown keys added) go
through ``parse_job`` (returns, or raises JobError: never another exception) and through
the planner's ``Executive.submit`` (accepted, or rejected with a one-line reason whose
field path exists in the document or whose parent does, e.g. a missing required key).
Deterministic: hypothesis derandomized, no example database.
"""
from __future__ import annotations

import copy
import json
import math
import re
from functools import lru_cache
from pathlib import Path

import yaml
from hypothesis import HealthCheck, event, given, settings
from hypothesis.control import currently_in_test_context
from hypothesis import strategies as st

from cnc_msgs_py.job import JOB, parse_job
from cnc_msgs_py.kinds.move import AXIS_KEYS
from cnc_msgs_py.schema import JobError, List, Obj, _key
from cnc_planner.executive import Executive
from cnc_planner.planning import INTERNAL

ROOT = Path(__file__).resolve().parents[1]
EXAMPLES = {p.name: yaml.safe_load(p.read_text()) for p in sorted((ROOT / "config" / "jobs").glob("*.yaml"))}
WHOLE_DOCUMENT = ("not valid JSON", "expected a mapping")
FUZZ = settings(derandomize=True, database=None, deadline=None, print_blob=False,
                suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])


def schema_keys(spec, out: set[str]) -> set[str]:
    """Every key the schema knows, at any depth (random documents draw from them)."""
    if isinstance(spec, Obj):
        for key, sub in spec.fields.items():
            out.add(key)
            schema_keys(sub, out)
    elif isinstance(spec, List):
        schema_keys(spec.item, out)
    return out


KEYS = sorted(schema_keys(JOB, set()) | set(AXIS_KEYS))  # every key the schema has, at any depth
SPECIAL_NUMBERS = [math.nan, math.inf, -math.inf, 1e300, -1e300, 10**400, -(10**30), -1, -1.5, 0, -0.0, 1e9,
                   1e-300]
WRONG_TYPES = [None, True, False, "12", "", "nan", [], [1, 2], {}, {"x": 1}]


# --- checking a verdict ------------------------------------------------------------------------
def _resolve(node, text: str) -> tuple[bool, str]:
    """Walk one step of a field path: (found, rest of the text after it)."""
    if isinstance(node, list):
        m = re.match(r"\[(\d+)\]", text)
        if m and int(m.group(1)) < len(node):
            return True, text[m.end():]
        return False, text
    if isinstance(node, dict):
        for key in sorted(node, key=lambda k: -len(_key(k))):  # longest first: 'x' vs 'x_y'
            name = _key(key)
            if text.startswith(name) and text[len(name):len(name) + 1] in ("", ".", "[", ":"):
                return True, text[len(name):]
    return False, text


def field_path_known(doc, reason: str) -> bool:
    """The reason starts with a field path that exists in the document, or whose last step
    is a schema key missing under a parent that exists (a required key, or a default that
    breaks a rule)."""
    if reason.startswith(WHOLE_DOCUMENT):
        return True
    line = re.match(r"line (\d+): ", reason)
    if line and isinstance(doc, dict) and isinstance(doc.get("program"), dict):  # a G-code program's line
        text = doc["program"].get("gcode")
        return isinstance(text, str) and 1 <= int(line.group(1)) <= len(text.splitlines()) + 1
    node, spec, rest, first = doc, JOB, reason, True
    while True:
        if not first:
            if rest.startswith(": "):
                return True  # the whole path exists
            if rest.startswith("."):
                rest = rest[1:]
        found, after = _resolve(node, rest)
        if not found:
            # the missing last step: a key of the schema under an existing parent, then ': '
            m = re.match(r"([A-Za-z_][A-Za-z0-9_]*): ", rest)
            return bool(m) and isinstance(node, dict) and isinstance(spec, Obj) and m.group(1) in spec.fields
        step = rest[: len(rest) - len(after)]
        if isinstance(node, list):
            node, spec = node[int(step[1:-1])], spec.item if isinstance(spec, List) else None
            if isinstance(node, dict):  # a list entry given as a mapping (a hole, an arc)
                spec = getattr(spec, "mapping", spec)
        else:
            key = _key_of(node, step)
            node, spec = node[key], spec.fields.get(key) if isinstance(spec, Obj) else None
        rest, first = after, False


def _key_of(node: dict, name: str):
    return next(k for k in node if _key(k) == name)


@lru_cache(maxsize=None)
def _machine(name: str):
    from cnc_msgs_py.machine import load_machine
    return load_machine(name)


def verdict(doc) -> None:
    """parse_job and Executive.submit on one document: never a crash, a field-naming reason."""

    try:
        parse_job(copy.deepcopy(doc))
    except JobError as err:
        assert "\n" not in str(err)
    text = json.dumps(doc)
    name = doc.get("machine") if isinstance(doc, dict) else None
    known = ("mill3", "lathe", "lathe_y", "5ax_table_table", "5ax_head_table")
    executive = Executive(_machine(name if name in known else "mill3"))
    status = executive.submit(text)
    if currently_in_test_context():
        event(status.state)  # --hypothesis-show-statistics tells how many were accepted
    assert status.state in ("accepted", "rejected"), status
    if status.state == "rejected":
        reason = status.reason
        assert reason and "\n" not in reason and "\r" not in reason, reason
        assert INTERNAL not in reason, reason  # a planner bug caught by the safety net
        assert field_path_known(doc, reason), (reason, text[:300])
        reason.encode("utf-8")  # publishable on job_status
    else:
        assert math.isfinite(status.duration_s) and status.duration_s >= 0.0


# --- random JSON-like documents ----------------------------------------------------------------
scalars = (st.none() | st.booleans() | st.integers(-(10**6), 10**6) | st.sampled_from(SPECIAL_NUMBERS)
           | st.floats(allow_nan=True, allow_infinity=True) | st.text(max_size=8) | st.sampled_from(KEYS))
keys = st.sampled_from(KEYS) | st.text(max_size=6)
json_like = st.recursive(scalars, lambda children: st.lists(children, max_size=4)
                         | st.dictionaries(keys, children, max_size=5), max_leaves=25)


@settings(FUZZ, max_examples=1000)
@given(json_like)
def test_random_documents_never_crash(doc):
    verdict(doc)


@st.composite
def skeletons(draw):
    """A valid header with a random block for its kind: gets past the first checks."""
    kind = draw(st.sampled_from(["drill", "move", "turn", "thread", "path", "bogus"]))
    doc = {"schema": "cnc_job/1", "job_id": "fuzz-1", "kind": kind,
           "machine": draw(st.sampled_from(["mill3", "lathe", "mill5"]))}
    if draw(st.booleans()):
        doc["spindle_rpm"] = draw(st.sampled_from([0, 600, 3000, -1, math.nan, 1e300]))
    doc[kind if kind != "bogus" else "drill"] = draw(json_like)
    if draw(st.booleans()):
        doc["vibration"] = draw(json_like)
    return doc


@settings(FUZZ, max_examples=1000)
@given(skeletons())
def test_random_blocks_never_crash(doc):
    verdict(doc)


# --- mutations of the example jobs ----------------------------------------------------------------
def paths(node, prefix=()):
    """Every (path, value) in a document, the root excluded."""
    items = node.items() if isinstance(node, dict) else enumerate(node) if isinstance(node, list) else ()
    for key, value in items:
        yield prefix + (key,), value
        yield from paths(value, prefix + (key,))


def containers(doc):
    return [p for p, v in [((), doc), *paths(doc)] if isinstance(v, dict)]


def _at(doc, path):
    for key in path:
        doc = doc[key]
    return doc


@st.composite
def mutants(draw):
    name = draw(st.sampled_from(sorted(EXAMPLES)))
    doc = copy.deepcopy(EXAMPLES[name])
    for _ in range(draw(st.integers(1, 3))):
        every = [p for p, _ in paths(doc)]
        op = draw(st.sampled_from(["drop", "type", "number", "unknown_key", "string_number", "retarget"]))
        if op == "retarget":  # a valid value of another job: the wrong machine or kind
            key = draw(st.sampled_from(["machine", "kind"]))
            doc[key] = draw(st.sampled_from(["mill3", "lathe", "lathe_y", "mill5"] if key == "machine"
                                            else ["drill", "move", "turn", "thread", "path"]))
            continue
        if op == "unknown_key":
            where = draw(st.sampled_from(containers(doc)))
            key = draw(st.sampled_from(["extra", "Depth", "feed_rate", "x ", "job\nid", "\ud800", "unit"]))
            _at(doc, where)[key] = draw(scalars)
            continue
        if not every:
            break
        path = draw(st.sampled_from(every))
        parent, last = _at(doc, path[:-1]), path[-1]
        if op == "drop":
            del parent[last]
        elif op == "type":
            parent[last] = copy.deepcopy(draw(st.sampled_from(WRONG_TYPES)))  # a shared [] or {} mutated later would nest in itself
        elif op == "number":
            parent[last] = draw(st.sampled_from(SPECIAL_NUMBERS))
        elif isinstance(parent[last], (int, float)) and not isinstance(parent[last], bool):
            parent[last] = str(parent[last])  # "3000" for 3000
    return doc


@settings(FUZZ, max_examples=300)
@given(mutants())
def test_mutated_example_jobs_are_accepted_or_rejected_by_field(doc):
    verdict(doc)


def test_the_examples_themselves_are_accepted():
    """The mutation base is valid: each example plans on its machine."""
    from cnc_planner.executive import Executive

    for name, doc in EXAMPLES.items():
        status = Executive(_machine(doc["machine"])).submit(json.dumps(doc))
        assert status.state == "accepted", (name, status.reason)


def test_every_example_on_every_machine_and_kind():
    """Each example retargeted at every machine and every kind: accepted or rejected by
    field, never a crash (a drill job on the lathe once raised KeyError)."""
    for name, base in EXAMPLES.items():
        for machine in ("mill3", "lathe", "lathe_y", "5ax_table_table", "mill5"):
            verdict({**base, "machine": machine})
        for kind in ("drill", "move", "turn", "thread", "path"):
            verdict({**base, "kind": kind})


def test_field_path_check_itself():
    doc = {"drill": {"holes": [[0, 0], [1, 2]], "depth": 5}, "move": None, "x_y": 1}
    assert field_path_known(doc, "drill.holes[1][0]: must be finite")
    assert field_path_known(doc, "drill.feed: required")  # missing key under an existing parent
    assert field_path_known(doc, "spindle_rpm: must be > 0")
    assert field_path_known(doc, "x_y: unknown key")
    assert field_path_known(doc, "not valid JSON (nested too deep)")
    assert not field_path_known(doc, "drill.holes[5]: out of range")
    assert not field_path_known(doc, "length: too short")  # not a top-level key of the schema
    assert field_path_known(doc, "drill.depth: too deep")
    assert not field_path_known(doc, "tool.length: too long")  # only the last step may be missing
    assert not field_path_known(doc, "drill.length: x")
    assert not field_path_known(doc, "drilling.depth: x")
    assert not field_path_known(doc, "needs axis x at nan mm")
