"""Tapered thread ends (G76's E and L; the thread job's end_taper), as LinuxCNC cuts them.

- By hand: at each tapered end every pass ramps x out by the thread's depth K over E of
  groove, z still on the lead: the tool tip is at its pass's depth d_k where the ramp
  begins and K above it (the last pass: the crest) at the thread's end, never shallower
  than LinuxCNC's straight ramp K*w/E (w into the ramp) nor deeper than the pass. Only the
  rounded corner where the ramp leaves the depth differs from LinuxCNC's line.
- G76 ... E L translates into it (L 1 entry, 2 exit, 3 both; E0 or L0 the plain thread),
  and rs274 -g's synchronised feeds (recorded: test/gcode_oracle/lathe_g76_taper.ngc) end
  where ours do: each pass's angled feeds K over E at its ends.
- Over topics, judged on feedback: the depth is judged over the untapered length, where it
  is full; the same feedback judged as a plain thread is short and off its flank line, so
  the judge really leaves the ramps out. On feedback the last pass reaches the crest at
  end_z.
"""
from __future__ import annotations

import json
import math
import sys
from pathlib import Path

import numpy as np
import pytest

from cnc_analysis.recording import read_run
from cnc_analysis.threads import analyze_thread, read_thread, thread_failures
from cnc_msgs_py.gcode.document import job_document
from cnc_msgs_py.job import parse_job
from cnc_msgs_py.machine import load_machine
from cnc_msgs_py.schema import JobError
from cnc_planner.kinds.thread.planning import plan_thread
from cnc_planner.kinds.thread.spec import ThreadError, ThreadSpec
from cnc_planner.motion.builder import PlanBuilder
from cnc_planner.planning import plan_job
from support import cnc, load_report

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "bench" / "peer"))
import examples  # noqa: E402  (bench/peer: the recorded rs274 outputs)
import oracle  # noqa: E402

ORACLE = ROOT / "test" / "gcode_oracle" / "lathe_g76_taper.ngc"
TAN = math.tan(math.radians(29.5))
G76_AT = "(CNC,MACHINE lathe)\nG18 G21 G90 G8\nS600 M3\nG0 X12 Z5\n"  # a G76 on line 5 follows
THREAD = {"start_z": 2.5, "end_z": -9.0, "major_radius": 6.0, "pitch": 1.5, "depth": 0.92, "passes": 4,
          "infeed_angle": 29.5, "spring_passes": 1}


def job(ends: str, length: float = 3.0, **more) -> dict:
    return {"schema": "cnc_job/1", "job_id": f"taper-{ends}", "kind": "thread", "machine": "lathe",
            "spindle_rpm": 600, "thread": {**THREAD, "end_taper": {"length": length, "ends": ends}}, **more}


def test_every_pass_ramps_out_by_the_depth_over_E_at_its_tapered_ends():
    """The uncompensated plan at 1 ms, no vibration: the tip's depth below the crest on each
    pass, against the groove coordinate g = z + d_k tan(29.5) of that pass."""
    spec = ThreadSpec.from_job(parse_job(job("both")))
    builder = PlanBuilder(load_machine("lathe"), {"x": 7e-3, "z": 4e-3})
    info = plan_thread(builder, spec, compensate=False)
    plan = builder.build()
    t = np.arange(0.0, plan.duration, 1e-3)
    x, z = (plan.sample(t)[0][:, plan.joints.index(j)] * 1e3 for j in ("x", "z"))
    K, E = 0.92, 3.0
    for p in info:
        d = p["depth_mm"]
        first = int(np.searchsorted(t, p["t_sync"]))
        past = first + int(np.argmax(z[first:] + d * TAN < -9.0))  # the first instant past end_z: x pulls out
        g, depth = z[first:past] + d * TAN, 6.0 - x[first:past]  # on the helix
        exit_w, entry_w = (-9.0 + E) - g, g - (2.5 - E)  # into each ramp (mm of groove), from its deep end
        body = (exit_w < 0.0) & (entry_w < 0.0)
        assert body.sum() > 300 and np.all(np.abs(depth[body] - d) < 1e-9)  # the pass's depth between the ramps
        for w in (exit_w, entry_w):
            ramp = (w >= 0.0) & (w <= E)
            rise = d - depth[ramp]  # out of the pass's depth
            assert ramp.sum() > 50 and np.all(rise >= -1e-9)
            assert np.all(rise <= K * w[ramp] / E + 1e-9)  # never shallower than LinuxCNC's line
            assert np.max(K * w[ramp] / E - rise) < 0.1 * K  # its rounded corner: h = 0.15 mm of E = 3 mm
        # the exit ramp's end (end_z, within a servo period of groove): K above the pass's depth
        assert exit_w[-1] == pytest.approx(E, abs=0.02) and depth[-1] == pytest.approx(d - K, abs=0.01)
    assert info[-1]["spring"] and info[-1]["depth_mm"] == pytest.approx(K)  # the last pass: to the crest


def test_end_taper_is_checked_and_the_ramp_must_fit_x():
    for ends, length, field in (("both", 6.0, "thread.end_taper.length"), ("top", 2.0, "thread.end_taper.ends"),
                                ("exit", 0.0, "thread.end_taper.length")):
        with pytest.raises(JobError, match=f"^{field}: "):
            parse_job(job(ends, length))
    spec = ThreadSpec.from_job(parse_job(job("exit", 0.2)))  # x cannot turn onto 0.92 mm over 0.2 mm at the lead
    with pytest.raises(ThreadError, match=r"^thread\.end_taper\.length: 0\.2 mm is too short .* needs >= 0\.[0-9]+ mm"):
        plan_thread(PlanBuilder(load_machine("lathe"), {"x": 7e-3, "z": 4e-3}), spec, compensate=False)
    # on a lathe whose x follows the vibration alone at 600 rpm, not with the ramp's corner on it
    soft = {**job("both", vibration={"D": 1.5, "Q": 1.2, "phase_shift": 180}), "machine": "lathe_soft"}
    plan_job(parse_job({**soft, "thread": {**THREAD, "passes": 5}}), load_machine("lathe_soft"))
    with pytest.raises(JobError, match=r"^vibration\.D: the x axis cannot follow .* on the tapered ends' ramp "
                                       r"at 600 rpm .*; max spindle speed 5[0-9]{2} rpm$"):
        plan_job(parse_job({**soft, "thread": {**soft["thread"], "passes": 5}}), load_machine("lathe_soft"))


def test_g76_e_and_l_are_linuxcncs_tapered_ends():
    ops = [(line, op.kind, doc) for line, op, doc in parse_job(job_document(ORACLE)).program.operations]
    threads = [doc["thread"].get("end_taper") for _, kind, doc in ops if kind == "thread"]
    assert threads == [{"length": 2.0, "ends": "exit"}, {"length": 3.0, "ends": "entry"},
                       {"length": 2.0, "ends": "both"}, None]
    lines = oracle.check_program(ORACLE.stem, ORACLE.read_text(), ops, oracle.recorded(examples.RS274_RECORDED))
    assert len(lines) == 4 and all(" same within " in line for line in lines), lines
    assert [" tapered exit over 2 mm" in lines[0], " tapered entry over 3 mm" in lines[1],
            " tapered both over 2 mm" in lines[2], "tapered" not in lines[3]] == [True] * 4


@pytest.mark.parametrize("words, ends", [("E2 L4", None), ("E2 L5", "entry"), ("E2 L6", "exit"), ("E2 L7", "both"),
                                         ("E-1 L3", None), ("E0 L2", None), ("E2 L0", None), ("E2.5", None)])
def test_g76_reads_e_and_l_as_rs274_does(tmp_path, words, ends):
    """L by its bits (1 entry, 2 exit) and E <= 0 as none, as rs274 -g feeds them (it angles
    L5's entry and L7's both ends, and neither for L4 or E-1)."""
    path = tmp_path / "g76.ngc"
    path.write_text(f"{G76_AT}G76 P1.5 Z-14 I-1 J0.3 K0.9 {words}\nM2\n")
    ops = parse_job(job_document(path)).program.operations
    thread = next(doc["thread"] for _, op, doc in ops if op.kind == "thread")
    assert thread.get("end_taper") == (None if ends is None else {"length": 2.0, "ends": ends})


@pytest.mark.parametrize("l_word", ["-1", "1.5"])
def test_g76_refuses_an_l_rs274_refuses(tmp_path, l_word):
    """rs274 -g: "Negative l word used", "Non integer value for integer"."""
    path = tmp_path / "bad.ngc"
    path.write_text(f"{G76_AT}G76 P1.5 Z-14 I-1 J0.3 K0.9 E2 L{l_word}\nM2\n")
    with pytest.raises(JobError, match=rf"line 5: L{l_word}: which ends taper must be a whole number >= 0"):
        parse_job(job_document(path))


def test_a_thread_with_tapered_ends_is_judged_on_feedback_over_its_untapered_length(tmp_path):
    doc = job("both", vibration={"D": 1.5, "Q": 1.2, "phase_shift": 180})
    doc["thread"]["passes"] = 5
    (tmp_path / "job.json").write_text(json.dumps(doc))
    result = cnc("cnc-run", tmp_path / "job.json", "--out", tmp_path / "out")
    assert result.returncode == 0, result.stderr[-3000:]
    thread = load_report(tmp_path / "out")["thread"]
    assert thread["verdict"]["passed"], thread["verdict"]
    assert thread["synchronised_passes"] == 6 and thread["cutting_passes"] == 5
    assert thread["full_depth"] and thread["max_chip_revs"] <= 1.0 and thread["helix_residual_mm"] < 0.01
    run = read_run(tmp_path / "out" / "bag")
    x, z, spindle = (run.feedback[:, run.column(j)] for j in ("x", "z", "spindle"))
    plain = analyze_thread(run.feedback_t, x, z, spindle, {k: v for k, v in doc["thread"].items() if k != "end_taper"})
    missed = thread_failures(plain, True)
    assert len(missed) == 2 and "short of the thread's depth" in missed[0] and "flank line" in missed[1], missed
    # the spring pass on feedback: full depth where the exit ramp begins, the crest at end_z
    i0, i1 = read_thread(run.feedback_t, x, z, spindle, doc["thread"]).segments[-1]
    xs, zs = x[i0:i1 + 1] * 1e3, z[i0:i1 + 1] * 1e3
    for g, depth in ((-6.0, thread["passes"][-1]["depth_mm"]), (-9.0, 0.0)):
        k = np.argmin(np.abs(zs - (g - 0.92 * TAN)))
        assert 6.0 - xs[k] == pytest.approx(depth, abs=0.02)
