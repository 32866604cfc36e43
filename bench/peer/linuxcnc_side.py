"""Run LinuxCNC (Debian's linuxcnc-uspace, 2.9) headless on our machine limits and record it.

`ensure_installed` installs the package with apt-get if ``linuxcnc`` is missing (without
its recommends: a realtime kernel and GUI toolkits that a headless sim does not use);
`ensure_user` creates the unprivileged user (rtapi_app refuses to run as root).
`run_session` writes the generated INI/HAL, the programs and rows.json into a work
directory the user owns, starts ``linuxcnc INI`` as that user (its DISPLAY is
driver.py), and parses what ``halsampler -t`` recorded into one array set per row.
"""
from __future__ import annotations

import json
import os
import pwd
import shutil
import subprocess
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from cnc_msgs_py.machine import Machine

from config import SERVO_PERIOD_NS, channels, write_config

USER = "cncbench"
PACKAGE = "linuxcnc-uspace"
SESSION_TIMEOUT = 600.0  # s of wall time for one LinuxCNC session


def ensure_installed() -> str:
    """The installed package version; installs it with apt-get when missing."""
    if shutil.which("linuxcnc") is None or shutil.which("halsampler") is None:
        if os.geteuid() != 0:
            raise RuntimeError(f"{PACKAGE} is not installed and this is not root: apt-get install {PACKAGE}")
        env = {**os.environ, "DEBIAN_FRONTEND": "noninteractive"}
        subprocess.run(["apt-get", "update"], check=True, env=env, stdout=subprocess.DEVNULL)
        subprocess.run(["apt-get", "install", "-y", "--no-install-recommends", PACKAGE], check=True, env=env,
                       stdout=subprocess.DEVNULL)
    return installed_version()


def installed_version() -> str:
    out = subprocess.run(["dpkg-query", "-W", "-f=${Version}", PACKAGE], capture_output=True, text=True)
    return out.stdout.strip() or "unknown"


def ensure_user() -> pwd.struct_passwd:
    """The unprivileged user LinuxCNC runs as, created if missing (needs root)."""
    try:
        return pwd.getpwnam(USER)
    except KeyError:
        subprocess.run(["useradd", "-m", USER], check=True)
        return pwd.getpwnam(USER)


@dataclass
class Program:
    """One row on the LinuxCNC side: its G-code and the MDI line to its start position."""

    name: str
    start: str
    gcode: str


@dataclass
class Recording:
    """Samples of one row, SI: t (s, from the row's first sample), axis positions (m),
    spindle angle (rad) on lathes, motion.motion-type and motion.program-line per sample."""

    name: str
    t: np.ndarray
    axes: dict[str, np.ndarray]
    spindle: np.ndarray | None
    motion_type: np.ndarray
    errors: list[str] = field(default_factory=list)
    finished: bool = False
    line: np.ndarray | None = None


@dataclass
class Session:
    """What one LinuxCNC run produced."""

    recordings: dict[str, Recording]
    errors: list[str]
    samples: int
    gaps: int  # missing sample numbers (FIFO overruns)
    wall_s: float
    workdir: Path


def _chown_tree(path: Path, user: pwd.struct_passwd) -> None:
    for root, dirs, files in os.walk(path):
        os.chown(root, user.pw_uid, user.pw_gid)
        for name in files:
            os.chown(os.path.join(root, name), user.pw_uid, user.pw_gid)


def run_session(machine: Machine, programs: list[Program], workdir: Path, log=print) -> Session:
    """Run every program in one LinuxCNC session; recordings keyed by program name."""
    user = ensure_user()
    if workdir.exists():
        shutil.rmtree(workdir)
    ini = write_config(machine, workdir)
    rows = []
    for k, p in enumerate(programs, start=1):
        path = workdir / f"row{k:02d}.ngc"
        path.write_text(p.gcode)
        rows.append({"name": p.name, "marker": k, "start": p.start, "program": str(path)})
    (workdir / "rows.json").write_text(json.dumps(rows, indent=1))
    _chown_tree(workdir, user)
    env = {"PATH": "/usr/local/bin:/usr/bin:/bin", "HOME": user.pw_dir, "USER": USER, "LOGNAME": USER,
           "LANG": "C.UTF-8"}
    cmd = ["runuser", "-u", USER, "--", "env", *[f"{k}={v}" for k, v in env.items()], "linuxcnc", str(ini)]
    begin = time.monotonic()
    with open(workdir / "linuxcnc.log", "w") as out:
        proc = subprocess.Popen(cmd, cwd=workdir, stdout=out, stderr=subprocess.STDOUT, start_new_session=True)
        try:
            proc.wait(timeout=SESSION_TIMEOUT)
        except subprocess.TimeoutExpired:
            os.killpg(proc.pid, 15)
            proc.wait(timeout=30)
            raise RuntimeError(f"LinuxCNC session on {machine.name} timed out; see {workdir / 'linuxcnc.log'}")
    wall = time.monotonic() - begin
    driver_log = workdir / "driver.json"
    if not driver_log.exists():
        tail = (workdir / "linuxcnc.log").read_text()[-3000:]
        raise RuntimeError(f"LinuxCNC on {machine.name} wrote no driver.json; log tail:\n{tail}")
    status = json.loads(driver_log.read_text())
    return parse_session(machine, status, workdir, wall)


def parse_session(machine: Machine, status: dict, workdir: Path, wall: float) -> Session:
    """Split samples.txt into rows by the marker channel (M68 E0 Q<row>); driver.json's status."""
    chans = channels(machine)
    cols = {c.name: k + 1 for k, c in enumerate(chans)}
    raw = np.loadtxt(workdir / "samples.txt", ndmin=2) if (workdir / "samples.txt").stat().st_size else \
        np.zeros((0, len(chans) + 1))
    n = raw[:, 0].astype(np.int64) if len(raw) else np.zeros(0, dtype=np.int64)
    gaps = int(np.sum(np.diff(n) - 1)) if len(n) > 1 else 0
    marker = np.rint(raw[:, cols["marker"]]).astype(int) if len(raw) else np.zeros(0, dtype=int)
    period = SERVO_PERIOD_NS * 1e-9
    recordings = {}
    for row in status["rows"]:
        sel = marker == row["marker"]
        if not np.any(sel):
            recordings[row["name"]] = None
            continue
        idx = n[sel]
        axes = {ax: raw[sel, cols[ax]] * 1e-6 for ax in machine.linear_axes}  # um -> m
        spindle = raw[sel, cols["spindle_revs"]] * 2.0 * np.pi if "spindle_revs" in cols else None
        recordings[row["name"]] = Recording(
            name=row["name"], t=(idx - idx[0]) * period, axes=axes, spindle=spindle,
            motion_type=raw[sel, cols["motion_type"]].astype(int), errors=row["errors"],
            finished=bool(row["finished"]), line=raw[sel, cols["line"]].astype(int))
    return Session(recordings, status.get("errors", []), len(n), gaps, wall, workdir)
