"""Job documents (schema ``cnc_job/1``): what a cell controller asks the planner to do.

Documents are JSON on the ``job_goal`` topic (YAML files on the command line) in
machinist units: lengths mm, feeds mm/min (turning feeds mm/rev), speeds rpm, angles deg.
``parse_job`` validates a whole document and returns it in SI units (m, m/s, rad, rad/s);
any error names the field path and the reason, before anything can move.

This module holds what every job has (its header, tool, setup, spindle and vibration); each
kind's block and rules are in its module under ``cnc_msgs_py.kinds`` (lathe outlines and their
arcs: ``cnc_msgs_py.kinds.turn``), found through ``KIND_SCHEMAS``.
"""
from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path
from types import SimpleNamespace
from typing import Any

import yaml

from .kinds import BLOCK_ORDER, KIND_SCHEMAS
from .kinds.kind import MAX_LIST  # noqa: F401  public: the longest list (holes, moves, points) a job may hold
from .kinds.kind import THREAD_ONLY_VIBRATION, KindSchema
from .schema import JobError, List, Num, Obj, Str, given, show
from .units import rpm
from .yaml_text import load_yaml

SCHEMA = "cnc_job/1"
KINDS = tuple(KIND_SCHEMAS)
MIN_RPM = 1.0  # a spindle is off (0) or turns at least this fast

AUTO = "auto"


@dataclass(frozen=True)
class VibrationSpec(Obj):
    """``vibration: auto`` (the planner chooses D/Q or E/R/Q for the machine and spindle
    speed; parsed, the string ``auto``) or a mapping of the parameters (parsed, a namespace
    with every key, None where not given); a mapping's unknown keys are refused by name."""

    def check(self, value: Any, path: str) -> SimpleNamespace | str:
        if value == AUTO:
            return AUTO
        if not isinstance(value, dict):
            raise JobError(path, f"expected {AUTO} or a mapping ({{D, Q}} or {{E, R}}), got {show(value)}")
        return super().check(value, path)


VIBRATION = VibrationSpec({
    "D": Num("1", gt=0.0, max=50.0, default=None),
    "Q": Num("1", gt=0.0, max=20.0, default=None),  # required with D; optional with E and R
    "E": Num("1", gt=0.0, max=50.0, default=None),
    "R": Num("1", gt=0.0, max=50.0, default=None),
    "phase_shift": Num("deg", min=-360.0, max=360.0, default=0.0),
    "D_step": Num("1", min=0.0, max=10.0, default=0.0),
}, default=None)

# Constant surface speed (G96 D S): the cutting speed at the tool's radius, m/min, and the rpm
# it may never exceed (D; without it the machine's spindle limit caps). Instead of spindle_rpm,
# on the kinds that turn along x on a lathe (turn, move); the others turn at one rpm and
# refuse it by name (their ``unused``).
SURFACE_SPEED = Obj({
    "m_min": Num("m/min", gt=0.0, min=1.0, max=3000.0),
    "max_rpm": Num("rpm", min=MIN_RPM, max=100_000.0, default=None),
}, default=None)

JOB = Obj({
    "schema": Str((SCHEMA,)),
    "job_id": Str(pattern=r"[A-Za-z0-9_.:-]{1,64}"),
    "kind": Str(KINDS),
    "machine": Str(pattern=r"[A-Za-z0-9_.-]{1,64}"),
    "tool": Obj({
        "length": Num("mm", min=0.0, max=1000.0, default=0.0),
        "diameter": Num("mm", min=0.0, max=500.0, default=None),  # 0: a lathe tool (D0)
        "nose_radius": Num("mm", min=0.0, max=10.0, default=0.0),
    }, default={}),
    "setup": Obj({
        "origin": List(Num("mm"), length=3, default=[0.0, 0.0, 0.0]),
        "rotation_deg": List(Num("deg"), length=3, default=[0.0, 0.0, 0.0]),
        # A named work offset of config/work_offsets.yaml instead of origin/rotation_deg
        # (the planner resolves it; with it, origin and rotation_deg must be left out or 0).
        "work_offset": Str(pattern=r"[A-Za-z0-9_.-]{1,64}", default=None),
    }, default={}),
    "spindle_rpm": Num("rpm", min=0.0, max=100_000.0, default=0.0),
    "surface_speed": SURFACE_SPEED,
    **{name: KIND_SCHEMAS[name].block for name in BLOCK_ORDER},
    "vibration": VIBRATION,
})


def _check_vibration(vib: SimpleNamespace | str, kind: KindSchema) -> None:
    """D with Q, or E and R (for D < 1), and a retreat that fits in the vibration's period;
    or auto, on the kinds whose vibration is the feed's waveform (a thread's has its own keys)."""
    if vib == AUTO:
        if not all(key in kind.unused for key in THREAD_ONLY_VIBRATION):
            raise JobError("vibration", f"auto is not available for {kind.name} jobs yet: give D and Q")
        return
    if vib.D is None and (vib.E is None or vib.R is None):
        raise JobError("vibration", "give D, or E and R (for D < 1)")
    if vib.D is not None and (vib.E is not None or vib.R is not None):
        raise JobError("vibration", "give either D or E and R, not both")
    if vib.E is not None and vib.R is not None and vib.R >= vib.E:
        raise JobError("vibration.R", "revolutions in retreat must be fewer than E")
    if vib.D is not None and vib.Q is None:
        raise JobError("vibration.Q", "required with D (amplitude = Q * feed per rev)")
    if vib.Q is None and not 2.0 * vib.R < vib.E:
        raise JobError("vibration.R", f"without Q the forward stroke and the retreat run at equal speed, "
                                      f"which needs R < E/2 = {vib.E / 2:g}; give Q as well")


def _check_common(job: SimpleNamespace, kind: KindSchema) -> None:
    """Cross-field rules every job has: its kind's block and no other, its spindle, its vibration."""
    if getattr(job, kind.name) is None:
        raise JobError(kind.name, f"required for kind '{kind.name}'")
    for other in KINDS:
        if other != kind.name and getattr(job, other) is not None:
            raise JobError(other, f"not allowed in a '{kind.name}' job")
    if 0.0 < job.spindle_rpm < rpm(MIN_RPM):
        raise JobError("spindle_rpm", f"must be 0 (spindle off) or at least {MIN_RPM:g} rpm")
    if job.surface_speed is not None:
        if "surface_speed" in kind.unused:  # before the kind's own rules, which read spindle_rpm
            raise JobError("surface_speed", f"not used by a {kind.name} job: {kind.unused['surface_speed']}")
        if job.spindle_rpm > 0.0:
            raise JobError("spindle_rpm", "give spindle_rpm or surface_speed, not both (the surface speed sets the rpm)")
        if job.vibration is not None:
            raise JobError("vibration", "a vibration is locked to one spindle speed: not with surface_speed "
                                        "(give spindle_rpm)")
    elif kind.needs_spindle and job.spindle_rpm <= 0.0:
        raise JobError("spindle_rpm", f"must be > 0 for a {kind.name} job")
    if job.vibration is not None:
        _check_vibration(job.vibration, kind)


def _check_unused(doc: dict, job: SimpleNamespace, kind: KindSchema) -> None:
    """A key the job's kind does not use is an error naming it: nothing given is ignored."""
    for key, why in kind.unused.items():
        if given(doc, key):
            raise JobError(key, f"not used by a {kind.name} job: {why}")
    if job.tool.diameter == 0.0 and not kind.lathe_tool:
        raise JobError("tool.diameter", f"must be > 0 mm for a {kind.name} job (0, D0, is a lathe tool's)")
    if kind.check_given is not None:
        kind.check_given(doc, job)


def parse_job(doc: Any) -> SimpleNamespace:
    """Validate a whole job document and return it in SI units.

    Args:
        doc: the decoded document (a dict), as from JSON or YAML.

    Raises:
        JobError: names the first offending field and the reason.
    """
    job = JOB.check(doc, "")
    kind = KIND_SCHEMAS[job.kind]
    _check_common(job, kind)
    kind.check(job)
    _check_unused(doc, job, kind)
    return job


def _unique_keys(pairs: list[tuple[str, Any]]) -> dict:
    """JSON objects with a key given twice are refused: which value was meant is unknown."""
    out = {}
    for key, value in pairs:
        if key in out:
            raise _DuplicateKey(key)
        out[key] = value
    return out


class _DuplicateKey(ValueError):
    pass


def decode_job(text: str) -> Any:
    """Decode a job_goal message (JSON); a decode error is a JobError too.

    JSON's ``NaN`` and ``Infinity`` tokens decode (the schema then names the field that
    holds one); a key given twice in one object, nesting too deep and integers too long
    to convert are decode errors.
    """
    try:
        return json.loads(text, object_pairs_hook=_unique_keys)
    except json.JSONDecodeError as err:
        raise JobError("", f"not valid JSON ({err.msg} at line {err.lineno} column {err.colno})") from err
    except _DuplicateKey as err:
        raise JobError("", f"not valid JSON (key {show(err.args[0])} given twice in one object)") from err
    except RecursionError as err:
        raise JobError("", "not valid JSON (nested too deep)") from err
    except ValueError as err:  # e.g. an integer literal beyond Python's digit limit
        raise JobError("", f"not valid JSON ({str(err).split(':')[0][:80]})") from err


def load_job_file(path: str | Path) -> dict:
    """Read a job document from a YAML or JSON file, as the CLI accepts them.

    Raises:
        JobError: the file is missing or not a YAML/JSON mapping.
    """
    path = Path(path)
    try:
        text = path.read_text()
    except OSError as err:
        raise JobError("", f"cannot read job file {path}: {err.strerror}") from err
    try:
        doc = load_yaml(text)
    except yaml.YAMLError as err:
        raise JobError("", f"job file {path} is not valid YAML/JSON ({err})") from err
    except RecursionError as err:
        raise JobError("", f"job file {path} is not valid YAML/JSON (nested too deep)") from err
    if not isinstance(doc, dict):
        raise JobError("", f"job file {path} must hold a mapping")
    return doc


def load_job(job: dict | str | Path) -> dict:
    """A job document from a dict, YAML/JSON text or a file path, validated whole.

    A string holding a newline, a '{' first or a 'key: value' pair is document text;
    any other string is a file path.

    Raises:
        JobError: names the offending field and the reason (or the unreadable file).
    """
    if isinstance(job, Path):
        doc = load_job_file(job)
    elif isinstance(job, str):
        text = job.strip()
        if "\n" in text or text.startswith("{") or ": " in text:
            try:
                doc = load_yaml(text)
            except yaml.YAMLError as err:
                raise JobError("", f"job text is not valid YAML/JSON ({err})") from err
        else:
            doc = load_job_file(text)
    else:
        doc = job
    if not isinstance(doc, dict):
        raise JobError("", "a job document must be a mapping")
    parse_job(doc)
    return doc


def job_id_of(doc: Any) -> str:
    """The job_id of a document even if it is invalid, for status messages."""
    if isinstance(doc, dict) and isinstance(doc.get("job_id"), str):
        # printable and encodable (a lone surrogate from a \ud800 escape is not), so that
        # the status and the log line carrying it cannot fail
        job_id = doc["job_id"][:64]
        if not job_id.isprintable():
            job_id = job_id.encode("unicode_escape").decode("ascii")[:64]
        return job_id.encode("utf-8", "backslashreplace").decode("utf-8")
    return ""
