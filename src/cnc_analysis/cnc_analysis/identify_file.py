"""cnc-identify's shell around the fit (identify.py): which machine the bags recorded, its
description file, and that description written back with the fitted drives."""
from __future__ import annotations

import json
import textwrap
import time
from dataclasses import dataclass
from pathlib import Path

import yaml

from cnc_msgs_py.machine import Drive, Machine, load_machine, machine_dirs

from .identify import AxisFit, Trace, identify, trace
from .recording import read_run

TOLERANCE_NOTE = ("Tolerance narrowed to what identification leaves open: kp and velocity_lag +-2 %, feed-forward "
                  "+-0.5 %, delay exact, identified backlash and friction +10 % (docs/machines.md, Commissioning a real "
                  "machine)")


class IdentifyError(ValueError):
    """The recordings cannot be identified together; the message says why."""


@dataclass
class Identified:
    """One machine identified from its recordings: its description file, the traces (with
    what each recorded: job and plant) and each axis's fit."""

    machine: Machine
    source: Path
    traces: list[Trace]
    recorded: dict[str, str]
    fits: dict[str, AxisFit]


def description_file(name: str) -> Path:
    """The file ``load_machine(name)`` reads: the first in machine_dirs()."""
    for folder in machine_dirs():
        if (folder / f"{name}.yaml").is_file():
            return folder / f"{name}.yaml"
    load_machine(name)  # raises the lookup's own MachineError
    raise IdentifyError(f"machine '{name}': no description file")


def _machine_named(bag: Path, goals: list[str]) -> str:
    """The machine the recorded job goals name: one, or an error."""
    names = set()
    for goal in goals:
        try:
            doc = json.loads(goal)
        except json.JSONDecodeError as err:
            raise IdentifyError(f"{bag}: a recorded job_goal is not JSON ({err})") from err
        if not isinstance(doc, dict) or not isinstance(doc.get("machine"), str):
            raise IdentifyError(f"{bag}: a recorded job_goal names no machine")
        names.add(doc["machine"])
    if not names:
        raise IdentifyError(f"{bag}: no job_goal recorded, so no machine named")
    if len(names) > 1:
        raise IdentifyError(f"{bag}: jobs of several machines ({', '.join(sorted(names))})")
    return names.pop()


def identify_bags(bags: list[Path]) -> Identified:
    """Read every bag (all of one machine) and fit its axes over all of them together."""
    runs, named, recorded = [], {}, {}
    for bag in bags:
        run = read_run(bag)
        named[bag] = _machine_named(bag, run.goals)
        jobs = ", ".join(str(json.loads(g).get("job_id")) for g in run.goals)
        recorded[str(bag)] = f"job {jobs}" + (f", plant {run.plant}" if run.plant else "")
        runs.append(run)
    machines = set(named.values())
    if len(machines) > 1:
        listed = ", ".join(f"{bag}: {name}" for bag, name in named.items())
        raise IdentifyError(f"the bags recorded different machines ({listed}): identify one machine at a time")
    name = machines.pop()
    source = description_file(name)
    machine = load_machine(str(source))
    traces = [trace(run, machine, str(bag)) for bag, run in zip(bags, runs)]
    return Identified(machine, source, traces, recorded, identify(traces, machine))


def _drive_doc(drive: Drive, original: dict) -> dict:
    """A drive block as the description writes it: the original's keys, the fitted values."""
    doc = {k: getattr(drive, k) for k in ("kp", "velocity_ff", "accel_ff", "velocity_lag")}
    doc.update({k: original[k] for k in ("resolution", "following_error_limit")})
    doc["delay"] = float(f"{drive.delay:.9g}")
    for key in ("backlash", "friction"):
        if getattr(drive, key) > 0.0 or key in original:
            doc[key] = getattr(drive, key)
    tol = drive.tolerance
    doc["tolerance"] = {"kp": list(tol.kp), "velocity_ff": list(tol.velocity_ff), "accel_ff": list(tol.accel_ff),
                        "velocity_lag": list(tol.velocity_lag), "delay": list(tol.delay),
                        "backlash": tol.backlash, "friction": tol.friction}
    return doc


def _residual(fit: AxisFit) -> str:
    (d_max, d_rms), (f_max, f_rms) = fit.residual_described, fit.residual_fitted
    return f"{f_max:.3f} / {f_rms:.3f} fitted (described {d_max:.1f} / {d_rms:.1f})"


def header(found: Identified, when: time.struct_time) -> str:
    """The comment a fitted description opens with: from which bags, when, how well."""
    lines = [f"{found.machine.name}: drives identified by cnc-identify on "
             f"{time.strftime('%Y-%m-%d %H:%M UTC', when)} from"]
    lines += [f"  {tr.name} ({found.recorded.get(tr.name, '')}, {len(tr.y) * tr.period:.1f} s)" for tr in found.traces]
    lines.append("simulated minus recorded feedback, max / RMS um (urad on rotary axes):")
    for joint, fit in found.fits.items():
        lines.append(f"  {joint}: {_residual(fit)}" if fit.drive is not None
                     else f"  {joint}: not identified ({fit.note}): the described drive kept")
    lines += textwrap.wrap("The spindle as described. " + TOLERANCE_NOTE, 90)
    return "".join(f"# {line}\n" for line in lines)


def write_description(found: Identified, out: Path, when: time.struct_time) -> Path:
    """The whole description with the fitted drives as ``out/<machine>.yaml``, checked to
    load back."""
    doc = yaml.safe_load(found.source.read_text())
    for joint, fit in found.fits.items():
        if fit.drive is not None:
            doc["drive"][joint] = _drive_doc(fit.drive, doc["drive"][joint])
    out.mkdir(parents=True, exist_ok=True)
    path = out / f"{found.machine.name}.yaml"
    text = yaml.safe_dump(doc, sort_keys=False, default_flow_style=None, width=140)
    path.write_text(header(found, when) + text)
    load_machine(str(path))
    return path


def table(machine: Machine, fits: dict[str, AxisFit]) -> str:
    """Described against fitted values, per axis, and the residual of each."""
    rows = [f"{'axis':<5} {'':<17} {'described':>12} {'fitted':>12}"]
    scaled = (("kp", "kp 1/s", 1.0), ("velocity_ff", "velocity_ff", 1.0), ("accel_ff", "accel_ff", 1.0),
              ("velocity_lag", "velocity_lag ms", 1e3), ("delay", "delay ms", 1e3), ("friction", "friction mm/s", 1e3),
              ("backlash", "backlash um", 1e6))
    for joint, fit in fits.items():
        described = machine.drives[joint]
        if fit.drive is None:
            rows.append(f"{joint:<5} not identified: {fit.note}")
            continue
        for i, (key, label, scale) in enumerate(scaled):
            shown = f"{getattr(fit.drive, key) * scale:>12.6g}"
            if key == "backlash" and not fit.backlash_identified:
                shown = f"{'not seen':>12}"
            rows.append(f"{joint if i == 0 else '':<5} {label:<17} {getattr(described, key) * scale:>12.6g} {shown}")
        if fit.backlash_identified:
            rows.append(f"{'':<5} {'encoder noise um':<17} {'':>12} {fit.noise * 1e6:>12.3g}")
        (d_max, d_rms), (f_max, f_rms) = fit.residual_described, fit.residual_fitted
        rows.append(f"{'':<5} {'residual max um':<17} {d_max:>12.3f} {f_max:>12.3f}")
        rows.append(f"{'':<5} {'residual RMS um':<17} {d_rms:>12.3f} {f_rms:>12.3f}")
        rows.append(f"{'':<5} {'servo periods':<17} {'':>12} {fit.samples:>12d}")
    if any(machine.axes[j].type != "linear" for j in fits):
        rows.append("rotary axes in rad: mm read mrad, um read urad")
    return "\n".join(rows)
