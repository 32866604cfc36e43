"""YAML text to plain Python, in one place for jobs, plants and work offsets: libyaml's C
loader where PyYAML was built with it (yaml.__with_libyaml__), else the pure-Python one.
The same safe subset either way (SafeConstructor); the C parser reads a 300-hole plate's
job about ten times faster (docs/benchmarks.md, issue 43).
"""
from __future__ import annotations

from typing import Any

import yaml

LOADER = getattr(yaml, "CSafeLoader", yaml.SafeLoader)


def load_yaml(text: str) -> Any:
    """``text`` as yaml.safe_load reads it.

    Raises:
        yaml.YAMLError: not YAML.
    """
    return yaml.load(text, Loader=LOADER)  # noqa: S506 - a safe loader, C or Python
