"""The interpreter: a program's blocks, line by line, into our job documents (operations).

Moves (G0/G1/G2/G3/G4) gather into ``move`` operations, canned cycles become the methods of
``cnc_msgs_py.gcode.cycles``; an operation ends where the next one of another kind, tool,
speed, work offset or cycle words begins. Every word of a line must be used by something
in it: a word nothing uses is refused, as is everything this front end does not implement.
"""
from __future__ import annotations

from dataclasses import dataclass, field

from . import arcs, compensation, homes, offsets, path_tolerance, saved_state, spindle_sync, splines, surface_speed, \
    system
from .control import Executor
from .drilling import hole
from .finishing import g70
from .lathe import g71, g76
from .lexer import Block, GcodeError, closed_by_percent, word_text
from .modal import DRILL_CYCLES, MOTION, ROUGHING_CYCLES, START_SPINDLE, Modal, check_groups
from .parameters import Parameters, whole
from .polar import has_polar, polar_xy

DIRECTIVE = "CNC,"  # our comments: (CNC,VIBRATION D=1.5 Q=1.2), (CNC,OVERLAP OFF), (CNC,MACHINE mill3)
VIBRATION_KEYS = {"D": "D", "Q": "Q", "E": "E", "R": "R", "PHASE": "phase_shift", "DSTEP": "D_step"}
AXES = ("x", "y", "z")
# an arc plane's first and second axis and their center offsets (LinuxCNC's order)
PLANES = {17.0: (("x", "y"), ("I", "J")), 18.0: (("z", "x"), ("K", "I")), 19.0: (("y", "z"), ("J", "K"))}


@dataclass
class Operation:
    """One of our jobs, as a document in machinist units, and the line it starts at."""

    line: int
    doc: dict


@dataclass(frozen=True)
class Hold:
    """A program pause (M0, or M1 with the optional stop on): the machine holds, axes at rest,
    before operation ``before`` (len(operations) when no motion follows it) until resumed."""

    before: int
    line: int
    code: str  # "M0" | "M1"


class Operations(list):
    """A program's operations, with its hold points (``holds``, in program order)."""

    def __init__(self, items: tuple | list = (), holds: list[Hold] | None = None) -> None:
        super().__init__(items)
        self.holds: list[Hold] = list(holds or [])


@dataclass
class Context:
    """What the program document gives besides the text (mm, as the document writes them)."""

    job_id: str
    machine: str
    setup: dict = field(default_factory=dict)
    tool_table: dict[int, dict] = field(default_factory=dict)  # tool number -> {length, diameter, nose_radius}
    work_offsets: dict[str, dict] = field(default_factory=dict)  # G55..G59 -> setup
    stock: list | None = None
    start: dict[str, float] = field(default_factory=dict)
    spindle_rpm: float | None = None  # the spindle turning (M3) at this speed as the program begins
    subroutines: dict[str, str] = field(default_factory=dict)  # name -> the text of <name>.ngc
    optional_stop: bool = True  # M1 holds (AXIS's "Stop at M1" is on by default)


def directives(comments: list[str]) -> list[tuple[str, list[str]]]:
    """Our directive comments of a line as (name, arguments), upper case."""
    out = []
    for c in comments:
        if c.upper().startswith(DIRECTIVE):
            parts = c[len(DIRECTIVE):].split()
            if parts:
                out.append((parts[0].upper(), parts[1:]))
    return out


def machine_named(text: str) -> str | None:
    """The machine a program names with ``(CNC,MACHINE name)``, if any."""
    for raw in text.splitlines():
        for c in raw.split("(")[1:]:
            for name, args in directives([c.split(")")[0]]):
                if name == "MACHINE" and args:
                    return args[0]
    return None


class Translator:
    """Reads a program once; ``operations`` holds its jobs after ``run``."""

    def __init__(self, ctx: Context) -> None:
        self.ctx = ctx
        self.state = Modal(position=dict(ctx.start), speed=ctx.spindle_rpm or 0.0,
                           spindle_on=ctx.spindle_rpm is not None)
        self.operations = Operations()
        self.current: Operation | None = None
        self.current_key: tuple | None = None
        self.vibration: dict | None = None
        self.overlap = "auto"
        self.cycle: dict = {}  # sticky canned-cycle words (R, Z, Q, P) and the initial Z
        self.params = Parameters(lambda name: system.named(self, name), lambda n: system.numbered(self, n))
        self.line = 0  # the line running, for #<_line>
        self.tools = {n: dict(entry) for n, entry in ctx.tool_table.items()}  # G10 L1/L10 edit this copy
        self.offsets = offsets.Offsets(ctx.setup, ctx.work_offsets)  # G10 L2/L20, G92, G52 edit these
        self.homes = homes.Homes(ctx.machine)  # G28.1/G30.1 store these
        self.comp = compensation.State()  # G41/G42: the moves wait for their offset until G40
        self.contours: dict[tuple[int, int], list[Block]] = {}  # G71 P Q's N blocks, for a G70 P Q after it

    # ---- the program
    def run(self, text: str) -> Operations:
        self.executor = Executor(text, self.ctx.subroutines, self.params)
        self.executor.on_return = saved_state.on_return(self)
        self.source = self.executor.blocks()
        ended = False
        for block in self.source:
            try:
                stop = self._line(block)
            except GcodeError as err:
                if not block.where or err.word.endswith(".ngc"):
                    raise
                name, _, at = block.where.partition(": ")
                raise GcodeError(block.line, name, f"{at}: {err.reason}", err.needs_start) from None
            if stop:
                ended = True
                break
        if not ended and not closed_by_percent(text):
            last = self.executor.main.lines[-1].line if self.executor.main.lines else 0
            raise GcodeError(last + 1, "end of file", "the program ends without M2 or M30")
        if self.comp.on:
            compensation.finish(self)  # the program's end turns compensation off, as LinuxCNC's does
        self._flush()
        if not self.operations:
            raise GcodeError(1, "program", "moves no axis: nothing to plan")
        return self.operations

    def _line(self, block: Block) -> bool:
        """One executed line; True at the program's end (M2, M30)."""
        self.line = block.number if block.number is not None else block.line
        self._directives(block)
        check_groups(block, self.ctx.machine)
        used: set[str] = set()
        stop = self._block(block, used)
        left = [k for k in block.words if k not in used]
        if left:
            k = left[0]
            raise GcodeError(block.line, word_text(k, block.words[k]), "not used by anything in this line")
        return stop

    def _directives(self, block: Block) -> None:
        for name, args in directives(block.comments):
            where = f"(CNC,{name})"
            if name == "OVERLAP":
                if [a.upper() for a in args] not in (["AUTO"], ["OFF"]):
                    raise GcodeError(block.line, where, "takes AUTO or OFF")
                self.overlap = args[0].lower()
            elif name == "VIBRATION":
                self.vibration = self._vibration(block.line, where, args)
            elif name != "MACHINE":
                raise GcodeError(block.line, where, "unknown directive (known: VIBRATION, OVERLAP, MACHINE)")

    @staticmethod
    def _vibration(line: int, where: str, args: list[str]) -> dict | None:
        if [a.upper() for a in args] == ["OFF"]:
            return None
        out: dict = {}
        for a in args:
            key, _, value = a.partition("=")
            if key.upper() not in VIBRATION_KEYS:
                raise GcodeError(line, where, f"unknown key {key!r} (known: {', '.join(VIBRATION_KEYS)}, or OFF)")
            try:
                out[VIBRATION_KEYS[key.upper()]] = float(value)
            except ValueError:
                raise GcodeError(line, where, f"{key} needs a number, as {key}=1.5") from None
        if not out:
            raise GcodeError(line, where, "give D=.. Q=.., or E=.. R=.., or OFF")
        return out

    # ---- one line, in LinuxCNC's order of execution
    def _block(self, b: Block, used: set[str]) -> bool:
        s = self.state
        g = [round(v, 1) for v in b.g]
        m = [round(v, 1) for v in b.m]
        compensation.check_line(self, b, g, m)
        if 20.0 in g or 21.0 in g:
            s.inch = 20.0 in g
        if 94.0 in g or 95.0 in g:
            s.per_rev = 95.0 in g
        if "F" in b.words:
            used.add("F")
            if b.words["F"] <= 0.0:
                raise GcodeError(b.line, word_text("F", b.words["F"]), "a feed must be > 0")
            s.feed = b.words["F"]
        if "S" in b.words:
            used.add("S")
            if b.words["S"] < 0.0:
                raise GcodeError(b.line, word_text("S", b.words["S"]), "a speed must be >= 0")
            s.speed = b.words["S"]
        surface_speed.words(self, b, used, g)  # G96 D S, G97
        if "T" in b.words:
            used.add("T")
            s.next_tool = self._tool_number(b, "T")
        if 61.0 in m:
            if "Q" not in b.words:
                raise GcodeError(b.line, "M61", "needs Q, the tool now in the spindle")
            used.add("Q")
            s.tool = self._tool_number(b, "Q")
        if 6.0 in m:
            if s.next_tool is None:
                raise GcodeError(b.line, "M6", "no tool selected with T")
            s.tool = s.next_tool
        if 3.0 in m:
            s.spindle_on = True
        if 5.0 in m:
            s.spindle_on = False
        if any(code in m for code in saved_state.CODES):
            saved_state.codes(self, b, m)  # after the spindle, before coolant: LinuxCNC's order
        if 7.0 in m or 8.0 in m:
            s.mist, s.flood = s.mist or 7.0 in m, s.flood or 8.0 in m
        if 9.0 in m:
            s.mist = s.flood = False
        for plane in (17.0, 18.0, 19.0):
            if plane in g:
                s.plane = plane
        if 7.0 in g or 8.0 in g:
            s.diameter = 7.0 in g
        compensation.words(self, b, used, g)
        if 43.0 in g:
            s.length_tool = self._tool_number(b, "H") if "H" in b.words else s.tool
            used.add("H")
            s.length_offset = True
        if 49.0 in g:
            s.length_offset = False
        for w in (54.0, 55.0, 56.0, 57.0, 58.0, 59.0, 59.1, 59.2, 59.3):
            if w in g:
                offsets.select(self, b, w)
        if 90.0 in g or 91.0 in g:
            s.incremental = 91.0 in g
        if 90.1 in g or 91.1 in g:
            s.arc_absolute = 90.1 in g
        for code in (61.0, 61.1, 64.0):
            if code in g:
                path_tolerance.set_mode(self, b, used, code)
        if 98.0 in g or 99.0 in g:
            s.retract_initial = 98.0 in g
        if 4.0 in g:
            self._dwell(b, used)
        if 10.0 in g:
            self._g10(b, used)  # its axis words are data, not motion
        elif any(c in g for c in offsets.OFFSET_CODES):
            offsets.g92(self, b, used, next(c for c in g if c in offsets.OFFSET_CODES))
        elif not homes.words(self, b, used, g):  # G28/G30 take the axis words, G28.1/G30.1 leave them
            surface_speed.check_motion(self, b, g)
            self._motion(b, g, used)
        if 0.0 in m or 1.0 in m:  # the stop group runs last, after the line's motion
            self._pause(b.line, "M0" if 0.0 in m else "M1")
        return 2.0 in m or 30.0 in m

    def _pause(self, line: int, code: str) -> None:
        """M0, and M1 when the optional stop is on: the operation so far ends (at rest) and
        the program holds there until resumed; the spindle keeps turning, as LinuxCNC's
        PROGRAM_STOP leaves it."""
        if code == "M1" and not self.ctx.optional_stop:
            return
        if self.comp.on:
            raise GcodeError(line, code, "a pause with cutter compensation on (G41/G42): its last move is not "
                                         "known before the next one; give G40 first")
        self._flush()
        self.operations.holds.append(Hold(len(self.operations), line, code))

    def _g10(self, b: Block, used: set[str]) -> None:
        """G10 L1 P<tool> Z R: a tool's length and radius into the table; G10 L10 P<tool> Z: its
        length such that the current position reads Z (a touch-off). The table is this
        program's copy: the job's table is not changed."""
        s = self.state
        level = b.words.get("L")
        if level in (2.0, 20.0):
            offsets.g10(self, b, used, level)
            return
        if level not in (1.0, 10.0):
            why = ("the G59.3 fixture's offsets are the machine's" if level == 11.0 else
                   "needs L1, L10 (tool table entries), L2 or L20 (coordinate systems)")
            raise GcodeError(b.line, "G10" if level is None else f"G10 L{level:g}", why)
        if "P" not in b.words:
            raise GcodeError(b.line, f"G10 L{level:g}", "needs P, the tool")
        used.update(k for k in "LP" if k in b.words)
        tool = self._tool_number(b, "P")
        if tool == 0:
            raise GcodeError(b.line, "P0", "tool 0 is no tool")
        for k in "XYABCUVW":
            if k in b.words:
                raise GcodeError(b.line, word_text(k, b.words[k]), "only the Z length is applied (G43), "
                                                                  f"an offset in {k} is not")
        entry = self.tools[tool]
        if "Z" in b.words:
            used.add("Z")
            z = s.length(b.words["Z"])
            if level == 10.0:
                if "z" not in s.position:
                    raise GcodeError(b.line, "G10 L10", "the Z position is unknown here: move Z first", True)
                z = s.position["z"] + self.applied_length() - z
                if s.length_offset and s.length_tool == tool:
                    s.position["z"] = s.length(b.words["Z"])  # the axis stays; its reading changes
            if z < 0.0:
                raise GcodeError(b.line, word_text("Z", b.words["Z"]), f"gives tool {tool} a negative length "
                                                                      f"({z:g} mm)")
            entry["length"] = z
        if "R" in b.words:
            used.add("R")
            entry["diameter"] = 2.0 * s.length(b.words["R"])

    def _tool_number(self, b: Block, letter: str) -> int:
        """A T, Q (M61) or H (G43) word's tool: a whole number in the tool table (0: none)."""
        value = b.words[letter]
        try:
            n = whole(value, word_text(letter, value))
        except ValueError:
            n = -1
        if n < 0 or n != 0 and n not in self.tools:
            raise GcodeError(b.line, word_text(letter, value), "no such tool in the tool table (program.tool_table, "
                                                              "--tools FILE)")
        return n

    def tool_entry(self, n: int) -> dict:
        """Tool ``n``'s table entry (mm), empty for tool 0."""
        return self.tools.get(n, {})

    def applied_length(self) -> float:
        """The tool length G43 applies now (mm), 0 under G49."""
        s = self.state
        return self.tool_entry(s.length_tool).get("length", 0.0) if s.length_offset else 0.0

    def _dwell(self, b: Block, used: set[str]) -> None:
        if "P" not in b.words or b.words["P"] < 0.0:
            raise GcodeError(b.line, "G4", "needs P, the dwell in seconds (>= 0)")
        used.add("P")
        if b.words["P"] > 0.0 and not compensation.hold(self, b.line, {"dwell": b.words["P"]}):
            self._move(b.line, {"dwell": b.words["P"]})

    # ---- motion
    def _motion(self, b: Block, g: list[float], used: set[str]) -> None:
        s = self.state
        motion = next((c for c in g if c in MOTION), None)
        if motion == 80.0:
            s.motion, self.cycle = None, {}
            if b.has_axes():
                raise GcodeError(b.line, "G80", "axis words with G80 and no motion to use them")
            return
        if motion in (70.0, 76.0, *ROUGHING_CYCLES):
            if 4.0 in g:
                raise GcodeError(b.line, word_text("G", motion), "cannot share a line with G4")
            self._one_shot(b, motion, used)
            return
        if motion == splines.CODE:  # the motion mode in force stays, as in LinuxCNC
            splines.g5_1(self, b, g, used)
            return
        if motion is not None:
            if motion in DRILL_CYCLES and s.motion != motion:
                self.cycle = {"initial_z": s.position.get("z")}
            s.motion = motion
        if s.motion is None:
            if b.has_axes():
                k = next(k for k in "XYZ" if k in b.words)
                raise GcodeError(b.line, word_text(k, b.words[k]), "no motion mode in force (give G0 or G1)")
            return
        if s.motion in spindle_sync.CODES:
            if b.has_axes():
                spindle_sync.locked(self, b, used)
            return
        if 53.0 in g and s.motion not in (0.0, 1.0):
            raise GcodeError(b.line, "G53", "needs G0 or G1 in force (machine coordinates are for straight moves)")
        if s.motion in DRILL_CYCLES:
            if b.has_axes() or motion is not None:
                self._hole(b, used)
            return
        full_circle = s.motion in (2.0, 3.0) and any(k in b.words for k in "IJK")
        if not b.has_axes() and not full_circle:
            return
        if s.motion in (0.0, 1.0) or 53.0 in g:
            before = dict(s.position)
            target = offsets.g53_target(self, b, used) if 53.0 in g else self._target(b, used)
            if target == before:
                return  # no motion: the tool is there already (our cycles end where LinuxCNC's return to)
            feed = None if s.motion == 0.0 else surface_speed.feed(self, b.line, "G1")  # (per rev under G96)
            if compensation.add(self, b.line, feed is None, feed, before, target):
                return
            if feed is None or not path_tolerance.add(self, b.line, before, target, feed):
                self._move(b.line, {"rapid": target} if feed is None else {"linear": target, **feed})
        else:
            self._arc(b, used)

    def _axis_value(self, b: Block, axis: str) -> float:
        v = self.state.length(b.words[axis.upper()])
        return v / 2.0 if axis == "x" and self.state.diameter else v

    def _target(self, b: Block, used: set[str]) -> dict[str, float]:
        """The new position (every known axis, mm), updating the state."""
        pos = self.state.position
        if has_polar(b):
            pos["x"], pos["y"] = polar_xy(self.state, b, used)
        for axis in AXES:
            if axis.upper() in b.words:
                used.add(axis.upper())
                v = self._axis_value(b, axis)
                if self.state.incremental:
                    if axis not in pos:
                        raise GcodeError(b.line, word_text(axis.upper(), b.words[axis.upper()]),
                                         "incremental move from an unknown position (give it absolutely first)", True)
                    v += pos[axis]
                pos[axis] = v
        return dict(pos)

    def _given_feed(self, line: int, word: str, turning: bool) -> float:
        """The F word in mm (per minute, or per revolution under G95, which needs the spindle
        ``turning``), refused at its line where there is none or the spindle stands."""
        s = self.state
        if s.feed is None:
            raise GcodeError(line, word, "no feed given (F)")
        if s.per_rev and not turning:
            raise GcodeError(line, word, f"G95 feeds per revolution need the spindle on: {START_SPINDLE}")
        return s.length(s.feed)

    def _feed_mm_min(self, line: int, word: str) -> float:
        s = self.state
        feed = self._given_feed(line, word, s.spindle_on and s.speed > 0.0)
        return feed * s.speed if s.per_rev else feed

    def _arc(self, b: Block, used: set[str]) -> None:
        s = self.state
        name = word_text("G", s.motion)
        (a, c), offsets = PLANES[s.plane]
        if a not in s.position or c not in s.position:
            raise GcodeError(b.line, name, "an arc from an unknown position (move both plane axes first)", True)
        start = (s.position[a], s.position[c])
        before = dict(s.position)
        end_pos = self._target(b, used)
        end = (end_pos[a], end_pos[c])
        try:
            if "R" in b.words:
                used.add("R")
                if any(k in b.words for k in offsets):
                    raise ValueError("give R or the center offsets, not both")
                center = arcs.center_from_radius(start, end, s.length(b.words["R"]), s.motion == 2.0)
            else:
                if not any(k in b.words for k in offsets):
                    raise ValueError(f"needs R or the center offsets {offsets[0]}/{offsets[1]}")
                used.update(k for k in offsets if k in b.words)
                off = [s.length(b.words.get(k, 0.0)) for k in offsets]
                center = (off[0], off[1]) if s.arc_absolute else (start[0] + off[0], start[1] + off[1])
                arcs.check_center(start, end, center)
        except ValueError as err:
            raise GcodeError(b.line, name, str(err)) from None
        feed = surface_speed.feed(self, b.line, name)
        if compensation.add(self, b.line, False, feed, before, end_pos, center, s.motion == 2.0):
            return
        third = next(k for k in AXES if k not in (a, c))
        at = before
        for pa, pc, share in arcs.chords(start, end, center, s.motion == 2.0):
            target = {**end_pos, a: pa, c: pc}
            if third in end_pos and third in before:
                target[third] = before[third] + share * (end_pos[third] - before[third])
            if not path_tolerance.add(self, b.line, at, target, feed):
                self._move(b.line, {"linear": target, **feed})
            at = target

    # ---- operations
    def _common(self, kind: str) -> dict:
        s = self.state
        tool = dict(self.tool_entry(s.tool))
        tool.pop("length", None)
        if self.applied_length():
            tool["length"] = self.applied_length()
        doc = {"schema": "cnc_job/1", "job_id": "", "kind": kind, "machine": self.ctx.machine,
               "tool": tool, "setup": self.offsets.setup(s.work_offset), **surface_speed.spindle(s)}
        return doc

    def _begin(self, line: int, kind: str, key: tuple, block: dict | list, common: dict | None = None) -> dict | list:
        """The open operation's block if it continues with ``key``, else a new operation's (its header
        ``common``, as _common made it when the move was programmed, or now)."""
        if self.current is not None and self.current_key == (kind, key):
            return self.current.doc[kind]
        self._flush()
        doc = self._common(kind) if common is None else dict(common)
        doc[kind] = block
        if self.vibration is not None and kind != "move":  # a move operation takes it once it has a feed move
            doc["vibration"] = dict(self.vibration)
        self.current, self.current_key = Operation(line, doc), (kind, key)
        return block

    def _flush(self) -> None:
        if self.current is not None:
            k = len(self.operations) + 1
            self.current.doc["job_id"] = f"{self.ctx.job_id[:56]}.op{k}"
            spindle_sync.as_sync(self.current.doc)
            if self.current.doc["kind"] == "move" and self.vibration is not None and "vibration" not in self.current.doc \
                    and any("linear" in m for m in self.current.doc["move"]):
                self.current.doc["vibration"] = dict(self.vibration)
            self.operations.append(self.current)
        self.current, self.current_key = None, None

    def _key(self) -> tuple:
        s = self.state
        vib = None if self.vibration is None else tuple(sorted(self.vibration.items()))
        return (s.tool, self.applied_length(), self.offsets.key(s.work_offset), surface_speed.key(s), vib)

    def _move(self, line: int, entry: dict, key: tuple | None = None, common: dict | None = None) -> None:
        self._begin(line, "move", self._key() if key is None else key, [], common).append(entry)
        tool = self.current.doc["tool"]
        if tool.get("diameter") == 0.0:
            del tool["diameter"]  # a lathe tool (D0): a move plans no cutter, and its schema takes none or > 0

    def _need_spindle(self, line: int, word: str) -> None:
        if not (self.state.spindle_on and self.state.speed > 0.0):
            raise GcodeError(line, word, f"the spindle is off: {START_SPINDLE}")

    def _hole(self, b: Block, used: set[str]) -> None:
        hole(self, b, used)

    def _one_shot(self, b: Block, motion: float, used: set[str]) -> None:
        if motion == 76.0:
            g76(self, b, used)
        elif motion == 70.0:
            g70(self, b, used)
        else:
            g71(self, b, used, motion)


def translate(text: str, ctx: Context) -> Operations:
    """A program's operations (job documents, mm) and hold points, or GcodeError at its first
    bad line."""
    return Translator(ctx).run(text)
