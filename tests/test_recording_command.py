"""``bmg160-emu record`` and ``bmg160-emu replay`` from the command line."""

from __future__ import annotations

import numpy as np
import pytest

from bmg160_emu.cli import main
from bmg160_emu.io.recording import read_recording


@pytest.mark.parametrize("command", ["record", "replay"])
def test_help_has_an_example(command, capsys):
    with pytest.raises(SystemExit):
        main([command, "--help"])
    assert f"bmg160-emu {command} " in capsys.readouterr().out


def test_record_writes_the_requested_duration_at_the_requested_rate(tmp_path, capsys):
    out = tmp_path / "r.npz"
    args = ["record", "--duration", "2s", "--rate", "400", "--range", "250", "--seed", "1",
            "--true-rate", "3", "0", "0", "-o", str(out)]
    assert main(args) == 0
    rec = read_recording(out)
    assert (len(rec), rec.odr_hz, rec.metadata["range_dps"]) == (800, 400.0, 250)
    assert np.all(rec.true_rate_dps == [3.0, 0.0, 0.0])
    assert "recorded 800 samples at 400 Hz" in capsys.readouterr().out


def test_record_follows_a_scenario_for_its_duration(tmp_path):
    scenario = tmp_path / "spin.toml"
    scenario.write_text(
        'duration_s = 0.5\n[[motion]]\nkind = "constant"\nrate_dps = [0.0, 0.0, 20.0]\n'
    )
    out = tmp_path / "r.csv"
    assert main(["record", "--truth", str(scenario), "--rate", "100", "-o", str(out)]) == 0
    rec = read_recording(out)
    assert len(rec) == 50 and np.all(rec.true_rate_dps[:, 2] == 20.0)


@pytest.mark.parametrize(
    ("extra", "message"),
    [
        (["--duration", "ten"], "not a duration: 'ten'"),
        (["--duration", "1s", "--rate", "200", "--bandwidth", "4"], "--rate or --bandwidth"),
        ([], "--duration is needed"),
    ],
)
def test_record_refuses_bad_options_in_one_line(tmp_path, capsys, extra, message):
    assert main(["record", *extra, "-o", str(tmp_path / "r.csv")]) == 2
    err = capsys.readouterr().err
    assert message in err and err.count("\n") == 1


def test_record_then_replay_gives_back_the_same_samples(tmp_path):
    a, b = tmp_path / "a.csv", tmp_path / "b.csv"
    assert main(["record", "--duration", "3s", "--rate", "200", "--seed", "5", "-o", str(a)]) == 0
    assert main(["replay", str(a), "--unit", "counts", "--bandwidth", "6",
                 "--seed", "6", "-o", str(b)]) == 0
    first, second = read_recording(a), read_recording(b)
    assert np.array_equal(first.t_s, second.t_s)
    assert np.array_equal(first.counts, second.counts)
    assert second.true_rate_dps is None


def test_replay_errors_name_the_line(tmp_path, capsys):
    data = tmp_path / "lab.csv"
    data.write_text("t,x,y,z\n0.0,1,2,3\n0.01,1,2\n")
    assert main(["replay", str(data), "-o", str(tmp_path / "o.csv")]) == 2
    assert "lab.csv:3: 3 columns, expected 4" in capsys.readouterr().err


def test_replay_gap_error_names_the_line_and_the_option_that_allows_it(tmp_path, capsys):
    data = tmp_path / "lab.csv"
    data.write_text("t,x,y,z\n0.0,1,2,3\n0.01,1,2,3\n0.02,1,2,3\n0.5,1,2,3\n")
    assert main(["replay", str(data), "-o", str(tmp_path / "o.csv")]) == 2
    err = capsys.readouterr().err
    assert "lab.csv:5: gap of 0.48 s" in err and "--max-gap-factor" in err
    assert main(["replay", str(data), "--max-gap-factor", "100", "-o", str(tmp_path / "o.csv")]) == 0


def test_replay_can_drive_a_register_script(tmp_path, capsys):
    data = tmp_path / "lab.csv"
    rows = [f"{0.005 * k:.3f},100,0,0" for k in range(400)]
    data.write_text("\n".join(rows) + "\n")
    script = tmp_path / "check.script"
    counts = round(100 * 16.384)  # +-2000 deg/s, binary sensitivity (spec 5.1)
    script.write_text(
        f"advance 50ms\nburst RATE_X_LSB 2 == {counts & 0xFF:#x} {counts >> 8:#x}\n"
    )
    assert main(["replay", str(data), "--bandwidth", "6", "--script", str(script)]) == 0
    assert f"x={counts}" in capsys.readouterr().out


@pytest.mark.parametrize("command", ["record", "replay"])
def test_an_unwritable_output_is_refused_before_any_work(tmp_path, capsys, command):
    out = tmp_path / "missing-folder" / "out.csv"
    data = tmp_path / "lab.csv"
    data.write_text("t,x,y,z\n" + "".join(f"{0.01 * k:.2f},1,2,3\n" for k in range(10)))
    # a day of chip time would take minutes to record: refused at once instead
    args = ["record", "--duration", "1d"] if command == "record" else ["replay", str(data)]
    assert main([*args, "-o", str(out)]) == 2
    assert f"cannot write {out}" in capsys.readouterr().err
    assert not out.parent.exists()
