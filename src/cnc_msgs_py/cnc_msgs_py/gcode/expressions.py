"""RS274/NGC values as LinuxCNC 2.9 reads them: numbers, parameters, ``[expressions]``, functions.

A line is read once into closures (``Expr``) and evaluated each time it runs, so a loop
body is parsed once. Binary operators bind as LinuxCNC's ``precedence()`` says, left to
right within a level: ``**`` over ``* / MOD`` over ``+ -`` over ``EQ NE GT GE LT LE`` over
``AND OR XOR``. EQ and NE compare within 0.0001 (LinuxCNC's TOLERANCE_EQUAL); MOD's result
takes the divisor's sign away (fmod, then + |b| when negative); trigonometry is in degrees;
ROUND rounds halves away from zero; FIX and FUP are floor and ceiling.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Callable, Protocol

TOLERANCE_EQUAL = 0.0001


class Env(Protocol):
    """Where values come from when a line runs (``parameters.Parameters``)."""

    def read(self, number: float) -> float: ...

    def read_named(self, name: str) -> float: ...

    def exists(self, name: str) -> bool: ...


Expr = Callable[[Env], float]


class ExprError(ValueError):
    """A value that cannot be read or evaluated: ``word`` is what the reason quotes."""

    def __init__(self, word: str, reason: str, needs_start: bool = False) -> None:
        super().__init__(reason)
        self.word = word
        self.reason = reason
        self.needs_start = needs_start  # as GcodeError's


def _div(a: float, b: float) -> float:
    if b == 0.0:
        raise ExprError("/", "division by zero")
    return a / b


def _mod(a: float, b: float) -> float:
    if b == 0.0:
        raise ExprError("MOD", "modulo by zero")
    r = math.fmod(a, b)
    return r + abs(b) if r < 0.0 else r


def _pow(a: float, b: float) -> float:
    if a < 0.0 and b != math.floor(b):
        raise ExprError("**", f"a negative number ({a:g}) to a non-integer power ({b:g})")
    try:
        return a ** b
    except (OverflowError, ZeroDivisionError):
        raise ExprError("**", f"{a:g}**{b:g} has no finite value") from None


BINARY: dict[str, tuple[int, Callable[[float, float], float]]] = {
    "**": (6, _pow),
    "*": (5, lambda a, b: a * b), "/": (5, _div), "MOD": (5, _mod),
    "+": (4, lambda a, b: a + b), "-": (4, lambda a, b: a - b),
    "EQ": (3, lambda a, b: float(abs(a - b) < TOLERANCE_EQUAL)),
    "NE": (3, lambda a, b: float(abs(a - b) >= TOLERANCE_EQUAL)),
    "GT": (3, lambda a, b: float(a > b)), "GE": (3, lambda a, b: float(a >= b)),
    "LT": (3, lambda a, b: float(a < b)), "LE": (3, lambda a, b: float(a <= b)),
    "AND": (2, lambda a, b: float(a != 0.0 and b != 0.0)),
    "OR": (2, lambda a, b: float(a != 0.0 or b != 0.0)),
    "XOR": (2, lambda a, b: float((a != 0.0) != (b != 0.0))),
}
# longest first, so that ** is not read as *, GE not as G..., etc.
OPERATORS = sorted(BINARY, key=len, reverse=True)


def _domain(name: str, ok: Callable[[float], bool], f: Callable[[float], float], what: str) -> Callable[[float], float]:
    def run(x: float) -> float:
        if not ok(x):
            raise ExprError(name, f"{x:g} is {what}")
        return f(x)
    return run


def _round(x: float) -> float:
    return float(math.floor(x + 0.5) if x >= 0.0 else -math.floor(-x + 0.5))


UNARY: dict[str, Callable[[float], float]] = {
    "ABS": abs,
    "ACOS": _domain("ACOS", lambda x: -1.0 <= x <= 1.0, lambda x: math.degrees(math.acos(x)), "outside -1..1"),
    "ASIN": _domain("ASIN", lambda x: -1.0 <= x <= 1.0, lambda x: math.degrees(math.asin(x)), "outside -1..1"),
    "COS": lambda x: math.cos(math.radians(x)),
    "SIN": lambda x: math.sin(math.radians(x)),
    "TAN": lambda x: math.tan(math.radians(x)),
    "EXP": _domain("EXP", lambda x: x < 709.0, math.exp, "too large"),
    "FIX": lambda x: float(math.floor(x)),
    "FUP": lambda x: float(math.ceil(x)),
    "ROUND": _round,
    "LN": _domain("LN", lambda x: x > 0.0, math.log, "not > 0"),
    "SQRT": _domain("SQRT", lambda x: x >= 0.0, math.sqrt, "negative"),
}
FUNCTIONS = sorted([*UNARY, "ATAN", "EXISTS"], key=len, reverse=True)


@dataclass
class Reader:
    """A cursor over one line's code (upper case, no spaces, no comments)."""

    text: str
    k: int = 0

    def peek(self, n: int = 1) -> str:
        return self.text[self.k:self.k + n]

    def done(self) -> bool:
        return self.k >= len(self.text)

    def expect(self, ch: str, what: str) -> None:
        if self.peek() != ch:
            got = self.peek() or "end of line"
            raise ExprError(ch, f"expected {ch!r} {what}, found {got!r}")
        self.k += 1


def read_name(r: Reader) -> str:
    """``<name>`` after a ``#`` or an ``O``: lower case, as LinuxCNC prints it."""
    r.expect("<", "to open a name")
    end = r.text.find(">", r.k)
    if end < 0:
        raise ExprError("<", "a name is not closed with '>'")
    name = r.text[r.k:end].lower()
    if not name:
        raise ExprError("<>", "an empty name")
    r.k = end + 1
    return name


def read_parameter(r: Reader) -> Expr:
    """``#n``, ``#<name>``, ``#[expr]`` or ``##n``: the parameter's value when it runs."""
    r.expect("#", "for a parameter")
    if r.peek() == "<":
        name = read_name(r)
        return lambda env: env.read_named(name)
    index = read_value(r)
    return lambda env: env.read(index(env))


def parameter_target(r: Reader) -> Callable[[Env], int | str]:
    """What ``#...=`` writes: a number (evaluated when the line runs) or a name."""
    r.expect("#", "for a parameter")
    if r.peek() == "<":
        name = read_name(r)
        return lambda env: name
    index = read_value(r)
    return lambda env: index(env)


def _number(r: Reader) -> Expr:
    start = r.k
    if r.peek() in "+-":
        r.k += 1
    digits = 0
    while r.peek().isdigit():
        r.k += 1
        digits += 1
    if r.peek() == ".":
        r.k += 1
        while r.peek().isdigit():
            r.k += 1
            digits += 1
    if digits == 0:
        r.k = start
        got = r.peek() or "end of line"
        raise ExprError(got, "expected a number, a parameter or an expression")
    value = float(r.text[start:r.k])
    return lambda env: value


def _function(r: Reader, name: str) -> Expr:
    r.k += len(name)
    if name == "EXISTS":
        r.expect("[", "after EXISTS")
        if r.peek(2) != "#<":
            raise ExprError("EXISTS", "takes a named parameter, as EXISTS[#<name>]")
        r.k += 1
        target = read_name(r)
        r.expect("]", "to close EXISTS")
        return lambda env: float(env.exists(target))
    if r.peek() != "[":
        raise ExprError(name, f"needs its argument in brackets, as {name}[...]")
    arg = read_expression(r)
    if name == "ATAN":
        if r.peek() != "/":
            raise ExprError("ATAN", "is written ATAN[y]/[x]")
        r.k += 1
        if r.peek() != "[":
            raise ExprError("ATAN", "is written ATAN[y]/[x]")
        x = read_expression(r)
        return lambda env: math.degrees(math.atan2(arg(env), x(env)))
    f = UNARY[name]
    return lambda env: f(arg(env))


def read_value(r: Reader) -> Expr:
    """A real value: a number, a parameter, an expression, a function, or one of those
    after a unary minus or plus (LinuxCNC 2.9 takes ``-#1`` and ``-[...]``)."""
    c = r.peek()
    if c == "[":
        return read_expression(r)
    if c == "#":
        return read_parameter(r)
    if c in "+-" and r.peek(2)[1:] not in "0123456789.":
        r.k += 1
        inner = read_value(r)
        return (lambda env: -inner(env)) if c == "-" else inner
    if c.isalpha():
        name = next((f for f in FUNCTIONS if r.text.startswith(f, r.k)), None)
        if name is None:
            raise ExprError(c, "not a function (ABS ACOS ASIN ATAN COS EXISTS EXP FIX FUP LN ROUND SIN SQRT TAN)")
        return _function(r, name)
    return _number(r)


def read_expression(r: Reader) -> Expr:
    """``[ value (operator value)* ]`` folded by LinuxCNC's precedence, left to right."""
    r.expect("[", "to open an expression")
    values = [read_value(r)]
    ops: list[str] = []
    while True:
        if r.done():
            raise ExprError("[", "an expression is not closed with ']'")
        if r.peek() == "]":
            r.k += 1
            break
        op = next((o for o in OPERATORS if r.text.startswith(o, r.k)), None)
        if op is None:
            raise ExprError(r.peek(), "expected an operator (** * / MOD + - EQ NE GT GE LT LE AND OR XOR) or ']'")
        r.k += len(op)
        ops.append(op)
        values.append(read_value(r))
    return _fold(values, ops)


def _fold(values: list[Expr], ops: list[str]) -> Expr:
    """Shunting-yard over precedence levels: equal levels fold left to right."""
    out: list[Expr] = [values[0]]
    stack: list[str] = []

    def reduce() -> None:
        op = stack.pop()
        b, a = out.pop(), out.pop()
        f = BINARY[op][1]
        out.append(lambda env, a=a, b=b, f=f: f(a(env), b(env)))

    for op, value in zip(ops, values[1:]):
        while stack and BINARY[stack[-1]][0] >= BINARY[op][0]:
            reduce()
        stack.append(op)
        out.append(value)
    while stack:
        reduce()
    return out[0]
