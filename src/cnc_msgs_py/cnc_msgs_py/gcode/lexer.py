"""RS274/NGC lines as LinuxCNC 2.9 reads them: each line once into its words, parameter
settings and O-word, unevaluated (``Line``); ``Line.evaluate`` gives the ``Block`` of values
each time the line runs.

Spaces outside comments mean nothing, letters are case-insensitive, comments are ``( ... )``
(not nested) or ``;`` to the end of the line, a line of ``%`` marks the file's ends. A word's
value is a number, a parameter (``#3``, ``#<depth>``), an ``[expression]`` or a function
(``expressions``); ``#n=value`` sets a parameter after every value of its line is read
(LinuxCNC's reads-before-writes). Polar ``@`` ``^`` are words (``polar``); block delete ``/``
is refused by line and word, never skipped.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable

from ..schema import JobError
from .expressions import Env, Expr, ExprError, Reader, parameter_target, read_name, read_value

LETTERS = set("ABCDEFGHIJKLMNPQRSTUVWXYZ@^")  # @ ^: polar distance and angle
# O-word keywords, longest first so that ENDSUB is not read as END...
O_KEYWORDS = ("ENDREPEAT", "ENDWHILE", "CONTINUE", "ENDSUB", "ELSEIF", "REPEAT", "RETURN", "ENDIF", "BREAK",
              "WHILE", "ELSE", "CALL", "SUB", "IF", "DO")
O_CONDITION = {"if", "elseif", "while", "repeat"}  # need one [expression]
O_OPTIONAL = {"endsub", "return"}  # may return one [expression]


class GcodeError(JobError):
    """A program refused at a line: its field is ``line N`` and its reason ``<word>: <why>``.
    ``needs_start``: the line reads where the tool stands before the program has said it,
    which the machine knows when the program runs (kinds.program starts it there)."""

    def __init__(self, line: int, word: str, reason: str, needs_start: bool = False) -> None:
        super().__init__(f"line {line}", f"{word}: {reason}")
        self.line = line
        self.word = word
        self.needs_start = needs_start


@dataclass
class Block:
    """One line's words. ``g`` and ``m`` keep their order; other letters map to their value."""

    line: int
    g: list[float] = field(default_factory=list)
    m: list[float] = field(default_factory=list)
    words: dict[str, float] = field(default_factory=dict)
    comments: list[str] = field(default_factory=list)
    number: int | None = None  # N
    where: str = ""  # "name.ngc: line 3" for a line of a subroutine file

    def has_axes(self) -> bool:
        return any(k in self.words for k in "XYZ@^")


def word_text(letter: str, value: float) -> str:
    """A word as a reason quotes it: G81, X12.5, G90.1."""
    return f"{letter}{value:g}"


def _strip_comments(text: str, line: int) -> tuple[str, list[str]]:
    """The line without its comments, and the comments' texts."""
    out, comments, k = [], [], 0
    while k < len(text):
        ch = text[k]
        if ch == ";":
            comments.append(text[k + 1:].strip())
            break
        if ch == "(":
            end = text.find(")", k + 1)
            if end < 0:
                raise GcodeError(line, "(", "comment not closed on its line")
            inner = text[k + 1:end]
            if "(" in inner:
                raise GcodeError(line, "(", "comments cannot be nested")
            comments.append(inner.strip())
            k = end + 1
            continue
        if ch == ")":
            raise GcodeError(line, ")", "closes no comment")
        out.append(ch)
        k += 1
    return "".join(out), comments




@dataclass
class OWord:
    """An O-word statement: ``o100 while [#1 LT 3]``; ``name`` is ``100`` or a ``<name>``'s."""

    name: str
    kind: str  # sub endsub return call if elseif else endif while endwhile do repeat endrepeat break continue
    args: list[Expr] = field(default_factory=list)

    @property
    def text(self) -> str:
        label = self.name if self.name.isdigit() else f"<{self.name}>"
        return f"o{label} {self.kind}"


Setting = tuple[Callable[[Env], "int | str | float"], Expr]


@dataclass
class Line:
    """One line as read once: its words and parameter settings unevaluated, or an O-word."""

    line: int
    number: int | None = None
    words: list[tuple[str, Expr]] = field(default_factory=list)
    settings: list[Setting] = field(default_factory=list)
    comments: list[str] = field(default_factory=list)
    o: OWord | None = None

    def evaluate(self, env: Env, line: int | None = None) -> Block:
        """The line's values now, its parameter settings done after every read (LinuxCNC's rule)."""
        at = self.line if line is None else line
        block = Block(at, number=self.number, comments=self.comments)
        try:
            values = [(letter, value(env)) for letter, value in self.words]
            writes = [(target(env), value(env)) for target, value in self.settings]
        except ExprError as err:
            raise GcodeError(at, err.word, err.reason, err.needs_start) from None
        for letter, value in values:
            if letter == "G":
                block.g.append(value)
            elif letter == "M":
                block.m.append(value)
            elif letter in block.words:
                raise GcodeError(at, word_text(letter, value), f"{letter} given twice in one line")
            else:
                block.words[letter] = value
        for target, value in writes:
            try:
                env.write(target, value)  # type: ignore[attr-defined]
            except ExprError as err:
                raise GcodeError(at, err.word, err.reason, err.needs_start) from None
        return block


def _o_word(r: Reader, line: Line) -> OWord:
    r.k += 1  # the O
    if r.peek() == "<":
        name = read_name(r)
    else:
        start = r.k
        while r.peek().isdigit():
            r.k += 1
        if r.k == start:
            raise ExprError("O", "needs a number or a <name>")
        name = str(int(r.text[start:r.k]))
    kind = next((k for k in O_KEYWORDS if r.text.startswith(k, r.k)), None)
    label = name if name.isdigit() else f"<{name}>"
    if kind is None:
        raise ExprError(f"o{label}", "needs sub, endsub, return, call, if, elseif, else, endif, while, endwhile, "
                                     "do, repeat, endrepeat, break or continue")
    r.k += len(kind)
    o = OWord(name, kind.lower())
    while r.peek() == "[":
        o.args.append(read_value(r))
    if not r.done():
        raise ExprError(o.text, f"unexpected {r.text[r.k:r.k + 12]!r} after the O-word")
    if o.kind in O_CONDITION and len(o.args) != 1:
        raise ExprError(o.text, "needs one [expression]")
    if o.kind in O_OPTIONAL and len(o.args) > 1:
        raise ExprError(o.text, "returns at most one [expression]")
    if o.kind not in O_CONDITION | O_OPTIONAL | {"call"} and o.args:
        raise ExprError(o.text, "takes no expression")
    if line.words or line.settings:
        raise ExprError(o.text, "an O-word cannot share its line with other words")
    return o


def read_line(text: str, line: int) -> Line | None:
    """One line read once; None for a blank line or a ``%`` line."""
    code, comments = _strip_comments(text, line)
    code = "".join(code.split()).upper()
    if code == "%":
        return None
    out = Line(line, comments=comments)
    if not code:
        return out if comments else None
    if code.startswith("/"):
        raise GcodeError(line, "/", "block delete is not supported")
    r = Reader(code)
    try:
        while not r.done():
            letter = r.peek()
            if letter == "#":
                target = parameter_target(r)
                r.expect("=", "after the parameter it sets")
                out.settings.append((target, read_value(r)))
                continue
            if letter == "O":
                out.o = _o_word(r, out)
                break
            if letter not in LETTERS:
                raise ExprError(letter, "not a G-code word letter")
            r.k += 1
            if r.done():
                raise ExprError(letter, "needs a number after the letter")
            value = read_value(r)
            if letter == "N":
                if out.number is not None or out.words or out.settings:
                    raise ExprError("N", "a line number must come first, once")
                out.number = int(value(_NO_PARAMETERS))
            else:
                out.words.append((letter, value))
    except ExprError as err:
        raise GcodeError(line, err.word, err.reason) from None
    return out


class _NoParameters:
    """N numbers are plain numbers: a parameter there is refused."""

    def read(self, number: float) -> float:
        raise ExprError("N", "a line number cannot read a parameter")

    read_named = read  # type: ignore[assignment]
    exists = read  # type: ignore[assignment]


_NO_PARAMETERS = _NoParameters()


def read_lines(text: str) -> list[Line]:
    """Every line of a program (line numbers count from 1), blank ones left out."""
    if not isinstance(text, str):
        raise GcodeError(0, "program", "must be G-code text")
    lines = []
    percent = 0
    for n, raw in enumerate(text.splitlines(), start=1):
        if raw.strip() == "%":
            percent += 1
            if percent == 2 or lines:
                break  # LinuxCNC reads no further than the closing %
            continue
        line = read_line(raw, n)
        if line is not None:
            lines.append(line)
    return lines


def closed_by_percent(text: str) -> bool:
    """Whether the program opens and closes with ``%`` lines, which end it as M2 does."""
    marks = [k for k, raw in enumerate(text.splitlines()) if raw.strip() == "%"]
    first = next((k for k, raw in enumerate(text.splitlines()) if raw.strip()), -1)
    return len(marks) >= 2 and marks[0] == first
