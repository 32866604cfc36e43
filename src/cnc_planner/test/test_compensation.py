"""The drive compensation's learning: its FFT padding is free where the learning operator
decays, so it is padded to a length the FFT is fast at."""
import math

import numpy as np

from cnc_msgs_py.machine import load_machine
from cnc_planner.motion import compensation
from cnc_planner.motion.compensation import _fast_length, learn_correction
from cnc_servo_bridge.drive import DriveModel


def _smooth(k: int) -> bool:
    for prime in (2, 3, 5):
        while k % prime == 0:
            k //= prime
    return k == 1


def test_the_fast_length_is_the_least_5_smooth_length_at_least_n():
    for n in [*range(1, 3000), 16214, 31010]:
        length = _fast_length(n)
        assert length >= n and _smooth(length), n
        assert not any(_smooth(k) for k in range(n, length)), n
    assert (_fast_length(16214), _fast_length(31010)) == (16384, 31104)


def test_on_the_shipped_drives_the_padding_changes_the_correction_by_rounding_only(monkeypatch):
    """A thread-like reference on the lathe's x and z: learned with the fast length and with
    exactly twice the samples (the padding before) the corrections agree to 1e-12 m."""
    machine = load_machine("lathe")
    drive = DriveModel(machine, 0.001, ("x", "z"))
    t = np.arange(15505) * 0.001  # thread_m16's length: 2n = 31010 = 2*5*7*443
    ramp = np.clip((t - 0.2) / 0.5, 0.0, 1.0) * np.clip((t[-1] - 0.2 - t) / 0.5, 0.0, 1.0)
    p = np.stack([1e-4 * ramp * np.sin(2 * math.pi * 7 * t), 2e-3 * ramp], 1)
    v, a = np.gradient(p, 0.001, axis=0), np.gradient(np.gradient(p, 0.001, axis=0), 0.001, axis=0)
    fast = learn_correction(drive, p, v, a, 50)
    monkeypatch.setattr(compensation, "_fast_length", lambda n: n)
    exact_double = learn_correction(drive, p, v, a, 50)
    assert np.max(np.abs(fast)) > 1e-6  # a correction worth the name
    assert np.max(np.abs(fast - exact_double)) < 1e-12
