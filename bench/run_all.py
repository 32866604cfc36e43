"""`make bench`: rerun every benchmark; each prints its table and keeps it in bench/results/."""
from __future__ import annotations

import subprocess
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
BENCHES = ("drill_cycle.py", "deep_holes.py", "vibration_speed.py", "turning_air.py", "thread_chips.py",
           "thread_bound.py", "path_5ax.py", "load.py", "memory.py", "plants.py", "startup.py")


def main() -> int:
    failed = []
    for name in BENCHES:
        print(f"== {name}", flush=True)
        start = time.monotonic()
        if subprocess.run([sys.executable, str(HERE / name)]).returncode != 0:
            failed.append(name)
        print(f"({time.monotonic() - start:.0f} s)\n", flush=True)
    if failed:
        print(f"failed: {', '.join(failed)}", file=sys.stderr)
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
