"""RESD (Renode Sensor Data) files: byte layout from Renode's specification, round trips,
errors that name the byte, and the generate/record commands writing them."""

from __future__ import annotations

import math
import struct

import numpy as np
import pytest

from bmg160_emu import cli
from bmg160_emu.io.resd import (
    DPS_PER_UNIT,
    ResdFormatError,
    ResdWriter,
    iter_blocks,
    read_angular_rate,
    write_resd,
)


def test_bytes_follow_the_specification(tmp_path):
    # Layout written out by hand from Renode's "Renode Sensor Data Format" page and its parser:
    # header 'RESD' 01 00 00 00; block: u8 type 2, u16 sample type 3, u16 channel, u64 size,
    # u64 start ns, u64 period ns, u64 metadata size 0, then int32 x, y, z in 1e-5 rad/s.
    one_rad_s_dps = math.degrees(1.0)
    rates = np.array([[one_rad_s_dps, -one_rad_s_dps / 2, 0.0], [0.0, 1e-3, -1.0]])
    path = tmp_path / "two.resd"
    write_resd(path, np.array([0.005, 0.010]), {3: rates})
    expected = b"RESD\x01\x00\x00\x00" + struct.pack(
        "<BHHQQQQ", 2, 0x0003, 3, 24 + 2 * 12, 5_000_000, 5_000_000, 0
    ) + struct.pack("<6i", 100000, -50000, 0, 0, round(math.radians(1e-3) * 1e5), round(
        math.radians(-1.0) * 1e5))
    assert path.read_bytes() == expected


def test_round_trip_keeps_times_exactly_and_rates_to_half_a_count(tmp_path):
    rng = np.random.default_rng(3)
    t = np.arange(1, 2001) / 200.0
    output = rng.normal(0.0, 50.0, (2000, 3))
    truth = rng.normal(0.0, 500.0, (2000, 3))
    path = tmp_path / "rec.resd"
    write_resd(path, t, {0: output, 1: truth})
    for channel, rates in ((0, output), (1, truth)):
        t_back, rates_back = read_angular_rate(path, channel)
        np.testing.assert_array_equal(t_back, t)
        assert np.abs(rates_back - rates).max() <= DPS_PER_UNIT / 2 * (1 + 1e-9)
    assert [b.channel for b in iter_blocks(path)] == [0, 1]


def test_streaming_writer_counts_its_samples(tmp_path):
    with open(tmp_path / "x.resd", "wb") as handle:
        writer = ResdWriter(handle, rate_hz=200.0, samples=3)
        writer.write_dps(np.zeros((2, 3)))
        with pytest.raises(ResdFormatError, match="more than the 3 samples"):
            writer.write_dps(np.zeros((2, 3)))
        with pytest.raises(ResdFormatError, match="2 samples written, 3 announced"):
            writer.close()


@pytest.mark.parametrize(
    ("t", "message"),
    [
        (np.array([0.0, 0.005, 0.011]), "not uniform"),
        (np.array([-0.005, 0.0]), "RESD times start at 0"),
        (np.arange(4) / 7e8, "no whole-nanosecond period"),
    ],
)
def test_what_resd_cannot_hold_is_refused(tmp_path, t, message):
    with pytest.raises(ResdFormatError, match=message):
        write_resd(tmp_path / "x.resd", t, {0: np.zeros((len(t), 3))})


def test_rate_beyond_int32_is_refused(tmp_path):
    with pytest.raises(ResdFormatError, match="does not fit"):
        write_resd(tmp_path / "x.resd", np.array([0.0]), {0: np.array([[2e6, 0.0, 0.0]])})


@pytest.mark.parametrize(
    ("mutate", "message"),
    [
        (lambda b: b"RESX" + b[4:], "byte 0: not a RESD file"),
        (lambda b: b[:4] + b"\x02" + b[5:], "byte 4: RESD version 2, not 1"),
        (lambda b: b[:-5], "byte 8: block of 48 bytes runs past the end"),
        (lambda b: b[:8] + b"\x07" + b[9:], "byte 8: unknown block type 7"),
        (lambda b: b + b"\x02\x03", "byte 69: truncated block header"),
    ],
)
def test_bad_files_name_the_byte(tmp_path, mutate, message):
    good = tmp_path / "good.resd"
    write_resd(good, np.array([0.0, 0.5]), {0: np.zeros((2, 3))})
    bad = tmp_path / "bad.resd"
    bad.write_bytes(mutate(good.read_bytes()))
    with pytest.raises(ResdFormatError, match=message) as info:
        list(iter_blocks(bad))
    assert str(info.value).startswith(f"{bad}: ")


def test_blocks_of_other_types_are_skipped_as_renode_skips_them(tmp_path):
    path = tmp_path / "mixed.resd"
    write_resd(path, np.array([0.0, 0.5]), {0: np.ones((2, 3))})
    data = path.read_bytes()
    temperature = struct.pack("<BHHQQQQi", 2, 0x0001, 0, 28, 0, 10**9, 0, 23_000)
    arbitrary = struct.pack("<BHHQ", 1, 0x0003, 0, 4) + b"\0" * 4
    path.write_bytes(data[:8] + temperature + arbitrary + data[8:])
    t, rates = read_angular_rate(path)
    assert len(t) == 2 and np.allclose(rates, 1.0, atol=DPS_PER_UNIT)


def test_generate_writes_resd_equal_to_its_npy(tmp_path):
    npy, resd = tmp_path / "n.npy", tmp_path / "n.resd"
    for out in (npy, resd):
        args = ["generate", "--rate", "200", "--duration", "2s", "--seed", "5", "-o", str(out)]
        assert cli.main(args) == 0
    t, rates = read_angular_rate(resd)
    np.testing.assert_allclose(t, np.arange(1, 401) / 200.0, rtol=0, atol=1e-12)
    assert np.abs(rates - np.load(npy)).max() <= DPS_PER_UNIT / 2 * (1 + 1e-9)


def test_record_writes_output_and_truth_channels(tmp_path, capsys):
    from bmg160_emu.io.recording import read_recording

    csv, resd = tmp_path / "r.csv", tmp_path / "r.resd"
    for out in (csv, resd):
        args = ["record", "--duration", "0.5s", "--rate", "400", "--seed", "2",
                "--true-rate", "10", "0", "-30", "-o", str(out)]  # fmt: skip
        assert cli.main(args) == 0
    rec = read_recording(csv)
    t, output = read_angular_rate(resd, 0)
    _, truth = read_angular_rate(resd, 1)
    np.testing.assert_allclose(t, rec.t_s, rtol=0, atol=1e-9)
    assert np.abs(output - rec.rate_dps).max() <= DPS_PER_UNIT / 2 * (1 + 1e-9)
    assert np.abs(truth - rec.true_rate_dps).max() <= DPS_PER_UNIT / 2 * (1 + 1e-9)


def test_commands_name_the_new_suffix_in_their_errors(tmp_path, capsys):
    assert cli.main(["generate", "--duration", "1s", "-o", str(tmp_path / "x.txt")]) == 2
    assert "must end in .npy, .csv or .resd" in capsys.readouterr().err
    assert cli.main(["record", "--duration", "1s", "-o", str(tmp_path / "x.txt")]) == 2
    assert "must end in .csv, .npz or .resd" in capsys.readouterr().err


def test_a_refused_write_leaves_no_file(tmp_path):
    target = tmp_path / "x.resd"
    with pytest.raises(ResdFormatError, match="channel 1: 1 rows for 2 times"):
        write_resd(target, np.array([0.0, 0.5]), {0: np.zeros((2, 3)), 1: np.zeros((1, 3))})
    assert list(tmp_path.iterdir()) == []  # not half a file under the target's name
