"""Several gyros on emulated buses: seeds, mounting, truth output."""

from __future__ import annotations

import numpy as np
import pytest

from bmg160_emu.adcs.attitude import angle_between_deg, integrate_attitude
from bmg160_emu.adcs.evaluation import FifoReader
from bmg160_emu.adcs.rig import GyroRig, GyroSpec, gyro_spec_from_dict
from bmg160_emu.adcs.scenarios import Scenario, ScenarioError, scenario_from_dict

# White noise only, no bias: statistics with a known answer (N as the paper's, section 2.5).
WHITE = {ax: {"N": 1.779073e-2, "B": 0.0, "T": 1.0, "K": 0.0, "bias": 0.0} for ax in "xyz"}


def _rates(rig: GyroRig, gyro: int, seconds: float, range_dps: int = 2000) -> np.ndarray:
    g = rig.gyros[gyro]
    reader = FifoReader(g.bus, g.address, range_dps=range_dps, bandwidth_code=4)
    reader.configure()
    chunks = []
    for _ in range(round(seconds / 0.1)):
        rig.advance(0.1)
        chunks.append(reader.read_frames())
    return np.concatenate(chunks)


def test_two_gyros_on_one_bus_answer_at_0x68_and_0x69_with_their_own_noise():
    rig = GyroRig(Scenario.constant([0, 0, 0], 10.0),
                  [GyroSpec(address=0x68), GyroSpec(address=0x69)], seed=5)
    bus = rig.bus()
    assert sorted(bus.devices) == [0x68, 0x69]
    a, b = _rates(rig, 0, 1.0), _rates(rig, 1, 1.0)
    assert not np.array_equal(a, b)


def test_the_master_seed_fixes_every_gyros_noise_and_another_seed_changes_it():
    def run(seed):
        rig = GyroRig(Scenario.constant([0, 0, 0], 10.0),
                      [GyroSpec(bus=1), GyroSpec(bus=2, address=0x69)], seed=seed)
        return _rates(rig, 0, 0.5), _rates(rig, 1, 0.5)

    first = run(42)
    again = run(42)
    other = run(43)
    assert np.array_equal(first[0], again[0]) and np.array_equal(first[1], again[1])
    assert not np.array_equal(first[0], other[0])


def test_gyros_on_several_buses_share_one_clock():
    rig = GyroRig(Scenario.constant([0, 0, 0], 10.0),
                  [GyroSpec(bus=1), GyroSpec(bus=3)], seed=1)
    assert sorted(rig.buses) == [1, 3]
    assert rig.gyros[0].chip.clock is rig.gyros[1].chip.clock
    with pytest.raises(ValueError, match="say which"):
        rig.bus()


def test_mounting_rotates_the_body_rate_into_the_sensor_frame():
    # sensor turned +90 deg about body z: body x appears on sensor -y
    spec = gyro_spec_from_dict({"noise": False, "mounting": {"euler_zyx_deg": [90, 0, 0]}}, 0)
    rig = GyroRig(Scenario.constant([10.0, 0.0, 0.0], 5.0), [spec], seed=0)
    rates = _rates(rig, 0, 1.0, range_dps=250)
    lsb = 1 / 131.072  # deg/s per count at +-250 deg/s (spec 5.1, binary table)
    assert np.allclose(rates[-1], [0.0, -10.0, 0.0], atol=lsb)


def test_a_rate_below_one_lsb_is_kept_exactly_and_shows_through_noise_dither():
    # 0.02 deg/s is 0.33 LSB at +-2000 deg/s: a noiseless chip reads 0 counts ...
    scenario = Scenario.constant([0.0, 0.0, 0.02], 200.0)
    quiet = GyroRig(scenario, [GyroSpec(noise=False)], seed=0)
    assert np.all(_rates(quiet, 0, 1.0)[:, 2] == 0.0)
    # ... while white noise dithers it: 100 s at 200 Hz = 20000 samples, per-sample sd
    # N sqrt(200) = 0.25 deg/s -> sd of the mean 0.0018 deg/s; 5 sd = 0.009 deg/s.
    noisy = GyroRig(scenario, [GyroSpec(profile=WHITE)], seed=3)
    rates = _rates(noisy, 0, 100.0)
    assert rates.shape[0] == 20000
    assert rates[:, 2].mean() == pytest.approx(0.02, abs=0.009)
    truth = noisy.truth(0)
    assert np.all(truth.rate_dps[:, 2] == 0.02)


def test_truth_has_one_row_per_output_sample_with_rate_and_attitude():
    scenario = scenario_from_dict({"duration_s": 10.0, "motion": [
        {"kind": "jitter", "amplitude_dps": [2.0, 1.0, 0.5], "frequency_hz": 0.7}]})
    rig = GyroRig(scenario, [GyroSpec(noise=False)], seed=0)
    _rates(rig, 0, 2.0)  # configures 200 Hz output
    truth = rig.truth(0)
    steps = np.diff(truth.times_s[-100:])
    assert np.allclose(steps, 0.005)
    assert np.allclose(truth.rate_dps, scenario.rate_dps(truth.times_s))
    expected = integrate_attitude(scenario.rate_dps, truth.times_s[-1:], t0=0.0)
    assert angle_between_deg(truth.quaternion[-1], expected[0]) < 1e-9
    assert np.all(truth.fault_flags == 0)
    assert truth.to_array().shape == (truth.times_s.size, 9)
    assert truth.at(truth.times_s[10]) == 10


def test_bad_rigs_are_refused():
    scenario = Scenario.constant([0, 0, 0], 1.0)
    with pytest.raises(ScenarioError, match="same bus and address"):
        GyroRig(scenario, [GyroSpec(), GyroSpec()])
    with pytest.raises(ScenarioError, match="0x68 or 0x69"):
        GyroSpec(address=0x6A)
    with pytest.raises(ScenarioError, match="proper rotation"):
        GyroSpec(mounting=[[1, 0, 0], [0, 1, 0], [0, 0, -1]])
    with pytest.raises(ScenarioError, match="unknown keys"):
        gyro_spec_from_dict({"adress": 0x68}, 0)


def test_truth_holds_every_sample_due_by_now_even_on_a_gyro_nobody_has_read():
    # The chips make their samples lazily, when next accessed; truth asked after
    # rig.advance() must still cover every output period up to the rig's time.
    rig = GyroRig(Scenario.constant([0.0, 0.0, 0.06], 5.0),
                  [GyroSpec(noise=False), GyroSpec(address=0x69, noise=False)], seed=1)
    rig.bus().write_byte_data(0x68, 0x10, 0x04)  # gyro 0 at 200 Hz; gyro 1 keeps 2000 Hz
    rig.advance(1.0)
    first, second = rig.truth(0), rig.truth(1)
    assert first.times_s[-1] > rig.time - 0.005  # the last 200 Hz period before now
    assert second.times_s[-1] > rig.time - 0.0005  # the last 2000 Hz period before now
    assert second.times_s.size > 1900  # 2000 Hz for 1 s, less the start-up time
    assert np.allclose(second.rate_dps, [0.0, 0.0, 0.06])


@pytest.mark.parametrize(
    "entry, message",
    [
        ({"address": "0x68"}, "address must be 0x68 or 0x69"),
        ({"bus": "two"}, "bus must be a whole number"),
        ({"bus": -1}, "bus must be a whole number"),
        ({"scale_factor_error": "x"}, "scale_factor_error must be"),
        ({"scale_factor_error": [0.1, 0.2]}, "scale_factor_error must be"),
        ({"temperature_c": "hot"}, "temperature_c must be a finite number"),
        ({"noise": "yes"}, "noise must be true or false"),
        ({"noise_mode": "fast"}, "noise_mode must be 'physical' or 'paper'"),
        ({"profile": "nope"}, "unknown noise profile 'nope'"),
        ({"misalignment_rad": "x"}, "misalignment_rad must be a 3x3 matrix"),
    ],
)
def test_a_bad_gyro_table_is_refused_by_name_before_the_run(entry, message):
    # A [[gyro]] table read from TOML: every mistake is a ScenarioError naming the gyro (the
    # montecarlo command prints it as one line), never a Python error from deep in the chip.
    scenario = scenario_from_dict({"duration_s": 1.0, "gyro": [entry]})
    with pytest.raises(ScenarioError, match=message) as caught:
        GyroRig(scenario, seed=0)
    assert "gyro0" in str(caught.value)


def test_scale_factor_and_misalignment_from_a_gyro_table_reach_the_registers():
    # [[gyro]] keys as a user writes them: +2 % scale on x, and sensor x picking up 1 % of
    # body y (a small-angle misalignment of 0.01 rad); both off on the other axes.
    spec = gyro_spec_from_dict({"noise": False, "scale_factor_error": [0.02, 0.0, 0.0],
                                "misalignment_rad": [[0, 0.01, 0], [0, 0, 0], [0, 0, 0]]}, 0)
    rig = GyroRig(Scenario.constant([50.0, 100.0, 0.0], 5.0), [spec], seed=0)
    rates = _rates(rig, 0, 1.0, range_dps=250)
    lsb = 1 / 131.072  # deg/s per count at +-250 deg/s (spec 5.1, binary table)
    # sensor = (I + M)(I + S) R body (docs/scenarios.md): x = 1.02 * 50 + 0.01 * 100 = 52.0
    # (the other order would give 52.02, 2.6 LSB away); y and z untouched
    assert np.allclose(rates[-1], [52.0, 100.0, 0.0], atol=lsb)
