"""Register dumps: table and json formats, detection, parsing errors, and decoded diffs."""

from __future__ import annotations

import json

import pytest

from bmg160_emu.device import registers
from bmg160_emu.device.fields import decode_register, resolve_register_name
from bmg160_emu.io.dump import (
    DumpFormatError,
    RegisterDump,
    detect_format,
    format_dump,
    format_i2cdump,
    format_json,
    format_table,
    parse_dump,
)
from bmg160_emu.session.decode import diff_dumps, format_diff

RANGE = registers.address_of("RANGE")
BW = registers.address_of("BW")


def _with(**changes: int) -> RegisterDump:
    values = bytearray(registers.RESET_VALUES)
    for name, value in changes.items():
        values[registers.address_of(name)] = value
    return RegisterDump(bytes(values), address=0x68, time_s=1.25)


def test_table_names_every_register_and_decodes_range_with_its_sensitivity():
    text = format_table(_with(RANGE=0x02), sensitivity="nominal")
    lines = [line for line in text.splitlines() if not line.startswith("#")]
    assert len(lines) == 64
    for reg, line in enumerate(lines):
        assert line.startswith(f"0x{reg:02X} {registers.REGISTERS[reg].name} ")
    assert "range=2 (+-500 deg/s, 65.6 LSB/(deg/s))" in lines[RANGE]
    binary = format_table(_with(RANGE=0x02), sensitivity="binary").splitlines()[1 + RANGE]
    assert "65.536 LSB/(deg/s)" in binary


@pytest.mark.parametrize("fmt", ["i2cdump", "table", "json"])
def test_every_format_parses_back_to_the_same_registers(fmt):
    dump = _with(RANGE=0x82, BW=0x84, INT_EN_0=0x80)
    back = parse_dump(format_dump(dump, fmt))
    assert back.values == dump.values
    assert detect_format(format_dump(dump, fmt)) == fmt


@pytest.mark.parametrize("fmt", ["table", "json"])
def test_table_and_json_keep_address_and_time(fmt):
    back = parse_dump(format_dump(_with(), fmt))
    assert (back.address, back.time_s) == (0x68, 1.25)


def test_json_lists_fields_by_name():
    document = json.loads(format_json(_with(BW=0x84)))
    entry = document["registers"][BW]
    assert entry == {"register": "0x10", "name": "BW", "value": "0x84",
                     "fields": {"bw_fixed": 1, "bw": 4}}


def test_table_line_with_the_wrong_name_is_an_error_naming_the_line():
    text = format_table(_with()).replace("0x0F RANGE", "0x0F BW   ", 1)
    with pytest.raises(DumpFormatError, match=r"a.txt:17: register 0x0F is RANGE, not BW"):
        parse_dump(text, source="a.txt")


def test_json_syntax_error_names_line_and_column():
    with pytest.raises(DumpFormatError, match=r"b.json:2:\d+: invalid JSON"):
        parse_dump('{\n "format": ,\n}', source="b.json")


def test_json_without_every_register_is_refused():
    document = json.loads(format_json(_with()))
    del document["registers"][5]
    with pytest.raises(DumpFormatError, match="missing: 0x05"):
        parse_dump(json.dumps(document))


def test_diff_lists_only_differing_registers_with_decoded_fields():
    a, b = _with(RANGE=0x00), _with(RANGE=0x02, BW=0x84)
    assert [d.register for d in diff_dumps(a, b)] == [RANGE, BW]
    text = format_diff(a, b, "before", "after")
    assert "range: 0 (+-2000 deg/s) -> 2 (+-500 deg/s)" in text
    assert "bw: 0 (ODR 2000 Hz, 523 Hz) -> 4 (ODR 200 Hz, 23 Hz)" in text
    assert text.rstrip().endswith("2 registers differ")
    assert "CHIP_ID" not in text


def test_diff_of_equal_dumps_says_so_and_show_all_lists_every_register():
    text = format_diff(_with(), _with(), show_all=True)
    assert text.rstrip().endswith("no difference")
    assert len(text.splitlines()) == 1 + 64 + 1


def test_register_names_resolve_case_insensitively():
    assert resolve_register_name("range") == RANGE
    assert resolve_register_name("NOT_A_REGISTER") is None


def test_decoded_flags_show_only_when_set():
    fields = {f.name: f for f in decode_register(registers.address_of("INT_EN_0"), 0x80)}
    assert fields["data_en"].text == "data_en"
    assert fields["fifo_en"].text == ""


def test_dump_must_hold_64_registers():
    with pytest.raises(ValueError, match="64 bytes"):
        RegisterDump(bytes(10))
    with pytest.raises(DumpFormatError, match="empty"):
        parse_dump("\n\n")
    assert format_i2cdump(bytes(64)).count("\n") == 5
