"""LinuxCNC tool tables (``tool.tbl``) as a program document's ``tool_table``.

One tool a line, ``T<n> P<pocket> X Y Z A B C U V W D<diameter> I<front angle> J<back angle>
Q<orientation> ;comment`` in any order, letters case-insensitive, lengths in mm. Z is the
tool length G43 applies, D the diameter (0 for a lathe's tool, as LinuxCNC's lathe tables
write it). The front end applies lengths along the tool axis only, so an offset in any
other axis (a lathe tool's X) is refused with its line rather than dropped; P, I, J and Q
say where the tool sits and how it is ground, which a plan does not need.

A machine's own table is ``config/machines/<name>.tbl`` beside its description; a job's
``program.tool_table`` (or ``--tools FILE``) replaces it.
"""
from __future__ import annotations

import re
from pathlib import Path

from ..machine import machine_dirs
from ..schema import JobError

WORD = re.compile(r"([A-Za-z])\s*([+-]?(?:\d+\.?\d*|\.\d+))")
IGNORED = set("PIJQ")
UNAPPLIED = set("XYABCUVW")


def parse_tool_table(text: str, source: str = "tool table") -> list[dict]:
    """The tools of a tool.tbl text as ``program.tool_table`` entries (tool, length, diameter)."""
    tools: list[dict] = []
    seen: set[int] = set()
    for n, raw in enumerate(text.splitlines(), start=1):
        code = raw.split(";", 1)[0].strip()
        if not code:
            continue
        where = f"{source} line {n}"
        rest = WORD.sub("", code).strip()
        if rest:
            raise JobError(where, f"cannot read {rest[:20]!r} (words are a letter and a number: T1 Z12.5 D6)")
        words = {m.group(1).upper(): float(m.group(2)) for m in WORD.finditer(code)}
        if "T" not in words or words["T"] != int(words["T"]) or words["T"] < 1:
            raise JobError(where, "needs T, a whole tool number >= 1")
        tool = int(words["T"])
        if tool in seen:
            raise JobError(where, f"T{tool} given twice")
        seen.add(tool)
        for letter, value in words.items():
            if letter in UNAPPLIED and value != 0.0:
                raise JobError(where, f"T{tool}: {letter}{value:g}: only the Z length is applied (G43), "
                                      f"an offset in {letter} is not")
            if letter not in UNAPPLIED | IGNORED | {"T", "Z", "D"}:
                raise JobError(where, f"T{tool}: {letter} is not a tool table word (T P X Y Z A B C U V W D I J Q)")
        entry = {"tool": tool, "length": words.get("Z", 0.0)}
        if "D" in words:
            entry["diameter"] = words["D"]
        tools.append(entry)
    return tools


def load_tool_table(path: str | Path) -> list[dict]:
    """A tool.tbl file's tools; JobError naming the file (and line) if it cannot be read."""
    path = Path(path)
    try:
        text = path.read_text()
    except (OSError, UnicodeDecodeError) as err:
        raise JobError("tools", f"cannot read {path}: {getattr(err, 'strerror', None) or err}") from err
    return parse_tool_table(text, path.name)


def machine_tool_table(machine: str) -> list[dict] | None:
    """The tools of ``config/machines/<machine>.tbl``, None when the machine has no table."""
    for folder in machine_dirs():
        path = folder / f"{machine}.tbl"
        if path.is_file():
            return load_tool_table(path)
    return None
