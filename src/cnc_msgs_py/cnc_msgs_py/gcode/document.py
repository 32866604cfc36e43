"""A job document from a file on the command line: a G-code program (``.ngc``, ``.nc``,
``.gcode``, ``.tap``) becomes a program document, anything else is read as a YAML/JSON job.

The machine is ``--machine NAME``, else the program's ``(CNC,MACHINE name)`` comment; the
job id is the file's name (its characters outside the job-id pattern replaced by ``-``).
``--tools FILE`` (a LinuxCNC tool.tbl) becomes ``program.tool_table``, ``--spindle RPM``
``program.start.spindle_rpm`` (the spindle an operator started in MDI before cycle start, for
a program that never starts it: LinuxCNC's examples written for its simulator). Every ``o<name> call``
the program does not define is looked up as ``<name>.ngc`` (lower case, as LinuxCNC does) in
the program's folder, then in the folders of ``CNC_SUBROUTINE_PATH`` (LinuxCNC's
SUBROUTINE_PATH, ``os.pathsep`` separated), and carried in ``program.subroutines`` so that
the document stays whole on the topics.
"""
from __future__ import annotations

import argparse
import os
import re
from pathlib import Path

from ..job import load_job_file
from ..schema import JobError
from .tools import load_tool_table
from .translate import machine_named

PROGRAM_SUFFIXES = (".ngc", ".nc", ".gcode", ".tap")
CALL = re.compile(r"^[^;(]*?o\s*<([^>]+)>\s*call", re.I | re.M)
SUB = re.compile(r"^[^;(]*?o\s*<([^>]+)>\s*sub\b", re.I | re.M)


def _names(pattern: re.Pattern, text: str) -> set[str]:
    return {"".join(m.group(1).split()).lower() for m in pattern.finditer(text)}


def subroutine_files(text: str, folders: list[Path]) -> list[dict]:
    """The ``<name>.ngc`` files of every subroutine the program (and those files) call but do
    not define, first found on ``folders``; a name found nowhere is left for the translation
    to refuse at its call's line."""
    found: dict[str, str] = {}
    todo = [text]
    while todo:
        body = todo.pop()
        for name in sorted(_names(CALL, body) - _names(SUB, body) - set(found)):
            path = next((f / f"{name}.ngc" for f in folders if (f / f"{name}.ngc").is_file()), None)
            if path is None:
                continue
            try:
                found[name] = path.read_text()
            except (OSError, UnicodeDecodeError) as err:
                raise JobError("program.subroutines", f"cannot read {path}: {err}") from err
            todo.append(found[name])
    return [{"name": name, "gcode": found[name]} for name in sorted(found)]


def search_path(program: Path) -> list[Path]:
    """The program's folder, then CNC_SUBROUTINE_PATH's."""
    extra = [Path(p) for p in os.environ.get("CNC_SUBROUTINE_PATH", "").split(os.pathsep) if p]
    return [program.resolve().parent, *extra]


def program_document(path: Path, machine: str | None = None) -> dict:
    """The program document of a G-code file, with the machine it runs on."""
    try:
        text = path.read_text()
    except (OSError, UnicodeDecodeError) as err:
        raise JobError("", f"cannot read program {path}: {getattr(err, 'strerror', None) or err}") from err
    name = machine or machine_named(text)
    if not name:
        raise JobError("machine", f"{path.name} names no machine: give --machine NAME or a (CNC,MACHINE name) comment")
    job_id = re.sub(r"[^A-Za-z0-9_.:-]", "-", path.stem)[:64] or "program"
    block: dict = {"gcode": text}
    subs = subroutine_files(text, search_path(path))
    if subs:
        block["subroutines"] = subs
    return {"schema": "cnc_job/1", "job_id": job_id, "kind": "program", "machine": name, "program": block}


def job_from_args(args: argparse.Namespace) -> dict:
    """The job document of ``args.job`` with the options of ``tool.add_program_options``."""
    return job_document(args.job, args.machine, args.tools, args.spindle)


def job_document(path: str | Path, machine: str | None = None, tools: str | Path | None = None,
                 spindle_rpm: float | None = None) -> dict:
    """A program document from a G-code file, else the YAML/JSON job (``machine`` filling in
    a machine the job does not name); ``tools`` a tool.tbl for a program's ``tool_table``,
    ``spindle_rpm`` its ``start.spindle_rpm``."""
    path = Path(path)
    if path.suffix.lower() in PROGRAM_SUFFIXES:
        doc = program_document(path, machine)
    else:
        doc = load_job_file(path)
        if machine and "machine" not in doc:
            doc["machine"] = machine
    options = {"tools": ("a tool table", tools), "spindle": ("the spindle at a program's start", spindle_rpm)}
    for option, (what, given) in options.items():
        if given is not None and (doc.get("kind") != "program" or not isinstance(doc.get("program"), dict)):
            raise JobError(option, f"{what} is for G-code programs (kind: program)")
    if tools is not None:
        doc["program"]["tool_table"] = load_tool_table(tools)
    if spindle_rpm is not None:
        start = doc["program"].get("start")
        doc["program"]["start"] = {**(start if isinstance(start, dict) else {}), "spindle_rpm": spindle_rpm}
    return doc
