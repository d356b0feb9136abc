"""Record inputs for identification: CSV, .npy, .npz, rate from a time column, clear errors."""

from __future__ import annotations

import numpy as np
import pytest

from bmg160_emu.io.rate_table import RateFileError as RecordError
from bmg160_emu.io.rates import load_rate_record
from bmg160_emu.noise.identify import IdentificationError, identify


@pytest.fixture
def samples():
    return np.random.default_rng(0).standard_normal((2000, 3)) * 0.25


def write_csv(path, rows, header=None, comments=()):
    lines = [f"# {c}" for c in comments]
    if header:
        lines.append(",".join(header))
    lines += [",".join(repr(float(v)) for v in row) for row in rows]
    path.write_text("\n".join(lines) + "\n")


def test_csv_with_time_column_gives_the_rate(tmp_path, samples):
    t = np.arange(samples.shape[0]) / 400.0
    path = tmp_path / "rec.csv"
    write_csv(path, np.column_stack([t, samples]), ["t_s", "x_dps", "y_dps", "z_dps"], ["made"])
    rec = load_rate_record(path)
    assert rec.rate_hz == pytest.approx(400.0)
    assert rec.axis_names == ("x", "y", "z")
    np.testing.assert_allclose(rec.rate_dps, samples)


def test_csv_without_header_needs_the_rate(tmp_path, samples):
    path = tmp_path / "plain.csv"
    write_csv(path, samples[:, :1])
    with pytest.raises(RecordError, match="give the sample rate"):
        load_rate_record(path)
    rec = load_rate_record(path, rate_hz=200.0)
    assert rec.rate_dps.shape == (2000, 1) and rec.rate_hz == 200.0


def test_chip_recording_layout_picks_the_dps_columns(tmp_path, samples):
    # the layout of `bmg160-emu record`: counts and truth columns beside the deg/s ones,
    # truth left empty when unknown
    path = tmp_path / "chip.csv"
    lines = [
        "# bmg160-emu recording v1",
        "t_s,x_counts,y_counts,z_counts,x_dps,y_dps,z_dps,true_x_dps,true_y_dps,true_z_dps",
    ]
    for i, row in enumerate(samples):
        lines.append(
            f"{i / 200.0!r},1,2,3,{float(row[0])!r},{float(row[1])!r},{float(row[2])!r},,,"
        )
    path.write_text("\n".join(lines) + "\n")
    rec = load_rate_record(path)
    np.testing.assert_allclose(rec.rate_dps, samples)
    assert rec.rate_hz == pytest.approx(200.0)


def test_time_column_must_increase(tmp_path, samples):
    t = np.arange(samples.shape[0]) / 200.0
    t[10] = t[8]
    path = tmp_path / "bad.csv"
    write_csv(path, np.column_stack([t, samples]), ["time", "x", "y", "z"])
    with pytest.raises(RecordError, match="not strictly increasing.*sample 10"):
        load_rate_record(path)


def test_given_rate_must_agree_with_the_time_column(tmp_path, samples):
    t = np.arange(samples.shape[0]) / 200.0
    path = tmp_path / "rec.csv"
    write_csv(path, np.column_stack([t, samples]), ["t", "x", "y", "z"])
    with pytest.raises(RecordError, match="disagrees with the time column"):
        load_rate_record(path, rate_hz=100.0)


def test_npy_and_npz_inputs(tmp_path, samples):
    np.save(tmp_path / "a.npy", samples)
    assert load_rate_record(tmp_path / "a.npy", rate_hz=200.0).rate_dps.shape == (2000, 3)
    np.savez(tmp_path / "b.npz", rate_dps=samples, t_s=np.arange(2000) / 1000.0)
    rec = load_rate_record(tmp_path / "b.npz")
    assert rec.rate_hz == pytest.approx(1000.0)
    np.savez(tmp_path / "c.npz", x=samples[:, 0], y=samples[:, 1])
    assert load_rate_record(tmp_path / "c.npz", rate_hz=200.0).axis_names == ("x", "y")
    np.savez(tmp_path / "d.npz", a=samples, b=samples)
    with pytest.raises(RecordError, match="cannot tell which arrays"):
        load_rate_record(tmp_path / "d.npz", rate_hz=200.0)


@pytest.mark.parametrize(
    ("name", "content", "message"),
    [
        ("x.json", "{}", r"must end in \.csv, \.npy, \.npz, \.resd"),
        ("e.csv", "# only a comment\n", "no data rows"),
        ("w.csv", "1,2,3,4\n5,6,7,8\n", "1 to 3 axes"),
        ("s.csv", "t,x\n0,1\n0.1,abc\n", r"s\.csv:3: not a number: 'abc'"),
    ],
)
def test_bad_files_are_clear_errors(tmp_path, name, content, message):
    path = tmp_path / name
    path.write_text(content)
    with pytest.raises(RecordError, match=message):
        load_rate_record(path, rate_hz=200.0)


def test_missing_file_is_a_clear_error(tmp_path):
    with pytest.raises(RecordError, match="no such record file"):
        load_rate_record(tmp_path / "nope.npy", rate_hz=200.0)


def test_empty_and_short_records_say_how_long_is_needed():
    with pytest.raises(IdentificationError, match="empty.*N needs at least 1000 samples"):
        identify(np.empty((0, 3)), 200.0)
    with pytest.raises(IdentificationError, match="too short: 999 samples.*about 100 T.*K needs"):
        identify(np.zeros((999, 1)), 200.0)


@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf])
def test_non_finite_samples_are_rejected(samples, bad):
    samples[123, 1] = bad
    with pytest.raises(IdentificationError, match="NaN or infinite.*sample 123 of column 1"):
        identify(samples, 200.0)


@pytest.mark.parametrize("rate", [0, -5, float("nan"), "200"])
def test_bad_rate_is_rejected(samples, rate):
    with pytest.raises(IdentificationError, match="sample rate"):
        identify(samples, rate)


def test_constant_column_is_rejected(samples):
    samples[:, 2] = 0.5
    with pytest.raises(IdentificationError, match="column 2 is constant"):
        identify(samples, 200.0)


def test_errors_quote_plain_numbers_not_numpy_reprs(tmp_path, samples):
    t = np.arange(samples.shape[0]) / 200.0
    t[10] = t[8]
    path = tmp_path / "bad.csv"
    write_csv(path, np.column_stack([t, samples]), ["time", "x", "y", "z"])
    with pytest.raises(RecordError, match=r"time 0\.04 s is not after 0\.045 s \(.*at sample 10\)") as info:
        load_rate_record(path)
    assert "np." not in str(info.value)
    samples[:, 2] = 0.5
    with pytest.raises(IdentificationError, match=r"\(0\.5 throughout\)"):
        identify(samples, 200.0)


def test_a_gap_in_the_time_column_is_refused_but_jitter_is_not(tmp_path, samples):
    n = samples.shape[0]
    jitter = np.random.default_rng(1).uniform(-0.001, 0.001, n)  # +-20 % of a 5 ms period
    jittered = tmp_path / "jitter.csv"
    write_csv(jittered, np.column_stack([np.arange(n) / 200.0 + jitter, samples]),
              ["time", "x", "y", "z"])
    assert load_rate_record(jittered).rate_hz == pytest.approx(200.0, rel=1e-3)
    t = np.arange(n) / 200.0
    t[100:] += 0.5  # 100 samples missing after sample 99
    gapped = tmp_path / "gap.csv"
    write_csv(gapped, np.column_stack([t, samples]), ["time", "x", "y", "z"])
    with pytest.raises(RecordError, match="gap of 0.505 s after sample 99"):
        load_rate_record(gapped)


def test_an_empty_npz_record_is_a_one_line_error(tmp_path, capsys):
    # t_s and rate_dps of 0 rows used to end in a numpy reshape ValueError traceback
    from bmg160_emu.cli import main

    path = tmp_path / "empty.npz"
    np.savez(path, t_s=np.zeros(0), rate_dps=np.zeros((0, 3)))
    assert main(["identify", str(path), "--rate", "200"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "record is empty" in err


def test_a_generate_csv_cut_short_is_refused_not_read_as_a_shorter_record(tmp_path, capsys):
    # its '#' header says samples=2000; a copy of its first 500 lines was accepted silently
    from bmg160_emu.cli import main

    full, cut = tmp_path / "g.csv", tmp_path / "cut.csv"
    assert main(["generate", "--duration", "10s", "--seed", "1", "-o", str(full)]) == 0
    cut.write_text("".join(full.read_text().splitlines(keepends=True)[:500]))
    capsys.readouterr()
    assert main(["identify", str(cut)]) == 2
    err = capsys.readouterr().err
    assert "says samples=2000 but it holds 498 rows: the file was cut short" in err


@pytest.mark.parametrize(("name", "per_second", "epoch"), [
    ("timestamp_s", 1, 0), ("time_ms", 1_000, 0), ("timestamp_us", 1_000_000, 0),
    ("t_ns", 10**9, 0), ("timestamp [ns]", 10**9, 1_403_636_579_758_555_392)])
def test_a_time_column_in_any_unit_its_name_says_gives_the_rate(tmp_path, samples, name,
                                                                per_second, epoch):
    # stamps of a 250 Hz log in the column's unit; the last from an epoch in ns as ROS and
    # EuRoC stamp (1.4e18: a float64 holds it to 256 ns, an int64 exactly)
    n = samples.shape[0]
    if per_second >= 10**6:  # integer stamps
        t = epoch + np.arange(n, dtype=np.int64) * (per_second // 250)
        cells = [str(int(v)) for v in t]
    else:
        t = np.arange(n) * (per_second / 250)
        cells = [repr(float(v)) for v in t]
    path = tmp_path / "stamped.csv"
    path.write_text("\n".join([f"{name},gx,gy,gz"] + [
        c + "," + ",".join(repr(float(v)) for v in row) for c, row in zip(cells, samples)])
        + "\n")
    assert load_rate_record(path).rate_hz == pytest.approx(250.0, rel=1e-6)
    archive = tmp_path / "stamped.npz"
    np.savez(archive, **{name: t}, x=samples[:, 0])
    assert load_rate_record(archive).rate_hz == pytest.approx(250.0, rel=1e-9)


def test_a_time_column_in_another_unit_than_its_name_says_is_refused(tmp_path, samples):
    # PX4's CSV export stamps in us under a bare "timestamp", which reads as seconds: a
    # 250 Hz log became 0.00025 Hz, and identify fitted 20,000 hours without a word
    path = tmp_path / "px4.csv"
    path.write_text("timestamp,x,y,z\n" + "".join(
        f"{4000 * i}," + ",".join(repr(float(v)) for v in row) + "\n"
        for i, row in enumerate(samples)))
    with pytest.raises(RecordError, match=r"gives 0.00025 Hz, outside 0.001 to 1e\+06 Hz: "
                                          r"are its stamps in ms, us or ns\?"):
        load_rate_record(path)


@pytest.mark.parametrize(("header", "message"), [
    ("t,a,a,a", r"data.csv:1: column 'a' appears 3 times in the header; name each axis once"),
    ("t,x,y,x", r"data.csv:1: column 'x' appears 2 times"),
    ("t,,,", r"data.csv:1: column 2 of the header has no name"),
])
def test_axes_named_twice_or_not_at_all_are_refused(tmp_path, samples, header, message):
    # the reader looked each name up by its first place: the same column read as every axis
    path = tmp_path / "data.csv"
    path.write_text(header + "\n" + "".join(
        f"{i * 0.004!r}," + ",".join(repr(float(v)) for v in row) + "\n"
        for i, row in enumerate(samples)))
    with pytest.raises(RecordError, match=message):
        load_rate_record(path)


def test_columns_naming_an_axis_twice_is_refused(tmp_path, samples):
    path = tmp_path / "data.csv"
    write_csv(path, samples, ["gx", "gy", "gz"])
    with pytest.raises(RecordError, match="--columns names 'gx' more than once"):
        load_rate_record(path, 250.0, ["gx", "gx"])


def test_a_file_without_a_time_column_names_the_ones_that_work(tmp_path, samples):
    path = tmp_path / "stamped.csv"
    write_csv(path, samples, ["stamp", "gx", "gy"])
    with pytest.raises(RecordError, match=r"t, time or timestamp in seconds, or with a unit"):
        load_rate_record(path)


def test_an_npz_of_raw_counts_with_their_step_and_rate_is_read_in_deg_s(tmp_path):
    # a sensor's raw output as a logger keeps it (the shared ADIS16405 record's layout:
    # counts int16, lsb_dps, rate_hz, axes), read by default identify with no option
    counts = np.random.default_rng(1).integers(-40, 40, size=(3000, 3)).astype(np.int16)
    path = tmp_path / "raw.npz"
    np.savez(path, counts=counts, lsb_dps=np.float64(0.05), rate_hz=np.float64(100.0),
             axes=np.array(["gx", "gy", "gz"]))
    rec = load_rate_record(path)
    assert rec.rate_hz == 100.0 and rec.axis_names == ("gx", "gy", "gz")
    np.testing.assert_array_equal(rec.rate_dps, counts * 0.05)
    assert load_rate_record(path, rate_hz=100.5).rate_hz == 100.5  # within 1 %: the user's
    with pytest.raises(RecordError, match="disagrees with the file's rate_hz"):
        load_rate_record(path, rate_hz=200.0)
    np.savez(path, counts=counts, rate_hz=np.float64(100.0))
    with pytest.raises(RecordError, match="counts without lsb_dps"):
        load_rate_record(path)
    np.savez(path, counts=counts, lsb_dps=np.array([0.05, 0.1]))
    with pytest.raises(RecordError, match="key lsb_dps must be one positive number"):
        load_rate_record(path, rate_hz=100.0)


def test_npz_records_of_any_key_shape_and_type_are_read_or_refused_in_one_error(tmp_path):
    # a structured fuzz of the NPZ layouts (a byte-level mutation of an archive mostly meets
    # its CRC first): every mix of the keys identify looks for, each of a hostile shape or
    # type; seeded (600 archives, each read with and without --rate) and shown to catch a
    # defect once (the one-positive-number check of lsb_dps and rate_hz taken out)
    import random

    from bmg160_emu.io.errors import FormatError

    rng = random.Random(7380000)
    values = {
        "counts": [np.zeros((0, 3), np.int16), np.ones((5, 3), np.int16), np.ones(5, np.int16),
                   np.ones((5, 4), np.int16), np.ones((2, 2, 2)), np.array(3),
                   np.array(["a", "b"]), np.ones((5, 3), bool), np.full((5, 3), np.nan),
                   np.full((5, 3), 2**63, np.uint64)],
        "lsb_dps": [np.float64(0.05), np.array([0.1, 0.2]), np.array("x"), np.float64(-1),
                    np.float64(np.inf), np.array([]), np.float64(0), np.float64(1e308)],
        "rate_hz": [np.float64(100), np.float64(-5), np.array([1, 2]), np.array("z"),
                    np.float64(np.nan), np.float64(1e-300)],
        "axes": [np.array(["x", "y", "z"]), np.array([b"a", b"b", b"c"]), np.array([1, 2, 3]),
                 np.array(["x"]), np.array([["x", "y", "z"]])],
        "t": [np.arange(5) * 0.01, np.arange(4), np.zeros(5)],
        "rate_dps": [np.ones((5, 3)), np.ones((5, 3), complex), np.array(1.0)],
    }
    outcomes = {"read": 0, "refused": 0}
    for k in range(600):
        arrays = {key: rng.choice(options) for key, options in values.items()
                  if rng.random() < (0.2 if key == "rate_dps" else 0.8)}
        path = tmp_path / f"{k}.npz"
        np.savez(path, **arrays)
        for rate in (None, 100.0):
            try:
                record = load_rate_record(path, rate_hz=rate)
            except FormatError as exc:
                assert "\n" not in str(exc) and str(path) in str(exc), str(exc)
                outcomes["refused"] += 1
            else:
                assert np.all(np.isfinite(record.rate_dps)) and record.rate_hz > 0
                outcomes["read"] += 1
    assert outcomes["read"] > 20 and outcomes["refused"] > 600, outcomes
