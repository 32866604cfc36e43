"""The stream's lead, from chunks whose arrival and reach are set by hand."""
import pytest

from cnc_analysis.recording import Chunk, Run
from cnc_analysis.summary import stream_leads

MS = 1_000_000


def chunk(stamp_ms: int, end_ms: int, received_ms: int) -> Chunk:
    return Chunk(stamp_ms * MS, end_ms * MS, end_ms - stamp_ms + 1, True, received_ms * MS)


def test_the_lead_is_what_was_buffered_beyond_each_arrival():
    # 100-point chunks sent 1 s ahead, then one 0.3 s late: the buffer reached 1.299 s when it came at 1.6 s
    run = Run(chunks=[chunk(1000, 1099, 0), chunk(1100, 1199, 100), chunk(1200, 1299, 200), chunk(1300, 1399, 1600)])
    t, lead = stream_leads(run)
    assert t == pytest.approx([0.1, 0.2, 1.6])
    assert lead == pytest.approx([0.999, 0.999, -0.301])


def test_a_stop_replacing_buffered_points_ends_the_buffer_where_it_ends():
    # a stop from 0.5 s to 0.799 s arrives at 0.2 s and replaces what reached 0.999 s
    run = Run(chunks=[chunk(0, 999, 0), chunk(500, 799, 200), chunk(800, 899, 300)])
    assert stream_leads(run)[1] == pytest.approx([0.799, 0.499])


def test_one_chunk_has_no_lead_to_measure():
    assert all(len(x) == 0 for x in stream_leads(Run(chunks=[chunk(0, 99, 0)])))
