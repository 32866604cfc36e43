"""What every executable of the workspace answers like a command-line tool: --help, --version."""
from __future__ import annotations

import argparse
from importlib.metadata import version


def tool_parser(prog: str, package: str, **kwargs) -> argparse.ArgumentParser:
    """An ArgumentParser for ``prog`` with ``--version`` (the installed package's version)."""
    parser = argparse.ArgumentParser(prog=prog, **kwargs)
    parser.add_argument("--version", action="version", version=f"{prog} {version(package)}")
    return parser
