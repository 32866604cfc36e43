"""Where every benchmark keeps its latest output: bench/results/, beside the scripts."""
from __future__ import annotations

from pathlib import Path

RESULTS = Path(__file__).resolve().parent / "results"


def write_result(name: str, text: str) -> Path:
    """Keep a benchmark's table (or figure path name) in bench/results/; returns its path."""
    RESULTS.mkdir(parents=True, exist_ok=True)
    path = RESULTS / name
    path.write_text(text.rstrip("\n") + "\n")
    return path
