"""``bmg160-emu demo``: the driver-style session runs and shows what it read."""

from __future__ import annotations

import re

import pytest

from bmg160_emu.cli import main

ROW = re.compile(r"^\s+(\d+)\s+(-?\d+)\s+(-?\d+)\s+(-?\d+)\s+(-?[\d.]+)\s+(-?[\d.]+)\s+(-?[\d.]+)$")


def _run(capsys, *args: str) -> tuple[int, str, str]:
    code = main(["demo", *args])
    out, err = capsys.readouterr()
    return code, out, err


def _rows(text: str) -> list[tuple[int, ...]]:
    return [tuple(float(g) for g in m.groups()) for m in map(ROW.match, text.splitlines()) if m]


def test_demo_reads_chip_id_configures_and_shows_samples_and_fifo(capsys):
    code, out, _ = _run(
        capsys, "--seed", "3", "--samples", "4", "--fifo-frames", "3", "--range", "500"
    )
    assert code == 0
    assert "CHIP_ID = 0x0F" in out
    assert "range=2" in out  # +-500 deg/s written after the soft reset
    rows = _rows(out)
    assert len(rows) == 4 + 3  # streamed samples, then FIFO frames
    sensitivity = 65.536  # binary table, +-500 deg/s (spec 5.1)
    for row in rows:
        for count, dps in zip(row[1:4], row[4:7]):
            assert dps == pytest.approx(count / sensitivity, abs=1e-3)
    assert "FIFO_STATUS after the read: 0x00" in out


def test_noiseless_chip_at_rest_reads_zero_everywhere(capsys):
    code, out, _ = _run(capsys, "--no-noise", "--samples", "3", "--fifo-frames", "2")
    assert code == 0
    assert all(v == 0 for row in _rows(out) for v in row[1:])


def test_two_chips_each_get_a_session(capsys):
    code, out, _ = _run(
        capsys, "--address", "0x68", "--address", "0x69", "--samples", "1", "--fifo-frames", "1"
    )
    assert code == 0
    assert "BMG160 at 0x68" in out and "BMG160 at 0x69" in out


@pytest.mark.parametrize("args", [["--samples", "0"], ["--fifo-frames", "101"], ["--bus", "-1"]])
def test_bad_options_exit_2_with_a_one_line_reason(capsys, args):
    with pytest.raises(SystemExit) as info:
        main(["demo", *args])
    assert info.value.code == 2
    assert "demo: error:" in capsys.readouterr().err


def test_help_shows_an_example(capsys):
    with pytest.raises(SystemExit):
        main(["demo", "--help"])
    assert "bmg160-emu demo --seed 7" in capsys.readouterr().out


def test_demo_says_what_the_chip_is_given_and_the_std_its_samples_show(capsys):
    code, out, _ = _run(capsys, "--seed", "5", "--true-rate", "10", "0", "-5", "--samples",
                        "400", "--fifo-frames", "1")
    assert code == 0
    assert "given: true rate 10 0 -5 deg/s (x y z), noise profile 'paper'" in out
    expected = [float(s) for s in re.search(r"std of ([\d.]+) ([\d.]+) ([\d.]+) deg/s",
                                             out).groups()]
    streamed = [r for r in _rows(out) if r[0] < 400][:400]
    assert len(streamed) == 400
    import numpy as np

    shown = np.array([r[4:7] for r in streamed]).std(axis=0)
    # 400 samples at 200 Hz through the 23 Hz filter: ~100 independent ones, so the sample
    # std is within ~7 % (1 sigma) of the chip's own; 35 % is five sigma and catches a
    # figure of another profile, range or bandwidth (the datasheet profile gives 0.57x)
    assert np.allclose(shown, expected, rtol=0.35)
    assert out.count("spec N.N below: section N.N of the BMG160 data sheet") == 1
