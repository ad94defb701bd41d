"""A line of parts (SPEC section 13): the reference belt at speed_max with its feed (a
block every 8 s by the twin's time, jittered), jobs one after another: every block fed
is picked, none let go (109) nor gone by, at the picks per minute the cell's cycle allows
(bench/bench_conveyor.py --parts N runs longer lines and prints the figures)."""

from __future__ import annotations

from bench.bench_conveyor import run_line

#: check's bound for the reference pick at 0.30 m/s is 7.7-7.9 parts/min (its cycle); a
#: block every 8 s offers 7.5 a minute
FEED_PER_MIN = 60 / 8.0


def test_a_run_of_blocks_at_speed_max_misses_none():
    line = run_line(6)
    assert line["codes"] == [0] * 6
    assert (line["let_go"], line["gone_by"]) == (0, 0)
    # each block is picked as it comes: the line's pace is the feed's
    assert 0.9 * FEED_PER_MIN < line["ppm"] <= 1.05 * FEED_PER_MIN + 0.5
