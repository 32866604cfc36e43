"""How numbers read on the report page, shared by the kinds' verdicts and tables."""
from __future__ import annotations


def mm(value) -> str:
    """A length in mm for a verdict's detail, or n/a."""
    return "n/a" if value is None else f"{value:.4f} mm"


def fixed(value, digits: int) -> str:
    """A table cell: the value with ``digits`` decimals, empty if there is none."""
    return "" if value is None else f"{value:.{digits}f}"
