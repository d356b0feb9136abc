"""The i2cdump format: i2c-tools' byte-mode layout, and what Debian's i2c-stub-from-dump loads."""

from __future__ import annotations

import os
import re
import shutil
import stat
import subprocess
from pathlib import Path

import pytest

from bmg160_emu.device.registers import REGISTER_COUNT
from bmg160_emu.io.dump import (
    I2CDUMP_HEADER,
    DumpFormatError,
    format_i2cdump,
    parse_i2cdump,
)

STUB_FROM_DUMP = shutil.which("i2c-stub-from-dump") or "/usr/sbin/i2c-stub-from-dump"

# Every byte class i2cdump distinguishes: 0x00/0xff ('.'), control and high bytes ('?'),
# printable ASCII; 0x0F is CHIP_ID's reset value.
SAMPLE = bytes([0x0F, 0x00, 0xFF, 0x1F, 0x20, 0x41, 0x7E, 0x7F, 0x80] + list(range(0x90, 0x90 + 55)))


def test_layout_matches_i2cdump_byte_mode_printf_format():
    text = format_i2cdump(SAMPLE)
    lines = text.split("\n")
    assert lines[0] == I2CDUMP_HEADER
    assert lines[-1] == ""  # i2cdump ends every row with a newline
    assert len(lines) == 1 + REGISTER_COUNT // 16 + 1
    # i2cdump.c: printf("%02x: ", i); 16 x printf("%02x ", v); printf("   "); 16 chars
    assert lines[1] == (
        "00: 0f 00 ff 1f 20 41 7e 7f 80 90 91 92 93 94 95 96    ?..? A~??" + "?" * 7
    )
    for row, line in zip(range(0, REGISTER_COUNT, 16), lines[1:-1]):
        assert len(line) == 4 + 16 * 3 + 3 + 16
        assert line.startswith(f"{row:02x}: ")


def test_ascii_column_follows_i2cdump_rules():
    line = format_i2cdump(SAMPLE).split("\n")[1]
    assert line[-16:] == "?..? A~??" + "?" * 7


def test_partial_range_is_blanked_like_i2cdump_r_option():
    values = list(SAMPLE)
    text = format_i2cdump(values, first=0x02, last=0x04)
    row = text.split("\n")[1]
    assert row == "00:       ff 1f 20 " + " " * 33 + "   " + "  .? " + " " * 11


def test_failed_reads_print_xx():
    values: list = list(SAMPLE)
    values[5] = None
    row = format_i2cdump(values).split("\n")[1]
    assert row[4 + 5 * 3 : 4 + 5 * 3 + 3] == "XX "
    assert row[-16 + 5] == "X"


def test_round_trip_gives_back_the_64_registers():
    assert parse_i2cdump(format_i2cdump(SAMPLE)) == SAMPLE


def test_full_256_register_dump_is_accepted():
    text = format_i2cdump(list(SAMPLE) + [0] * 192, 0x00, 0xFF)
    assert parse_i2cdump(text) == SAMPLE


def test_unreadable_register_is_an_error_naming_the_line():
    values: list = list(SAMPLE)
    values[0x23] = None
    with pytest.raises(DumpFormatError, match=r"dump.txt:4: register 0x23 was unreadable"):
        parse_i2cdump(format_i2cdump(values), source="dump.txt")


def test_garbage_row_is_an_error_naming_the_line():
    text = format_i2cdump(SAMPLE).replace("20: ", "20 ", 1)
    with pytest.raises(DumpFormatError, match=r":4: not an i2cdump byte-mode row"):
        parse_i2cdump(text)


def test_missing_rows_are_reported():
    text = "\n".join(format_i2cdump(SAMPLE).split("\n")[:3])
    with pytest.raises(DumpFormatError, match="missing.*0x20"):
        parse_i2cdump(text)


def _perl_process_dump(tmp_path: Path) -> Path:
    """Run the parsing half of Debian's i2c-stub-from-dump (its process_dump sub) unchanged.

    The script's top level loads kernel modules, so only its ``process_dump`` sub is taken
    verbatim and driven with a recording stand-in for ``i2cset`` on PATH.
    """
    script = Path(STUB_FROM_DUMP).read_text()
    match = re.search(r"^sub process_dump\n\{.*?^\}\n", script, re.DOTALL | re.MULTILINE)
    assert match, "process_dump not found in i2c-stub-from-dump"
    driver = tmp_path / "process_dump.pl"
    driver.write_text(
        "use strict;\nuse vars qw($bus_nr);\n$bus_nr = 0;\n"
        'open(SAVEOUT, ">&STDOUT");\n'
        + match.group(0)
        + "exit(process_dump(0x68, $ARGV[0]));\n"
    )
    bindir = tmp_path / "bin"
    bindir.mkdir()
    fake = bindir / "i2cset"
    fake.write_text('#!/bin/sh\necho "$@" >> "$I2CSET_LOG"\n')
    fake.chmod(fake.stat().st_mode | stat.S_IXUSR)
    return driver


@pytest.mark.skipif(
    not (Path(STUB_FROM_DUMP).exists() and shutil.which("perl")),
    reason="Debian's i2c-stub-from-dump (package i2c-tools) or perl is not installed",
)
def test_debian_i2c_stub_from_dump_loads_every_register(tmp_path):
    driver = _perl_process_dump(tmp_path)
    dump = tmp_path / "bmg160.dump"
    dump.write_text(format_i2cdump(SAMPLE))
    log = tmp_path / "i2cset.log"
    env = dict(os.environ, PATH=f"{tmp_path / 'bin'}:{os.environ['PATH']}", I2CSET_LOG=str(log))
    result = subprocess.run(
        ["perl", str(driver), str(dump)], capture_output=True, text=True, env=env, check=False
    )
    assert result.returncode == 0, result.stderr
    assert result.stdout.strip() == "64 byte values written to 0-0068"
    loaded = {}
    for line in log.read_text().splitlines():
        yes, bus, address, register, value, mode = line.split()
        assert (yes, bus, address, mode) == ("-y", "0", "104", "b")
        loaded[int(register, 16)] = int(value, 16)
    assert loaded == dict(enumerate(SAMPLE))
