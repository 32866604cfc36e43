"""The planners alive, counted from liveliness changes of which the first may be missed."""
from cnc_msgs_py.liveliness import AliveWriters


def counts(changes: list[int]) -> list[int]:
    alive = AliveWriters()
    return [alive.change(change) for change in changes]


def test_every_event_heard():
    assert counts([+1, -1, +1]) == [1, 0, 1]  # a planner, lost, back


def test_the_first_alive_missed():
    # The planner was alive before the event was armed: its loss is the first event heard.
    assert counts([-1, +1, -1]) == [0, 1, 0]


def test_a_missed_alive_is_known_once_its_loss_shows_it():
    # Two planners, the first alive unheard: the count is one short until that one is lost.
    assert counts([+1, -1, +1, -1, -1]) == [1, 0, 1, 0, 0]
    assert counts([+1, +1, -1, -1, -1, +1]) == [1, 2, 1, 0, 0, 1]


def test_no_count_goes_below_zero_however_many_were_missed():
    alive = AliveWriters()
    assert [alive.change(c) for c in (-1, -1)] == [0, 0]
    assert alive.change(+1) == 1
