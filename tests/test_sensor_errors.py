"""The deterministic error budget (bmg160_emu.noise.sensor_errors, unit_population): each
term as the model in the module docstring states it, validation, turn-on bias and units."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import stats

from bmg160_emu.device.unit_population import BMG160_TOLERANCES, draw_unit
from bmg160_emu.noise.sensor_errors import NO_ERRORS, SensorErrors, TurnOnBias

FS = 2000.0


def test_no_errors_pass_the_rate_through_unchanged():
    w = np.random.default_rng(1).normal(0, 100, (50, 3))
    assert not NO_ERRORS.active
    assert np.array_equal(NO_ERRORS.apply(w, 40.0, FS), w)


def test_the_bias_follows_its_temperature_polynomial():
    e = SensorErrors(reference_temperature_c=25.0, zero_rate_offset_dps=(0.5, -0.2, 0.1),
                     bias_tc_dps_per_k=((0.01, 1e-4, -2e-6), (0.02, 0, 0), (0, 0, 1e-5)))
    temps = np.array([-20.0, 25.0, 60.0])
    dt = temps - 25.0
    expected = np.column_stack([0.5 + 0.01 * dt + 1e-4 * dt**2 - 2e-6 * dt**3,
                                -0.2 + 0.02 * dt, 0.1 + 1e-5 * dt**3])
    assert np.allclose(e.apply(np.zeros((3, 3)), temps, FS), expected, rtol=0, atol=1e-15)
    assert np.allclose(e.bias_dps(temps), expected, rtol=0, atol=1e-15)


def test_scale_factor_and_its_temperature_change_multiply_the_rate():
    e = SensorErrors(scale_factor_error=(0.01, -0.02, 0.0), sensitivity_tc_per_k=(3e-4, 0, 0))
    out = e.apply(np.full((2, 3), 100.0), np.array([25.0, 35.0]), FS)
    assert out[0].tolist() == pytest.approx([101.0, 98.0, 100.0], abs=1e-12)
    assert out[1, 0] == pytest.approx(100.0 * (1.01 + 10 * 3e-4), abs=1e-12)


def test_cross_axis_couples_one_axis_into_the_others():
    cross = np.zeros((3, 3))
    cross[1, 0], cross[2, 0] = 0.01, -0.005  # y and z see 1 % and -0.5 % of x
    out = SensorErrors(cross_axis=cross).apply(np.array([[100.0, 0, 0]]), 25.0, FS)
    assert out[0].tolist() == pytest.approx([100.0, 1.0, -0.5], abs=1e-12)


def test_nonlinearity_is_the_largest_deviation_from_the_best_fit_straight_line():
    # the data sheet's figure: max |output - least-squares line| over the range, in % of FS
    nl = 0.0005  # 0.05 %FS
    w = np.linspace(-FS, FS, 20001)
    out = SensorErrors(nonlinearity_fs=(nl, -nl, 0)).apply(np.column_stack([w, w, w]), 25.0, FS)
    for axis in (0, 1):
        slope, intercept = np.polyfit(w, out[:, axis], 1)
        deviation = np.max(np.abs(out[:, axis] - (slope * w + intercept)))
        assert deviation == pytest.approx(nl * FS, rel=1e-3)
    assert np.array_equal(out[:, 2], w)


def test_g_sensitivity_adds_deg_per_s_per_g():
    g = np.diag([0.1, 0.05, 0.02])
    out = SensorErrors(g_sensitivity_dps_per_g=g).apply(
        np.zeros((1, 3)), 25.0, FS, acceleration_g=np.array([0.0, 0.0, 1.0]))
    assert out[0].tolist() == pytest.approx([0.0, 0.0, 0.02], abs=1e-15)


@pytest.mark.parametrize(("changes", "message"), [
    ({"zero_rate_offset_dps": (np.inf, 0, 0)}, "zero_rate_offset_dps must be 3 finite"),
    ({"zero_rate_offset_dps": (1e308, 0, 0)}, r"within \+-1000"),
    ({"bias_tc_dps_per_k": ((1, 2, 3, 4),) * 3}, "a cubic at most"),
    ({"cross_axis": np.eye(3) * 0.01}, "no diagonal"),
    ({"g_sensitivity_dps_per_g": np.zeros((2, 2))}, "3x3"),
    ({"turn_on_bias_sigma_dps": (-1, 0, 0)}, "must not be negative"),
    ({"reference_temperature_c": float("nan")}, "reference_temperature_c"),
])
def test_bad_values_are_refused_by_name(changes, message):
    with pytest.raises(ValueError, match=message):
        SensorErrors(**changes)


def test_a_dictionary_round_trip_and_unknown_keys():
    e = draw_unit(seed=3, unit=7, turn_on_bias_sigma_dps=0.02)
    assert SensorErrors.from_dict(e.to_dict()) == e
    with pytest.raises(ValueError, match="errors: unknown keys \\['tco'\\]"):
        SensorErrors.from_dict({"tco": 1})


def test_turn_on_bias_is_the_configured_normal_and_repeats_with_its_seed():
    sigma = (0.05, 0.1, 0.2)
    draws = np.array([TurnOnBias(sigma, seed=11).next() for _ in range(1)])  # a fresh sequence
    sequence = TurnOnBias(sigma, seed=11)
    cycles = np.array([sequence.next() for _ in range(1000)])
    assert np.array_equal(cycles[0], draws[0])
    again = TurnOnBias(sigma, seed=11)
    assert np.array_equal(np.array([again.next() for _ in range(1000)]), cycles)
    for axis in range(3):
        # KS against N(0, sigma) at the 1 % level for each axis (fixed seed: deterministic)
        assert stats.kstest(cycles[:, axis] / sigma[axis], "norm").pvalue > 0.01
    other = TurnOnBias(sigma, seed=12)
    assert not np.array_equal(other.next(), cycles[0])


def test_units_of_a_lot_follow_the_data_sheet_spread_and_repeat():
    units = [draw_unit(seed=2026, unit=k) for k in range(1000)]
    assert draw_unit(seed=2026, unit=5) == units[5]
    assert draw_unit(seed=2027, unit=5) != units[5]
    t = BMG160_TOLERANCES
    samples = {
        "zero-rate offset": ([u.zero_rate_offset_dps for u in units], t.zero_rate_offset.sigma),
        "offset TC": ([[c[0] for c in u.bias_tc_dps_per_k] for u in units], t.offset_tc.sigma),
        "sensitivity": ([u.scale_factor_error for u in units], t.sensitivity.sigma),
        "sensitivity TC": ([u.sensitivity_tc_per_k for u in units], t.sensitivity_tc.sigma),
        "nonlinearity": ([u.nonlinearity_fs for u in units], t.nonlinearity.sigma),
        "cross axis": ([np.asarray(u.cross_axis)[~np.eye(3, dtype=bool)] for u in units],
                       t.cross_axis.sigma),
        "g-sensitivity": ([np.ravel(u.g_sensitivity_dps_per_g) for u in units],
                          t.g_sensitivity.sigma),
    }
    assert t.g_sensitivity.sigma == pytest.approx(0.1 / 3)  # a max figure is 3 sigma
    assert t.sensitivity.sigma == pytest.approx(0.01)  # +-1 % typ is 1 sigma
    tests = sum(np.asarray(v).shape[1] for v, _ in samples.values())
    for name, (values, sigma) in samples.items():
        values = np.asarray(values)
        for column in values.T:
            # KS against N(0, sigma); Bonferroni over all columns keeps the family-wise level
            # at 1 % (fixed seed: the outcome is deterministic, the level says how strict)
            assert stats.kstest(column / sigma, "norm").pvalue > 0.01 / tests, name
