"""A record's angular-rate unit: from a CSV column's name (the EuRoC/TUM-VI layout, gx_rad_s,
x_dps, mdps) or from --record-units; rad/s read as deg/s before identification.

Why: identify works in deg/s, and a rad/s record read as deg/s gave a profile 57.3 times too
quiet that still passed its own verdict (record and profile in the same wrong unit).
"""

from __future__ import annotations

import contextlib
import io
import math

import numpy as np
import pytest

from bmg160_emu import cli
from bmg160_emu.io.rate_units import rate_unit
from bmg160_emu.io.rates import RateFileError, load_rate_record

RAD = math.degrees(1.0)


@pytest.mark.parametrize(("name", "expected"), [
    ("w_RS_S_x [rad s^-1]", ("w_rs_s_x", "rad/s", RAD)),
    ("#w_RS_S_y [rad s^-1]", ("w_rs_s_y", "rad/s", RAD)),
    ("gyro_x (rad/s)", ("gyro_x", "rad/s", RAD)),
    ("gz [deg/s]", ("gz", "deg/s", 1.0)),
    ("gx_rad_s", ("gx", "rad/s", RAD)),
    ("x_dps", ("x", "deg/s", 1.0)),
    ("y_mdps", ("y", "mdeg/s", 1e-3)),
    ("z (mrad/s)", ("z", "mrad/s", RAD * 1e-3)),
    ("field.angular_velocity.x", ("x", "rad/s", RAD)),  # sensor_msgs/Imu: rad/s by definition
])
def test_a_column_name_with_a_rate_unit(name, expected):
    base, unit, scale = rate_unit(name)
    assert (base, unit) == expected[:2] and scale == pytest.approx(expected[2], rel=1e-15)


@pytest.mark.parametrize("name", ["x", "gx", "timestamp [ns]", "a_RS_S_x [m s^-2]", "_dps",
                                  "temp (degC)", "rads"])
def test_a_column_name_without_one(name):
    assert rate_unit(name) is None


def _euroc(path, rows):
    """The EuRoC MAV / TUM-VI imu0/data.csv layout: its header is a '#' line."""
    t = 1403636579758555392 + 5_000_000 * np.arange(len(rows))
    with open(path, "w") as f:
        f.write("#timestamp [ns],w_RS_S_x [rad s^-1],w_RS_S_y [rad s^-1],w_RS_S_z [rad s^-1],"
                "a_RS_S_x [m s^-2],a_RS_S_y [m s^-2],a_RS_S_z [m s^-2]\n")
        f.writelines(f"{stamp},{x!r},{y!r},{z!r},0.1,-0.2,9.81\n" for stamp, (x, y, z) in zip(t.tolist(), rows.tolist()))


def test_the_euroc_layout_gives_its_three_gyro_columns_in_deg_s_and_every_row(tmp_path):
    rows = np.random.default_rng(1).normal(0, 0.003, (1000, 3))
    path = tmp_path / "data.csv"
    _euroc(path, rows)
    record = load_rate_record(path)
    assert record.rate_dps.shape == (1000, 3)  # the first row too (it was taken as a header)
    np.testing.assert_array_equal(record.rate_dps, rows * RAD)
    assert record.axis_names == ("w_rs_s_x", "w_rs_s_y", "w_rs_s_z")
    assert record.unit == "rad/s" and record.rate_hz == pytest.approx(200.0)


def test_a_rostopic_csv_of_an_imu_topic_gives_its_angular_velocity_in_deg_s(tmp_path):
    rows = np.random.default_rng(4).normal(0, 0.003, (1000, 3))
    path = tmp_path / "imu.csv"
    with open(path, "w") as f:  # rostopic echo -p /imu: %time in ns, then the fields
        f.write("%time,field.header.seq,field.header.stamp,field.header.frame_id,"
                "field.angular_velocity.x,field.angular_velocity.y,field.angular_velocity.z,"
                "field.linear_acceleration.z\n")
        for i, (x, y, z) in enumerate(rows.tolist()):
            stamp = 1_600_000_000_000_000_000 + 5_000_000 * i
            f.write(f"{stamp},{i},{stamp},imu_link,{x!r},{y!r},{z!r},9.81\n")
    record = load_rate_record(path)
    np.testing.assert_array_equal(record.rate_dps, rows * RAD)
    assert record.axis_names == ("x", "y", "z") and record.rate_hz == pytest.approx(200.0)


def test_a_comment_with_commas_above_headerless_rows_stays_a_comment(tmp_path):
    path = tmp_path / "plain.csv"
    path.write_text("# logged by a, b and c\n" + "".join(f"{i * 0.01},{i},{-i}\n"
                                                       for i in range(20)))
    record = load_rate_record(path, rate_hz=100.0)
    assert record.rate_dps.shape == (20, 3) and record.rate_dps[0, 0] == 0.0


def test_record_units_scales_a_record_that_states_none(tmp_path):
    rows = np.random.default_rng(2).normal(0, 0.01, (500, 3))
    np.save(tmp_path / "r.npy", rows)
    record = load_rate_record(tmp_path / "r.npy", 100.0, record_units="rad/s")
    np.testing.assert_array_equal(record.rate_dps, rows * RAD)
    assert record.unit == "rad/s"
    assert load_rate_record(tmp_path / "r.npy", 100.0).unit == "deg/s"


def test_record_units_is_refused_where_the_file_states_another(tmp_path):
    path = tmp_path / "dps.csv"
    path.write_text("t,x_dps,y_dps,z_dps\n" + "".join(f"{i * 0.01},1,2,3\n" for i in range(20)))
    with pytest.raises(RateFileError, match="states its rates in deg/s"):
        load_rate_record(path, record_units="rad/s")
    np.savez(tmp_path / "r.npz", rate_dps=np.zeros((20, 3)), rate_hz=100.0)
    with pytest.raises(RateFileError, match="states its rates in deg/s"):
        load_rate_record(tmp_path / "r.npz", record_units="rad/s")


def test_identify_says_the_unit_it_converted(tmp_path):
    rows = np.random.default_rng(3).normal(0, 0.003, (20_000, 3))
    path = tmp_path / "data.csv"
    _euroc(path, rows)
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        assert cli.main(["identify", str(path), "--poles", "0", "--json"]) == 0
    assert f"{path}: rates in rad/s, read as deg/s" in err.getvalue()
    import json

    result = json.loads(out.getvalue())
    # white noise of std s sampled at f has N = s / sqrt(f) (ADEV(tau) = N / sqrt(tau)), here
    # in deg/s: the unit applied. N's 95 % interval at 20,000 samples is about +-2 %; 5 %
    # leaves room, and a missed conversion is off by 57x.
    n = result["axes"]["w_rs_s_x"]["N"]["value"]
    assert n == pytest.approx(0.003 * RAD / math.sqrt(200.0), rel=0.05)
