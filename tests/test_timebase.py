"""Time stamps: rate from the column, cross-check with --rate, irregular steps named by line."""

import numpy as np
import pytest

from bayes_imu.errors import InputError
from bayes_imu.io.timebase import RATE_TOLERANCE, check_time


def _lines(n):
    return np.arange(2, n + 2)  # a header on line 1


def test_regular_time_gives_rate_and_all_samples(rng):
    # clock jitter (0.2% of a step) is accepted
    t = np.arange(1000) / 200.0 + 1e-5 * rng.standard_normal(1000)
    base = check_time(t, lines=_lines(1000))
    assert base.rate_source == "time column" and (base.start, base.stop) == (0, 1000)
    # the span estimate: rate error ~ 200 Hz * sqrt(2) 1e-5 s / 5 s = 6e-4 Hz (1 sigma); 0.003 Hz is
    # 5 sigma
    assert abs(base.rate_hz - 200.0) < 0.003 and base.first_line == 2 and base.last_line == 1001


def test_rate_alone_and_rate_cross_check():
    assert check_time(None, rate_hz=50, n_samples=10).rate_hz == 50.0
    t = np.arange(100) / 100.0
    assert check_time(t, rate_hz=100.0 * (1 + RATE_TOLERANCE / 2)).rate_hz == pytest.approx(100.0)
    with pytest.raises(InputError, match=r"gives 100 Hz, .* but rate_hz is 105 Hz"):
        check_time(t, rate_hz=105, where="log.csv")
    with pytest.raises(InputError, match="no sample rate"):
        check_time(None, n_samples=10)


def test_a_unit_picked_by_the_rate_is_not_said_to_agree_with_a_rate_it_disagrees_with():
    """Stamps 0.01 apart and rate_hz=150: seconds are the unit whose rate (100 Hz) lies within 50%
    of the rate given, so they are picked, and the two rates then disagree by more than 1%. The
    message said "stamps in s (agrees with rate_hz=150)" and, in the same line, that they do not
    agree; it now says how the unit was picked, with one pair of parentheses. Where they agree, the
    record says the same."""
    t = np.arange(100) / 100.0
    with pytest.raises(InputError) as info:
        check_time(t, rate_hz=150, where="timed.csv")
    text = str(info.value)
    assert text == ("timed.csv: the time column gives 100 Hz, a step of 0.01 s with stamps in s "
                    "(the unit nearest rate_hz=150), but rate_hz is 150 Hz; expected them to agree "
                    "within 1% (or give only one)")
    assert "agrees" not in text
    base = check_time(t, rate_hz=100.5)
    assert (base.time_unit, base.time_unit_source) == ("s", "the unit nearest rate_hz=100.5")
    for bad in (0, -1, float("nan"), float("inf"), "fast"):
        with pytest.raises(InputError, match="rate_hz="):
            check_time(None, rate_hz=bad, n_samples=10)


@pytest.mark.parametrize("where, value, message", [
    (500, 4.0, "line 502: time goes backwards from 4.99 s to 4.0 s"),
    (500, 4.99, "line 502: time stamp 4.99 s repeats"),
    (500, 5.5, "line 502: gap from 4.99 s to 5.5 s (0.51 s, about 50 missing samples)"),
])
def test_irregular_steps_are_named_by_line(where, value, message):
    t = np.arange(1000) / 100.0
    if value == 5.5:
        t[where:] += 0.5  # the clock jumps: 4.99 s, then 5.5 s
    else:
        t[where] = value
    with pytest.raises(InputError) as info:
        check_time(t, lines=_lines(1000), where="log.csv: column 'time'")
    text = str(info.value)
    assert message in text and "\n" not in text and "gaps='longest'" in text, text


def test_longest_segment_is_used_and_reported():
    t = np.arange(1000) / 100.0
    t[300:] += 1.0  # gap after 300 samples
    t[900:] += 2.0  # another after 900
    base = check_time(t, lines=_lines(1000), gaps="longest")
    assert (base.start, base.stop) == (300, 900)
    assert base.irregular == 2 and base.dropped == 400
    assert base.first_line == 302 and base.last_line == 901
    assert "lines 302-901 (600 of 1000 samples)" in base.action
    with pytest.raises(InputError, match="gaps='skip'"):
        check_time(t, gaps="skip")
