"""The drive compensation's learning operator: the circular convolution it always was,
computed on FFT lengths that are fast."""
import numpy as np

from cnc_msgs_py.machine import load_machine
from cnc_planner.motion.compensation import _fast_length, _inverse_response, _learning_operator
from cnc_servo_bridge.drive import DriveModel


def _smooth(k: int) -> bool:
    for prime in (2, 3, 5):
        while k % prime == 0:
            k //= prime
    return k == 1


def test_the_fast_length_is_the_least_5_smooth_length_at_least_n():
    for n in [*range(1, 3000), 31010]:
        length = _fast_length(n)
        assert length >= n and _smooth(length), n
        assert not any(_smooth(k) for k in range(n, length)), n
    assert _fast_length(31010) == 31104


def _circular(inverse: np.ndarray, error: np.ndarray) -> np.ndarray:
    """The step as learned before: error zero-padded to 2n, times the inverse, back."""
    n = error.shape[0]
    return np.fft.irfft(np.fft.rfft(error, 2 * n, axis=0) * inverse, 2 * n, axis=0)[:n]


def test_the_learning_operator_is_the_circular_convolution_over_2n():
    """On the lathe's drives (a kernel that decays within milliseconds) and on a random
    response (one that never decays, as on some drawn machines, where any other padding
    would change the correction at all), at lengths with awkward prime factors."""
    rng = np.random.default_rng(7)
    drive = DriveModel(load_machine("lathe"), 0.001, ("x", "z"))
    for n in (1, 2, 7, 443, 1000, 15505):  # 2n = 31010 = 2*5*7*443: thread_m16's
        error = rng.normal(size=(n, 2)) * 1e-5
        lathe = _inverse_response(drive, 2 * n)
        wild = rng.normal(size=(n + 1, 2)) + 1j * rng.normal(size=(n + 1, 2))
        for inverse in (lathe, wild):
            expected = _circular(inverse, error)
            got = _learning_operator(inverse, n)(error)
            assert got.shape == expected.shape
            assert np.max(np.abs(got - expected)) <= 1e-12 * np.max(np.abs(expected)), n
