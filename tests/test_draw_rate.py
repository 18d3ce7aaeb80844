"""The page's drawing rate paces what the server sends it (``study.server.draw_rate``)."""

from __future__ import annotations

import itertools

import pytest

from study.server.draw_rate import MIN_INSET_HZ, MIN_SCENE_HZ, Pacer, inset_hz, scene_hz
from study.server.page_inputs import InputRejected, parse_draw_rate


def test_a_page_gets_twice_the_frames_it_draws_within_the_servers_bounds() -> None:
    assert scene_hz(None, render_hz=60.0) == 60.0  # not said yet: everything
    assert scene_hz(14.0, render_hz=60.0) == 28.0
    assert scene_hz(59.0, render_hz=60.0) == 60.0
    assert scene_hz(2.0, render_hz=60.0) == MIN_SCENE_HZ
    assert scene_hz(14.0, render_hz=20.0) == 20.0  # --render-hz still caps
    assert inset_hz(None, most_hz=15.0) == 15.0
    assert inset_hz(10.0, most_hz=15.0) == 10.0
    assert inset_hz(40.0, most_hz=15.0) == 15.0
    assert inset_hz(1.0, most_hz=15.0) == MIN_INSET_HZ


@pytest.mark.parametrize("hz", [10.0, 20.0, 28.0, 45.0])
def test_a_loop_at_60_hz_sends_at_the_rate_asked_not_at_a_divisor_of_its_own(hz: float) -> None:
    pacer = Pacer()
    sent = [i / 60 for i in range(600) if pacer.due(i / 60, hz)]  # ten seconds of wakes
    assert abs(len(sent) / 10 - hz) <= 0.02 * hz
    gaps = [b - a for a, b in itertools.pairwise(sent)]
    assert min(gaps) >= 1 / 60 - 1e-9 and max(gaps) <= 1 / hz + 1 / 60 + 1e-9


def test_no_burst_after_an_idle_stretch_and_a_faster_rate_takes_at_once() -> None:
    pacer = Pacer()
    assert pacer.due(0.0, 20.0)
    wakes = [100 + i / 60 for i in range(60)]  # 100 s later: the pace again, not a catch-up
    sent = [pacer.due(t, 20.0) for t in wakes]
    assert sent[0] and sum(sent[:6]) <= 3 and 19 <= sum(sent) <= 21
    assert not any(a and b for a, b in itertools.pairwise(sent))
    assert pacer.due(200.0, 60.0) and pacer.due(200.0 + 1 / 60, 60.0)


def test_draw_rates_are_whole_numbers_from_1_to_1000() -> None:
    assert parse_draw_rate("14") == 14.0
    assert parse_draw_rate("1000") == 1000.0
    for bad in ("0", "1001", "", " 14", "14 ", "1e3", "14.0", "-3", "\u0661\u0664", "9" * 50):
        with pytest.raises(InputRejected):
            parse_draw_rate(bad)
