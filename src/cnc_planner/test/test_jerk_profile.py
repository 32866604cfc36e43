"""The bulk sampler equals ruckig's own at_time, instant by instant."""
import numpy as np
import pytest
from ruckig import ControlInterface, InputParameter, Result, Ruckig, Synchronization, Trajectory

from cnc_planner.motion.jerk_profile import TrajectorySampler, add_corrections, axis_row, sample_spans


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


def pieces(seed: int, count: int, stretch: float, local):
    """Every dof of random trajectories as sample_spans' pieces, piece k starting at a plan
    time that does not round trip through the subtraction, 40 instants each from before its
    start to ``stretch`` times its duration: (rows, starts, lo, hi, instants) and each
    dof's TrajectorySampler values at local(plan time - start, duration), and the
    trajectories' final states."""
    rows, starts, lo, hi, expected, ts, ends = [], [], [], [], [], [], []
    n = 0
    for k, trajectory in enumerate(random_trajectories(count, seed=seed)):
        sampler = TrajectorySampler(trajectory)
        start = 0.37 * k + 1e-3 / 3
        t = start + np.linspace(-0.01, stretch * trajectory.duration + 0.01, 40)
        values = sampler.sample(local(t - start, sampler.duration))
        end = trajectory.at_time(sampler.duration)
        for dof, row in enumerate(sampler.rows):
            ts.append(t)
            rows.append(row)
            starts.append(start)
            lo.append(n)
            hi.append(n + len(t))
            expected.append(values[:, :, dof])
            ends.append([q[dof] for q in end])
            n += len(t)
    args = np.array(rows), np.array(starts), np.array(lo), np.array(hi), np.concatenate(ts)
    return args, np.concatenate(expected, axis=1), np.array(ends)


def test_one_call_over_many_pieces_equals_each_sampler_bit_for_bit():
    """sample_spans over many pieces at once (as a timeline samples its ruckig pieces)
    gives exactly each dof's own TrajectorySampler values at its local instants (plan time
    minus the piece's start), with and without brakes, into strided outputs as a plan's
    columns are."""
    args, expected, _ = pieces(11, 300, 1.1, lambda t, duration: t)
    plan = np.zeros((3, expected.shape[1], 2))  # the second column stays untouched
    sample_spans(*args, (plan[0, :, 0], plan[1, :, 0], plan[2, :, 0]))
    assert np.array_equal(plan[:, :, 0], expected)
    assert not plan[:, :, 1].any()


def test_held_pieces_equal_sampling_at_the_end_after_it_bit_for_bit():
    """held=True (the thread cycle's stretches: an axis at rest in its end state after a
    move) gives each dof's sampler values at np.minimum(local time, duration) exactly; past
    the end of a move that ends moving it is not the unheld continuation."""
    args, expected, ends = pieces(13, 200, 1.5, np.minimum)
    held, unheld = np.zeros_like(expected), np.zeros_like(expected)
    sample_spans(*args, held, held=True)
    sample_spans(*args, unheld)
    assert np.array_equal(held, expected)
    assert np.sum(np.abs(ends[:, 1]) > 1e-6) > 20 and not np.array_equal(held, unheld)


def test_a_one_dof_row_is_the_samplers_and_several_dofs_have_none():
    one = [tr for tr in random_trajectories(120, seed=17) if tr.degrees_of_freedom == 1]
    assert len(one) > 20
    for trajectory in one:
        assert np.array_equal(axis_row(trajectory), TrajectorySampler(trajectory).rows[0])
    several = next(tr for tr in random_trajectories(20, seed=17) if tr.degrees_of_freedom > 1)
    with pytest.raises(ValueError, match="one-dof"):
        axis_row(several)


def test_bad_spans_are_refused_naming_the_array():
    sampler = TrajectorySampler(next(random_trajectories(1, seed=3)))
    out = [np.zeros(4) for _ in range(3)]
    with pytest.raises(ValueError, match="piece 0"):
        sample_spans(np.array(sampler.rows[:1]), np.zeros(1), np.array([2]), np.array([5]), np.zeros(4), out)
    with pytest.raises(TypeError, match="p: expected an array of format 'd'"):
        sample_spans(np.array(sampler.rows[:1]), np.zeros(1), np.array([0]), np.array([4]), np.zeros(4),
                     [np.zeros(4, np.float32)] + out[1:])


def test_corrections_equal_np_interp_added_in_order_bit_for_bit():
    """add_corrections (the compiled X/Y correction pass) equals np.interp on the servo
    grid added with np.add.at in part order: before, on and between grid points, past the
    end, overlapping parts, and a one-sample correction."""
    rng = np.random.default_rng(5)
    period = 1e-3
    corrections = [rng.normal(size=(3, k)) for k in (1, 2, 57, 300)]
    table = np.concatenate([c.ravel() for c in corrections])
    bases = np.cumsum([0] + [c.size for c in corrections])[:-1]
    ts = np.sort(np.concatenate([np.arange(600) * period, rng.uniform(-0.01, 0.4, 400)]))
    parts = [(int(rng.integers(4)), float(rng.uniform(-0.05, 0.3)), *sorted(rng.integers(0, len(ts), 2))) for _ in range(60)]
    parts += [(3, 0.0, 0, len(ts)), (2, 0.1, 10, 10)]  # the grid itself; an empty part
    base = [rng.normal(size=len(ts)) for _ in range(3)]
    expected = [b.copy() for b in base]
    for c, start, lo, hi in parts:
        grid = np.arange(corrections[c].shape[1]) * period
        for q in range(3):
            np.add.at(expected[q], np.arange(lo, hi), np.interp(ts[lo:hi] - start, grid, corrections[c][q]))
    out = [b.copy() for b in base]
    add_corrections(table, [bases[c] for c, *_ in parts], [corrections[c].shape[1] for c, *_ in parts],
                    [start for _, start, _, _ in parts], [lo for *_, lo, _ in parts], [hi for *_, hi in parts],
                    period, ts, out)
    assert all(np.array_equal(o, e) for o, e in zip(out, expected))
    with pytest.raises(ValueError, match="part 0"):
        add_corrections(table, [table.size], [2], [0.0], [0], [1], period, ts, out)
