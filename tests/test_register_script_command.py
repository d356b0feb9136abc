"""``bmg160-emu script`` from the command line: log, exit statuses, trace output."""

from __future__ import annotations

import pytest

from bmg160_emu.cli import main
from bmg160_emu.io.trace import read_trace
from bmg160_emu.session.trace_replay import replay_trace

SCRIPT = """\
read CHIP_ID == 0x0F
write RANGE 0x02
write BW 0x04
advance 20ms
burst RATE_X_LSB 6
"""


def _script(tmp_path, text: str = SCRIPT):
    path = tmp_path / "s.script"
    path.write_text(text)
    return path


def test_help_has_an_example(capsys):
    with pytest.raises(SystemExit):
        main(["script", "--help"])
    assert "bmg160-emu script bringup.script" in capsys.readouterr().out


def test_a_passing_script_exits_0_and_logs_every_statement(tmp_path, capsys):
    assert main(["script", str(_script(tmp_path)), "--seed", "3"]) == 0
    out = capsys.readouterr().out.splitlines()
    assert len(out) == 6 and out[-1].startswith("ok: 5 statements")
    assert "burst read 0x02..0x07 -> x=" in out[4]


def test_a_failed_expectation_exits_1_with_the_line(tmp_path, capsys):
    path = _script(tmp_path, "write RANGE 0x01\nread RANGE == 0x02\n")
    assert main(["script", str(path), "-q"]) == 1
    captured = capsys.readouterr()
    assert captured.out == ""
    assert "s.script:2: 0x0F RANGE: expected 0x02, read 0x01" in captured.err


def test_syntax_errors_exit_2_listing_every_mistake(tmp_path, capsys):
    path = _script(tmp_path, "read CHIP_ID ==\nadvance 3 parsecs\nwrite RANGE 2\n")
    assert main(["script", str(path)]) == 2
    err = capsys.readouterr().err
    assert "2 error(s) in the script, nothing was run" in err
    assert "s.script:1:16: missing expected value" in err and "s.script:2:9:" in err


def test_a_traced_script_session_replays_without_divergence(tmp_path, capsys):
    trace = tmp_path / "s.jsonl"
    args = ["script", str(_script(tmp_path)), "--seed", "8", "--range", "500",
            "--true-rate", "5", "0", "-1", "--trace", str(trace), "-q"]
    assert main(args) == 0
    header, records = read_trace(trace)
    assert len(records) == 4  # the advance statement is not a transaction
    assert replay_trace(header, records).ok
    assert main(["trace", str(trace), "--replay"]) == 0
    assert "no divergence: 4 transactions replayed" in capsys.readouterr().out


def test_a_traced_script_without_seed_records_the_seed_it_chose(tmp_path, capsys):
    # Without --seed the chips draw a random seed; the trace must name it, or its replay
    # gets other noise and diverges at the first rate read.
    trace = tmp_path / "s.jsonl"
    assert main(["script", str(_script(tmp_path)), "--trace", str(trace), "-q"]) == 0
    header, records = read_trace(trace)
    assert isinstance(header["seed"], int)
    assert replay_trace(header, records).ok


def test_a_traced_script_that_changes_the_true_rate_replays_without_divergence(tmp_path):
    # `rate` changes the chip's input mid-session: the trace must carry the change, or the
    # replay keeps the old true rate (65.6 LSB/(deg/s) at 500 deg/s: 40 deg/s is ~2600
    # counts, far beyond the noise).
    text = SCRIPT + "rate 40 -20 10\nadvance 50ms\nburst RATE_X_LSB 6\n"
    trace = tmp_path / "s.jsonl"
    args = ["script", str(_script(tmp_path, text)), "--seed", "8", "--trace", str(trace), "-q"]
    assert main(args) == 0
    header, records = read_trace(trace)
    result = replay_trace(header, records)
    assert result.ok, str(result.divergence)
    assert result.transactions == 5


def test_a_script_over_spi_is_traced_and_replays_without_divergence(tmp_path, capsys):
    text = SCRIPT + "rate 40 -20 10\nadvance 50ms\nburst RATE_X_LSB 6\n"
    trace = tmp_path / "s.jsonl"
    args = ["script", str(_script(tmp_path, text)), "--spi", "--seed", "8",
            "--trace", str(trace), "-q"]
    assert main(args) == 0
    header, records = read_trace(trace)
    assert {r["kind"] for r in records} == {"spi_read", "spi_write", "true_rate"}
    result = replay_trace(header, records)
    assert result.ok, str(result.divergence)
    assert result.transactions == 5


def test_spi_with_two_chips_is_a_clear_error(tmp_path, capsys):
    path = _script(tmp_path)
    assert main(["script", str(path), "--spi", "--address", "0x68", "--address", "0x69"]) == 2
    assert "--spi drives one chip" in capsys.readouterr().err


def test_chip_and_sample_faults_work_over_spi(tmp_path, capsys):
    # was AttributeError: 'NoneType' object has no attribute 'transaction_hooks'
    text = ("rate 50 0 0\nfault stuck_axis axis=x\nadvance 20ms\n"
            "read RATE_X_LSB\nadvance 20ms\nread RATE_X_LSB\n")
    assert main(["script", str(_script(tmp_path, text)), "--spi", "--seed", "1"]) == 0
    out = capsys.readouterr().out
    reads = [line.split("->")[1].split()[0] for line in out.splitlines() if "RATE_X_LSB ->" in line]
    assert len(reads) == 2 and reads[0] == reads[1]  # the stuck axis holds its value


def test_bus_faults_over_spi_are_refused_with_the_line(tmp_path, capsys):
    path = _script(tmp_path, "fault nack max_count=2\nread CHIP_ID\n")
    assert main(["script", str(path), "--spi"]) == 1
    assert f"{path}:1: bus faults need the script to run on a bus" in capsys.readouterr().err


def test_a_trace_onto_a_full_disk_is_a_one_line_error(tmp_path, capsys):
    # was an OSError traceback; the session itself runs to its end (a failing trace file
    # must not fail the driver's bus transactions), the error comes when the trace is closed
    full = tmp_path / "full.jsonl"
    full.symlink_to("/dev/full")
    status = main(["script", str(_script(tmp_path)), "--trace", str(full), "-q", "--seed", "1"])
    err = capsys.readouterr().err
    assert status == 2 and err.count("\n") == 1 and "No space left on device" in err
    assert full.is_symlink()


def test_a_trace_appears_only_when_the_session_is_over(tmp_path, monkeypatch):
    # the writer works under a temporary name beside the target and renames at close
    from bmg160_emu.io.trace import TraceHeader, TraceWriter, read_trace

    target = tmp_path / "s.jsonl"
    writer = TraceWriter(target, TraceHeader(seed=1))
    writer({"time": 0.0, "bus": 1, "address": 0x68, "kind": "read_byte_data",
            "register": 0, "written": [], "read": [15], "error": None})
    assert not target.exists() and len(list(tmp_path.glob(".s.jsonl.*.part*"))) == 1
    writer.close()
    assert [r["read"] for r in read_trace(target)[1]] == [[15]]
    assert list(tmp_path.glob(".s.jsonl.*")) == []
