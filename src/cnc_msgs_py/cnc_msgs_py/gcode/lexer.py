"""RS274/NGC lines into blocks of words, as LinuxCNC 2.9 reads them.

Spaces inside a line mean nothing, letters are case-insensitive, comments are ``( ... )``
(not nested) or ``;`` to the end of the line, a line of ``%`` marks the file's ends. What
this front end does not evaluate (parameters ``#``, expressions ``[ ]``, polar ``^`` ``@``,
block delete ``/``, O-word control flow other than ``sub``/``endsub``) is refused by line
and word, never skipped.
"""
from __future__ import annotations

import re
from dataclasses import dataclass, field

from ..schema import JobError

LETTERS = set("ABCDEFGHIJKLMNPQRSTUVWXYZ")
# A number as RS274/NGC writes it: optional sign, digits with an optional decimal point.
NUMBER = re.compile(r"[+-]?(\d+\.?\d*|\.\d+)")
O_WORD = re.compile(r"O(\d+)(SUB|ENDSUB|CALL)?$")
NOT_EVALUATED = {"#": "parameters are not evaluated by this front end",
                 "[": "expressions are not evaluated by this front end",
                 "^": "polar coordinates are not supported",
                 "@": "polar coordinates are not supported",
                 "/": "block delete is not supported"}


class GcodeError(JobError):
    """A program refused at a line: its field is ``line N`` and its reason ``<word>: <why>``."""

    def __init__(self, line: int, word: str, reason: str) -> None:
        super().__init__(f"line {line}", f"{word}: {reason}")
        self.line = line
        self.word = word


@dataclass
class Block:
    """One line's words. ``g`` and ``m`` keep their order; other letters map to their value."""

    line: int
    g: list[float] = field(default_factory=list)
    m: list[float] = field(default_factory=list)
    words: dict[str, float] = field(default_factory=dict)
    comments: list[str] = field(default_factory=list)
    o_word: tuple[int, str] | None = None  # (number, 'sub' | 'endsub' | 'call')
    number: int | None = None  # N

    def has_axes(self) -> bool:
        return any(k in self.words for k in "XYZ")


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


def read_block(text: str, line: int) -> Block | None:
    """One line as a Block; None for a blank or comment-only line or a ``%`` line."""
    code, comments = _strip_comments(text, line)
    code = "".join(code.split()).upper()
    if code == "%":
        return None
    block = Block(line, comments=comments)
    if not code:
        return block if comments else None
    for mark, why in NOT_EVALUATED.items():
        if mark in code:
            raise GcodeError(line, mark, why)
    if code.startswith("O"):
        o = O_WORD.match(code)
        if o is None or o.group(2) is None:
            raise GcodeError(line, code[:12], "O-word control flow other than sub/endsub/call is not supported")
        block.o_word = (int(o.group(1)), o.group(2).lower())
        return block
    k = 0
    while k < len(code):
        letter = code[k]
        if letter not in LETTERS:
            raise GcodeError(line, letter, "not a G-code word letter")
        number = NUMBER.match(code, k + 1)
        if number is None:
            raise GcodeError(line, letter, "needs a number after the letter")
        value = float(number.group(0))
        k = number.end()
        if letter == "G":
            block.g.append(value)
        elif letter == "M":
            block.m.append(value)
        elif letter == "N":
            if block.number is not None or block.g or block.m or block.words:
                raise GcodeError(line, word_text("N", value), "a line number must come first, once")
            block.number = int(value)
        elif letter in block.words:
            raise GcodeError(line, word_text(letter, value), f"{letter} given twice in one line")
        else:
            block.words[letter] = value
    return block


def read_program(text: str) -> list[Block]:
    """Every line of a program as blocks (line numbers count from 1); stops at M2/M30's line
    is the interpreter's business, not the reader's."""
    if not isinstance(text, str):
        raise GcodeError(0, "program", "must be G-code text")
    blocks = []
    for n, raw in enumerate(text.splitlines(), start=1):
        block = read_block(raw, n)
        if block is not None:
            blocks.append(block)
    return blocks
