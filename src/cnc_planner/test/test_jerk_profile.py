"""The bulk sampler equals ruckig's own at_time, instant by instant."""
import numpy as np
import pytest
from ruckig import ControlInterface, InputParameter, Result, Ruckig, Synchronization, Trajectory

from cnc_planner.motion.jerk_profile import TrajectorySampler, sample_pieces


def random_trajectories(count: int, seed: int):
    """Position and velocity interfaces, 1-3 dofs, synchronised or not, and starts beyond
    the limits (so ruckig prepends a brake) about half of the time."""
    rng = np.random.default_rng(seed)
    for k in range(count):
        n = int(rng.integers(1, 4))
        inp = InputParameter(n)
        inp.max_velocity = rng.uniform(0.5, 2, n).tolist()
        inp.max_acceleration = rng.uniform(1, 5, n).tolist()
        inp.max_jerk = rng.uniform(5, 100, n).tolist()
        inp.current_position = rng.uniform(-1, 1, n).tolist()
        inp.target_position = rng.uniform(-1, 1, n).tolist()
        scale = 3.0 if k % 2 else 0.3
        inp.current_velocity = rng.uniform(-scale, scale, n).tolist()
        inp.current_acceleration = rng.uniform(-2 * scale, 2 * scale, n).tolist()
        if k % 3 == 0:
            inp.control_interface = ControlInterface.Velocity
            inp.target_velocity = rng.uniform(-1, 1, n).tolist()
        if k % 5 == 0:
            inp.synchronization = Synchronization.No
        trajectory = Trajectory(n)
        if Ruckig(n).calculate(inp, trajectory) in (Result.Working, Result.Finished):
            yield trajectory


def test_bulk_sampling_equals_at_time_with_and_without_brakes():
    braked = 0
    for trajectory in random_trajectories(600, seed=7):
        braked += any(p.brake.duration > 0 for p in trajectory.profiles[0])
        t = np.concatenate([np.linspace(-0.01, 1.2 * trajectory.duration + 0.01, 150), [trajectory.duration, 0.0]])
        reference = np.array([trajectory.at_time(float(x)) for x in t]).transpose(1, 0, 2)
        assert TrajectorySampler(trajectory).sample(t) == pytest.approx(reference, abs=1e-12, rel=0)
    assert braked > 100  # the brake pre-trajectory was exercised



def test_one_pass_over_many_pieces_equals_each_sampler_bit_for_bit():
    """sample_pieces (a timeline's runs of ruckig pieces) gives exactly the values of each
    dof's own sampler: plans hashed before and after must not differ by one ulp."""
    pieces, expected, lo = [], [], 0
    for trajectory in random_trajectories(300, seed=11):
        sampler = TrajectorySampler(trajectory)
        t = np.linspace(0.0, 1.1 * trajectory.duration, 40)
        values = sampler.sample(t)
        for dof, row in enumerate(sampler.rows):
            pieces.append((lo, lo + len(t), t, row))
            expected.append(values[:, :, dof])
            lo += len(t)
    out = [np.zeros(lo) for _ in range(3)]
    sample_pieces(pieces, out)
    assert np.array_equal(np.array(out), np.concatenate(expected, axis=1))
