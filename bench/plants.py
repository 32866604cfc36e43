"""The machine is not its description: five example jobs run with `cnc-run` on the described
drives and on three plants that differ from them, before and after `cnc-identify`.

Plants (on every linear and rotary axis of the job's machine, the spindle as described):
  described        the description itself
  softer gain      kp x 0.7                                   (edge of the default tolerance)
  slow loop+delay  velocity_lag x 3 and 2 ms transport delay  (edge of the default tolerance)
  friction+lash    Coulomb friction 0.3 mm/s, 4 um backlash   (outside it: the tolerance allows none)

"After" identifies each plant from one run of the machine layout's calibration job
(config/jobs/identify_<layout>.yaml) and the job's own "before" recording, then runs the job
again with CNC_MACHINE_PATH pointing at the fitted description. Every run is the user's command, end to end over topics; the
figures are read from its report.json.

Usage: bench/plants.py [--jobs drill_row,thread_m12,...] [--no-identify]
"""
from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

import yaml

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
sys.path.insert(0, str(HERE))

from publish import write_result  # noqa: E402

from cnc_msgs_py.gcode.document import load_job_file  # noqa: E402
from cnc_msgs_py.machine import SPINDLE, load_machine  # noqa: E402

BIN = Path(sys.executable).parent
JOBS = ROOT / "config" / "jobs"
PLANTS = {  # name -> what changes on every axis but the spindle
    "described": None,
    "softer gain": lambda d: {"kp": d.kp * 0.7},
    "slow loop+delay": lambda d: {"velocity_lag": d.velocity_lag * 3.0, "delay": d.delay + 0.002},
    "friction+lash": lambda d: {"friction": 3e-4, "backlash": 4e-6},
}


def plate_doc() -> dict:
    """drill_row with 300 holes on a 10 mm grid (as bench/load.py's plate)."""
    doc = load_job_file(JOBS / "drill_row.yaml")
    doc["job_id"] = "plate-300"
    doc["drill"]["holes"] = [[-400 + 10 * (i % 80), -250 + 10 * (i // 80)] for i in range(300)]
    return doc


JOB_DOCS = {
    "drill_row": lambda: load_job_file(JOBS / "drill_row.yaml"),
    "plate 300": plate_doc,
    "thread_m12": lambda: load_job_file(JOBS / "thread_m12.yaml"),
    "lathe_feed_vibration": lambda: load_job_file(JOBS / "lathe_feed_vibration.yaml"),
    "path_5ax_tilt": lambda: load_job_file(JOBS / "path_5ax_tilt.yaml"),
}


def plant_file(machine_name: str, plant: str, folder: Path) -> Path | None:
    """The plant's YAML for a machine (None for the description)."""
    change = PLANTS[plant]
    if change is None:
        return None
    machine = load_machine(machine_name)
    drives = {j: change(d) for j, d in machine.drives.items() if j != SPINDLE}
    path = folder / f"{machine_name}_{plant.replace(' ', '_').replace('+', '_')}.yaml"
    path.write_text(yaml.safe_dump({"name": plant, "seed": 1, "drive": drives}))
    return path


def cnc_run(job: Path, out: Path, plant: Path | None, machine_path: Path | None = None) -> tuple[int, dict]:
    """cnc-run as a user runs it; its exit code and report.json."""
    env = {**os.environ, "ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST"}
    if machine_path is not None:
        env["CNC_MACHINE_PATH"] = str(machine_path)
    command = [str(BIN / "cnc-run"), str(job), "--out", str(out)] + (["--plant", str(plant)] if plant else [])
    code = subprocess.run(command, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL).returncode
    report = out / "report.json"
    return code, json.loads(report.read_text()) if report.is_file() else {}


def identify(machine_name: str, plant: Path, production: Path, folder: Path) -> Path:
    """Fit a description from the layout's calibration job run on the plant and from the
    job's own recording there (any production bag works: the calibration moves only X, Y and
    Z, a 5-axis path excites the rotaries)."""
    layout = load_machine(machine_name).layout
    calibration = folder / f"calibrate_{plant.stem}"
    if not calibration.exists():
        cnc_run(JOBS / f"identify_{layout}.yaml", calibration, plant)
    fitted = folder / f"fitted_{production.name}"
    subprocess.run([str(BIN / "cnc-identify"), str(calibration / "bag"), str(production / "bag"), "--out",
                    str(fitted)], check=True, stdout=subprocess.DEVNULL)
    return fitted


def figures(report: dict, target_depth_mm: float | None) -> dict:
    """The figures of one run that the table shows."""
    drill, thread = report.get("drill") or {}, report.get("thread") or {}
    depths = [h["depth_mm"] for h in drill.get("holes", []) if h.get("depth_mm") is not None]
    chip = thread.get("max_chip_revs", (report.get("aircut") or {}).get("max_chip_revs"))
    failed = sorted(k for k, v in report.items() if isinstance(v, dict) and isinstance(v.get("verdict"), dict)
                    and v["verdict"].get("passed") is False)
    return {
        "violations": drill.get("safety_violations"),
        # holes: the signed error of the hole farthest off (negative: short); threads: the analyser's
        "depth_err_um": (max((d - target_depth_mm for d in depths), key=abs) * 1e3 if depths and target_depth_mm
                         else thread.get("depth_error_mm", None) and thread["depth_error_mm"] * 1e3),
        "overcut_um": thread["overcut_mm"] * 1e3 if "overcut_mm" in thread else None,
        "chip_revs": chip,
        "tip_um": (report.get("kinematics") or {}).get("max_tip_deviation_mm") and
                  report["kinematics"]["max_tip_deviation_mm"] * 1e3,
        "cycle_s": report.get("cycle_time_s"),
        "state": report.get("state"),
        "failed": ",".join(failed) or "-",
    }


def exact_machines(folder: Path) -> Path:
    """Every shipped machine with its drives' tolerance closed: the plan trusts the description."""
    exact = folder / "exact"
    exact.mkdir()
    for path in sorted((ROOT / "config" / "machines").glob("*.yaml")):
        doc = yaml.safe_load(path.read_text())
        for drive in doc["drive"].values():
            drive["tolerance"] = {"kp": [1.0, 1.0], "velocity_ff": [1.0, 1.0], "accel_ff": [1.0, 1.0],
                                  "velocity_lag": [1.0, 1.0], "delay": [0.0, 0.0]}
        (exact / path.name).write_text(yaml.safe_dump(doc))
    return exact


def planned_time(job: Path, out: Path, machine_path: Path | None = None) -> float:
    """cnc-plan's planned duration (s) of a job."""
    env = {**os.environ, **({"CNC_MACHINE_PATH": str(machine_path)} if machine_path else {})}
    subprocess.run([str(BIN / "cnc-plan"), str(job), "--out", str(out)], env=env, check=True, stdout=subprocess.DEVNULL)
    return json.loads((out / "summary.json").read_text())["duration_s"]


def cell(value, fmt: str) -> str:
    return "-" if value is None else format(value, fmt)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--jobs", default=",".join(JOB_DOCS), help="comma-separated subset of " + ", ".join(JOB_DOCS))
    parser.add_argument("--no-identify", action="store_true", help="skip the runs after identification")
    args = parser.parse_args()
    rows, costs = [], []
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        exact = exact_machines(folder)
        for name in args.jobs.split(","):
            doc = JOB_DOCS[name]()
            job = folder / f"{name.replace(' ', '_')}.json"
            job.write_text(json.dumps(doc))
            stem = name.replace(" ", "_")
            costs.append((name, planned_time(job, folder / f"plan_exact_{stem}", exact),
                          planned_time(job, folder / f"plan_{stem}")))
            depth = doc.get("drill", {}).get("depth")
            for plant in PLANTS:
                path = plant_file(doc["machine"], plant, folder)
                before = folder / f"run_{len(rows)}"
                runs = [("before", before, None)]
                for when, out, machine_path in runs:
                    code, report = cnc_run(job, out, path, machine_path)
                    rows.append({"job": name, "plant": plant, "when": when, "exit": code, **figures(report, depth)})
                    print(json.dumps(rows[-1]), flush=True)
                    if when == "before" and path is not None and not args.no_identify:
                        runs.append(("after", folder / f"run_{len(rows)}", identify(doc["machine"], path, before,
                                                                                     folder)))
    header = (f"{'job':<21} {'plant':<16} {'ident.':<6} {'exit':>4} {'X/Y below R':>11} {'depth err um':>12} "
              f"{'overcut um':>10} {'chip rev':>8} {'tip um':>7} {'cycle s':>8}  failed verdicts")
    lines = [header, "-" * len(header)]
    for r in rows:
        lines.append(f"{r['job']:<21} {r['plant']:<16} {r['when']:<6} {r['exit']:>4} {cell(r['violations'], 'd'):>11} "
                     f"{cell(r['depth_err_um'], '.1f'):>12} {cell(r['overcut_um'], '.1f'):>10} "
                     f"{cell(r['chip_revs'], '.2f'):>8} {cell(r['tip_um'], '.1f'):>7} {cell(r['cycle_s'], '.3f'):>8}  "
                     f"{r['failed']}")
    lines += ["", "What the default tolerance costs on the described drives (cnc-plan, planned duration):",
              f"{'job':<21} {'exact description s':>19} {'default tolerance s':>19} {'cost':>7}"]
    lines += [f"{name:<21} {t_exact:>19.3f} {t_tol:>19.3f} {100 * (t_tol / t_exact - 1):>6.1f}%"
              for name, t_exact, t_tol in costs]
    print("\n".join(lines))
    write_result("plants.txt", __doc__ + "\n" + "\n".join(lines))
    return 0


if __name__ == "__main__":
    sys.exit(main())
