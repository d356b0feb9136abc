"""The unit's error budget in the chip (issue 16): the bias follows its temperature polynomial
over an orbit's thermal cycle while TEMP reports that temperature, turn-on bias per power
cycle, units of a lot, g-sensitivity, and traces that carry the errors."""

from __future__ import annotations

import json

import numpy as np
import pytest
from scipy import stats

from bmg160_emu.adcs.thermal import OrbitThermalCycle
from bmg160_emu.bus.smbus import FakeSMBus
from bmg160_emu.device import spec_choices as choice
from bmg160_emu.device.chip import BMG160
from bmg160_emu.device.config import ChipConfig
from bmg160_emu.device.unit_population import draw_unit
from bmg160_emu.noise.sensor_errors import SensorErrors
from bmg160_emu.session.record import record

WHITE_N = 0.014  # deg/s/sqrt(Hz), the BMG160 data sheet's typical noise density
WHITE = {"name": "white", **{axis: {"N": WHITE_N, "B": 0.0, "T": 1.0, "K": 0.0, "bias": 0.0}
                             for axis in "xyz"}}
CUBIC = SensorErrors(reference_temperature_c=20.0, zero_rate_offset_dps=(0.3, -0.2, 0.1),
                     bias_tc_dps_per_k=((0.015, 2e-4, -3e-6), (-0.01, 0, 5e-6), (0.005, -1e-4, 0)))
ORBIT = OrbitThermalCycle(sunlit_c=60.0, eclipse_c=-20.0, period_s=95 * 60.0,
                          eclipse_s=35 * 60.0, time_constant_s=300.0)


def test_over_an_orbit_the_bias_follows_its_polynomial_and_temp_reports_the_temperature():
    chip = BMG160(seed=4, profile=WHITE, errors=CUBIC, temperature_c=ORBIT)
    chip.write(0x0F, b"\x04")  # +-125 deg/s: 262.144 LSB per deg/s, quantization << noise
    chip.write(0x10, b"\x05")  # ODR 100 Hz
    chip.advance(0.1)
    rec = record(chip, ORBIT.period_s)
    rate = rec.counts / chip.sensitivity
    temps = ORBIT.temperature_c(rec.t_s)
    expected = CUBIC.bias_dps(temps)
    # 4 K bins over -20..60 C; each bin's mean output against the mean of the polynomial over
    # the same samples, within 4 standard errors of the white noise (sigma = N sqrt(ODR) per
    # sample, a few hundred samples a bin; about 20 bins x 3 axes: P(any beyond 4 SE) < 0.5 %)
    sigma = WHITE_N * np.sqrt(100.0)
    edges = np.arange(-20.0, 64.0, 4.0)
    which = np.digitize(temps, edges)
    checked = 0
    for b in np.unique(which):
        rows = which == b
        if rows.sum() < 100:
            continue
        se = sigma / np.sqrt(rows.sum())
        assert np.all(np.abs(rate[rows].mean(axis=0) - expected[rows].mean(axis=0)) < 4 * se)
        checked += 1
    assert checked >= 15
    # TEMP: two's complement, 0.5 K per LSB, 0 = 23 deg C (spec 5.2), sampled with the data
    with FakeSMBus(1, devices={0x68: chip}) as bus:
        for _ in range(25):  # through the next orbit
            chip.advance(ORBIT.period_s / 25)
            raw = bus.read_byte_data(0x68, 0x08)
            reported = choice.TEMP_ZERO_C + (raw - 256 if raw > 127 else raw) * choice.TEMP_LSB_K
            assert reported == pytest.approx(ORBIT(chip.time), abs=0.25 + 0.01)


def test_a_fresh_turn_on_bias_at_every_power_cycle_from_the_seed():
    errors = SensorErrors(turn_on_bias_sigma_dps=(0.05, 0.1, 0.2))
    chip = BMG160(seed=9, noise=False, errors=errors)
    cycles = []
    for _ in range(1000):
        cycles.append(chip.turn_on_bias_dps)
        chip.power_on_reset()
    cycles = np.array(cycles)
    for axis, sigma in enumerate(errors.turn_on_bias_sigma_dps):
        # KS against N(0, sigma) at the 1 % level per axis (fixed seed: deterministic)
        assert stats.kstest(cycles[:, axis] / sigma, "norm").pvalue > 0.01
    again = BMG160(seed=9, noise=False, errors=errors)
    assert np.array_equal(again.turn_on_bias_dps, cycles[0])
    again.soft_reset()  # a soft reset is a power cycle too
    assert np.array_equal(again.turn_on_bias_dps, cycles[1])
    # ... and the output carries it: +-125 deg/s, one count is 1/262 deg/s
    again.write(0x0F, b"\x04")
    again.advance(0.2)
    counts = np.frombuffer(again.read(0x02, 6), "<i2")
    assert np.allclose(counts / again.sensitivity, cycles[1], atol=1 / again.sensitivity)


def test_unit_k_of_a_lot_is_drawn_from_the_seed():
    chip = BMG160(seed=2026, unit=7, noise=False)
    assert chip.sensor_errors == draw_unit(2026, 7)
    assert BMG160(seed=2026, unit=8).sensor_errors != chip.sensor_errors
    with pytest.raises(ValueError, match="give the chip a seed"):
        BMG160(unit=1)


def test_g_sensitivity_follows_the_acceleration_input():
    g = np.zeros((3, 3))
    g[:, 2] = (0.1, -0.05, 0.02)  # deg/s per g along z
    chip = BMG160(seed=1, noise=False, errors=SensorErrors(g_sensitivity_dps_per_g=g))
    chip.write(0x0F, b"\x04")
    chip.advance(0.1)
    assert np.frombuffer(chip.read(0x02, 6), "<i2").tolist() == [0, 0, 0]
    chip.set_acceleration((0.0, 0.0, 1.0))
    chip.advance(0.1)
    counts = np.frombuffer(chip.read(0x02, 6), "<i2")
    assert np.allclose(counts / chip.sensitivity, g[:, 2], atol=1 / chip.sensitivity)


def test_a_trace_header_carries_the_errors_so_replay_builds_the_same_unit():
    config = ChipConfig(errors=draw_unit(5, 3), unit=None, acceleration_g=(0.0, 0.0, 1.0))
    entry = json.loads(json.dumps(config.to_dict()))
    again = ChipConfig.from_dict(entry)
    a, b = config.build(seed=1), again.build(seed=1)
    a.advance(0.05)
    b.advance(0.05)
    assert a.read(0x02, 6) == b.read(0x02, 6)
    assert a.sensor_errors == b.sensor_errors


SCENARIO = """
duration_s = 10.0
[thermal]
kind = "orbit"
sunlit_c = 60.0
eclipse_c = -20.0
[[gyro]]
unit = "per-run"
lot = 77
[[gyro]]
address = 0x69
unit = 3
lot = 77
"""


def test_a_rig_flies_units_of_a_lot_in_its_thermal_environment(tmp_path):
    from bmg160_emu.adcs.rig import GyroRig
    from bmg160_emu.adcs.scenarios import load_scenario

    path = tmp_path / "s.toml"
    path.write_text(SCENARIO)
    scenario = load_scenario(path)
    a, b, again = GyroRig(scenario, seed=1), GyroRig(scenario, seed=2), GyroRig(scenario, seed=1)
    # "per-run": each Monte Carlo run (rig seed) flies another unit of the lot, reproducibly
    assert a.gyros[0].chip.sensor_errors == draw_unit(77, 1)
    assert b.gyros[0].chip.sensor_errors == draw_unit(77, 2)
    assert again.gyros[0].chip.sensor_errors == a.gyros[0].chip.sensor_errors
    # a fixed unit is the same in every run
    assert a.gyros[1].chip.sensor_errors == b.gyros[1].chip.sensor_errors == draw_unit(77, 3)
    a.advance(1.0)
    raw = a.gyros[0].chip.peek(0x08)
    reported = choice.TEMP_ZERO_C + (raw - 256 if raw > 127 else raw) * choice.TEMP_LSB_K
    assert reported == pytest.approx(scenario.thermal(a.gyros[0].chip.time), abs=0.26)


def test_a_gyro_table_refuses_errors_and_a_unit_together(tmp_path):
    from bmg160_emu.adcs.rig import GyroRig
    from bmg160_emu.adcs.scenarios import ScenarioError, load_scenario

    path = tmp_path / "s.toml"
    path.write_text('duration_s = 1.0\n[[gyro]]\nunit = 1\nerrors = {zero_rate_offset_dps = 1}\n')
    with pytest.raises(ScenarioError, match="give errors or unit, not both"):
        GyroRig(load_scenario(path), seed=1)
