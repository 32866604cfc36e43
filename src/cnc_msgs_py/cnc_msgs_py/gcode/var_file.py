"""A machine's stored work offsets, as LinuxCNC keeps them in its parameter (var) file.

On a real controller the fixture offsets G55..G59.3 are touched off on the machine and kept
there, not in the program: LinuxCNC writes them to its var file, one ``<number> <value>``
per line (#5241-#5249 G55's X..W, #5250 its rotation about Z, each further system 20 on).
Ours is ``config/machines/<machine>.var`` beside the description, lengths in mm; a job's
``program.work_offsets`` overrides a system it names. A machine without the file keeps no
offsets, and a program selecting a system nothing set is refused for that machine reason.
"""
from __future__ import annotations

from ..machine import machine_dirs
from ..schema import JobError
from .offsets import SYSTEM_FIRST, SYSTEM_STRIDE, SYSTEMS

ROTATION = 9  # a system's rotation about Z, after its nine axes


def parse_var_file(text: str, source: str = "var file") -> dict[str, dict]:
    """The work offsets G55..G59.3 a var file's text sets, as ``program.work_offsets`` entries
    (G54 is the job's setup: its parameters are read and left to it)."""
    values: dict[int, float] = {}
    for n, raw in enumerate(text.splitlines(), start=1):
        fields = raw.split()
        if not fields:
            continue
        try:
            values[int(fields[0])] = float(fields[1])
        except (IndexError, ValueError):
            raise JobError(source, f"line {n}: expected '<parameter number> <value>', got {raw.strip()!r}") from None
    offsets = {}
    for k, name in enumerate(SYSTEMS[1:], start=1):
        first = SYSTEM_FIRST + k * SYSTEM_STRIDE
        if any(first + i in values for i in (0, 1, 2, ROTATION)):
            offsets[name] = {"origin": [values.get(first + i, 0.0) for i in range(3)],
                             "rotation_deg": [0.0, 0.0, values.get(first + ROTATION, 0.0)]}
    return offsets


def machine_work_offsets(machine: str) -> dict[str, dict]:
    """The work offsets ``config/machines/<machine>.var`` keeps ({} when it keeps none)."""
    for folder in machine_dirs():
        path = folder / f"{machine}.var"
        if path.is_file():
            try:
                return parse_var_file(path.read_text(), str(path))
            except (OSError, UnicodeDecodeError) as err:
                raise JobError("machine", f"cannot read {path}: {err}") from err
    return {}
