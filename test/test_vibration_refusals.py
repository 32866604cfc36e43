"""Every refusal of a vibration names a parameter set that works on that machine (issue 25),
checked over drawn machine descriptions: the up-front checks a feed (move, turn, drill) and
a thread run are given a drawn lathe or mill, a waveform and a spindle speed; where they
refuse one on a vibration field, the set the refusal names is parsed back and passes the
same check (a feed's at the speed it names, a thread's with the changed parameter or at
the highest speed named).

Offline and check-level only (no drive model, no ROS): the planner refuses with these
checks before it plans anything (vibration.feed, kinds.drill.block, kinds.thread.checks).
"""
from __future__ import annotations

import dataclasses
import math
import re

from hypothesis import given, settings
from hypothesis import strategies as st

from cnc_msgs_py.machine import load_machine
from cnc_planner.kinds.thread.checks import check_thread
from cnc_planner.kinds.thread.spec import ThreadError, ThreadSpec, ThreadVibration
from cnc_planner.vibration.feed import vibration_error
from cnc_planner.vibration.waveform import Vibration, VibrationError, check_vibration, er_vibration
from support import log_uniform, machines

LATHE, MILL = load_machine("lathe"), load_machine("mill3")
FEED_SET = re.compile(r"(?:D (?P<D>[\d.]+)|E (?P<E>[\d.]+) R (?P<R>[\d.]+)) Q (?P<Q>[\d.]+) "
                      r"(?:up to|at) (?P<rpm>\d+) rpm")
THREAD_SET = re.compile(r"(?:(?P<name>Q|D|phase_shift) (?P<value>[\d.]+) works (?:at|up to) (?P<rpm>\d+) rpm"
                        r"|max spindle speed (?P<top>\d+) rpm)")
FEED_WAVES = [Vibration(D=1.5, Q=1.2), Vibration(D=1.5, Q=0.9), Vibration(D=2.5, Q=1.2), Vibration(D=0.8, Q=1.2),
              er_vibration(2.0, 0.5), er_vibration(3.0, 1.0), Vibration(D=None, Q=1.4, E=3.0, R=1.5)]
THREAD_WAVES = [ThreadVibration(1.5, 1.2), ThreadVibration(1.5, 0.9), ThreadVibration(0.5, 1.2),
                ThreadVibration(0.8, 1.2), ThreadVibration(1.5, 1.2, 0.0)]


def rad_s(rpm: float) -> float:
    return rpm * 2 * math.pi / 60


@settings(max_examples=40, deadline=None, derandomize=True)
@given(base=st.sampled_from([LATHE, MILL]), data=st.data(), wave=st.sampled_from(FEED_WAVES),
       rpm=log_uniform(100.0, 6000.0), feed_mm=log_uniform(0.02, 0.3))
def test_a_refused_feed_vibration_names_a_set_that_works(base, data, wave, rpm, feed_mm):
    axis = data.draw(machines(base)).axes["z"]
    feed = feed_mm * 1e-3
    try:
        check_vibration(wave, feed, rad_s(rpm), axis)
        return
    except VibrationError as err:
        refused = vibration_error(err, wave, feed, rad_s(rpm), axis)
    assert refused.field.startswith("vibration"), refused
    named = FEED_SET.search(str(refused).split("works: ", 1)[-1])
    assert named, refused
    works = (Vibration(D=float(named["D"]), Q=float(named["Q"])) if named["D"]
             else Vibration(D=None, Q=float(named["Q"]), E=float(named["E"]), R=float(named["R"])))
    check_vibration(works, feed, rad_s(float(named["rpm"])), axis)  # raises if it does not work


@settings(max_examples=25, deadline=None, derandomize=True)
@given(data=st.data(), wave=st.sampled_from(THREAD_WAVES), rpm=log_uniform(200.0, 2500.0))
def test_a_refused_thread_vibration_names_a_set_that_works(data, wave, rpm):
    machine = data.draw(machines(LATHE))
    spec = ThreadSpec(start_z=4e-3, end_z=-16e-3, major_radius=6e-3, pitch=1.75e-3, depth=1.07e-3,
                      spindle_speed=rad_s(rpm), passes=6, infeed_angle=math.radians(29.5), spring_passes=1,
                      vibration=wave)
    try:
        check_thread(spec, machine)
        return
    except ThreadError as err:
        refused = err
    if not refused.field.startswith("vibration"):
        return  # the thread itself (its speed along z), not its vibration
    named = THREAD_SET.search(str(refused))
    assert named, refused
    if named["top"]:
        works = dataclasses.replace(spec, spindle_speed=rad_s(float(named["top"])))
    else:
        value = math.radians(float(named["value"])) if named["name"] == "phase_shift" else float(named["value"])
        works = dataclasses.replace(spec, spindle_speed=min(spec.spindle_speed, rad_s(float(named["rpm"]))),
                                    vibration=dataclasses.replace(wave, **{named["name"]: value}))
    try:
        check_thread(works, machine)
    except ThreadError as err:  # the named set may still meet a limit of the thread itself
        assert not err.field.startswith("vibration"), (refused, err)
