"""The plant: the drives a bridge emulates when they differ from the machine description.

A real machine never equals its description. A plant file (``cnc-run --plant``, the
bridge's ``plant`` parameter) states how the emulated drives differ: a ``drive:`` block
with the description's keys per axis (any subset; what is missing comes from the
description) and the plant-only ``noise``; ``seed`` (top level) fixes the encoder noise.

    name: soft_gain
    seed: 7
    drive:
      x: {kp: 35.0}
      z: {velocity_lag: 0.003, delay: 0.002, friction: 0.0005, backlash: 5.0e-6, noise: 1.0e-7}

The planner never reads a plant: it plans for every plant inside each drive's stated
``tolerance`` (``Tolerance`` in machine.py), and ``tolerance_corners`` names the plants it
checks its timing against.
"""
from __future__ import annotations

from dataclasses import dataclass, replace
from itertools import product
from pathlib import Path

import yaml

from cnc_msgs_py.machine import Drive, Machine, MachineError, parse_drive
from cnc_msgs_py.yaml_text import load_yaml

DESCRIPTION = "description"  # the plant's name when the bridge emulates the description itself


@dataclass(frozen=True)
class Plant:
    """The drives a bridge emulates, one per joint, and the seed of their encoder noise."""

    name: str
    drives: dict[str, Drive]
    seed: int = 0


def description_plant(machine: Machine) -> Plant:
    """The machine's own description as the plant (the bridge's default)."""
    return Plant(DESCRIPTION, dict(machine.drives))


def parse_plant(doc: object, machine: Machine, source: str = "plant") -> Plant:
    """A plant over ``machine`` from a parsed YAML document; errors name the field."""
    if not isinstance(doc, dict):
        raise MachineError(f"{source}: expected a mapping at the top level")
    unknown = [k for k in doc if k not in ("name", "seed", "drive")]
    if unknown:
        raise MachineError(f"{source}: {unknown[0]}: unknown key (name, seed, drive)")
    spec = doc.get("drive", {})
    if not isinstance(spec, dict):
        raise MachineError(f"{source}: drive: expected a mapping of axis to drive keys")
    stray = [j for j in spec if j not in machine.drives]
    if stray:
        raise MachineError(f"{source}: drive.{stray[0]}: not an axis of machine '{machine.name}'")
    seed = doc.get("seed", 0)
    if isinstance(seed, bool) or not isinstance(seed, int) or seed < 0:
        raise MachineError(f"{source}: seed: expected a whole number >= 0, got {seed!r}")
    drives = {j: parse_drive(spec[j], f"{source}: drive.{j}", base=d, plant=True) if j in spec else d
              for j, d in machine.drives.items()}
    return Plant(str(doc.get("name", source)), drives, seed)


def load_plant(path: str, machine: Machine) -> Plant:
    """The plant file at ``path`` over ``machine``; an empty path is the description itself.

    Raises:
        MachineError: the file is missing or malformed.
    """
    if not path:
        return description_plant(machine)
    try:
        doc = load_yaml(Path(path).read_text())
    except OSError as err:
        raise MachineError(f"plant file {path}: {err.strerror}") from err
    except yaml.YAMLError as err:
        raise MachineError(f"plant file {path}: not valid YAML ({err})") from err
    return parse_plant(doc, machine, source=Path(path).stem)


def outside_tolerance(machine: Machine, plant: Plant) -> list[str]:
    """Where the plant leaves its description's tolerance, one line per key (empty: inside)."""
    found = []
    for joint, described in machine.drives.items():
        real, tol = plant.drives[joint], described.tolerance
        for key in ("kp", "velocity_ff", "accel_ff", "velocity_lag"):
            lo, hi = getattr(tol, key)
            base, value = getattr(described, key), getattr(real, key)
            if not (lo * base - 1e-12 <= value <= hi * base + 1e-12):
                found.append(f"{joint}.{key}: {value:g} outside {lo * base:g}..{hi * base:g}")
        lo, hi = tol.delay
        extra = real.delay - described.delay
        if not lo - 1e-12 <= extra <= hi + 1e-12:
            found.append(f"{joint}.delay: {real.delay:g} s outside {described.delay + lo:g}..{described.delay + hi:g}")
        for key in ("backlash", "friction"):
            limit = getattr(described, key) + getattr(tol, key)
            if getattr(real, key) > limit + 1e-15:
                found.append(f"{joint}.{key}: {getattr(real, key):g} above {limit:g}")
    return found


def _corner(drive: Drive, kp: int, lag: int, ff: int, delay: int, losses: bool) -> Drive:
    """The drive at one corner of its tolerance: each range's end 0 (low) or 1 (high), the
    feed-forwards together, with or without the most backlash and friction it allows."""
    tol = drive.tolerance
    return replace(drive, kp=drive.kp * tol.kp[kp], velocity_lag=drive.velocity_lag * tol.velocity_lag[lag],
                   velocity_ff=drive.velocity_ff * tol.velocity_ff[ff], accel_ff=drive.accel_ff * tol.accel_ff[ff],
                   delay=drive.delay + tol.delay[delay], backlash=drive.backlash + (tol.backlash if losses else 0.0),
                   friction=drive.friction + (tol.friction if losses else 0.0), noise=0.0)


def lagging_corner(drive: Drive) -> Drive:
    """The drive inside the tolerance that lags its command most: least gain and feed-forward,
    the slowest velocity loop, the longest delay, the most friction and backlash."""
    return _corner(drive, kp=0, lag=1, ff=0, delay=1, losses=True)


def tolerance_corners(drive: Drive) -> list[Drive]:
    """The drives at the corners of a drive's tolerance: every combination of its lowest and
    highest gain, velocity loop, feed-forward and delay, with and without its most backlash
    and friction (where it allows any), without repeats. The response is not monotonic in
    them (more gain with a slower loop overshoots, less feed-forward lags but overshoots
    less), so the planner checks its timing against all of them."""
    tol = drive.tolerance
    losses = (False, True) if tol.backlash or tol.friction else (False,)
    corners: list[Drive] = []
    for ends in product(range(2), range(2), range(2), range(2), losses):
        corner = _corner(drive, *ends)
        if corner not in corners:
            corners.append(corner)
    return corners
