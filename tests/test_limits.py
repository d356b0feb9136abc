"""limits.Bounded: one number type for every numeric option and file value (issue 24)."""

from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np
import pytest

from bmg160_emu import limits
from bmg160_emu.durations import MAX_SIMULATED_S, parse_duration
from bmg160_emu.limits import Bounded, LimitError

TEMPERATURE = Bounded("temperature", -40.0, 85.0, "deg C")
COUNT = Bounded("runs", 1, 1000, integer=True)


@pytest.mark.parametrize("text", ["nan", "NaN", "inf", "-inf", "1e308", "-1e308", "1e309",
                                  "85.0001", "-40.5", "", " ", "abc", "1e9d", "1_0", "0x10"])
def test_a_bad_number_is_one_line_naming_where_and_the_range(text):
    with pytest.raises(LimitError) as exc:
        TEMPERATURE.parse(text, "cfg.toml:3")
    message = str(exc.value)
    assert "\n" not in message
    assert message.startswith("cfg.toml:3: temperature must be a number from -40 to 85 deg C")


@pytest.mark.parametrize("text,value", [("85", 85.0), ("-40", -40.0), (" 23.5 ", 23.5),
                                        ("-0", 0.0), ("1e1", 10.0)])
def test_a_good_number_is_returned_as_a_float(text, value):
    got = TEMPERATURE.parse(text)
    assert got == value and type(got) is float and math.copysign(1, got) == math.copysign(1, value)


@pytest.mark.parametrize("text", ["0", "1001", "1e3", "1.5", "nan", "inf", str(2**63), "9" * 400,
                                  "1_000", "-1"])
def test_an_integer_quantity_refuses_exponents_fractions_and_range(text):
    with pytest.raises(LimitError, match="runs must be an integer from 1 to 1,000"):
        COUNT.parse(text)


@pytest.mark.parametrize("text,value", [("1", 1), ("1000", 1000), ("0x10", 16), ("+7", 7)])
def test_an_integer_quantity_reads_decimal_and_prefixed_integers(text, value):
    assert COUNT.parse(text) == value and type(COUNT.parse(text)) is int


@pytest.mark.parametrize("value", [True, None, "3", [1], float("nan"), np.float64("inf"), 2.5])
def test_check_refuses_what_a_file_gives_that_is_not_a_usable_count(value):
    with pytest.raises(LimitError):
        COUNT.check(value, "x.toml: key runs")


def test_check_takes_numpy_scalars_and_whole_floats():
    assert COUNT.check(np.int64(5)) == 5 and COUNT.check(7.0) == 7
    assert TEMPERATURE.check(np.float32(20.5)) == 20.5


def test_every_named_limit_is_listed_in_the_docs_with_its_range():
    page = (Path(__file__).resolve().parents[1] / "docs" / "limits.md").read_text()
    named = {k: v for k, v in vars(limits).items() if isinstance(v, Bounded)}
    assert len(named) >= 20
    for key, bounded in named.items():
        assert f"`{key}`" in page, f"docs/limits.md does not list limits.{key}"
        row = next(line for line in page.splitlines() if line.startswith(f"| `{key}` |"))
        low, high = re.findall(r"from (.+) to (.+?)(?: [a-zA-Z/ ]+)?$", bounded.describe())[0]
        assert low in row and high in row, f"docs/limits.md gives another range for {key}"
        assert bounded.reason, f"limits.{key} gives no reason for its range"


def test_durations_are_capped_at_thirty_days_and_one_nanosecond():
    assert parse_duration("30d") == MAX_SIMULATED_S
    for text in ("30.001d", "1e308us", "1e14s"):
        with pytest.raises(ValueError, match="cap on simulated time"):
            parse_duration(text)
    with pytest.raises(ValueError, match="1 ns step"):
        parse_duration("0.0004us", unit_required=True)
    assert parse_duration("0.001us") == pytest.approx(1e-9)


def test_an_integer_too_large_for_a_float_is_refused_not_an_overflow():
    with pytest.raises(LimitError, match="temperature must be"):
        TEMPERATURE.check(10**400, "x.toml: key t")


def test_an_integer_past_python_s_digit_limit_is_named_by_its_size():
    with pytest.raises(LimitError, match="an integer of 16610 bits"):
        COUNT.check(10**5000)
