"""The thread cycle's search for each pass's join onto its helix (issue 27): passing over
the helix revolutions that z cannot reach in time, bisecting the first one it can, and
searching x's latest turn back from the previous join's, finds the joins that trying every
servo instant and bisecting every turn finds, on drawn lathes and threads.

Within a revolution the later starts and face crossings z may return from are passed over
up to the first join each reaches in time, likewise. The premises (z's slack never falls
within a revolution, x's never rises the later it turns back) hold where the motion
followed stays within the ramps' limits; the cycle only bisects joins there, so the joins
and the whole plan must be the exhaustive search's, bit for bit.
"""
from __future__ import annotations

import itertools
from unittest import mock

import numpy as np
from hypothesis import HealthCheck, given, settings, strategies as st

from cnc_msgs_py.job import parse_job
from cnc_msgs_py.machine import Machine, load_machine
from cnc_planner.kinds.thread import cycle
from cnc_planner.kinds.thread.cycle import ThreadCycle
from cnc_planner.kinds.thread.planning import plan_thread
from cnc_planner.kinds.thread.spec import ThreadError, ThreadSpec
from cnc_planner.motion.builder import PlanBuilder
from support import machines

T = 1e-3
LATHE = load_machine("lathe")


def planned(spec: ThreadSpec, machine: Machine) -> tuple[list[dict], np.ndarray] | str:
    """The pass table and the 1 ms setpoints of the uncompensated cycle (the joins do not
    depend on the drive), or the rejection."""
    builder = PlanBuilder(machine, {"x": 7e-3, "z": 4e-3})
    try:
        info = plan_thread(builder, spec, compensate=False)
    except ThreadError as err:
        return str(err)
    plan = builder.build()
    return info, np.stack(plan.sample(np.arange(0.0, plan.duration + T / 2, T)))


@st.composite
def threads(draw) -> ThreadSpec:
    pitch = draw(st.sampled_from([1.0, 1.5, 1.75, 2.0]))
    job = {
        "schema": "cnc_job/1", "job_id": "joins", "kind": "thread", "machine": "lathe",
        "spindle_rpm": draw(st.sampled_from([300, 450, 600, 900])),
        "thread": {"start_z": 4.0, "end_z": -draw(st.sampled_from([8.0, 16.0])), "major_radius": 6.0,
                   "pitch": pitch, "depth": round(0.6134 * pitch, 3), "passes": draw(st.sampled_from([3, 6])),
                   "starts": draw(st.sampled_from([1, 2])), "taper": draw(st.sampled_from([0.0, 0.0625]))},
    }
    if draw(st.booleans()):
        job["vibration"] = {"D": 1.5, "Q": draw(st.sampled_from([1.2, 4.0])), "phase_shift": 180}
    return ThreadSpec.from_job(parse_job(job))


def test_the_joins_found_are_the_exhaustive_searchs_on_drawn_lathes_and_threads():
    out_of_reach, may_reach, latest = ThreadCycle._out_of_reach, ThreadCycle._may_reach, cycle.latest
    passed_over = []  # joins the bisection ruled out, over every example
    gated = []  # later starts and face crossings _may_reach ruled out

    def counting(self, join, starts):
        passed_over.append(out_of_reach(self, join, starts))
        return passed_over[-1]

    def gating(self, place, t_from, state):
        gated.append(not may_reach(self, place, t_from, state))
        return not gated[-1]

    outcomes = []

    @settings(max_examples=12, deadline=None, derandomize=True, database=None,
              suppress_health_check=[HealthCheck.too_slow])
    @given(threads(), st.one_of(st.just(LATHE), machines(LATHE)))
    def run(spec: ThreadSpec, machine: Machine) -> None:
        with mock.patch.object(ThreadCycle, "_out_of_reach", counting), \
                mock.patch.object(ThreadCycle, "_may_reach", gating):
            bisected = planned(spec, machine)
        with (mock.patch.object(ThreadCycle, "_past_out_of_reach",
                                lambda self, revolutions, starts: itertools.chain.from_iterable(revolutions)),
              mock.patch.object(ThreadCycle, "_may_reach", lambda self, place, t_from, state: True),
              mock.patch.object(cycle, "latest", lambda holds, lo, hi, hint: latest(holds, lo, hi, None))):
            exhaustive = planned(spec, machine)
        if isinstance(exhaustive, str):
            assert bisected == exhaustive
            outcomes.append("refused")
            return
        assert bisected[0] == exhaustive[0]  # every pass's start, join and end, exactly
        assert np.array_equal(bisected[1], exhaustive[1])
        outcomes.append("planned")

    run()
    assert outcomes.count("planned") >= 4, outcomes
    assert sum(passed_over) > 100  # the bisection did pass over joins: not a vacuous equality
    assert sum(gated) > 20, sum(gated)  # and later starts and crossings were passed over
