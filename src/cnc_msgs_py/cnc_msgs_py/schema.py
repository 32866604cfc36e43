"""A small declarative validator: field specs that check, default and convert to SI.

Each spec validates one value at a field path and returns it converted to SI units, so
a validated job needs no further unit handling. Errors are JobError("path: reason").
"""
from __future__ import annotations

import math
import re
from dataclasses import dataclass
from types import SimpleNamespace
from typing import Any

from .units import CONVERTERS

REQUIRED = object()


class JobError(ValueError):
    """A job document is invalid; ``field`` is the path of the offending field."""

    def __init__(self, field: str, reason: str) -> None:
        super().__init__(f"{field}: {reason}" if field else reason)
        self.field = field
        self.reason = reason


SHOW_CHARS = 60  # a rejected value is quoted up to this long, so a reason stays one short line


def _is_number(value: Any) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool)


def _finite(value: int | float) -> bool:
    """Finite and representable as a float (an integer of 400 digits is neither)."""
    try:
        return math.isfinite(value)
    except OverflowError:
        return False


def show(value: Any) -> str:
    """A value as quoted in a reason: repr (escapes newlines), cut short if long."""
    try:
        text = repr(value)
    except ValueError:  # an int too long for repr
        text = f"<{type(value).__name__}>"
    return text if len(text) <= SHOW_CHARS else text[: SHOW_CHARS - 3] + "..."


def _key(key: Any) -> str:
    """A mapping key as written in a field path; escaped (repr) if it would break the line."""
    text = str(key)
    if text.isprintable() and 0 < len(text) <= SHOW_CHARS:
        return text
    return show(text)


@dataclass(frozen=True)
class Num:
    """A finite number in a declared unit, with optional bounds (in that unit)."""

    unit: str = "1"
    default: Any = REQUIRED
    min: float | None = None
    max: float | None = None
    gt: float | None = None
    integer: bool = False

    def check(self, value: Any, path: str) -> Any:
        unit = "" if self.unit == "1" else f" {self.unit}"
        if not _is_number(value):
            raise JobError(path, f"expected a number{f' ({self.unit})' if unit else ''}, got {show(value)}")
        if not _finite(value):
            raise JobError(path, f"must be finite, got {show(value) if isinstance(value, float) else 'a huge number'}")
        if self.integer and value != int(value):
            raise JobError(path, f"expected a whole number, got {value}")
        if self.gt is not None and not value > self.gt:
            raise JobError(path, f"must be > {self.gt:g}{unit}, got {value:g}")
        if self.min is not None and value < self.min:
            raise JobError(path, f"must be >= {self.min:g}{unit}, got {value:g}")
        if self.max is not None and value > self.max:
            raise JobError(path, f"must be <= {self.max:g}{unit}, got {value:g}")
        return int(value) if self.integer else CONVERTERS[self.unit](float(value))


@dataclass(frozen=True)
class Str:
    """A string, optionally one of fixed choices or matching a pattern."""

    choices: tuple[str, ...] | None = None
    pattern: str | None = None
    default: Any = REQUIRED

    def check(self, value: Any, path: str) -> Any:
        if not isinstance(value, str):
            raise JobError(path, f"expected a string, got {show(value)}")
        if self.choices is not None and value not in self.choices:
            raise JobError(path, f"expected one of {', '.join(self.choices)}; got {show(value)}")
        if self.pattern is not None and not re.fullmatch(self.pattern, value):
            raise JobError(path, f"{show(value)} does not match {self.pattern}")
        return value


@dataclass(frozen=True)
class Bool:
    default: Any = REQUIRED

    def check(self, value: Any, path: str) -> Any:
        if not isinstance(value, bool):
            raise JobError(path, f"expected true or false, got {show(value)}")
        return value


@dataclass(frozen=True)
class Either:
    """One of several specs, tried in order (e.g. ``auto`` or a mode number)."""

    options: tuple[Any, ...]
    expected: str
    default: Any = REQUIRED

    def check(self, value: Any, path: str) -> Any:
        for option in self.options:
            try:
                return option.check(value, path)
            except JobError:
                continue
        raise JobError(path, f"expected {self.expected}, got {show(value)}")


@dataclass(frozen=True)
class List:
    """A list of items with bounded length; ``length`` fixes it (points, vectors)."""

    item: Any
    min_len: int = 0
    max_len: int = 100_000
    length: int | None = None
    default: Any = REQUIRED

    def check(self, value: Any, path: str) -> Any:
        if not isinstance(value, (list, tuple)):
            raise JobError(path, f"expected a list, got {show(value)}")
        if self.length is not None and len(value) != self.length:
            raise JobError(path, f"expected {self.length} values, got {len(value)}")
        if len(value) < self.min_len:
            raise JobError(path, f"needs at least {self.min_len} entries, got {len(value)}")
        if len(value) > self.max_len:
            raise JobError(path, f"has {len(value)} entries, more than the maximum {self.max_len}")
        return [self.item.check(v, f"{path}[{i}]") for i, v in enumerate(value)]


@dataclass(frozen=True)
class Obj:
    """A mapping with known keys; unknown keys are an error, not ignored."""

    fields: dict[str, Any]
    default: Any = REQUIRED

    def check(self, value: Any, path: str) -> Any:
        if not isinstance(value, dict):
            raise JobError(path, f"expected a mapping, got {show(value)}")
        for key in value:
            if key not in self.fields:
                raise JobError(_join(path, _key(key)), f"unknown key (known: {', '.join(self.fields)})")
        out = {}
        for key, spec in self.fields.items():
            where = _join(path, key)
            if key in value and value[key] is not None:
                out[key] = spec.check(value[key], where)
            elif spec.default is REQUIRED:
                raise JobError(where, "required")
            else:
                out[key] = _default(spec)
        return SimpleNamespace(**out)


@dataclass(frozen=True)
class PointOr:
    """A point given as a list, or a mapping form of it (an arc, a hole with its own depth)."""

    point: List
    mapping: Obj
    expected: str
    default: Any = None

    def check(self, value: Any, path: str) -> Any:
        if isinstance(value, dict):
            return self.mapping.check(value, path)
        if isinstance(value, list):
            return self.point.check(value, path)
        raise JobError(path, f"expected {self.expected}, got {show(value)}")


def _default(spec: Any) -> Any:
    """Defaults are written in the spec's own unit, so they convert like input."""
    if spec.default is None:
        return None
    return spec.check(spec.default, "default")


def _join(path: str, key: str) -> str:
    return f"{path}.{key}" if path else key


def given(doc: Any, dotted: str) -> bool:
    """Whether a raw document gives a value (not null) at a dotted key path."""
    node: Any = doc
    for key in dotted.split("."):
        if not isinstance(node, dict) or node.get(key) is None:
            return False
        node = node[key]
    return True
