"""`make bench-peer`: the same jobs on LinuxCNC 2.9 and on our planner, one table.

LinuxCNC (Debian's linuxcnc-uspace, installed with apt-get if missing) runs headless as
an unprivileged user on INI/HAL files generated from config/machines/mill3.yaml and
lathe.yaml (velocity and acceleration limits exactly ours; 2.9 plans without a jerk
limit), driven by bench/peer/driver.py, every joint position recorded each 1 ms servo
period with HAL's sampler and halsampler -t. Our side runs the same job documents through
both nodes over topics (bench/peer/ours.py: bridge and planner as cnc-run starts them,
every topic recorded), on the normal jerk-limited machine and on a "fair race" copy whose
jerk limit is so high that our profiles are trapezoids too, and judges the recorded
feedback; the offline prediction of the fair run is printed beside it. LinuxCNC's
recording goes through our drive model; both go through the same analysis code
(bench/peer/analysis.py). While LinuxCNC runs (in real time, about 5 minutes), our side runs.

    .venv/bin/python bench/peer/run.py [--keep DIR] [--reuse DIR] [--only REGEX]

--keep DIR keeps LinuxCNC's work directories (configs, programs, samples) in DIR;
--reuse DIR analyses the sessions kept there instead of running LinuxCNC again;
--only REGEX runs the rows whose name matches. Writes bench/results/peer.txt (--only deep
replaces just its deep-hole section, --only bolt_circle just the parameterised program's:
test/programs/bolt_circle_while.ngc, bench/peer/parameterised.py).
"""
from __future__ import annotations

import argparse
import json
import re
import shutil
import sys
import tempfile
import threading
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parents[1]
sys.path[:0] = [str(HERE), str(ROOT / "bench")] + [str(ROOT / "src" / p) for p in ("cnc_msgs_py", "cnc_analysis", "cnc_planner", "cnc_servo_bridge")]

import numpy as np  # noqa: E402

from cnc_msgs_py.job import parse_job  # noqa: E402
from cnc_msgs_py.machine import load_machine  # noqa: E402
from cnc_planner.kinds.drill.bound import lower_bound_time  # noqa: E402
from cnc_planner.kinds.drill.block import drill_cycle  # noqa: E402
from cnc_planner.kinematics import Kinematics  # noqa: E402

import analysis  # noqa: E402
import deep_holes  # noqa: E402
import gcode  # noqa: E402
import linuxcnc_side  # noqa: E402
import oracle  # noqa: E402
import ours  # noqa: E402
import parameterised  # noqa: E402
import programs  # noqa: E402
from rows import THREAD_CLEARANCE_MM, Row, all_rows  # noqa: E402

RESULTS = ROOT / "bench" / "results" / "peer.txt"


def mdi_start(start: dict[str, float]) -> str:
    return "G0 " + " ".join(f"{k.upper()}{v:.4f}" for k, v in start.items())


def programs_for(row: Row) -> list[tuple[str, linuxcnc_side.Program]]:
    """(variant, program) pairs of a row on the LinuxCNC side."""
    start = mdi_start(row.start)
    if row.kind == "drill":
        return [(v, linuxcnc_side.Program(f"{row.name} {v}", start, gcode.drill_program(row.name, row.doc, v)))
                for v in ("G99", "G98")]
    if row.kind == "deep":
        return [("G83", linuxcnc_side.Program(f"{row.name} G83", start, gcode.peck_program(row.name, row.doc)))]
    if row.kind == "thread":
        text = gcode.thread_program(row.name, row.doc, THREAD_CLEARANCE_MM, back_to_start=True)
        return [("G76", linuxcnc_side.Program(f"{row.name} G76", start, text))]
    return [("G71", linuxcnc_side.Program(f"{row.name} G71", start, gcode.turn_program(row.name, row.doc)))]


def run_linuxcnc(rows: list[Row], prows: list, workroot: Path, reuse: bool, out: dict, log) -> None:
    """Both sessions (mill3, lathe), one after the other, the generated rows then the program
    files; fills out[machine] or out['error']."""
    try:
        workroot.mkdir(parents=True, exist_ok=True)
        workroot.chmod(0o755)  # the unprivileged user must reach its work directories
        for name in ("mill3", "lathe"):
            mine = [r for r in rows if r.machine == name]
            files = [p.linuxcnc_program() for p in prows if p.machine == name]
            if not mine and not files:
                continue
            progs = [p for r in mine for _, p in programs_for(r)] + files
            workdir = workroot / name
            if reuse:
                status = json.loads((workdir / "driver.json").read_text())
                wall = status.get("finished", 0.0) - status.get("started", 0.0)  # the driver's part of it
                out[name] = linuxcnc_side.parse_session(load_machine(name), status, workdir, wall)
            else:
                log(f"LinuxCNC {name}: {len(progs)} programs ...")
                out[name] = linuxcnc_side.run_session(load_machine(name), progs, workdir)
                s = out[name]
                log(f"LinuxCNC {name}: done in {s.wall_s:.0f} s, {s.samples} samples, {s.gaps} lost")
    except Exception as err:  # noqa: BLE001 - reported in the table's notes
        out["error"] = f"{type(err).__name__}: {err}"


def our_side(row: Row, variants: dict) -> dict:
    """Our figures for one row on both machine descriptions (a deep-hole row: on the normal
    one, its plan run through the drive model, as bench/deep_holes.py judges it)."""
    if row.kind == "deep":
        _, cycle, chip, _, _ = deep_holes.judge(row.doc)  # over topics; asserts no violations
        return {"jerk": {"time": cycle, "chip": chip, "viol": 0}}
    res = {}
    for key, machine in variants[row.machine].items():
        o = ours.run_over_topics(row.doc, machine, row.start)
        res[key] = judge(row, o["t"], o["axes"], o["spindle"], machine)
        predicted = ours.run(row.doc, machine, row.start)
        res[key]["predicted"] = judge(row, predicted["t"], predicted["axes"], predicted["spindle"], machine)["time"]
        if row.reference_doc is not None:
            ref = ours.run_over_topics(row.reference_doc, machine, row.start)
            res[key + "_plain"] = judge(row, ref["t"], ref["axes"], ref["spindle"], machine)
    return res


def judge(row: Row, t, axes, spindle, machine) -> dict:
    """The row's figures from sampled positions (SI), whoever recorded them."""
    if row.kind == "drill":
        job = parse_job({**row.doc, "machine": machine.name})
        cycle = drill_cycle(job, machine, Kinematics(machine, job.setup, job.tool))
        a = analysis.drilling(t, axes, cycle)
        off, low = analysis.off_hole(axes, cycle)
        depths = [h.get("depth_mm") for h in a["holes"]]
        depth_um = (max(abs(d - row.doc["drill"]["depth"]) for d in depths) * 1e3
                    if depths and None not in depths else None)
        return {"time": a["cycle_time_s"], "viol": a["safety_violations"], "holes": len(cycle.holes),
                "off_um": off * 1e6, "low_mm": None if low is None else low * 1e3, "depth_um": depth_um}
    if row.kind == "deep":
        if spindle is None:  # LinuxCNC's mill records no spindle: it runs at speed from M3 on
            spindle = row.doc["spindle_rpm"] * 2 * np.pi / 60.0 * np.asarray(t)
        cycle, chip, viol = deep_holes.cycle_and_chip(np.asarray(t), axes["x"], axes["y"], axes["z"], spindle)
        return {"time": cycle, "chip": chip, "viol": viol}
    if row.kind == "thread":
        a = analysis.thread(t, axes, spindle, row.doc["thread"])
        p = a["passes"]
        gaps = [b["t_start"] - e["t_end"] for e, b in zip(p, p[1:])]
        return {"time": analysis.cycle_time(t, axes), "chip": a["max_chip_revs"], "passes": a["cutting_passes"],
                "synced": a["synchronised_passes"], "depth_error_mm": a["depth_error_mm"],
                "gap_s": sum(gaps) / len(gaps) if gaps else 0.0,
                "pass_s": sum(e["t_end"] - e["t_start"] for e in p) / len(p) if p else 0.0}
    turn = row.doc["turn"]
    a = analysis.turning_air(t, axes, turn["stock"], turn["feed"] * row.doc["spindle_rpm"])
    return {"time": analysis.cycle_time(t, axes), "air": a["air_share"], "feed_mm": a["feed_mm"],
            "air_mm": a["air_feed_mm"], "rapid_cut_mm": a["rapid_cut_mm"]}


def linuxcnc_figures(row: Row, sessions: dict) -> dict:
    """Per variant: figures on our drive model's feedback ('fb') and on the raw recording."""
    out = {}
    session = sessions.get(row.machine)
    machine = load_machine(row.machine)
    for variant, prog in programs_for(row):
        rec = session.recordings.get(prog.name) if session else None
        if rec is None:
            out[variant] = {"error": "not recorded"}
            continue
        if rec.errors or not rec.finished:
            out[variant] = {"error": "; ".join(rec.errors) or "did not finish"}
            continue
        fb = analysis.through_servo(rec.t, rec.axes, machine)
        out[variant] = {"fb": judge(row, rec.t, fb, rec.spindle, machine),
                        "raw": judge(row, rec.t, rec.axes, rec.spindle, machine)}
    return out


def bound(row: Row, variants: dict) -> float | None:
    if row.kind != "drill":
        return None
    machine = variants["mill3"]["fair"]
    job = parse_job({**row.doc, "machine": machine.name})
    cycle = drill_cycle(job, machine, Kinematics(machine, job.setup, job.tool))
    return lower_bound_time(machine, cycle, (row.start["x"] * 1e-3, row.start["y"] * 1e-3))


def fmt(v, spec=".3f") -> str:
    return "-" if v is None else format(v, spec)


def why(row: Row, lc: dict, fair: dict) -> str:
    """The figures behind a row: chips, air, or why the fair race went the way it did."""
    if row.kind == "drill":
        g99 = lc.get("G99", {}).get("fb")
        if not g99:
            return ""
        per_hole = (fair["time"] - g99["time"]) / fair["holes"] * 1e3
        if fair["time"] < g99["time"] and fair["viol"] == 0:
            return f"fair faster by {-per_hole:.0f} ms/hole"
        return (f"fair +{per_hole:.0f} ms/hole: G99 feeds Z past R {g99['viol'] / g99['holes']:.0f} ms/hole "
                f"before X/Y settles (up to {g99['off_um']:.0f} um off); ours keeps Z above R until X/Y is in")
    return ""


def table(rows: list[Row], lc: dict, us: dict, bounds: dict) -> list[str]:
    head = (f"{'row':<22} {'peer':>4} {'LC s':>7} {'ideal s':>7} {'safe s':>7} {'G98 s':>7} {'fair s':>7} {'pred s':>7} "
            f"{'jerk s':>7} {'bound s':>7} {'fair/LC':>7} {'jerk/LC':>7} {'f/safe':>7} {'viol LC':>9} "
            f"{'viol us':>7}  figures / why")
    lines = [head, "-" * (len(head) + 60)]
    for row in rows:
        if row.kind == "deep":
            continue  # its own table (deep_section)
        figs = lc.get(row.name, {})
        peer = {"drill": "G99", "thread": "G76", "turn": "G71"}[row.kind]
        main = figs.get(peer, {})
        fair, jerk = us[row.name]["fair"], us[row.name]["jerk"]
        lc_t = main.get("fb", {}).get("time")
        ideal = main.get("raw", {}).get("time")
        g98 = safe = None
        viol_lc = viol_us = "-"
        extra = why(row, figs, fair)
        if row.kind == "drill":
            g98 = figs.get("G98", {}).get("fb", {}).get("time")
            v99, v98 = main.get("fb", {}).get("viol"), figs.get("G98", {}).get("fb", {}).get("viol")
            safe = lc_t + v99 * 1e-3 if lc_t is not None else None
            viol_lc = f"{fmt(v99, 'd')}/{fmt(v98, 'd')}"
            viol_us = f"{fair['viol']}/{jerk['viol']}"
        elif row.kind == "thread":
            c = main.get("fb", {}).get("chip")
            plain = us[row.name]["fair_plain"], us[row.name]["jerk_plain"]
            extra = (f"longest chip LC {fmt(c, '.2f')}, fair {fair['chip']:.2f}, jerk {jerk['chip']:.2f} rev; "
                     f"ours w/o vibration {plain[0]['chip']:.2f} rev in "
                     f"{plain[0]['time']:.3f}/{plain[1]['time']:.3f} s")
        else:
            a = main.get("fb", {}).get("air")
            extra = (f"feed travel cutting air: LC {fmt(a and 100 * a, '.1f')} %, fair {100 * fair['air']:.1f} %, "
                     f"jerk {100 * jerk['air']:.1f} %")
        ratio = (lambda x: fmt(x / lc_t)) if lc_t else (lambda x: "-")
        lines.append(f"{row.name:<22} {peer:>4} {fmt(lc_t):>7} {fmt(ideal):>7} {fmt(safe):>7} {fmt(g98):>7} "
                     f"{fair['time']:>7.3f} {fair['predicted']:>7.3f} {jerk['time']:>7.3f} {fmt(bounds.get(row.name)):>7} "
                     f"{ratio(fair['time']):>7} {ratio(jerk['time']):>7} "
                     f"{fmt(safe and fair['time'] / safe):>7} {viol_lc:>9} {viol_us:>7}  {extra}")
        for variant, f in figs.items():
            if "error" in f:
                lines.append(f"{'':<22} {variant:>4} LinuxCNC error: {f['error']}")
    return lines


DEEP_HEADER = "Deep holes (bench/deep_holes.py's job):"


def deep_section(rows: list[Row], lc: dict, us: dict) -> list[str]:
    """The deep-hole rows: LinuxCNC G83 against our G83-like pecking, cycle time and chip."""
    lines = []
    for row in (r for r in rows if r.kind == "deep"):
        d = row.doc["drill"]
        g83 = lc.get(row.name, {}).get("G83", {})
        mine = us[row.name]["jerk"]
        revs_per_mm = 1.0 / (d["feed"] / row.doc["spindle_rpm"])
        lines += [f"{DEEP_HEADER} {len(d['holes'])} holes of {row.doc['tool']['diameter']:g} mm, {d['depth']:g} mm deep, "
                  f"pecks of {d['peck']['depth']:g} mm ({d['peck']['depth'] * revs_per_mm:.0f} rev of chip at "
                  f"{d['feed'] / row.doc['spindle_rpm']:g} mm/rev), {row.doc['spindle_rpm']:g} rpm, same limits",
                  f"  {'way':<44} {'cycle s':>8} {'chip revs':>10} {'viol':>6}"]
        for name, f in (("LinuxCNC G83 (drive-model feedback)", g83.get("fb", {})),
                        ("LinuxCNC G83 (ideal loop)", g83.get("raw", {})),
                        ("ours, G83-like pecks (recorded feedback)", mine)):
            lines.append(f"  {name:<44} {fmt(f.get('time'), '8.2f')} {fmt(f.get('chip'), '10.2f')} "
                         f"{fmt(f.get('viol'), '6d')}")
        if "error" in g83:
            lines.append(f"  LinuxCNC error: {g83['error']}")
    if lines:
        lines += ["  ours: the normal mill3 (max_jerk 200 m/s^3; LinuxCNC 2.9 plans without a jerk limit), over topics",
                  "  and judged on the recorded feedback, as bench/deep_holes.py judges it.",
                  "  viol: samples (ms) with the tip below R while X/Y is more than 10 um off the hole.",
                  "  chip: longest stretch cut without an air-cut (analyze_aircut per hole from the surface, as in",
                  "  bench/deep_holes.py; LinuxCNC's spindle taken at speed from M3 on); vibration drilling of the",
                  "  same holes: bench/results/deep_holes.txt."]
    return lines


def splice_section(header: str, section: list[str], only: str) -> None:
    """Replace the section of peer.txt that starts with ``header`` (its lines after the first
    indented), as a rerun of that row alone (--only) makes it; a new one goes before the notes."""
    old = RESULTS.read_text().splitlines() if RESULTS.exists() else []
    note = f"  (this section rerun alone on {time.strftime('%Y-%m-%d')}: run.py --only {only}; the rest is older)"
    section = section + [note]
    start = next((k for k, line in enumerate(old) if line.startswith(header)), None)
    if start is None:  # before the notes, after a blank line
        start = end = next((k for k, line in enumerate(old) if line.startswith("LC s:")), len(old))
        section = section + [""]
    else:
        end = next((k for k in range(start + 1, len(old)) if not old[k].startswith("  ")), len(old))
    RESULTS.write_text("\n".join(old[:start] + section + old[end:]) + "\n")


def lc_limits(sessions: dict) -> list[str]:
    """What LinuxCNC did with the limits it was given, from its ideal-loop recordings."""
    out = []
    for name in ("mill3", "lathe"):
        s = sessions.get(name)
        if not s:
            continue
        m = load_machine(name)
        parts = []
        for ax in m.linear_axes:
            recs = [r for r in s.recordings.values() if r is not None]
            if not recs:
                continue
            v = max(float(np.abs(np.diff(r.axes[ax])).max()) / 1e-3 for r in recs)
            acc = np.concatenate([np.abs(np.diff(r.axes[ax], 2)) / 1e-6 for r in recs])
            acc = np.round(acc[acc > 0.5 * m.axes[ax].max_acceleration], 2)  # the plateaus of rapids
            values, counts = np.unique(acc, return_counts=True) if len(acc) else (np.zeros(1), np.zeros(1))
            a = m.axes[ax]
            held = values[int(np.argmax(counts))] * 1e3
            parts.append(f"{ax} v {a.max_velocity * 1e3:g} mm/s (peak used {v * 1e3:.0f}), "
                         f"a {a.max_acceleration * 1e3:g} mm/s^2 (held at {held:.0f}, "
                         f"peak {acc.max(initial=0) * 1e3:.0f})")
        out.append(f"  {name}: " + "; ".join(parts))
        out.append(f"  {name}: {s.samples} samples recorded, {s.gaps} lost; session {s.wall_s:.0f} s wall")
    return out


def notes(rows: list[Row], lc: dict, us: dict, sessions: dict) -> list[str]:
    mill, lathe = load_machine("mill3"), load_machine("lathe")
    jerk = ", ".join(f"{m.name} {m.axes['x'].max_jerk:g}" for m in (mill, lathe))
    lines = [
        "LC s: LinuxCNC's recorded joint positions (sampler + halsampler -t, every 1 ms servo period) run through",
        "  our bridge's drive model (DriveModel of the machine: kp, feed-forward, velocity lag, encoder), the same",
        "  servo our side runs on; ideal s: the same recording as LinuxCNC's sim loops it back (no servo lag).",
        "  safe s: G99 had Z waited at R until X/Y is within 10 um (LC s + its violation samples x 1 ms).",
        "  G98 s: G98 (retract to the start level, 5 mm above the surface) on the drive model. peer: G99/G76/G71.",
        "fair s / jerk s: our planner and bridge over topics (both nodes, localhost, recorded joint_states), on the",
        "  machine with every max_jerk raised to 1e6 m/s^3 (trapezoids, like LinuxCNC) / on the normal description",
        f"  (max_jerk m/s^3: {jerk}). pred s: the fair run predicted offline (plan + drive model), for comparison.",
        "bound s: lower_bound_time (X/Y positioning + fastest feed and exit below R per hole) at these limits.",
        "fair/LC, jerk/LC, f/safe: ratios of our times to LinuxCNC's (LC s) and to the safe G99 (safe s).",
        "viol: samples (ms) with the tip below R while X/Y is more than 10 um off the hole (analyze_drilling),",
        "  LinuxCNC G99/G98 on the drive-model feedback, ours fair/jerk on the recorded feedback; on LinuxCNC's ideal loop G99 and G98",
        "  have " + _ideal_viol(rows, lc) + ".",
        f"Over topics, {len(ours.RERUNS)} runs were aborted by the bridge because the planner starved it (host load)"
        + (f" and run again: {', '.join(ours.RERUNS)}." if ours.RERUNS else "."),
        "Times: first to last axis motion on the positions (analyze_drilling / cnc_analysis.summary.cycle_time).",
        "Both sides start at the same point (drilling: one pitch before the first hole, 5 mm above the surface;",
        "  thread: the drive line 1 mm above the major radius at start_z; roughing: the origin Q0) with the",
        "  spindle at speed. Chips: analyze_thread (longest continuous cut of the cutting passes, spindle revs);",
        "  air: feed travel not touching the stock left (cnc_planner.kinds.turn.stock.StockModel replay of the path).",
        "",
        "LinuxCNC got exactly our per-axis limits (INI [AXIS_*]/[JOINT_*], SI -> mm; [TRAJ] vector limits set",
        "  to the norm of the axis limits so they never bind). LinuxCNC 2.9 plans without a jerk limit",
        "  (trapezoidal, no S-curve). What it used, from the ideal-loop recordings:",
        *lc_limits(sessions),
    ]
    drill = [r for r in rows if r.kind == "drill"]
    faster = [r for r in drill if lc.get(r.name, {}).get("G99", {}).get("fb")
              and us[r.name]["fair"]["time"] < lc[r.name]["G99"]["fb"]["time"] and us[r.name]["fair"]["viol"] == 0]
    safe = [r for r in drill if lc.get(r.name, {}).get("G99", {}).get("fb") and us[r.name]["fair"]["time"]
            < lc[r.name]["G99"]["fb"]["time"] + lc[r.name]["G99"]["fb"]["viol"] * 1e-3]
    if drill:
        lines += ["", f"Fair race, drilling: ours faster than G99 on {len(faster)} of {len(drill)} rows, faster than "
                  f"G99 made safe (safe s) on {len(safe)} of {len(drill)}; ours has "
                  f"{sum(us[r.name]['fair']['viol'] + us[r.name]['jerk']['viol'] for r in drill)} "
                  "safety violations on feedback in all drilling rows.",
                  "  G99 is exact on its own ideal loop (0 violations) but starts the Z feed at R the moment X/Y's",
                  "  command arrives; behind a servo (the same drive model as ours) X/Y is then still settling, so the",
                  f"  tip goes below R off the hole, down to {_lowest(drill, lc):.2f} mm above the surface. "
                  "Our cycle holds",
                  "  the crossing of R until X/Y's feedback is within 10 um, which costs more than its overlap",
                  "  gains back at these limits (mill3: kp 50/s, no acceleration feed-forward)."]
    for row in rows:
        figs = lc.get(row.name, {})
        if row.kind == "thread" and figs.get("G76", {}).get("fb"):
            g, f = figs["G76"]["fb"], us[row.name]["fair"]
            lines += [f"Thread: LinuxCNC G76 cuts {g['passes']} passes + spring, each a continuous chip of "
                      f"{g['chip']:.2f} rev (the whole thread); ours breaks it at {f['chip']:.2f} rev.",
                      f"  Cycle: passes last {g['pass_s']:.3f} s (G76) / {f['pass_s']:.3f} s (ours); between passes "
                      f"G76 needs {g['gap_s']:.3f} s (retract, rapid back, plunge, wait for the index), ours "
                      f"{f['gap_s']:.3f} s",
                      "  (retract overlapping the return, which lands on the next pass's running helix when the "
                      "spindle phase comes round)."]
        if row.kind == "turn" and figs.get("G71", {}).get("fb"):
            g, f, j = figs["G71"]["fb"], us[row.name]["fair"], us[row.name]["jerk"]
            lines += [f"Roughing: G71 feeds {g['feed_mm']:.0f} mm, {g['air_mm']:.0f} mm of it in air (it assumes a "
                      f"cylinder of the start radius); ours feeds {f['feed_mm']:.0f} mm, {f['air_mm']:.0f} mm in air.",
                      f"  Rapids touching stock on feedback: LC {g['rapid_cut_mm']:.2f} mm, ours fair "
                      f"{f['rapid_cut_mm']:.2f} mm, jerk {j['rapid_cut_mm']:.2f} mm.",
                      "  G71 runs the profile as an O-word subroutine (2.9 needs collinear points removed: 'Cannot",
                      "  intersect parallel lines'); its D offsets the profile normal to it, our allowance is radial."]
    return lines


def _lowest(rows: list[Row], lc: dict) -> float:
    lows = [f["fb"]["low_mm"] for r in rows for f in lc.get(r.name, {}).values()
            if f.get("fb", {}).get("low_mm") is not None]
    return min(lows, default=float("nan"))


def _ideal_viol(rows: list[Row], lc: dict) -> str:
    total = sum(f.get("raw", {}).get("viol", 0) for r in rows if r.kind == "drill"
                for f in lc.get(r.name, {}).values())
    return f"{total} in all rows together"


def program_checks(prows: list) -> tuple[list[str], dict[str, str]]:
    """LinuxCNC's interpreter (rs274 -g) as the oracle of our front end, per cycle operation;
    a file it refuses is compared with the file whose operations ours reads identically.
    Also rs274's outputs, by program (test_gcode checks the front end against them)."""
    lines = ["What our front end makes of each file, against LinuxCNC's own interpreter (rs274 -g, its",
             "canonical moves; bench/peer/oracle.py): per cycle, the numbers the cycle's words give"]
    if shutil.which("rs274") is None:
        return lines + ["  rs274 not installed: skipped"], {}
    outputs: dict[str, str] = {}
    for prow in prows:
        lines += oracle.check_program(prow.name, prow.text, prow.operations, oracle.recording(oracle.rs274, outputs))
        twins = [o.name for o in prows if o is not prow and _same_operations(o, prow)]
        if twins:
            lines.append(f"  {prow.name}: its operations (documents) are identical to {', '.join(twins)}'s")
    return lines, outputs


def _same_operations(a, b) -> bool:
    """Two programs our front end reads as the same operations (job ids aside)."""
    def docs(p):
        return [{k: v for k, v in d.items() if k != "job_id"} for _, _, d in p.operations]
    return docs(a) == docs(b)


def program_notes() -> list[str]:
    return ["  Operations split by line: ours by the planner's operation marks (job_events), LinuxCNC by",
            "  motion.program-line; each judged with the operation's own document (times: first to last axis",
            "  motion within it). LC's spindle changes speed at once (sim_spindle); ours runs it down and up",
            "  between operations within the spindle's limits, the axes waiting. viol and depth error: on the",
            "  recorded feedback, as the generated rows. The short moves between cycles are timed where each",
            "  side's split falls (LinuxCNC changes line as its blended motion reaches the block): not comparable."]


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--keep", type=Path, help="keep LinuxCNC's work directories here")
    parser.add_argument("--reuse", type=Path, help="analyse the sessions kept in this directory")
    parser.add_argument("--only", help="rows whose name matches this regular expression")
    args = parser.parse_args()
    begin = time.monotonic()

    def log(msg: str) -> None:
        print(f"[{time.monotonic() - begin:5.0f} s] {msg}", flush=True)

    rows = [r for r in all_rows() if not args.only or re.search(args.only, r.name)]
    prows = programs.program_rows(args.only)
    param = parameterised.rows(args.only)
    version = linuxcnc_side.installed_version() + " (recording reused)"
    if not args.reuse:
        version = linuxcnc_side.ensure_installed()
        linuxcnc_side.ensure_user()
    tmp = Path(tempfile.mkdtemp(prefix="bench-peer-"))
    workroot = args.reuse or args.keep or tmp
    variants = {name: ours.machines(name, tmp / "machines") for name in {r.machine for r in [*rows, *prows, *param]}}
    sessions: dict = {}
    worker = threading.Thread(target=run_linuxcnc, args=(rows, prows + param, workroot, bool(args.reuse), sessions, log))
    worker.start()
    us, bounds = {}, {}
    for row in rows:
        us[row.name] = our_side(row, variants)
        bounds[row.name] = bound(row, variants)
        log(f"ours: {row.name}: " + ", ".join(f"{k} {v['time']:.3f} s" for k, v in us[row.name].items()
                                              if k in ("fair", "jerk")))
    us_p = {}
    for prow in prows:
        us_p[prow.name] = programs.our_side(prow, variants, ours.run_over_topics, judge)
        log(f"ours: program {prow.name}: " + ", ".join(f"{k} {v['time']:.3f} s" if "time" in v else f"{k} failed"
                                                        for k, v in us_p[prow.name].items()))
    param_outputs: dict[str, str] = {}
    interpret = oracle.recording(oracle.rs274, param_outputs)
    ends = {p.name: parameterised.feed_ends(p, interpret, load_machine(p.machine)) for p in param}
    us_q = {}
    for p in param:
        us_q[p.name] = parameterised.our_side(p, variants, ours.run_over_topics, judge, ends[p.name])
        log(f"ours: parameterised {p.name}: " + ", ".join(f"{k} {v['time']:.3f} s" if "time" in v else f"{k} failed"
                                                          for k, v in us_q[p.name].items()))
    checks, outputs = program_checks(prows)
    worker.join()
    param_lines = []
    for p in param:
        lc_q = parameterised.linuxcnc_side(p, sessions, load_machine(p.machine), judge, ends[p.name])
        check = oracle.check_program(p.name, p.text, p.operations, interpret)
        param_lines += parameterised.section(p, lc_q, us_q[p.name], ends[p.name], check)
    outputs.update(param_outputs)
    lc = {row.name: linuxcnc_figures(row, sessions) for row in rows}
    lc_p = {p.name: programs.linuxcnc_figures(p, sessions, load_machine(p.machine), judge) for p in prows}
    lines = [f"LinuxCNC {version} (linuxcnc-uspace, headless sim, servo 1 ms) vs our planner: same jobs, "
             f"same axis limits, same servo model, same analysis; {time.strftime('%Y-%m-%d')}", ""]
    lines += table(rows, lc, us, bounds) if rows else []
    deep = deep_section(rows, lc, us)
    lines += ["", *deep] if deep else []
    if prows:
        lines += ["", *programs.table(prows, lc_p, us_p), *program_notes(), "", *checks]
    lines += ["", *param_lines] if param_lines else []
    if sessions.get("error"):
        lines.append(f"LinuxCNC failed: {sessions['error']}")
    lines += ["", *notes(rows, lc, us, sessions)]
    text = "\n".join(lines) + "\n"
    print(text)
    if not args.only:
        RESULTS.parent.mkdir(parents=True, exist_ok=True)
        RESULTS.write_text(text)
        log(f"written {RESULTS.relative_to(ROOT)}")
        if outputs:
            oracle.RECORDED.write_text(json.dumps(outputs, indent=0, sort_keys=True) + "\n")
            log(f"written {oracle.RECORDED.relative_to(ROOT)}")
    elif not prows and all(r.kind == "deep" for r in rows) and not sessions.get("error"):
        for header, section in ((DEEP_HEADER, deep), (parameterised.HEADER, param_lines)):
            if section:
                splice_section(header, section, args.only)
                log(f"section {header!r} spliced into {RESULTS.relative_to(ROOT)}")
    shutil.rmtree(tmp, ignore_errors=True)  # machines, the topics check; LinuxCNC's unless --keep
    log("done")
    return 0 if "error" not in sessions else 1


if __name__ == "__main__":
    sys.exit(main())
