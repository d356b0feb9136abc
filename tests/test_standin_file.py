"""Stand-in declarations: TOML and dump files, their one-line errors, and their round trip."""

from __future__ import annotations

import subprocess
import sys
import textwrap

import pytest

from bmg160_emu.device.standin import StandinDevice
from bmg160_emu.io.dump import format_i2cdump
from bmg160_emu.io.standin_file import (
    StandinFormatError,
    builtin_names,
    load_standin,
    spec_from_dict,
)

MINIMAL = """\
name = "widget"
chip_id_register = 0x0D
chip_id = 0xA7
addresses = [0x1C]

[registers]
0x20 = { name = "CTRL", reset = 0x07, writable = 0x7F }
"0x30-0x33" = { reset = 0x11 }
"""


def write(tmp_path, text: str, name: str = "widget.toml"):
    path = tmp_path / name
    path.write_text(textwrap.dedent(text))
    return path


def test_a_minimal_toml_declares_a_working_device(tmp_path):
    spec = load_standin(write(tmp_path, MINIMAL))
    d = StandinDevice(spec)
    assert d.address == 0x1C
    assert d.read(0x0D, 1) == b"\xa7"  # the chip-ID register is declared for you, read-only
    d.write(0x0D, b"\x00")
    assert d.read(0x0D, 1) == b"\xa7"
    d.write(0x20, b"\xff")
    assert d.read(0x20, 1) == b"\x7f"
    assert d.read(0x30, 4) == b"\x11" * 4
    assert d.read(0x34, 1) == b"\x00"


@pytest.mark.parametrize(("change", "message"), [
    ("name = 3", "name must be a word"),
    ("chip_id = 0x1FF", "chip_id must be an integer 0x00..0xFF"),
    ("addresses = [0x80]", "addresses[0] must be an integer 0x00..0x7F"),
    ("colour = 1", "unknown keys ['colour']"),
    ("[soft_reset]\nvalue = 0xB6", "[soft_reset]: needs register and value"),
    ("[soft_reset]\nregister = 0x7E\nvalue = 0xB6", "register 0x7E is not declared"),
    ("[power_gate]\nregister = 0x21\nmask = 0x01", "register 0x21 must be declared"),
])
def test_mistakes_are_one_line_errors_naming_file_and_place(tmp_path, change, message):
    key = change.split("=")[0].strip()
    body = "\n".join(line for line in MINIMAL.splitlines()
                     if line.split("=")[0].strip() != key)
    if change.startswith("["):
        text = body + "\n" + change + "\n"
    else:  # top-level keys go before the first table
        head, _, tables = body.partition("[registers]")
        text = head + change + "\n[registers]" + tables
    path = write(tmp_path, text)
    with pytest.raises(StandinFormatError) as info:
        load_standin(path)
    text = str(info.value)
    assert text.startswith(str(path)) and message in text and "\n" not in text, text


@pytest.mark.parametrize(("registers", "message"), [
    ('0x20 = { reset = 0x100 }', "[registers] 0x20: reset must be an integer"),
    ('0x20 = { reset = 1, colour = 2 }', "[registers] 0x20: unknown keys ['colour']"),
    ('0x20 = 7', "[registers] 0x20: must be a table"),
    ('zz = { reset = 1 }', "key 'zz' is not a register"),
    ('"0x30-0x20" = { reset = 1 }', "outside 0x00..0xFF or runs backwards"),
    ('"0x20-0x21" = {}\n0x21 = {}', "register 0x21 is declared twice"),
    ('0x0D = { reset = 0x00 }', "0x0D is the chip-ID register"),
])
def test_register_table_mistakes_name_the_register(tmp_path, registers, message):
    head = MINIMAL.partition("[registers]")[0]
    path = write(tmp_path, head + "[registers]\n" + registers + "\n")
    with pytest.raises(StandinFormatError) as info:
        load_standin(path)
    assert str(info.value).startswith(str(path)) and message in str(info.value), info.value


def test_bad_toml_syntax_and_bad_bytes_name_the_file(tmp_path):
    path = write(tmp_path, "name = \n")
    with pytest.raises(StandinFormatError, match=rf"^{path}: not valid TOML"):
        load_standin(path)
    raw = tmp_path / "raw.toml"
    raw.write_bytes(b'name = "\xff"\n')
    with pytest.raises(StandinFormatError, match=rf"^{raw}:1:9: not UTF-8"):
        load_standin(raw)


def test_a_missing_file_and_a_folder_are_refused_with_the_builtins_named(tmp_path):
    with pytest.raises(StandinFormatError, match="built-in stand-ins: bma2x2_accel, bmi088"):
        load_standin(tmp_path / "nothing.toml")
    with pytest.raises(StandinFormatError, match="is a folder"):
        load_standin(tmp_path)


def test_a_dump_becomes_plain_storage_with_a_read_only_chip_id(tmp_path):
    values = [None if r in (0x05, 0x06) else (r * 7) & 0xFF for r in range(0x100)]
    values[0] = 0x44
    path = tmp_path / "board.dump"
    path.write_text(format_i2cdump(values))
    spec = load_standin(path)
    assert spec.name == "board" and spec.chip_id == 0x44 and spec.addresses == ()
    d = StandinDevice(spec, 0x2A)
    assert d.read(0x00, 1) == b"\x44"
    assert d.read(0x07, 2) == bytes([0x07 * 7, 0x08 * 7])
    assert d.read(0x05, 1) == b"\x00"  # unreadable in the dump (XX): absent here
    d.write(0x07, b"\x99")
    d.write(0x00, b"\x99")
    assert d.read(0x00, 1) == b"\x44" and d.read(0x07, 1) == b"\x99"
    with pytest.raises(ValueError, match="declares no address"):
        StandinDevice(spec)


def test_a_dump_that_is_not_i2cdump_is_refused_at_its_line(tmp_path):
    path = tmp_path / "bad.txt"
    path.write_text("00: fa 00\nnot a row\n")
    with pytest.raises(StandinFormatError, match=rf"^{path}:1: not an i2cdump byte-mode row"):
        load_standin(path)


def test_the_dump_command_output_of_a_stand_in_loads_back_as_the_same_registers(tmp_path):
    out = tmp_path / "bmm150.dump"
    done = subprocess.run(
        [sys.executable, "-m", "bmg160_emu", "dump", "--device", "bmm150@0x10", "--seed", "1",
         "-o", str(out)], capture_output=True, text=True, check=False)
    assert done.returncode == 0, done.stderr
    spec = load_standin(out)
    original = StandinDevice(load_standin("bmm150"))
    assert StandinDevice(spec, 0x10).dump() == original.dump()  # suspended: all 0x00 but 0x4B


def test_every_builtin_round_trips_through_its_plain_data():
    for name in builtin_names():
        spec = load_standin(name)
        again = spec_from_dict(spec.to_dict(), "again")
        assert StandinDevice(again).dump() == StandinDevice(spec).dump()
        assert again.registers == spec.registers
        assert again.soft_reset == spec.soft_reset and again.power_gate == spec.power_gate
        assert again.no_increment == spec.no_increment and again.addresses == spec.addresses


def test_every_key_of_the_wrong_type_is_a_format_error_never_another_exception():
    base = load_standin("bmm150").to_dict()
    wrong = [None, True, -1, 256, 1.5, "x", [], [1, "a"], {}, {"a": 1}, [[1]]]
    for key in base:
        for value in wrong:
            data = {**base, key: value}
            try:
                spec_from_dict(data, "fuzz")
            except StandinFormatError as exc:
                assert str(exc).startswith("fuzz") and "\n" not in str(exc)
    for table in ("soft_reset", "power_gate"):
        for sub in base[table]:
            for value in wrong:
                data = {**base, table: {**base[table], sub: value}}
                try:
                    spec_from_dict(data, "fuzz")
                except StandinFormatError as exc:
                    assert str(exc).startswith("fuzz")
    for value in wrong:
        data = {**base, "registers": {"0x40": {"reset": value}}}
        with pytest.raises(StandinFormatError):
            spec_from_dict({**data, "registers": {"0x40": value}}, "fuzz")
