"""The data path (spec 6.1, 5.2, 5.3): filter, unfiltered data, mounting, hooks, inputs."""

import numpy as np
import pytest
from _chip_helpers import period_s, quiet_chip, rates

from bmg160_emu.device.chip import BMG160


def _step_response(code, n=400):
    chip = quiet_chip()
    chip.write(0x10, bytes([code]))
    chip.write(0x0F, b"\x04")
    chip.advance(period_s(chip))
    chip.set_true_rate((100.0, 0.0, 0.0))
    out = []
    for _ in range(n):
        chip.advance(period_s(chip))
        out.append(rates(chip)[0])
    return chip, np.array(out)


@pytest.mark.parametrize("code", range(8))
def test_filter_has_unity_dc_gain(code):
    chip, y = _step_response(code)
    assert y[-1] == 32767 or y[-1] == round(100.0 * chip.sensitivity)


@pytest.mark.parametrize("narrow, wide, t", [(5, 7, 0.01), (4, 6, 0.005), (3, 2, 0.005)])
def test_narrower_bandwidth_responds_more_slowly(narrow, wide, t):
    # compare at equal elapsed time t after the step, well before either settles
    c1, y1 = _step_response(narrow)
    c2, y2 = _step_response(wide)
    i1, i2 = round(t * c1.odr_hz) - 1, round(t * c2.odr_hz) - 1
    assert y1[i1] < y2[i2]


def test_data_high_bw_gives_the_unfiltered_step():
    chip = quiet_chip()
    chip.write(0x10, b"\x05")
    chip.write(0x13, b"\x80")
    chip.read(0x00)
    chip.set_true_rate((10.0, 0, 0))
    chip.advance(period_s(chip))
    assert rates(chip)[0] == round(10.0 * chip.sensitivity)


def test_rewriting_the_same_bandwidth_does_not_disturb_the_output():
    chip = quiet_chip(true_rate=(25.0, -3.0, 7.0))
    chip.write(0x10, b"\x04")
    expected = rates(chip)
    for _ in range(20):
        chip.write(0x10, b"\x04")
        chip.write(0x0F, b"\x00")
        chip.advance(period_s(chip))
        assert rates(chip) == expected


def test_bandwidth_change_keeps_a_constant_rate_exact():
    chip = quiet_chip(true_rate=(33.3, 0, 0))
    for code in (1, 2, 3, 4, 5, 6, 7, 0):
        chip.write(0x10, bytes([code]))
        chip.advance(period_s(chip))
        assert rates(chip)[0] == round(33.3 * chip.sensitivity)


def test_mounting_rotation_maps_body_rate_to_sensor_axes():
    rot = np.array([[0, 1, 0], [-1, 0, 0], [0, 0, 1]], dtype=float)  # 90 deg about Z
    chip = quiet_chip(true_rate=(10.0, 20.0, 30.0), mounting=rot)
    s = chip.sensitivity
    assert rates(chip) == (round(20 * s), round(-10 * s), round(30 * s))


def test_scale_factor_and_misalignment_apply_per_axis():
    mis = np.zeros((3, 3))
    mis[0, 1] = 0.01  # 1 % of Y leaks into X
    chip = quiet_chip(true_rate=(100.0, 50.0, 0.0), scale_factor=(0.02, 0.0, 0.0),
                      misalignment=mis)
    s = chip.sensitivity
    assert rates(chip)[:2] == (round((102.0 + 0.5) * s), round(50.0 * s))


@pytest.mark.parametrize("kwargs", [{"mounting": np.ones((3, 3))}, {"scale_factor": (1, 2)},
                                    {"misalignment": np.eye(2)}])
def test_bad_mounting_options_are_refused(kwargs):
    with pytest.raises(ValueError):
        BMG160(**kwargs)


def test_sample_array_input_is_played_one_row_per_output_sample():
    chip = quiet_chip()
    chip.write(0x13, b"\x80")
    chip.read(0x00)
    samples = np.array([[1.0, 0, 0], [2.0, 0, 0], [3.0, 0, 0]])
    chip.set_true_rate(samples)
    s = chip.sensitivity
    got = []
    for _ in range(5):
        chip.advance(period_s(chip))
        got.append(rates(chip)[0])
    assert got == [round(v * s) for v in (1, 2, 3, 3, 3)]


def test_callable_input_is_evaluated_at_sample_times():
    times = []
    chip = quiet_chip(true_rate=lambda t: (times.append(t) or (0.0, 0.0, 0.0)))
    chip.advance(0.002)
    assert times[:5] == pytest.approx([0.0, 0.0005, 0.001, 0.0015, 0.002])


@pytest.mark.parametrize("bad", [(1, 2), "abc", np.zeros((4, 2)), (1.0, float("nan"), 0)])
def test_bad_true_rate_is_refused(bad):
    with pytest.raises(ValueError):
        quiet_chip().set_true_rate(bad)


def test_sample_hook_can_replace_and_drop_samples():
    chip = quiet_chip(true_rate=(1.0, 1.0, 1.0))
    chip.read(0x00)
    calls = []

    def hook(c, t, rate):
        calls.append((t, rate.copy()))
        if len(calls) == 2:
            return None  # lost sample
        return rate * 2

    chip.sample_hooks.append(hook)
    chip.advance(period_s(chip))
    s = chip.sensitivity
    assert rates(chip) == (round(2 * s),) * 3
    before = chip.read(0x02, 6)
    seq = chip.state.sample_seq
    chip.advance(period_s(chip))
    assert chip.read(0x02, 6) == before and chip.state.sample_seq == seq
    assert calls[0][1] == pytest.approx([1.0, 1.0, 1.0])


def test_truth_hook_sees_the_body_rate_before_mounting():
    rot = np.array([[0, 1, 0], [-1, 0, 0], [0, 0, 1]], dtype=float)
    chip = BMG160(seed=1, true_rate=(5.0, 6.0, 7.0), mounting=rot)
    seen = []
    chip.truth_hooks.append(lambda c, t, r: seen.append((t, tuple(r))))
    chip.advance(2 * period_s(chip))
    assert seen[-1][1] == (5.0, 6.0, 7.0) and len(seen) == 3


def test_temperature_encoding_and_callable_temperature():
    chip = quiet_chip(temperature_c=lambda t: 23.0 + 100.0 * t)
    chip.advance(0.1)
    assert chip.read(0x08)[0] == round(10.0 / 0.5)
    chip.set_temperature(-100.0)
    assert chip.read(0x08)[0] == 0x80  # clamped to -128


def test_poke_changes_content_without_access_rules():
    chip = quiet_chip(true_rate=(10.0, 0, 0))
    chip.write(0x11, b"\x80")  # suspend: RANGE writes are ignored...
    chip.poke(0x0F, 0x01)  # ...but an upset is not
    assert chip.read(0x0F) == b"\x01"


@pytest.mark.parametrize("kwargs, error", [
    ({"noise_mode": "fancy", "noise": False}, ValueError), ({"seed": "abc"}, TypeError),
    ({"address": 0x10}, ValueError), ({"startup_time_s": -1}, ValueError),
    ({"temperature_c": float("nan")}, ValueError), ({"clock": 5}, TypeError),
    ({"nvm_image": b"12"}, ValueError), ({"nvm_remain": 16}, ValueError),
])
def test_bad_constructor_options_are_clear_errors(kwargs, error):
    with pytest.raises(error):
        BMG160(**kwargs)


def test_temperature_is_frozen_while_not_sampling_and_converts_again_after_wake_up():
    chip = quiet_chip(temperature_c=30.0)
    chip.advance(0.01)
    assert chip.read(0x08)[0] == round((30.0 - 23.0) / 0.5)
    chip.write(0x11, b"\x80")  # suspend: no conversions (spec 5.2, unconfirmed choice)
    chip.set_temperature(40.0)
    chip.advance(0.1)
    assert chip.read(0x08)[0] == round((30.0 - 23.0) / 0.5)
    chip.write(0x11, b"\x00")  # normal: the first sample after the wake-up time converts
    chip.advance(0.001)
    assert chip.read(0x08)[0] == round((30.0 - 23.0) / 0.5)
    chip.advance(0.05)
    assert chip.read(0x08)[0] == round((40.0 - 23.0) / 0.5)


@pytest.mark.parametrize("func, message", [
    (lambda t: (1.0, 2.0), "must return 3 numbers in deg/s, got 2"),
    (lambda t: ("a", 0.0, 0.0), "must return 3 numbers in deg/s"),
    (lambda t: (float("nan"), 0.0, 0.0), "non-finite"),
])
def test_a_true_rate_function_returning_the_wrong_thing_is_a_clear_error(func, message):
    chip = quiet_chip()
    chip.set_true_rate(func)
    with pytest.raises(ValueError, match=message):
        chip.advance(0.01)


def test_a_sample_hook_returning_the_wrong_shape_is_a_clear_error():
    chip = quiet_chip()
    chip.sample_hooks.append(lambda c, t, rate: rate[:2])
    with pytest.raises(ValueError, match="must return 3 numbers in deg/s or None, got 2"):
        chip.advance(0.01)


@pytest.mark.parametrize("bad", ["abc", [1, "x", 2], {"x": 1}])
def test_a_true_rate_that_is_not_numbers_says_what_is_expected(bad):
    with pytest.raises(ValueError, match="true rate must be 3 numbers in deg/s"):
        quiet_chip().set_true_rate(bad)


def test_a_failing_true_rate_function_can_be_replaced():
    chip = quiet_chip()
    chip.set_true_rate(lambda t: 1 / 0)
    with pytest.raises(ZeroDivisionError):
        chip.advance(0.01)
    chip.set_true_rate((10.0, 0.0, 0.0))  # the samples the function could not produce use this
    assert rates(chip)[0] == round(10.0 * chip.sensitivity)
    chip.advance(0.01)
    assert rates(chip)[0] == round(10.0 * chip.sensitivity)
