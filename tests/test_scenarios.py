"""True-motion scenarios: each kind of motion gives the body rate it describes."""

from __future__ import annotations

import math

import numpy as np
import pytest

from bmg160_emu.adcs.scenarios import (
    Scenario,
    ScenarioError,
    load_scenario,
    orbital_rate_dps,
    scenario_from_dict,
)


def _one(kind: str, duration_s: float = 100.0, **keys) -> Scenario:
    return scenario_from_dict({"duration_s": duration_s, "motion": [{"kind": kind, **keys}]})


def test_rest_is_zero_rate_everywhere():
    scenario = _one("rest")
    assert np.all(scenario.rate_dps(np.linspace(0, 100, 7)) == 0.0)


def test_a_scenario_without_motion_is_rest():
    scenario = scenario_from_dict({"duration_s": 5.0})
    assert np.all(scenario.rate_dps(2.5) == 0.0)


def test_orbital_rate_below_one_lsb_is_kept_exactly_as_a_float():
    # 0.06 deg/s is 0.98 LSB at the 2000 deg/s range (16.384 LSB per deg/s, spec 5.1):
    # the scenario must not round it, only the chip does.
    scenario = _one("constant", rate_dps=[0.0, -0.06, 0.0])
    assert scenario.rate_dps(12.345)[1] == -0.06


def test_orbital_motion_from_period_turns_360_degrees_per_orbit():
    scenario = _one("orbital", period_s=5400.0)
    assert np.array_equal(scenario.rate_dps(1.0), [0.0, -360.0 / 5400.0, 0.0])


def test_orbital_rate_at_500_km_is_about_0_06_deg_per_s():
    # Kepler: 2 pi sqrt(a^3 / mu) = 5677 s for a = 6878 km -> 0.0634 deg/s
    assert orbital_rate_dps(500.0) == pytest.approx(360.0 / 5676.98, rel=1e-5)
    scenario = _one("orbital", altitude_km=500.0, axis=[0, 0, 2])
    assert scenario.rate_dps(0.0)[2] == pytest.approx(orbital_rate_dps(500.0), rel=1e-15)


def test_slew_respects_rate_and_acceleration_limits_and_turns_the_angle():
    scenario = _one("slew", axis=[1, 1, 0], angle_deg=60.0, max_rate_dps=4.0,
                    max_accel_dps2=0.5, start_s=3.0)
    t = np.arange(0.0, 40.0, 0.001)
    rate = scenario.rate_dps(t)
    speed = np.linalg.norm(rate, axis=1)
    assert speed.max() == pytest.approx(4.0)
    assert np.max(np.abs(np.diff(speed))) / 0.001 <= 0.5 + 1e-9
    assert np.all(speed[t < 3.0] == 0.0)
    # rectangle rule on a 1 ms grid: error below accel * dt * ramp count
    assert np.sum(speed) * 0.001 == pytest.approx(60.0, abs=1e-3)
    assert np.allclose(rate[speed > 0] / speed[speed > 0, None], [2**-0.5, 2**-0.5, 0.0])


def test_short_slew_has_a_triangular_profile():
    scenario = _one("slew", axis=[0, 0, 1], angle_deg=-4.0, max_rate_dps=10.0, max_accel_dps2=1.0)
    slew = scenario.motions[0]
    assert slew.peak_dps == pytest.approx(2.0)  # sqrt(angle * accel)
    assert slew.duration_s == pytest.approx(4.0)
    assert scenario.rate_dps(2.0)[2] == pytest.approx(-2.0)
    assert np.all(scenario.rate_dps(np.array([4.0, 10.0])) == 0.0)


def test_jitter_is_a_sinusoid_per_axis_with_its_phase():
    scenario = _one("jitter", amplitude_dps=[0.1, 0.2, 0.0], frequency_hz=2.0,
                    phase_deg=[0.0, 90.0, 0.0])
    t = np.array([0.0, 0.125, 0.25])
    rate = scenario.rate_dps(t)
    assert np.allclose(rate[:, 0], [0.0, 0.1, 0.0])
    assert np.allclose(rate[:, 1], [0.2, 0.0, -0.2])


def test_symmetric_tumble_spins_at_constant_rate_and_asymmetric_one_conserves_momentum():
    sphere = _one("tumble", initial_rate_dps=[10.0, -5.0, 20.0], inertia_kg_m2=[2, 2, 2])
    assert np.allclose(sphere.rate_dps(np.array([0.0, 50.0])), [10.0, -5.0, 20.0])

    inertia = np.array([0.03, 0.05, 0.02])
    body = _one("tumble", initial_rate_dps=[10.0, -5.0, 20.0], inertia_kg_m2=inertia.tolist())
    w = np.radians(body.rate_dps(np.linspace(0, 100, 11)))
    momentum = np.linalg.norm(w * inertia, axis=1)
    energy = np.sum(inertia * w**2, axis=1)
    assert np.allclose(momentum, momentum[0], rtol=1e-8)
    assert np.allclose(energy, energy[0], rtol=1e-8)
    assert not np.allclose(w[5], w[0], rtol=1e-3)  # it really nutates


def test_detumbling_decays_the_rate_with_its_time_constant():
    scenario = _one("tumble", duration_s=200.0, initial_rate_dps=[5.0, 0.0, 0.0],
                    inertia_kg_m2=[1, 1, 1], damping_time_s=50.0)
    assert scenario.rate_dps(100.0)[0] == pytest.approx(5.0 * math.exp(-2.0), rel=1e-7)


def test_table_interpolates_linearly_or_holds_and_converts_rad_per_s(tmp_path):
    samples = [[0.0, 0.0, 0.0, 0.0], [1.0, 1.0, 2.0, 3.0], [2.0, 1.0, 2.0, 3.0]]
    linear = _one("table", samples=samples)
    assert np.allclose(linear.rate_dps(0.5), [0.5, 1.0, 1.5])
    held = _one("table", samples=samples, interpolation="previous")
    assert np.allclose(held.rate_dps(0.5), [0.0, 0.0, 0.0])

    csv = tmp_path / "dynamics.csv"
    csv.write_text("t_s,wx,wy,wz\n0,0,0,0\n10,0.1,0,0\n")
    (tmp_path / "s.toml").write_text(
        'duration_s = 10.0\n[[motion]]\nkind = "table"\nfile = "dynamics.csv"\nunits = "rad/s"\n'
    )
    from_file = load_scenario(tmp_path / "s.toml")
    assert from_file.rate_dps(5.0)[0] == pytest.approx(math.degrees(0.05))
    assert from_file.name == "s"


def test_motions_add_up_within_their_windows():
    scenario = scenario_from_dict({
        "duration_s": 10.0,
        "motion": [
            {"kind": "constant", "rate_dps": [1.0, 0.0, 0.0]},
            {"kind": "constant", "rate_dps": [0.0, 2.0, 0.0], "start_s": 2.0, "end_s": 4.0},
        ],
    })
    assert np.allclose(scenario.rate_dps(np.array([1.0, 3.0, 4.0])),
                       [[1, 0, 0], [1, 2, 0], [1, 0, 0]])


def test_a_python_callable_is_a_scenario_and_scalar_times_give_3_vectors():
    scenario = Scenario.from_callable(lambda t: (math.sin(t), 0.0, 0.06), duration_s=5.0)
    assert scenario(1.0).shape == (3,)
    assert np.allclose(scenario.rate_dps(np.array([0.0, 1.0])), [[0, 0, 0.06], [math.sin(1), 0, 0.06]])



@pytest.mark.parametrize("times", [[0.5, 1.0, 2.0], [0.5, 1.0], [0.5, 1.0, 2.0, 3.0]])
def test_a_vectorised_callable_returning_one_row_per_axis_is_read_right_for_three_times(times):
    # f(t) -> [x(t), y(t), z(t)] gives a (3, n) array: with n == 3 it is also (n, 3) in
    # shape, and must still be read as one row per axis.
    scenario = Scenario.from_callable(lambda t: np.array([np.sin(t), 0 * t, 0.06 + 0 * t]), 5.0)
    expected = [[math.sin(t), 0.0, 0.06] for t in times]
    assert np.allclose(scenario.rate_dps(np.array(times)), expected)


@pytest.mark.parametrize(
    "data, message",
    [
        ({}, "duration_s"),
        ({"duration_s": -1}, "duration_s"),
        ({"duration_s": 1, "motion": [{"kind": "spin"}]}, "kind must be one of"),
        ({"duration_s": 1, "motion": [{"kind": "constant", "rate_dps": [1, 2]}]}, "3 finite"),
        ({"duration_s": 1, "motion": [{"kind": "constant", "rate": [1, 2, 3]}]}, "unknown keys"),
        ({"duration_s": 1, "motion": [{"kind": "slew", "axis": [0, 0, 0], "angle_deg": 1,
                                       "max_rate_dps": 1, "max_accel_dps2": 1}]}, "zero vector"),
        ({"duration_s": 1, "motion": [{"kind": "orbital"}]}, "altitude_km or period_s"),
        ({"duration_s": 1, "motion": [{"kind": "table", "samples": [[1, 0, 0, 0], [0, 0, 0, 0]]}]},
         "strictly increasing"),
        ({"duration_s": 1, "motion": [{"kind": "tumble", "initial_rate_dps": [1, 0, 0],
                                       "inertia_kg_m2": [1, -1, 1]}]}, "positive definite"),
        ({"duration_s": 1, "speed": 3}, "unknown top-level keys"),
    ],
)
def test_bad_scenarios_are_refused_with_the_reason(data, message):
    with pytest.raises(ScenarioError, match=message):
        scenario_from_dict(data)


def test_bad_scenario_files_name_the_file(tmp_path):
    path = tmp_path / "broken.toml"
    path.write_text("duration_s = [\n")
    with pytest.raises(ScenarioError, match="broken.toml: not valid TOML"):
        load_scenario(path)
    with pytest.raises(ScenarioError, match="cannot read scenario"):
        load_scenario(tmp_path / "missing.toml")


def test_the_example_scenario_files_load_and_describe_their_motion():
    from pathlib import Path

    folder = Path(__file__).resolve().parent.parent / "examples" / "scenarios"
    scenarios = {p.stem: load_scenario(p) for p in sorted(folder.glob("*.toml"))}
    assert {"rest", "orbit_pointing", "slew", "detumble", "dynamics_table"} <= set(scenarios)
    assert np.all(scenarios["rest"].rate_dps(30.0) == 0.0)
    # the detumbling controller damps the tumble: 60 s = 3 time constants
    detumble = scenarios["detumble"]
    ratio = np.linalg.norm(detumble.rate_dps(60.0)) / np.linalg.norm(detumble.rate_dps(0.0))
    assert 0.02 < ratio < 0.1
    assert len(detumble.gyros) == 2
    assert [f["kind"] for f in scenarios["dynamics_table"].faults] == ["nack", "stuck_axis"]


def test_a_tumble_is_extended_on_demand_beyond_its_duration():
    # the chip computes samples ahead of time, past the scenario's end
    scenario = _one("tumble", duration_s=2.0, initial_rate_dps=[10.0, -5.0, 20.0],
                    inertia_kg_m2=[1, 2, 3])
    late = scenario.rate_dps(500.0)
    inertia = np.array([1.0, 2.0, 3.0])
    momentum = np.linalg.norm(np.radians(late) * inertia)
    assert momentum == pytest.approx(np.linalg.norm(np.radians([10, -5, 20]) * inertia), rel=1e-7)


def test_a_table_file_with_text_in_its_rows_is_refused(tmp_path):
    (tmp_path / "bad.csv").write_text("t,x,y,z\n0,0,0,0\n1,0,zero,0\n")
    (tmp_path / "s.toml").write_text(
        'duration_s = 1.0\n[[motion]]\nkind = "table"\nfile = "bad.csv"\n')
    with pytest.raises(ScenarioError, match=r"motion 1: .*bad\.csv:3: not a number: 'zero'"):
        load_scenario(tmp_path / "s.toml")


# the last three from tools/fuzz.py (scenario seeds 7900297 and 7951583): an integer beyond
# a double (OverflowError out of the loader) and a tumble started 1e308 s ago (the
# integrator overflowed); a motion may start before the scenario, within the run cap
@pytest.mark.parametrize("key, value", [("start_s", "a"), ("end_s", "b"), ("start_s", float("nan")),
                                        ("start_s", 10**400), ("start_s", -1e308),
                                        ("end_s", 2592001)])
def test_a_motion_window_that_is_not_a_number_is_refused_by_name(key, value):
    entry = {"kind": "jitter", "amplitude_dps": [1.0, 1.0, 1.0], "frequency_hz": 1.0, key: value}
    with pytest.raises(ScenarioError, match=f"motion 1: {key} must be a finite number"):
        scenario_from_dict({"duration_s": 2.0, "motion": [entry]})


@pytest.mark.parametrize(
    "motion, message",
    [
        ({"kind": "tumble", "initial_rate_dps": [1, 2, 3], "inertia_kg_m2": ["a", 1, 1]},
         "inertia_kg_m2 must be 3 principal moments or a 3x3 matrix"),
        ({"kind": "tumble", "initial_rate_dps": [1, 2, 3], "inertia_kg_m2": [10**400, 1, 1]},
         "inertia_kg_m2 must be 3 principal moments or a 3x3 matrix"),
        ({"kind": "jitter", "amplitude_dps": [1, 1, 1], "frequency_hz": 10**400},
         "frequency_hz must be a positive finite number"),
        ({"kind": "table", "samples": [[0, 1, 2, 3], [1, "a", 2, 3]]},
         "a rate table needs rows of 4 numbers"),
    ],
)
def test_text_where_numbers_belong_in_a_motion_is_refused_by_name(motion, message):
    with pytest.raises(ScenarioError, match=f"motion 1: {message}"):
        scenario_from_dict({"duration_s": 2.0, "motion": [motion]})


def test_a_slew_with_end_s_is_refused_since_its_profile_sets_its_end():
    # end_s was silently dropped: the slew ends when its rate profile does
    entry = {"kind": "slew", "axis": [0, 0, 1], "angle_deg": 90.0, "max_rate_dps": 3.0,
             "max_accel_dps2": 1.0, "end_s": 5.0}
    with pytest.raises(ScenarioError, match="motion 1: a slew ends by itself"):
        scenario_from_dict({"duration_s": 60.0, "motion": [entry]})


@pytest.mark.parametrize(
    ("body", "message"),
    [
        ("duration_s = 10\nmotion = [1]", "motion must be an array of tables"),
        ('duration_s = 10\nreadout = "abc"', "readout must be a table"),
        ("duration_s = 10\ngyro = 0.5", "gyro must be an array of tables"),
        ("duration_s = 10\nfault = [0.5]", "fault must be an array of tables"),
        ("duration_s = inf", "duration_s must be a positive number"),
        ("duration_s = true", "duration_s must be a positive number"),
        # a tumble integrated ahead to 2**63 s hung the loader
        ('duration_s = 9.2e18\n[[motion]]\nkind = "tumble"\ninitial_rate_dps = [1, 2, 3]',
         "up to 30 days"),
        (('duration_s = 10\n[[motion]]\nkind = "tumble"\ninitial_rate_dps = [1, 2, 3]\n'
         "inertia_kg_m2 = [inf, 1, 1]"), "(finite, symmetric)"),
        (('duration_s = 10\n[[motion]]\nkind = "jitter"\namplitude_dps = [1, 1, 1]\n'
         "frequency_hz = inf"), "frequency_hz must be a positive finite number"),
    ],
)
def test_malformed_scenarios_are_refused_naming_the_file_and_the_key(tmp_path, body, message):
    path = tmp_path / "bad.toml"
    path.write_text(body + "\n")
    with pytest.raises(ScenarioError) as exc:
        load_scenario(path)
    assert str(exc.value).startswith(f"{path}: ") and message in str(exc.value)


def test_a_thirty_day_tumble_loads_without_integrating_thirty_days_ahead(tmp_path):
    path = tmp_path / "long.toml"
    path.write_text('duration_s = 2592000\n[[motion]]\nkind = "tumble"\n'
                    "initial_rate_dps = [1, 2, 3]\n")
    scenario = load_scenario(path)
    assert scenario.rate_dps(1.0).shape == (3,)


def test_a_scenario_past_the_cap_on_simulated_time_is_refused(tmp_path):
    # ten years used to load, and `record --truth` would then simulate them (issue 24)
    path = tmp_path / "long.toml"
    path.write_text('duration_s = 315576000\n[[motion]]\nkind = "rest"\n')
    with pytest.raises(ScenarioError, match="30 days"):
        load_scenario(path)


def test_montecarlo_on_a_scenario_shorter_than_its_readout_is_a_one_line_error(tmp_path, capsys):
    from bmg160_emu.cli import main

    path = tmp_path / "short.toml"
    path.write_text('duration_s = 0.5\n[[motion]]\nkind = "constant"\nrate_dps = [1, 2, 3]\n')
    assert main(["montecarlo", str(path), "--runs", "2", "--scheduler", "sync"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and str(path) in err and "shorter than the readout needs" in err


@pytest.mark.parametrize("row", ["1,nan,0,0", "1,0,inf,0", "nan,0,0,0", "1,0,0,-inf"])
def test_a_table_file_that_holds_nan_or_inf_is_refused_naming_file_and_line(tmp_path, row):
    # issue 35: a nan passed loading and failed later, naming neither file nor line
    (tmp_path / "table.csv").write_text(f"t,x,y,z\n0,0,0,0\n{row}\n2,0,0,0\n")
    (tmp_path / "s.toml").write_text(
        'duration_s = 1.0\n[[motion]]\nkind = "table"\nfile = "table.csv"\n')
    with pytest.raises(ScenarioError, match=r"motion 1: .*table\.csv:3: empty or non-finite "
                                            r"value"):
        load_scenario(tmp_path / "s.toml")


def test_a_table_path_that_is_a_folder_is_reported_as_the_table(tmp_path):
    (tmp_path / "table.csv").mkdir()
    (tmp_path / "s.toml").write_text(
        'duration_s = 1.0\n[[motion]]\nkind = "table"\nfile = "table.csv"\n')
    with pytest.raises(ScenarioError, match=r"s\.toml: motion 1: .*table\.csv: is a directory, "
                                            r"not a rate table file"):
        load_scenario(tmp_path / "s.toml")


def test_an_npy_table_with_nan_or_a_lying_header_is_refused_by_row(tmp_path):
    table = np.array([[0, 0, 0, 0], [1, 0, np.nan, 0]], dtype=float)
    np.save(tmp_path / "t.npy", table)
    (tmp_path / "s.toml").write_text(
        'duration_s = 1.0\n[[motion]]\nkind = "table"\nfile = "t.npy"\n')
    with pytest.raises(ScenarioError, match=r"t\.npy: row 1: empty or non-finite value"):
        load_scenario(tmp_path / "s.toml")
    header = {"descr": "<f8", "fortran_order": False, "shape": (10**11, 4)}
    with (tmp_path / "t.npy").open("wb") as handle:  # 1e11 rows declared, 64 bytes held
        np.lib.format.write_array_header_1_0(handle, header)
        handle.write(b"\0" * 64)
    with pytest.raises(ScenarioError, match=r"t\.npy.*header declares"):
        load_scenario(tmp_path / "s.toml")


def test_inline_samples_with_nan_are_refused_by_row():
    with pytest.raises(ScenarioError, match="motion 1: samples row 2: the times and rates"):
        scenario_from_dict({"duration_s": 1.0, "motion": [
            {"kind": "table", "samples": [[0, 0, 0, 0], [1, float("nan"), 0, 0]]}]})
