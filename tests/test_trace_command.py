"""``bmg160-emu trace``: decoding for a person, replay and its exit statuses."""

from __future__ import annotations

import json

import pytest

from bmg160_emu.cli import main


@pytest.fixture
def trace_file(tmp_path):
    script = tmp_path / "s.script"
    script.write_text("write RANGE 0x02\nwrite BW 0x04\nadvance 50ms\nburst RATE_X_LSB 6\n")
    trace = tmp_path / "s.jsonl"
    assert main(["script", str(script), "--seed", "4", "--trace", str(trace), "-q"]) == 0
    return trace


def test_help_has_an_example(capsys):
    with pytest.raises(SystemExit):
        main(["trace", "--help"])
    assert "bmg160-emu trace session.jsonl" in capsys.readouterr().out


def test_decoding_prints_one_readable_line_per_transaction(trace_file, capsys):
    capsys.readouterr()
    assert main(["trace", str(trace_file)]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert len(lines) == 3
    assert "write 0x0F RANGE <- 0x02 (+-500 deg/s)" in lines[0]
    assert "burst read 0x02..0x07 -> x=" in lines[2] and lines[2].lstrip().startswith("0.050000s")


def test_a_tampered_trace_diverges_with_exit_1(trace_file, capsys):
    lines = trace_file.read_text().splitlines()
    record = json.loads(lines[3])
    record["read"][1] ^= 0x40
    lines[3] = json.dumps(record)
    trace_file.write_text("\n".join(lines) + "\n")
    capsys.readouterr()
    assert main(["trace", str(trace_file), "--replay"]) == 1
    assert f"divergence at {trace_file}:line 4" in capsys.readouterr().err


def test_a_file_that_is_not_a_trace_is_a_one_line_error(tmp_path, capsys):
    bad = tmp_path / "bad.jsonl"
    bad.write_text("[1, 2]\n")
    assert main(["trace", str(bad)]) == 2
    assert "bad.jsonl:1: each line must be a JSON object" in capsys.readouterr().err
