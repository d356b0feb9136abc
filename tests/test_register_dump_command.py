"""``bmg160-emu dump`` and ``bmg160-emu diff`` from the command line."""

from __future__ import annotations

import json

import pytest

from bmg160_emu.cli import main
from bmg160_emu.io.dump import I2CDUMP_HEADER, parse_dump


@pytest.mark.parametrize("command", ["dump", "diff"])
def test_help_has_an_example(command, capsys):
    with pytest.raises(SystemExit) as info:
        main([command, "--help"])
    assert info.value.code == 0
    out = capsys.readouterr().out
    assert "examples:" in out and f"bmg160-emu {command} " in out


def test_dump_in_i2cdump_format_reflects_chip_options(capsys):
    assert main(["dump", "--format", "i2cdump", "--range", "250", "--no-noise"]) == 0
    out = capsys.readouterr().out
    assert out.startswith(I2CDUMP_HEADER + "\n00: 0f ")
    assert parse_dump(out)[0x0F] == 0x03  # +-250 deg/s is RANGE code 3 (spec 4.8)


def test_dump_after_a_script_shows_its_writes_and_logs_it_to_stderr(tmp_path, capsys):
    script = tmp_path / "s.script"
    script.write_text("write BW 0x04\nwrite INT_EN_0 0x80\n")
    assert main(["dump", "--after", str(script), "--format", "json", "--seed", "1"]) == 0
    captured = capsys.readouterr()
    document = json.loads(captured.out)
    assert document["registers"][0x10]["value"] == "0x84"
    assert document["registers"][0x15]["fields"]["data_en"] == 1
    assert "write 0x10 BW <- 0x04" in captured.err


def test_dump_with_a_broken_script_is_a_one_line_error(tmp_path, capsys):
    script = tmp_path / "s.script"
    script.write_text("write BWW 4\n")
    assert main(["dump", "--after", str(script)]) == 2
    assert "s.script:1:7: unknown register name 'BWW'" in capsys.readouterr().err


def test_diff_exit_status_and_decoded_fields(tmp_path, capsys):
    a, b = tmp_path / "a.dump", tmp_path / "b.txt"
    assert main(["dump", "--format", "i2cdump", "--no-noise", "-o", str(a)]) == 0
    assert main(["dump", "--no-noise", "--range", "125", "--bandwidth", "5", "-o", str(b)]) == 0
    capsys.readouterr()
    assert main(["diff", str(a), str(b)]) == 1
    out = capsys.readouterr().out
    assert "range: 0 (+-2000 deg/s) -> 4 (+-125 deg/s)" in out
    assert "bw: 0 (ODR 2000 Hz, 523 Hz) -> 5 (ODR 100 Hz, 12 Hz)" in out
    assert main(["diff", str(a), str(a)]) == 0


def test_diff_of_a_missing_or_broken_file_is_a_clear_error(tmp_path, capsys):
    broken = tmp_path / "broken.dump"
    broken.write_text(I2CDUMP_HEADER + "\n00: 0f zz\n")
    assert main(["diff", str(broken), str(tmp_path / "nope")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "broken.dump:2: not an i2cdump byte-mode row" in err
