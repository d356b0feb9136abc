"""The one duration parser shared by --duration options and the register-script language."""

import pytest

from bmg160_emu.durations import UNIT_SECONDS, parse_duration


@pytest.mark.parametrize(
    ("text", "seconds"),
    [
        ("100us", 100e-6),
        ("250ms", 0.25),
        ("2.5s", 2.5),
        ("10min", 600.0),
        ("1.5h", 5400.0),
        ("1d", 86400.0),
        ("42", 42.0),
        ("  3 s ", 3.0),
        ("10MS", 0.01),
        ("1e3ms", 1.0),
    ],
)
def test_every_unit_and_a_bare_number_give_seconds(text, seconds):
    assert parse_duration(text) == pytest.approx(seconds, rel=1e-12)


def test_the_unit_table_is_what_the_parser_reads():
    for unit, factor in UNIT_SECONDS.items():
        assert parse_duration(f"2{unit}") == pytest.approx(2 * factor, rel=1e-12)


@pytest.mark.parametrize("text", ["soon", "", "s", "ten seconds", "1..5s", "nan", "inf"])
def test_text_that_is_not_a_duration_is_refused_with_its_text(text):
    with pytest.raises(ValueError, match="not a duration") as info:
        parse_duration(text)
    assert repr(text) in str(info.value)


def test_an_unknown_unit_is_named_with_the_units_that_exist():
    with pytest.raises(ValueError, match=r"unknown time unit 'w'.*us, ms, s, min, h or d"):
        parse_duration("2w")


@pytest.mark.parametrize("text", ["0s", "-1s", "-5", "1e400s", "0"])
def test_zero_negative_and_infinite_durations_are_refused_by_default(text):
    with pytest.raises(ValueError, match="must be positive"):
        parse_duration(text)


def test_zero_is_accepted_only_when_allowed_and_negative_never():
    assert parse_duration("0ms", allow_zero=True) == 0.0
    assert str(parse_duration("-0s", allow_zero=True)) == "0.0"
    with pytest.raises(ValueError, match="must be zero or positive"):
        parse_duration("-1ms", allow_zero=True)


def test_a_bare_number_is_refused_when_a_unit_is_required():
    with pytest.raises(ValueError, match="'10' needs a unit"):
        parse_duration("10", unit_required=True)
    assert parse_duration("10s", unit_required=True) == 10.0


def test_a_non_text_argument_is_a_type_error():
    with pytest.raises(TypeError):
        parse_duration(10)  # type: ignore[arg-type]


def test_every_front_end_uses_the_same_parser():
    from bmg160_emu.commands import generate
    from bmg160_emu.session.script_language import parse_script

    assert generate.parse_duration is parse_duration
    script = parse_script("advance 1d\nadvance 250ms\nadvance 0s\n")
    assert [st.seconds for st in script] == [86400.0, 0.25, 0.0]


@pytest.mark.parametrize(("seconds", "report", "exact"), [
    (5400.0, "1.5 h", "5400 s"), (1200.0, "20 min", "1200 s"), (0.25, "0.25 s", "250 ms"),
    (1e-4, "0.0001 s", "100 us"), (0.0, "0 s", "0 s"),
])
def test_durations_are_written_in_the_units_the_parser_reads_back(seconds, report, exact):
    from bmg160_emu.durations import duration_text, exact_duration_text

    assert duration_text(seconds) == report
    assert exact_duration_text(seconds) == exact
    assert parse_duration(duration_text(seconds, gap=""), allow_zero=True) == pytest.approx(seconds)
    assert parse_duration(exact.replace(" ", ""), allow_zero=True) == pytest.approx(seconds)
