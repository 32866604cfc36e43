"""The drive compensation's learning operator: a convolution with the inverse drive
response's kernel, computed on FFT lengths that are fast."""
import numpy as np

from cnc_msgs_py.machine import load_machine
from cnc_planner.motion.compensation import INVERSE_BAND, _fast_length, _inverse_response, _learning_operator
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


def _padded_2n(drive: DriveModel, error: np.ndarray) -> np.ndarray:
    """The step as learned before: error zero-padded to 2n, times the inverse at 2n bins, back."""
    n = error.shape[0]
    inverse = _inverse_response(drive, 2 * n, INVERSE_BAND)
    return np.fft.irfft(np.fft.rfft(error, 2 * n, axis=0) * inverse, 2 * n, axis=0)[:n]


def test_the_learning_operator_convolves_with_the_kernel_over_lags_within_n():
    """Each output is the sum over the error's samples of the kernel at their lag (the
    response's kernel at the operator's length): checked term by term on short errors."""
    rng = np.random.default_rng(3)
    drive = DriveModel(load_machine("mill3_soft"), 0.001, ("x", "y", "z"))
    for n in (1, 2, 7, 40):
        length = _fast_length(2 * n - 1)
        kernel = np.fft.irfft(_inverse_response(drive, length, INVERSE_BAND), length, axis=0)
        error = rng.normal(size=(n, 3)) * 1e-5
        expected = np.array([[sum(error[i, j] * kernel[(q - i) % length, j] for i in range(n))
                              for j in range(3)] for q in range(n)])
        got = _learning_operator(drive, n, INVERSE_BAND)(error)
        assert np.max(np.abs(got - expected)) <= 1e-12 * np.max(np.abs(expected)), n


def test_the_learning_operator_is_the_2n_padded_one_where_the_kernel_dies_out():
    """On the shipped drives, at lengths with awkward prime factors, the operator is the
    2n-padded circular convolution it was, but for the kernel's aliased tail (it falls off
    as the cube of the lag): within 3e-7 of the correction at n = 443, 5e-11 at 15505."""
    rng = np.random.default_rng(7)
    for machine, joints in (("lathe", ("x", "z")), ("mill3", ("x", "y", "z"))):
        drive = DriveModel(load_machine(machine), 0.001, joints)
        for n in (443, 1000, 15505):  # 2n = 31010 = 2*5*7*443: thread_m16's
            error = rng.normal(size=(n, len(joints))) * 1e-5
            expected = _padded_2n(drive, error)
            got = _learning_operator(drive, n, INVERSE_BAND)(error)
            assert got.shape == expected.shape
            bound = 1e-6 if n < 1000 else 1e-10
            assert np.max(np.abs(got - expected)) <= bound * np.max(np.abs(expected)), (machine, n)
