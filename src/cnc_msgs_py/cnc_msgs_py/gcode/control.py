"""O-word control flow as LinuxCNC 2.9 runs it: the program's lines in the order they execute.

``sub``/``endsub``/``return`` (with a value into ``#<_value>``; a ``return`` may carry any
O-number, as LinuxCNC's own examples write it), ``call`` with arguments into
#1-#30, ``if``/``elseif``/``else``/``endif``, ``while``/``endwhile``, ``do``/``while``,
``repeat``/``endrepeat``, ``break``/``continue``. The statements pair by their O-number as in
LinuxCNC; every pairing is checked before the first line runs, so a malformed program is
refused at its line before anything is translated. A ``o<name> call`` that the program does
not define runs ``<name>.ngc`` from ``program.subroutines`` (``document.subroutine_files``
fills those from a search path, LinuxCNC's SUBROUTINE_PATH). A runaway program is refused:
its loops may jump back ``MAX_ITERATIONS`` times in all, its calls nest ``MAX_CALL_DEPTH`` deep.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable, Iterator

from .expressions import ExprError
from .lexer import Block, GcodeError, Line, OWord, read_lines
from .parameters import Parameters, whole

MAX_ITERATIONS = 100_000
MAX_CALL_DEPTH = 50
LOOPS = ("while", "do", "repeat")


@dataclass
class Unit:
    """One file's lines and their pairings (indices into ``lines``)."""

    label: str  # "" for the program itself, "name.ngc" for a subroutine file
    lines: list[Line]
    subs: dict[str, tuple[int, int]] = field(default_factory=dict)  # name -> (sub, endsub)
    branches: dict[int, list[int]] = field(default_factory=dict)  # if -> [if, elseif.., else?, endif]
    branch_end: dict[int, int] = field(default_factory=dict)  # elseif/else -> endif
    loop_end: dict[int, int] = field(default_factory=dict)  # while/do/repeat -> its end
    loop_start: dict[int, int] = field(default_factory=dict)  # endwhile/closing while/endrepeat -> start
    jumps: dict[int, int] = field(default_factory=dict)  # break/continue -> their loop's start


@dataclass
class Frame:
    """A running call: where in which unit, where to go back to, its repeat counts."""

    unit: Unit
    pc: int
    at: int  # the program line a subroutine file's lines report (the call's line)
    repeats: dict[int, int] = field(default_factory=dict)
    saved: dict | None = None  # the modal state M70 saved in this call (gcode.saved_state)
    autorestore: dict | None = None  # the modal state M73 saved, restored as the call returns


def pair(unit: Unit) -> Unit:
    """Pair every O-word statement with its partners, or refuse the first unpaired one."""
    stack: list[tuple[str, str, int]] = []  # (kind, name, index)
    for i, ln in enumerate(unit.lines):
        o = ln.o
        if o is None:
            continue
        top = stack[-1] if stack else None

        def refuse(why: str, o: OWord = o, ln: Line = ln) -> GcodeError:
            return GcodeError(ln.line, o.text, why)

        if o.kind == "sub":
            if stack:
                raise refuse("a subroutine cannot be defined inside another block")
            if o.name in unit.subs:
                raise refuse("defined twice")
            stack.append(("sub", o.name, i))
        elif o.kind in ("if", "do", "repeat") or (o.kind == "while" and not (top and top[:2] == ("do", o.name))):
            stack.append((o.kind, o.name, i))
            if o.kind == "if":
                unit.branches[i] = [i]
        elif o.kind == "while":  # closes a do
            unit.loop_end[top[2]], unit.loop_start[i] = i, top[2]
            stack.pop()
        elif o.kind in ("elseif", "else", "endif"):
            if not top or top[:2] != ("if", o.name):
                raise refuse(f"no open o{_label(o.name)} if")
            chain = unit.branches[top[2]]
            if unit.lines[chain[-1]].o.kind == "else" and o.kind != "endif":  # type: ignore[union-attr]
                raise refuse("comes after the else")
            chain.append(i)
            if o.kind == "endif":
                stack.pop()
                for b in chain[1:-1]:
                    unit.branch_end[b] = i
        elif o.kind in ("endwhile", "endrepeat"):
            opener = "while" if o.kind == "endwhile" else "repeat"
            if not top or top[:2] != (opener, o.name):
                raise refuse(f"no open o{_label(o.name)} {opener}")
            unit.loop_end[top[2]], unit.loop_start[i] = i, top[2]
            stack.pop()
        elif o.kind in ("break", "continue"):
            loop = next((s for s in reversed(stack) if s[0] in LOOPS and s[1] == o.name), None)
            if loop is None:
                raise refuse(f"not inside an o{_label(o.name)} loop")
            unit.jumps[i] = loop[2]
        elif o.kind in ("endsub", "return"):
            sub = next((s for s in stack if s[0] == "sub"), None)
            if sub is None or o.kind == "endsub" and sub[1] != o.name:
                raise refuse(f"not inside o{_label(o.name)} sub" if o.kind == "endsub" else "not inside a subroutine")
            if o.kind == "endsub":
                if top != sub:
                    raise refuse(f"o{_label(top[1])} {top[0]} is still open")  # type: ignore[index]
                unit.subs[o.name] = (sub[2], i)
                stack.pop()
    if stack:
        kind, name, i = stack[-1]
        raise GcodeError(unit.lines[i].line, f"o{_label(name)} {kind}", "is never closed")
    return unit


def _label(name: str) -> str:
    return name if name.isdigit() else f"<{name}>"


class Executor:
    """Runs a program's lines: ``blocks()`` yields each executed line's values as a Block."""

    def __init__(self, text: str, files: dict[str, str], params: Parameters) -> None:
        self.main = pair(Unit("", read_lines(text)))
        self.files = {k.lower(): v for k, v in files.items()}
        self.units: dict[str, Unit] = {}
        self.params = params
        self.frames = [Frame(self.main, 0, 0)]
        self.iterations = 0
        self.on_return: Callable[[Frame], None] = lambda frame: None  # as a subroutine returns (M73)

    def blocks(self) -> Iterator[Block]:
        """The program's blocks in execution order; ends where the program's lines end."""
        return self._run(0)

    def expand(self, name: str, line: int) -> Iterator[Block]:
        """The blocks one call of subroutine ``name`` makes (G71's contour), no arguments, each
        evaluated as it is taken: the caller moves #<_x>/#<_z> along the contour as LinuxCNC
        reads it (lathe._profile). Take them all."""
        depth = len(self.frames)
        self._call(OWord(name, "call"), [], line)
        return self._run(depth)

    def _unit_of(self, name: str, line: int) -> tuple[Unit, tuple[int, int]]:
        for unit in (self.frames[-1].unit, self.main):
            if name in unit.subs:
                return unit, unit.subs[name]
        if name.isdigit() or name not in self.files:
            raise GcodeError(line, f"o{_label(name)} call", "no such subroutine in the program"
                             + ("" if name.isdigit() else f" nor a {name}.ngc on the subroutine path"))
        if name not in self.units:
            label = f"{name}.ngc"
            try:
                self.units[name] = pair(Unit(label, read_lines(self.files[name])))
            except GcodeError as err:
                raise GcodeError(line, label, str(err)) from None
        unit = self.units[name]
        if name not in unit.subs:
            raise GcodeError(line, f"o<{name}> call", f"{name}.ngc defines no o<{name}> sub")
        return unit, unit.subs[name]

    def _call(self, o: OWord, args: list[float], line: int) -> None:
        if len(self.frames) > MAX_CALL_DEPTH:
            raise GcodeError(line, o.text, f"calls nest deeper than {MAX_CALL_DEPTH} (a runaway recursion?)")
        if len(args) > 30:
            raise GcodeError(line, o.text, "takes at most 30 arguments (#1-#30)")
        unit, (start, _) = self._unit_of(o.name, line)
        self.params.call(args)
        self.frames.append(Frame(unit, start + 1, line))

    def _jump_back(self, frame: Frame, to: int, o: OWord, line: int) -> None:
        self.iterations += 1
        if self.iterations > MAX_ITERATIONS:
            raise GcodeError(line, o.text, f"loops jumped back {MAX_ITERATIONS} times: a runaway program is refused")
        frame.pc = to

    def _run(self, depth: int) -> Iterator[Block]:
        while len(self.frames) > depth:
            frame = self.frames[-1]
            unit = frame.unit
            if frame.pc >= len(unit.lines):
                return  # the program's last line ran
            ln = unit.lines[frame.pc]
            at = ln.line if unit is self.main else frame.at
            try:
                if ln.o is not None:
                    self._statement(frame, unit, ln, at)
                    continue
                frame.pc += 1
                block = ln.evaluate(self.params, at)
            except ExprError as err:
                raise self._located(unit, ln, at, GcodeError(at, err.word, err.reason, err.needs_start)) from None
            except GcodeError as err:
                raise self._located(unit, ln, at, err) from None
            if unit.label:
                block.where = f"{unit.label}: line {ln.line}"
            yield block

    @staticmethod
    def _located(unit: Unit, ln: Line, at: int, err: GcodeError) -> GcodeError:
        """An error inside a subroutine file, at the program line that called it."""
        if not unit.label or err.word.endswith(".ngc"):
            return err
        return GcodeError(at, unit.label, f"line {ln.line}: {err.reason}", err.needs_start)

    def _statement(self, frame: Frame, unit: Unit, ln: Line, at: int) -> None:
        o, i = ln.o, frame.pc
        assert o is not None
        kind = o.kind
        values = [a(self.params) for a in o.args] if kind in ("call", "endsub", "return", "repeat") else []
        if kind == "sub":
            frame.pc = unit.subs[o.name][1] + 1  # a definition: skipped where it stands
        elif kind == "call":
            frame.pc += 1
            self._call(o, values, at)
        elif kind in ("endsub", "return"):
            self.params.ret(values[0] if values else None)
            self.on_return(self.frames.pop())
        elif kind == "if":
            frame.pc = self._branch(unit, i)
        elif kind in ("elseif", "else"):
            frame.pc = unit.branch_end[i] + 1  # the branch before it ran
        elif kind == "while" and i in unit.loop_start:  # closing a do
            if o.args[0](self.params) != 0.0:
                self._jump_back(frame, unit.loop_start[i] + 1, o, at)
            else:
                frame.pc += 1
        elif kind == "while":
            frame.pc = i + 1 if o.args[0](self.params) != 0.0 else unit.loop_end[i] + 1
        elif kind == "endwhile":
            self._jump_back(frame, unit.loop_start[i], o, at)
        elif kind == "repeat":
            frame.repeats[i] = whole(values[0], o.text)
            frame.pc = i + 1 if frame.repeats[i] > 0 else unit.loop_end[i] + 1
        elif kind == "endrepeat":
            start = unit.loop_start[i]
            frame.repeats[start] -= 1
            if frame.repeats[start] > 0:
                self._jump_back(frame, start + 1, o, at)
            else:
                frame.pc += 1
        elif kind == "break":
            frame.pc = unit.loop_end[unit.jumps[i]] + 1
        elif kind == "continue":
            start = unit.jumps[i]
            opener = unit.lines[start].o.kind  # type: ignore[union-attr]
            self._jump_back(frame, start if opener == "while" else unit.loop_end[start], o, at)
        else:  # endif, do
            frame.pc += 1

    def _branch(self, unit: Unit, i: int) -> int:
        """The line after the first branch whose condition holds (or after the endif)."""
        chain = unit.branches[i]
        for k in chain[:-1]:
            o = unit.lines[k].o
            assert o is not None
            if o.kind == "else" or o.args[0](self.params) != 0.0:
                return k + 1
        return chain[-1] + 1
