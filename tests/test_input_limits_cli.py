"""Issue 24's examples, one each, as the commands meet them (the fuzz suite covers classes)."""

from __future__ import annotations

import re

import numpy as np
import pytest

from bmg160_emu.cli import main


def _run(argv, capsys):
    try:
        status = main(argv)
    except SystemExit as exc:
        status = exc.code
    err = capsys.readouterr().err
    return status, err


def _one_error_line(err):
    lines = [x for x in err.splitlines() if x.startswith("bmg160-emu") and "error:" in x]
    assert len(lines) == 1 and "Traceback" not in err, err
    return lines[0]


def test_firmware_capture_of_infinite_seconds_is_refused_not_reported_as_written(tmp_path,
                                                                                 capsys):
    # it used to exit 0 saying it wrote "inf simulated s", the file a 2-line header
    status, err = _run(["firmware", "capture", "--duration", "inf", "--output",
                        str(tmp_path / "s.txt")], capsys)
    assert status == 2 and "not a duration" in _one_error_line(err)
    assert not (tmp_path / "s.txt").exists()


def test_record_refuses_more_samples_than_it_can_hold(tmp_path, capsys):
    # 29 days at 2000 Hz was a 37 GiB MemoryError traceback
    status, err = _run(["record", "--seed", "1", "--duration", "29d", "-o",
                        str(tmp_path / "r.csv")], capsys)
    line = _one_error_line(err)
    assert status == 2 and "samples to record" in line and "100,000,000" in line


def test_a_write_record_without_its_bytes_is_refused_by_replay_naming_the_line(tmp_path,
                                                                               capsys):
    script = tmp_path / "s.script"
    script.write_text("write RANGE 0x02\nread RANGE == 0x02\n")
    trace = tmp_path / "t.jsonl"
    assert main(["script", str(script), "-q", "--seed", "1", "--trace", str(trace)]) == 0
    lines = trace.read_text().splitlines()
    cut = [x.replace('"written": [2]', '"written": []') if "write_byte_data" in x else x
           for x in lines]
    trace.write_text("\n".join(cut) + "\n")
    capsys.readouterr()
    status, err = _run(["trace", "--replay", str(trace)], capsys)
    line = _one_error_line(err)
    assert status == 2 and f"{trace}: line 2" in line and "needs 1 written byte" in line
    assert main(["trace", str(trace)]) == 0  # plain trace still decodes it


@pytest.mark.parametrize("seeds", ["0:1000000000000", str(2**70), "-1"])
def test_montecarlo_seeds_are_bounded_before_any_list_is_made(tmp_path, capsys, seeds):
    scenario = tmp_path / "s.toml"
    scenario.write_text('duration_s = 2.0\n[[motion]]\nkind = "rest"\n')
    status, err = _run(["montecarlo", str(scenario), "--scheduler", "sync", "--no-progress",
                        "--seeds", seeds], capsys)
    assert status == 2 and "--seeds" in _one_error_line(err)


def test_a_cr_only_csv_is_read_like_the_same_csv_with_lf(tmp_path):
    from bmg160_emu.io.rates import load_rate_record

    t = np.arange(50) / 200.0
    rows = [f"{a:.3f},{b:.4f},{b:.4f},{b:.4f}" for a, b in zip(t, np.sin(t))]
    lf, cr = tmp_path / "lf.csv", tmp_path / "cr.csv"
    lf.write_text("t_s,x_dps,y_dps,z_dps\n" + "\n".join(rows) + "\n")
    cr.write_bytes(lf.read_bytes().replace(b"\n", b"\r"))
    a, b = load_rate_record(lf), load_rate_record(cr)
    assert np.array_equal(a.rate_dps, b.rate_dps) and a.rate_hz == b.rate_hz


def test_an_npy_header_claiming_more_than_the_file_holds_is_refused_before_allocating(tmp_path):
    from bmg160_emu.io.array_files import read_npy
    from bmg160_emu.io.rate_table import RateFileError

    header = "{'descr': '<f8', 'fortran_order': False, 'shape': (100000000000, 3), }"
    header += " " * (63 - (len(header) + 10) % 64) + "\n"
    path = tmp_path / "huge.npy"
    path.write_bytes(b"\x93NUMPY\x01\x00" + len(header).to_bytes(2, "little")
                     + header.encode() + bytes(4096))
    with pytest.raises(RateFileError, match=r"declares shape \(100000000000, 3\)"):
        read_npy(path)


def test_the_true_rate_file_is_read_or_refused_in_one_line(tmp_path):
    from bmg160_emu.commands.vhost_user_i2c import read_true_rate

    path = tmp_path / "rate.txt"
    path.write_text("1 -2 3.5\n")
    assert read_true_rate(path) == (1.0, -2.0, 3.5)
    path.write_text("")
    assert read_true_rate(path) is None  # caught between truncation and write
    for body, message in ((b"1 nan 3", "angular rate must be"), (b"\xff\xfe1 2 3", "not UTF-8"),
                          (b"1 2", "three numbers"), (b"1 2 1e9", "angular rate must be")):
        path.write_bytes(body)
        with pytest.raises(ValueError, match=message) as exc:
            read_true_rate(path)
        assert str(exc.value).startswith(str(path)) and "\n" not in str(exc.value)


def test_a_directory_is_said_to_be_one(tmp_path, capsys):
    folder = tmp_path / "d.csv"
    folder.mkdir()
    status, err = _run(["identify", str(folder)], capsys)
    assert status == 2 and "is a directory" in _one_error_line(err)


def test_a_scenario_path_is_named_once(tmp_path, capsys):
    scenario = tmp_path / "scen.toml"
    scenario.write_text("duration_s = -1\n")
    status, err = _run(["record", "--truth", str(scenario), "-o", str(tmp_path / "r.csv")],
                       capsys)
    line = _one_error_line(err)
    assert status == 2 and line.count(str(scenario)) == 1


@pytest.mark.parametrize("body,message", [
    ("advance 20d\nadvance 20d\n", "2:1: simulated time reaches 3.456e+06 s: past the cap"),
    ("poll INT_STATUS_1 bit 7 == 1 timeout 29d\n", "1:1: poll reads up to 2.51e+09 times"),
    ("poll INT_STATUS_1 bit 7 == 1 timeout 20ms every 0.0004us\n", "1 ns step"),
    ("advance 1e308us\n", "1:9: duration '1e308us' is longer than the cap"),
    ("rate 1 nan 3\n", "1:8: angular rate must be a number"),
])
def test_a_script_that_would_run_for_ever_is_refused_before_it_runs(tmp_path, body, message):
    from bmg160_emu.session.script_language import ScriptSyntaxError, parse_script

    with pytest.raises(ScriptSyntaxError, match=re.escape(message)):
        parse_script(body, source="s.script")


def test_a_replay_span_past_the_cap_is_refused_before_recording(tmp_path, capsys):
    t = np.arange(40000) * 100.0  # evenly spaced: no gap, 4e6 s
    path = tmp_path / "span.csv"
    np.savetxt(path, np.column_stack([t, np.zeros((t.size, 3))]), delimiter=",",
               header="t_s,x_dps,y_dps,z_dps", comments="")
    status, err = _run(["replay", str(path), "--seed", "1", "-o", str(tmp_path / "o.csv")],
                       capsys)
    assert status == 2 and "cap on simulated time" in _one_error_line(err)


def test_thermal_on_two_temperature_plateaus_is_refused_without_a_warning(tmp_path, capsys):
    # a cubic through two plateaus: inv() of a singular matrix gave negative variances and
    # "RuntimeWarning: invalid value encountered in sqrt" on stderr, then exit 0
    import warnings

    t = np.arange(6000) / 10.0
    temp = np.where(t < 300, 20.0, 40.0)
    rates = np.random.default_rng(3).standard_normal((t.size, 3)) * 0.01
    path = tmp_path / "step.csv"
    np.savetxt(path, np.column_stack([t, rates, temp]), delimiter=",",
               header="time_s,x_dps,y_dps,z_dps,temperature_c", comments="")
    with warnings.catch_warnings():
        warnings.simplefilter("error", RuntimeWarning)
        status, err = _run(["thermal", str(path), "--block", "10s"], capsys)
    assert status == 2 and "determine only 2 of the 4 coefficients" in _one_error_line(err)


def test_thermal_refuses_a_temperature_no_die_survives_naming_its_line(tmp_path, capsys):
    t = np.arange(600) / 10.0
    temp = 20.0 + t / 3
    temp[5] = 1e12
    path = tmp_path / "hot.csv"
    np.savetxt(path, np.column_stack([t, np.zeros((t.size, 3)), temp]), delimiter=",",
               header="time_s,x_dps,y_dps,z_dps,temperature_c", comments="")
    status, err = _run(["thermal", str(path)], capsys)
    assert status == 2 and f"{path}:7: temperature must be" in _one_error_line(err)
