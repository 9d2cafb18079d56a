"""Numbers and units as the tables print them (issue 35 item 4)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import assume, given
from hypothesis import strategies as st

from aquasim_py.reporting.display import column_blocks, fits, format_number, format_row, unit_of, wrap_name


@pytest.mark.parametrize(
    ("value", "text"),
    [
        (0.545767, "0.5458"),
        (2.13406, "2.134"),
        (9.91498e-07, "9.915e-07"),
        (1369, "1369"),
        (np.int64(7), "7"),
        (9.9996, "10.00"),  # rounded before the digits are counted
        (99999.5, "1.000e+05"),
        (-0.0123456, "-0.01235"),
        (0.0, "0"),
        (math.nan, "-"),
        (None, "-"),
        (True, "True"),
        ("text", "text"),
    ],
)
def test_format_number(value, text):
    assert format_number(value) == text


@given(st.floats(allow_nan=False, allow_infinity=False, min_value=-9.99e98, max_value=9.99e98))
def test_a_number_is_short_and_reads_back_to_four_digits(x):
    assume(x == 0.0 or abs(x) >= 1e-99)  # two-digit exponents
    text = format_number(x)
    assert len(text) <= 10
    back = float(text)
    assert back == pytest.approx(x, rel=5e-4, abs=0.0)


def test_times_take_the_unit_of_their_row():
    # the complaint: sync errors printed as 3.05157e-05 s
    shown, cells = format_row("sync.mean_abs_error_s", [3.05157e-05, 5.53226e-05, 0.00100079, 7.86779e-05])
    assert shown == "sync.mean_abs_error (us)"
    assert cells == ["30.52", "55.32", "1001", "78.68"]
    assert format_row("x.delay_s", [0.25, 0.5])[0] == "x.delay (ms)"
    assert format_row("x.duration_s", [12.0])[0] == "x.duration (s)"
    assert format_row("x.t_s", [3e-9])[0] == "x.t (ns)"
    assert format_row("localization.rmse_m", [0.5, math.nan]) == ("localization.rmse (m)", ["0.5000", "-"])
    assert format_row("packets.sent", [614]) == ("packets.sent", ["614"])
    assert unit_of("a.speed_mps").unit == "m/s" and unit_of("a.snr_db").unit == "dB"


def test_names_break_after_their_parts():
    assert wrap_name("ramezani.localization_essp.sqrt_mean_crb (m)", 26) == (
        "ramezani.localization_\nessp.sqrt_mean_crb (m)"
    )
    assert wrap_name("short", 26) == "short"


def test_column_blocks_fit_and_are_even():
    blocks = column_blocks(28, [9] * 5, 80)
    assert [len(b) for b in blocks] == [3, 2]
    assert [i for b in blocks for i in b] == list(range(5))
    assert all(28 + 4 + sum(9 + 3 for _ in b) <= 80 for b in blocks)
    assert column_blocks(10, [9] * 5, 200) == [[0, 1, 2, 3, 4]]


def test_fits_counts_the_longest_word():
    assert fits({"a": ["one two three"]}, 20)
    assert not fits({"a": ["(sync.final_mean_abs_error_s),"], "b": ["x"]}, 30)
