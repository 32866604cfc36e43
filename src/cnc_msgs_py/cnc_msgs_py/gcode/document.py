"""A job document from a file on the command line: a G-code program (``.ngc``, ``.nc``,
``.gcode``, ``.tap``) becomes a program document, anything else is read as a YAML/JSON job.

The machine is ``--machine NAME``, else the program's ``(CNC,MACHINE name)`` comment; the
job id is the file's name (its characters outside the job-id pattern replaced by ``-``).
"""
from __future__ import annotations

import re
from pathlib import Path

from ..job import load_job_file
from ..schema import JobError
from .translate import machine_named

PROGRAM_SUFFIXES = (".ngc", ".nc", ".gcode", ".tap")


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
    return {"schema": "cnc_job/1", "job_id": job_id, "kind": "program", "machine": name, "program": {"gcode": text}}


def job_document(path: str | Path, machine: str | None = None) -> dict:
    """A program document from a G-code file, else the YAML/JSON job (``machine`` filling in
    a machine the job does not name)."""
    path = Path(path)
    if path.suffix.lower() in PROGRAM_SUFFIXES:
        return program_document(path, machine)
    doc = load_job_file(path)
    if machine and "machine" not in doc:
        doc["machine"] = machine
    return doc
