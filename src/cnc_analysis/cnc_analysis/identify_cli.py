"""cnc-identify BAG... --out DIR: the machine's drives fitted from recordings, written as its
description (DIR/<machine>.yaml) for CNC_MACHINE_PATH=DIR.

Exit codes: 0 written; 2 bad input (a bag that cannot be read, bags of different machines or
servo periods, no machine named in the recorded job). It parses its arguments before it
imports numpy, the bag reader or the fit (cnc_msgs_py.tool).
"""
from __future__ import annotations

import sys
import time
from pathlib import Path

from cnc_msgs_py.tool import tool_parser

TOOL = "cnc-identify"


def _fail(message: str) -> int:
    print(f"{TOOL}: {message}", file=sys.stderr)
    return 2


def main(argv: list[str] | None = None) -> int:
    parser = tool_parser(TOOL, "cnc_analysis", description="Fit each axis's servo drive (kp, feed-forward, velocity "
                         "loop, delay; friction and backlash where they show) from recorded runs of one machine and "
                         "write its description with the fitted drives: DIR/<machine>.yaml.")
    parser.add_argument("bags", nargs="+", type=Path, metavar="BAG", help="recordings (cnc-run's DIR/bag)")
    parser.add_argument("--out", type=Path, required=True, help="directory for <machine>.yaml (CNC_MACHINE_PATH)")
    args = parser.parse_args(argv)
    from cnc_msgs_py.machine import MachineError

    from .identify_file import IdentifyError, identify_bags, table, write_description

    try:
        found = identify_bags(args.bags)
        path = write_description(found, args.out, time.gmtime())
    except (IdentifyError, MachineError, FileNotFoundError, ValueError) as err:
        return _fail(str(err))
    print(table(found.machine, found.fits))
    print(f"{TOOL}: wrote {path} (plan with it: CNC_MACHINE_PATH={args.out})")
    return 0


if __name__ == "__main__":
    sys.exit(main())
