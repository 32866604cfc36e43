"""Parameters as LinuxCNC 2.9 keeps them for one program run.

- ``#1``-``#5399``: numbered, 0 until written; ``#1``-``#30`` are a subroutine call's
  arguments (saved on the call, restored on its return), the rest global.
- ``#5161``-``#5390`` (G28/G30 homes, G92 and G54..G59.3 offsets) LinuxCNC keeps in its var
  file between runs. Here ``#5161``-``#5169`` and ``#5181``-``#5189`` read the G28 and G30
  positions (``homes``: the machine's home until G28.1/G30.1 store one), ``#5210``-``#5390``
  the G92 offset and the coordinate systems as the job and the program's G10 L2/L20, G92
  and G52 set them (``offsets``); writing any of them is refused: those words set them,
  not a var file.
- ``#5220`` the work offset in force (1 = G54), ``#5400`` the tool in the spindle,
  ``#5401``-``#5409`` its applied offsets (Z = the G43 length), ``#5410`` its diameter,
  ``#5420``-``#5428`` the current position (X Y Z A B C U V W), program coordinates and
  units: read only, the interpreter's. ``#5599`` and up a program may write, as in LinuxCNC.
- ``#<name>``: local to the subroutine call (or the main program) that writes it; read
  before any write is an error, as in LinuxCNC. ``#<_name>``: global.
- ``#<_x>``, ``#<_metric>``, ... : the documented read-only system parameters
  (``SYSTEM_NAMES``), from the interpreter's state when the line is read.
- ``#<_ini[...]>`` and ``#<_hal[...]>`` are refused: there is no INI file or HAL here.
"""
from __future__ import annotations

from typing import Callable

from .expressions import ExprError

MAX_NUMBER = 5602  # LinuxCNC's RS274NGC_MAX_PARAMETERS: valid numbers are below it
ARGUMENTS = 30
VAR_FILE = range(5161, 5391)
OFFSETS = range(5210, 5391)  # G92 and G54..G59.3, read from offsets.Offsets
HOMES = (*range(5161, 5170), *range(5181, 5190))  # G28 and G30, read from homes.Homes
READ_ONLY_FROM = 5400
WRITABLE_FROM = 5599  # #5599 (DEBUG output on/off) and up LinuxCNC lets a program write
INTEGER_TOLERANCE = 1.0e-4  # LinuxCNC reads an integer value within this of a whole number

SYSTEM_NAMES = (
    "_vmajor _vminor _line _motion_mode _plane _ccomp _metric _imperial _absolute _incremental _inverse_time "
    "_units_per_minute _units_per_rev _coord_system _tool_offset _retract_r_plane _retract_old_z "
    "_spindle_rpm_mode _spindle_css_mode _ijk_absolute_mode _lathe_diameter_mode _lathe_radius_mode "
    "_spindle_on _spindle_cw _mist _flood _speed_override _feed_override _adaptive_feed _feed_hold _feed _rpm "
    "_x _y _z _a _b _c _u _v _w _current_tool _current_pocket _selected_tool _selected_pocket "
    "_call_level _remap_level _task").split()


def whole(value: float, word: str) -> int:
    """An integer value as LinuxCNC reads one (within 0.0001 of a whole number)."""
    n = round(value)
    if abs(value - n) > INTEGER_TOLERANCE:
        raise ExprError(word, f"{value:g} is not a whole number")
    return n


class Parameters:
    """The numbered, named and system parameters of one program run (an ``Env``)."""

    def __init__(self, system: Callable[[str], float], numbered_system: Callable[[int], float]) -> None:
        self.system = system
        self.numbered_system = numbered_system
        self.numbered: dict[int, float] = {}
        self.globals: dict[str, float] = {"_value": 0.0, "_value_returned": 0.0}
        self.frames: list[tuple[dict[str, float], dict[int, float]]] = [({}, {})]

    def _number(self, value: float) -> int:
        n = whole(value, f"#{value:g}")
        if not 1 <= n < MAX_NUMBER:
            raise ExprError(f"#{n}", f"no such parameter (1-{MAX_NUMBER - 1})")
        return n

    def read(self, number: float) -> float:
        n = self._number(number)
        if READ_ONLY_FROM <= n < WRITABLE_FROM or n in OFFSETS or n in HOMES:
            return self.numbered_system(n)
        return self.numbered.get(n, 0.0)

    def read_named(self, name: str) -> float:
        if name.startswith(("_ini[", "_hal[")):
            raise ExprError(f"#<{name}>", "reads the machine's INI file or HAL, which a job document does not carry")
        if name in SYSTEM_NAMES:
            return self.system(name)
        if name.startswith("_"):
            if name not in self.globals:
                raise ExprError(f"#<{name}>", "read before it is set")
            return self.globals[name]
        local = self.frames[-1][0]
        if name not in local:
            raise ExprError(f"#<{name}>", "read before it is set (named parameters are local to their subroutine)")
        return local[name]

    def exists(self, name: str) -> bool:
        if name in SYSTEM_NAMES:
            return True
        return name in (self.globals if name.startswith("_") else self.frames[-1][0])

    def write(self, target: float | str, value: float) -> None:
        if isinstance(target, str):
            if target in SYSTEM_NAMES or target.startswith(("_ini[", "_hal[")):
                raise ExprError(f"#<{target}>", "is read only (the interpreter's)")
            (self.globals if target.startswith("_") else self.frames[-1][0])[target] = value
            return
        n = self._number(target)
        if READ_ONLY_FROM <= n < WRITABLE_FROM or n == 5220:
            raise ExprError(f"#{n}", "is read only (the interpreter's)")
        if n in VAR_FILE:
            raise ExprError(f"#{n}", "LinuxCNC keeps it in its var file: here the job's setup and "
                                     "work_offsets, G10 L2/L20, G92, G52, G28.1 and G30.1 set it")
        self.numbered[n] = value

    def call(self, args: list[float]) -> None:
        """A subroutine call: #1-#30 saved and set to the arguments (0 beyond them), new locals."""
        saved = {n: self.numbered.get(n, 0.0) for n in range(1, ARGUMENTS + 1)}
        self.frames.append(({}, saved))
        for n in range(1, ARGUMENTS + 1):
            self.numbered[n] = args[n - 1] if n <= len(args) else 0.0
        self.globals["_value_returned"] = 0.0

    def ret(self, value: float | None) -> None:
        """Back from a call: #1-#30 and the locals restored, ``#<_value>`` set when returned."""
        _, saved = self.frames.pop()
        self.numbered.update(saved)
        if value is not None:
            self.globals["_value"] = value
            self.globals["_value_returned"] = 1.0

    @property
    def level(self) -> int:
        return len(self.frames) - 1
