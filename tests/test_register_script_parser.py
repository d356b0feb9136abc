"""Register scripts: the parser reports every mistake with line and column before anything runs."""

from __future__ import annotations

import pytest

from bmg160_emu.device import registers
from bmg160_emu.session.script_language import ScriptSyntaxError, parse_script

GOOD = """\
# bring-up as the Linux driver does it
write BGW_SOFTRESET 0xB6        # soft reset
advance 30ms
read CHIP_ID == 0x0F
write RANGE 0b10000010
read INT_STATUS_1 == 0x80 mask 0x80
burst RATE_X_LSB 6
burst 0x0F 2 == 0x82 BW mask 0x07
poll INT_STATUS_1 bit 7 == 1 timeout 20ms every 250us
rate 10 -2.5 0
dump i2cdump
dump
"""


def _errors(text: str) -> list[tuple[int, int, str]]:
    with pytest.raises(ScriptSyntaxError) as info:
        parse_script(text, fault_available=False)
    return info.value.errors


def test_a_sound_script_parses_with_names_resolved_and_durations_in_seconds():
    statements = parse_script(GOOD, fault_available=False)
    assert [s.command for s in statements] == [
        "write", "advance", "read", "write", "read", "burst", "burst", "poll", "rate", "dump", "dump",
    ]
    assert [s.line for s in statements][:3] == [2, 3, 4]
    soft = statements[0]
    assert (soft.register, soft.values) == (registers.address_of("BGW_SOFTRESET"), (0xB6,))
    assert statements[1].seconds == pytest.approx(0.030)
    assert statements[3].values == (0x82,)
    masked = statements[4]
    assert (masked.values, masked.mask) == ((0x80,), 0x80)
    burst = statements[6]
    # a register name is accepted where a number is: BW stands for its address 0x10
    assert (burst.count, burst.values, burst.mask) == (2, (0x82, 0x10), 0x07)
    poll = statements[7]
    assert (poll.bit, poll.expected_bit) == (7, 1)
    assert (poll.seconds, poll.interval_s) == pytest.approx((0.020, 0.000250))
    assert statements[8].rate_dps == (10.0, -2.5, 0.0)
    assert (statements[9].dump_format, statements[10].dump_format) == ("i2cdump", "table")


def test_unknown_register_name_is_reported_at_its_column():
    assert _errors("read CHIP_ID\nwrite RANGEE 2\n") == [(2, 7, "unknown register name 'RANGEE'")]


def test_bad_number_missing_argument_and_unknown_command_are_all_reported():
    errors = _errors("write RANGE 0xZZ\nread\nfrobnicate 3\nadvance 10\n")
    assert [(line, col) for line, col, _ in errors] == [(1, 13), (2, 5), (3, 1), (4, 9)]
    messages = [message for _, _, message in errors]
    assert "bad number '0xZZ'" in messages[0]
    assert messages[1] == "missing register"
    assert "unknown command 'frobnicate'" in messages[2]
    assert "needs a unit" in messages[3]


def test_values_out_of_range_are_refused():
    errors = _errors("write 0x40 1\nwrite RANGE 256\npoll BW bit 8 timeout 1ms\nburst CHIP_ID 0\n")
    assert [line for line, _, _ in errors] == [1, 2, 3, 4]
    assert "outside 0..0x3f" in errors[0][2]


def test_a_burst_expectation_needs_one_value_per_byte():
    (error,) = _errors("burst RATE_X_LSB 2 == 0x00\n")
    assert error[0] == 1 and "expected value (2 needed)" in error[2]


def test_trailing_tokens_are_pointed_at():
    assert _errors("advance 1ms 2ms\n") == [(1, 13, "unexpected '2ms'")]


def test_fault_is_refused_when_fault_injection_is_not_available():
    (error,) = _errors("fault nack\n")
    assert error[:2] == (1, 7) and "not available" in error[2]


def test_error_message_carries_source_line_and_column():
    with pytest.raises(ScriptSyntaxError, match=r"^bringup.txt:1:6: unknown register name 'FOO'$"):
        parse_script("read FOO\n", source="bringup.txt", fault_available=False)


def test_comments_and_blank_lines_are_ignored():
    assert parse_script("\n   # only a comment\n\n", fault_available=False) == []


def test_chip_statement_takes_a_7_bit_address():
    (statement,) = parse_script("chip 0x69\n", fault_available=False)
    assert (statement.command, statement.register) == ("chip", 0x69)
    assert _errors("chip 0x80\nchip\n") == [
        (1, 6, "I2C address 0x80 is outside 0x00..0x7f"), (2, 5, "missing I2C address"),
    ]
