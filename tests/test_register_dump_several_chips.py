"""``bmg160-emu dump`` with two chips: one block per address, each readable on its own."""

from __future__ import annotations

import json

import pytest

from bmg160_emu.cli import main
from bmg160_emu.io.dump import (
    I2CDUMP_HEADER,
    DumpFormatError,
    RegisterDump,
    format_dump,
    format_dumps,
    parse_dump,
    parse_dumps,
)

TWO_CHIPS = ["--address", "0x68", "--address", "0x69", "--seed", "4"]
SCRIPT = "write RANGE 0x01\nchip 0x69\nwrite RANGE 0x03\nwrite BW 0x05\n"


@pytest.fixture
def script(tmp_path):
    path = tmp_path / "two.script"
    path.write_text(SCRIPT)
    return path


def _dump(capsys, *args) -> str:
    assert main(["dump", *TWO_CHIPS, *args]) == 0
    return capsys.readouterr().out


@pytest.mark.parametrize("fmt", ["i2cdump", "table", "json"])
def test_every_chip_is_dumped_with_its_own_registers(capsys, script, fmt):
    text = _dump(capsys, "--after", str(script), "--format", fmt)
    dumps = parse_dumps(text)
    assert [d.address for d in dumps] == [0x68, 0x69]
    assert [d[0x0F] for d in dumps] == [0x01, 0x03]  # RANGE as the script wrote it per chip
    assert [d[0x10] & 0x0F for d in dumps] == [0x00, 0x05]
    assert all(d[0x00] == 0x0F for d in dumps)  # CHIP_ID


def test_each_i2cdump_block_is_what_i2cdump_prints_for_that_address(capsys, script):
    text = _dump(capsys, "--after", str(script), "--format", "i2cdump")
    blocks = text.split("\n\n")
    assert len(blocks) == 2
    for block, address, dump in zip(blocks, (0x68, 0x69), parse_dumps(text)):
        title, body = block.split("\n", 1)
        assert title.startswith(f"# bmg160-emu register dump  address=0x{address:02x}  t=")
        body = body if body.endswith("\n") else body + "\n"
        assert body == format_dump(RegisterDump(dump.values), "i2cdump")
        assert body.startswith(I2CDUMP_HEADER + "\n00: 0f ")


def test_chip_option_dumps_one_chip_exactly_as_a_single_chip_dump(capsys, script):
    both = parse_dumps(_dump(capsys, "--after", str(script), "--format", "i2cdump"))
    one = _dump(capsys, "--after", str(script), "--format", "i2cdump", "--chip", "0x69")
    assert one.startswith(I2CDUMP_HEADER + "\n")  # no title: i2c-stub-from-dump's input
    assert one == format_dump(RegisterDump(both[1].values), "i2cdump")


def test_one_chip_output_is_unchanged_by_the_several_chip_support(capsys):
    assert main(["dump", "--seed", "4", "--format", "table"]) == 0
    single = capsys.readouterr().out
    assert single.count("# bmg160-emu register dump") == 1
    assert main(["dump", "--seed", "4", "--format", "json"]) == 0
    assert isinstance(json.loads(capsys.readouterr().out), dict)


def test_json_of_two_chips_is_a_list_of_single_chip_documents(capsys):
    documents = json.loads(_dump(capsys, "--format", "json"))
    assert [d["address"] for d in documents] == ["0x68", "0x69"]
    assert all(d["format"] == "bmg160-emu register dump" for d in documents)


def test_a_chip_that_is_not_emulated_is_a_clear_error(capsys):
    assert main(["dump", *TWO_CHIPS, "--chip", "0x6a"]) == 2
    assert "--chip 0x6a is not an emulated chip (0x68, 0x69)" in capsys.readouterr().err
    with pytest.raises(SystemExit) as info:  # argparse's usage error, exit status 2
        main(["dump", *TWO_CHIPS, "--chip", "sixty"])
    assert info.value.code == 2
    assert "not an I2C address: 'sixty'" in capsys.readouterr().err


@pytest.mark.parametrize("fmt", ["i2cdump", "table", "json"])
def test_reading_a_two_chip_dump_as_one_says_so(fmt):
    dumps = [RegisterDump(bytes([0x0F] + [0] * 63), address=a, time_s=0.0) for a in (0x68, 0x69)]
    with pytest.raises(DumpFormatError, match=r"holds the dumps of 2 chips \(0x68, 0x69\)"):
        parse_dump(format_dumps(dumps, fmt), "two.dump")


def test_errors_in_a_later_block_name_the_line_of_the_whole_text():
    dumps = [RegisterDump(bytes([0x0F] + [0] * 63), address=a) for a in (0x68, 0x69)]
    lines = format_dumps(dumps, "i2cdump").split("\n")
    bad = lines.index("# bmg160-emu register dump  address=0x69") + 3
    lines[bad] = "10: zz"
    with pytest.raises(DumpFormatError, match=rf"two.dump:{bad + 1}: not an i2cdump"):
        parse_dumps("\n".join(lines), "two.dump")


def test_diff_refuses_a_two_chip_dump_with_a_clear_error(tmp_path, capsys):
    two, one = tmp_path / "two.dump", tmp_path / "one.dump"
    assert main(["dump", *TWO_CHIPS, "--format", "i2cdump", "-o", str(two)]) == 0
    assert main(["dump", "--format", "i2cdump", "-o", str(one)]) == 0
    capsys.readouterr()
    assert main(["diff", str(two), str(one)]) == 2
    assert "holds the dumps of 2 chips" in capsys.readouterr().err
