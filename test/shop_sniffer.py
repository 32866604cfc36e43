"""Counts every frame that crosses a shop network's switch (run inside its namespace).

The thin shell of shopnet.classify_frame: one raw packet socket on all of the switch's
ports, frames counted once (as they enter the switch, not again as they leave it). Prints
"ready" once listening; on SIGTERM or SIGINT prints its counts as one JSON line and exits.
"""
from __future__ import annotations

import json
import signal
import socket
import sys
from collections import Counter

from shopnet import classify_frame

ETH_P_ALL = 0x0003
PACKET_OUTGOING = 4
SAMPLES = 20  # foreign frames described in full


def main() -> int:
    stop = []
    for sig in (signal.SIGTERM, signal.SIGINT):
        signal.signal(sig, lambda *_: stop.append(True))
    sock = socket.socket(socket.AF_PACKET, socket.SOCK_RAW, socket.htons(ETH_P_ALL))
    sock.settimeout(0.1)
    counts: Counter[str] = Counter()
    sources: Counter[str] = Counter()
    foreign: list[str] = []
    print("ready", flush=True)
    while not stop:
        try:
            frame, address = sock.recvfrom(65535)
        except (socket.timeout, InterruptedError):
            continue
        if address[2] == PACKET_OUTGOING:
            continue
        kind, what = classify_frame(frame)
        counts[kind] += 1
        if kind == "foreign" and len(foreign) < SAMPLES:
            foreign.append(what)
        elif kind == "shop":
            sources[what] += 1
    print(json.dumps({"counts": dict(counts), "sources": dict(sources), "foreign": foreign}), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
