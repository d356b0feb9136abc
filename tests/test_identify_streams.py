"""identify reads the firmware's UART stream (firmware capture, or a board's serial port) and
RESD files (generate/record -o .resd): the rates, the rate, and one-line errors that name the
file and the line or byte. tests/data/firmware_capture.txt is a recorded capture:
``bmg160-emu firmware capture --duration 6 --seed 4 --output tests/data/firmware_capture.txt``."""

from __future__ import annotations

import json
import struct
from pathlib import Path

import numpy as np
import pytest
from _firmware_backends import firmware_skip_reason

from bmg160_emu import cli
from bmg160_emu.io.formats import format_for
from bmg160_emu.io.rate_table import RateFileError
from bmg160_emu.io.rates import load_rate_record
from bmg160_emu.io.resd import DPS_PER_UNIT, read_angular_rate
from bmg160_emu.io.uart_stream import looks_like_uart_stream, parse_uart_stream

CAPTURE = Path(__file__).parent / "data" / "firmware_capture.txt"
PAPER_N = 1.779073e-2  # deg/s/sqrt(Hz), profiles/paper.toml (paper section 2.5)


def _identify_json(capsys, *args: str) -> dict:
    assert cli.main(["identify", *args, "--json"]) == 0
    return json.loads(capsys.readouterr().out)


def _one_line_error(capsys, *args: str) -> str:
    assert cli.main(["identify", *args]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "Traceback" not in err, err
    return err


def test_a_recorded_capture_reads_as_mdps_at_the_odr_its_first_line_names():
    lines = CAPTURE.read_text().splitlines()
    assert lines[0].startswith("# bmg160-emu firmware capture: simavr odr_hz=200 ")
    record = load_rate_record(CAPTURE)
    assert record.rate_hz == 200.0 and record.axis_names == ("x", "y", "z")
    first = [int(v) for v in lines[2].split()]  # INDEX X Y Z, after capture line and banner
    np.testing.assert_array_equal(record.rate_dps[0], np.array(first[1:]) / 1000.0)
    assert len(record.rate_dps) == len(lines) - 2


def test_identify_reads_the_capture_and_finds_the_firmwares_n(capsys):
    out = _identify_json(capsys, str(CAPTURE))
    assert out["rate_hz"] == 200.0 and set(out["axes"]) == {"x", "y", "z"}
    # 1193 samples: the white level's Allan deviation at tau = 5 ms rests on ~1190 differences,
    # relative error ~ 1 / sqrt(2 * 1190) = 2 %; 10 % is 5 sigma.
    for axis in out["axes"].values():
        assert axis["N"]["value"] == pytest.approx(PAPER_N, rel=0.10)


def test_a_boards_stream_needs_the_rate_and_a_wrong_one_is_refused(tmp_path, capsys):
    board = tmp_path / "board.txt"  # as `cat /dev/ttyUSB0`: the banner, no capture line
    board.write_text("\n".join(CAPTURE.read_text().splitlines()[1:]) + "\n")
    assert looks_like_uart_stream(board)
    err = _one_line_error(capsys, str(board))
    assert str(board) in err and "does not say its ODR" in err and "--rate" in err
    assert _identify_json(capsys, str(board), "--rate", "200")["rate_hz"] == 200.0
    err = _one_line_error(capsys, str(CAPTURE), "--rate", "100")
    assert "disagrees with the time column" in err and str(CAPTURE) in err
    bare = tmp_path / "bare.log"  # no banner either: told by its INDEX X Y Z lines
    bare.write_text("\n".join(CAPTURE.read_text().splitlines()[2:]) + "\n")
    assert load_rate_record(bare, rate_hz=200.0).rate_dps.shape == (1193, 3)


def test_a_csv_named_txt_is_still_a_csv(tmp_path):
    path = tmp_path / "r.txt"
    path.write_text("t,x\n0,1\n0.005,2\n")
    assert not looks_like_uart_stream(path)
    assert load_rate_record(path).rate_dps.ravel().tolist() == [1.0, 2.0]


@pytest.mark.parametrize(("edit", "message"), [
    (lambda lines: lines[:10] + lines[12:], r":11: the sample index jumps from 8 to 11 \(2 samples lost"),
    (lambda lines: lines[:5] + ["7 1 2"] + lines[6:], r":6: expected 'INDEX X Y Z', got '7 1 2'"),
    (lambda lines: lines[:5] + ["7 1 x 2"] + lines[6:], r":6: non-integer field in '7 1 x 2'"),
    (lambda lines: lines[:5] + ["2 1 1 1"] + lines[6:], r":6: index 2 does not increase"),
    (lambda lines: lines[:5] + ["4 1 1 " + "9" * 11] + lines[6:], r":6: a rate beyond the int32"),
    (lambda lines: lines[:2], "holds no sample lines"),
])
def test_a_bad_stream_is_an_error_naming_the_file_and_line(tmp_path, capsys, edit, message):
    path = tmp_path / "stream.txt"
    path.write_text("\n".join(edit(CAPTURE.read_text().splitlines())) + "\n")
    with pytest.raises(RateFileError, match=message) as caught:
        load_rate_record(path)
    assert str(caught.value).startswith(str(path))
    _one_line_error(capsys, str(path))


def test_bytes_that_are_not_ascii_are_named_by_line_and_column(tmp_path):
    path = tmp_path / "stream.txt"
    data = CAPTURE.read_bytes().split(b"\n")
    data[4] = b"3 1\xff 2 3"
    path.write_bytes(b"\n".join(data))
    with pytest.raises(RateFileError, match=r"stream\.txt:5: not ASCII text \(byte 0xFF at column 4\)"):
        load_rate_record(path)


def test_parse_without_a_path_still_names_the_line():
    stream = parse_uart_stream("# bmg160-emu firmware capture: simavr odr_hz=400 seconds=1\n"
                               "1 10 20 30\n3 1 2 3\n4 1 2")  # cut inside the last line
    assert stream.odr_hz == 400.0 and stream.gaps == 1 and stream.first_gap() == 1
    assert stream.line_of.tolist() == [2, 3]


# --------------------------------------------------------------------------- RESD


def test_identify_reads_a_generated_resd_file_as_its_csv_to_the_resd_resolution(tmp_path, capsys):
    args = ["generate", "--profile", "paper", "--rate", "200", "--duration", "30s", "--seed", "2"]
    assert cli.main([*args, "-o", str(tmp_path / "n.resd")]) == 0
    assert cli.main([*args, "-o", str(tmp_path / "n.csv")]) == 0
    capsys.readouterr()
    resd = load_rate_record(tmp_path / "n.resd")
    csv = load_rate_record(tmp_path / "n.csv")
    assert resd.rate_hz == pytest.approx(200.0, rel=1e-12)
    assert np.abs(resd.rate_dps - csv.rate_dps).max() <= DPS_PER_UNIT / 2 * (1 + 1e-9)
    out = _identify_json(capsys, str(tmp_path / "n.resd"))
    ref = _identify_json(capsys, str(tmp_path / "n.csv"))
    for axis in "xyz":  # RESD's 5.7e-4 deg/s steps add (5.7e-4)^2/12 to a 0.25^2 variance
        assert out["axes"][axis]["N"]["value"] == pytest.approx(
            ref["axes"][axis]["N"]["value"], rel=1e-3)


def test_identify_of_a_recorded_resd_file_takes_the_output_channel_not_the_truth(tmp_path, capsys):
    path = tmp_path / "rec.resd"
    assert cli.main(["record", "--duration", "6s", "--rate", "200", "--seed", "5",
                     "--true-rate", "10", "0", "0", "-o", str(path)]) == 0
    capsys.readouterr()
    _t, output = read_angular_rate(path, channel=0)
    record = load_rate_record(path)
    np.testing.assert_array_equal(record.rate_dps, output)
    assert record.rate_dps[:, 0].std() > 0.1  # the noisy output; the truth is a constant 10
    out = _identify_json(capsys, str(path))
    assert out["axes"]["x"]["N"]["value"] == pytest.approx(PAPER_N, rel=0.15)


def test_a_damaged_resd_file_is_a_one_line_error_naming_the_byte(tmp_path, capsys):
    path = tmp_path / "n.resd"
    t = np.arange(1, 401) / 200.0
    format_for("rates", path).write(path, t, np.zeros((400, 3)))
    data = path.read_bytes()
    path.write_bytes(data[:-7])
    err = _one_line_error(capsys, str(path))
    assert err.startswith(f"bmg160-emu identify: {path}: byte 8: block of") or (
        f"{path}: byte 8: block of" in err), err
    # a start time and period whose last sample lies beyond 2**63 ns
    bad = bytearray(data)
    struct.pack_into("<Q", bad, 8 + 13 + 8, 2**62)  # the period, after the start time
    path.write_bytes(bytes(bad))
    err = _one_line_error(capsys, str(path))
    assert f"{path}: byte 21: sample times beyond 2**63 ns" in err
    path.write_bytes(b"RESD\x02\0\0\0")
    assert "byte 4: RESD version 2, not 1" in _one_line_error(capsys, str(path))


def test_the_registry_writes_rates_as_resd_and_refuses_what_resd_cannot_hold(tmp_path):
    path = tmp_path / "w.resd"
    fmt = format_for("rates", path)
    t = np.arange(1, 201) / 100.0
    rate = np.random.default_rng(1).normal(0.0, 1.0, (200, 3))
    fmt.write(path, t, rate)
    back = fmt.read(path)
    assert back.rate_hz == pytest.approx(100.0, rel=1e-12)
    assert np.abs(back.rate_dps - rate).max() <= DPS_PER_UNIT / 2 * (1 + 1e-9)
    with pytest.raises(RateFileError, match="RESD holds times and three axes"):
        fmt.write(path, None, rate)
    with pytest.raises(RateFileError, match="not uniform"):
        fmt.write(path, t ** 2, rate)


# --------------------------------------------------------------------------- end to end


@pytest.mark.firmware
@pytest.mark.skipif(firmware_skip_reason() is not None, reason=str(firmware_skip_reason()))
def test_firmware_capture_then_identify(tmp_path, capsys):
    stream = tmp_path / "stream.txt"
    assert cli.main(["firmware", "capture", "--duration", "6", "--rate", "400", "--output",
                     str(stream), "--out", str(tmp_path / "build")]) == 0
    capsys.readouterr()
    out = _identify_json(capsys, str(stream))
    assert out["rate_hz"] == 400.0 and out["samples"] > 2000
    # 400 Hz in physical mode: the same N (a density); ~2380 samples, 2 sigma ~ 3 %
    for axis in out["axes"].values():
        assert axis["N"]["value"] == pytest.approx(PAPER_N, rel=0.10)


def test_the_whole_stream_parser_and_the_line_parser_agree(monkeypatch):
    # a well-formed stream is parsed at C speed (np.fromstring); the line-by-line parser,
    # which names errors, must give the same result
    from bmg160_emu.io import uart_stream

    for data in (CAPTURE.read_bytes(), CAPTURE.read_bytes()[:-5],  # cut inside a line
                 CAPTURE.read_bytes().replace(b"\n", b"\r\n")):
        fast = uart_stream.parse_uart_stream(data)
        assert uart_stream._parse_whole(data, True) is not None
        with monkeypatch.context() as patch:
            patch.setattr(uart_stream, "_parse_whole", lambda *args: None)
            slow = uart_stream.parse_uart_stream(data)
        for name in ("index", "rate_dps", "line_of"):
            np.testing.assert_array_equal(getattr(fast, name), getattr(slow, name))
        assert (fast.banner, fast.odr_hz) == (slow.banner, slow.odr_hz)
