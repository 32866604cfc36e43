"""helix() (its arithmetic compiled in _helix_kernel.c) equals the formula in numpy, written
with waveform() as helix.py states it, to the last bit: on drawn threads (external and
internal, straight and taper, with and without vibration, every pass) and drawn helix
angles, negative, whole-cycle and huge ones included."""
from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from cnc_planner.kinds.thread import _helix_kernel
from cnc_planner.kinds.thread.helix import helix
from cnc_planner.kinds.thread.spec import TWO_PI, Pass, ThreadSpec, ThreadVibration, passes_of
from cnc_planner.vibration.waveform import waveform


def numpy_helix(spec: ThreadSpec, cut: Pass, psi: np.ndarray) -> np.ndarray:
    """The helix as numpy evaluates its formula (helix()'s docstring), operation by operation."""
    omega, s, tan = spec.spindle_speed, spec.direction, math.tan(spec.infeed_angle)
    rate = cut.per_rev * omega / TWO_PI
    w, w1, w2, _ = waveform(cut.per_rev * psi / TWO_PI + cut.phase)
    depth = cut.depth - cut.amplitude * (1.0 - w)
    ddepth, dddepth = cut.amplitude * rate * w1, cut.amplitude * rate**2 * w2
    groove = spec.start_z + s * spec.pitch * psi / TWO_PI
    cone = spec.radial * spec.taper / 2 * s * spec.lead_speed
    out = np.empty((3, psi.size, 2))
    out[0, :, 0] = spec.origin[0] + spec.surface(groove) + spec.radial * depth
    out[0, :, 1] = spec.origin[1] + groove + s * depth * tan
    out[1, :, 0], out[1, :, 1] = cone + spec.radial * ddepth, s * (spec.lead_speed + tan * ddepth)
    out[2, :, 0], out[2, :, 1] = spec.radial * dddepth, s * tan * dddepth
    return out


@st.composite
def threads(draw) -> ThreadSpec:
    internal, taper = draw(st.booleans()), draw(st.sampled_from([0.0, 0.0625, 0.125]))
    pitch = draw(st.floats(0.5e-3, 4e-3))
    vibration = draw(st.none() | st.builds(ThreadVibration, st.floats(0.5, 4.0), st.floats(1.05, 3.0),
                                           st.sampled_from([0.0, math.pi, 2.0]), st.floats(0.0, 0.5)))
    start_z, length = draw(st.floats(1e-3, 6e-3)), draw(st.floats(5e-3, 40e-3))
    direction = draw(st.sampled_from([-1.0, 1.0]))
    return ThreadSpec(start_z=direction * start_z, end_z=-direction * length, major_radius=draw(st.floats(3e-3, 30e-3)),
                      pitch=pitch, depth=0.6 * pitch, spindle_speed=draw(st.floats(10.0, 150.0)),
                      passes=draw(st.integers(1, 8)), infeed_angle=math.radians(draw(st.floats(0.0, 30.0))),
                      spring_passes=1, internal=internal, taper=taper, vibration=vibration,
                      origin=(draw(st.floats(-0.2, 0.2)), draw(st.floats(-0.5, 0.5))))


@settings(max_examples=60, deadline=None)
@given(spec=threads(), seed=st.integers(0, 2**32 - 1))
def test_the_compiled_helix_is_the_numpy_formula_bit_for_bit(spec, seed):
    rng = np.random.default_rng(seed)
    psi = np.concatenate([
        rng.uniform(-5 * TWO_PI, 400 * TWO_PI, 300),  # behind the face and far along the thread
        TWO_PI * np.arange(-3.0, 4.0),  # whole revolutions: the waveform's phase lands on 0 exactly
        [0.0, -0.0, 1e7, -1e-300],
    ])
    for cut in passes_of(spec):
        expected = numpy_helix(spec, cut, psi)
        assert np.array_equal(helix(spec, cut, psi), expected)
        # one point at a time (the cycle's exits) and strided input give the same
        assert np.array_equal(helix(spec, cut, psi[5:6]), expected[:, 5:6])
        assert np.array_equal(helix(spec, cut, psi[::3]), expected[:, ::3])


def test_the_waveforms_phase_is_numpys_remainder_on_every_side_of_a_cycle():
    """np.mod's rules: into [0, 1) from below zero, +0 on a whole cycle, NaN stays NaN."""
    u = np.array([-2.75, -1.0, -0.0, 0.0, 0.25, 1.0, 3.5, 1e16 + 0.5, -1e-17, np.nan])
    angle = np.empty_like(u)
    _helix_kernel.phase(u, TWO_PI, 0.0, TWO_PI, angle)
    expected = TWO_PI * np.mod(TWO_PI * u / TWO_PI + 0.0, 1.0)  # per_rev 2pi, phase 0
    assert np.array_equal(angle, expected, equal_nan=True)
    assert np.array_equal(np.signbit(angle), np.signbit(expected))


@pytest.mark.parametrize("argument, value, message", [
    (0, np.zeros((2, 3)), "psi: expected one dimension"),
    (1, np.zeros(4), "sin: expected 3 values"),
    (3, np.zeros((3, 3, 2))[:, ::-1], "not C-contiguous"),
    (3, np.zeros((3, 4, 2)), "out: expected a C-contiguous float64"),
    (2, np.zeros(3, dtype=np.float32), "cos: expected an array of format 'd'"),
])
def test_the_kernel_refuses_arrays_it_would_overrun(argument, value, message):
    args = [np.zeros(3), np.zeros(3), np.zeros(3), np.zeros((3, 3, 2))]
    args[argument] = value
    with pytest.raises((ValueError, TypeError), match=message):
        _helix_kernel.state(*args, tuple(range(19)))
    _helix_kernel.state(*[np.zeros(3), np.zeros(3), np.zeros(3), np.zeros((3, 3, 2))], tuple(range(19)))


def test_a_spec_with_the_origin_moved_moves_the_helix_by_exactly_that():
    """A hand check beside the bitwise one: the axis origin is a plain offset of x and z."""
    spec = ThreadSpec(start_z=4e-3, end_z=-16e-3, major_radius=6e-3, pitch=1.75e-3, depth=1.07e-3,
                      spindle_speed=20 * math.pi, passes=6, infeed_angle=math.radians(29.5),
                      vibration=ThreadVibration(1.5, 1.2, math.pi, 0.0))
    moved = dataclasses.replace(spec, origin=(0.25, -0.5))
    psi = np.linspace(0.0, 10 * TWO_PI, 101)
    cut = passes_of(spec)[2]
    a, b = helix(spec, cut, psi), helix(moved, cut, psi)
    assert np.allclose(b[0] - a[0], [0.25, -0.5], rtol=0.0, atol=1e-15)
    assert np.array_equal(b[1:], a[1:])
