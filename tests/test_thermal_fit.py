"""Bias against temperature from a thermal record (bmg160_emu.noise.thermal_fit) and the orbit
thermal cycle (bmg160_emu.adcs.thermal)."""

from __future__ import annotations

import json
import math
import re

import numpy as np
import pytest

from bmg160_emu.adcs.thermal import (
    OrbitThermalCycle,
    TableTemperature,
    ThermalError,
    thermal_from_dict,
)
from bmg160_emu.noise import NoiseGenerator, load_profile
from bmg160_emu.noise.thermal_fit import (
    NoiseTerms,
    ThermalFitError,
    block_covariance,
    fit_bias_temperature,
)

RATE_HZ = 100.0  # the lowest ODR the noise engine (and the chip) offers
ORBIT = OrbitThermalCycle(sunlit_c=60.0, eclipse_c=-20.0, period_s=95 * 60.0,
                          eclipse_s=35 * 60.0, time_constant_s=300.0)
# deg/s/K^k about 20 deg C: c1 is the data sheet's TCO (0.015 deg/s/K, BMG160 table 1)
TRUE_TC = np.array([[0.05, 0.015, 2e-4, -3e-6], [-0.1, -0.01, 0.0, 5e-6], [0.0, 0.005, -1e-4, 0]])


def _thermal_record(seed: int, hours: float = 6.0):
    n = int(hours * 3600 * RATE_HZ)
    t = np.arange(n) / RATE_HZ
    temps = ORBIT.temperature_c(t)
    noise = NoiseGenerator(profile="paper", rate_hz=RATE_HZ, seed=seed).generate(n)
    dt = (temps - 20.0).reshape(-1, 1)
    bias = TRUE_TC[:, 0] + dt * TRUE_TC[:, 1] + dt**2 * TRUE_TC[:, 2] + dt**3 * TRUE_TC[:, 3]
    return noise + bias, temps


def test_the_orbit_cycle_is_periodic_from_the_start_and_spans_its_equilibria():
    t = np.linspace(0, 3 * ORBIT.period_s, 30001)
    temps = ORBIT.temperature_c(t)
    assert np.allclose(ORBIT.temperature_c(t[:10001] + ORBIT.period_s), temps[:10001])
    # tau = 5 min against 35 and 60 min phases: within 0.1 K of both equilibria
    assert temps.max() == pytest.approx(60.0, abs=0.1) and temps.min() == pytest.approx(
        -20.0, abs=0.1)
    assert np.all(np.abs(np.diff(temps)) < 1.0)  # a first-order lag: no jumps


def test_a_slow_die_swings_less_than_its_environment():
    slow = OrbitThermalCycle(sunlit_c=60.0, eclipse_c=-20.0, time_constant_s=3600.0)
    temps = slow.temperature_c(np.linspace(0, slow.period_s, 5001))
    assert 60.0 - temps.max() > 5 and temps.min() + 20.0 > 5


def test_thermal_tables_from_a_scenario():
    assert thermal_from_dict({"kind": "constant", "temperature_c": 30}) == 30.0
    orbit = thermal_from_dict({"kind": "orbit", "sunlit_c": 40, "eclipse_c": 0})
    assert isinstance(orbit, OrbitThermalCycle) and orbit.sunlit_c == 40
    table = thermal_from_dict({"kind": "table", "samples": [[0, 10], [100, 30]]})
    assert isinstance(table, TableTemperature) and table(50.0) == 20.0 and table(500.0) == 30.0
    for bad, message in [({"kind": "orbit", "period_s": -1}, "period_s must be a positive"),
                         ({"kind": "wave"}, "kind must be one of"),
                         ({"kind": "table", "samples": [[0, 10], [0, 20]]}, "strictly increasing"),
                         ({"kind": "constant", "temperature_c": 1e9}, "within -150..200"),
                         ({"kind": "orbit", "sunset": 1}, "unknown keys"),
                         # integers beyond a double (TOML digits): OverflowError before
                         ({"kind": "orbit", "period_s": 10**400}, "period_s must be a positive"),
                         ({"kind": "orbit", "phase_s": 10**400}, "phase_s must be finite"),
                         ({"kind": "table", "samples": [[0, 10], [10**400, 20]]},
                          "beyond a double's range")]:
        with pytest.raises(ThermalError, match=message):
            thermal_from_dict(bad)


def test_block_covariance_matches_simulated_block_means():
    # 200 realisations of 20 one-minute blocks of the paper profile's x axis: the empirical
    # covariance of the block means against the closed forms (relative sampling error of a
    # variance from 200 draws: sqrt(2/200) = 10 %; compared within 30 %, 3 sd)
    axis = load_profile("paper").axes[0]
    terms = NoiseTerms.from_axis(axis)
    blocks, per = 20, int(60 * RATE_HZ)
    means = []
    for seed in range(200):
        x = NoiseGenerator(profile="paper", rate_hz=RATE_HZ, seed=seed).generate(blocks * per)[:, 0]
        means.append(x.reshape(blocks, per).mean(axis=1))
    empirical = np.cov(np.array(means).T)
    model = block_covariance(terms, blocks, 60.0)
    assert np.allclose(np.diag(empirical), np.diag(model), rtol=0.3)
    assert empirical[5, 6] == pytest.approx(model[5, 6], rel=0.3)
    assert empirical[2, 15] == pytest.approx(model[2, 15], rel=0.3)


@pytest.mark.slow
def test_the_cubic_comes_back_within_intervals_that_cover_at_their_level():
    # 50 seeds of a 6 h orbit thermal record (-20..+60 C, 95 min); GLS with the profile's own
    # noise terms. Coverage of each 95 % interval over 50 seeds is binomial(50, 0.95): mean
    # 47.5, sd 1.5; at least 44 of 50 (2.3 sd below) for every coefficient of every axis.
    axes = load_profile("paper").axes
    hits = np.zeros((3, 4))
    for seed in range(50):
        rate, temps = _thermal_record(seed)
        fit = fit_bias_temperature(rate, temps, RATE_HZ, order=3, reference_c=20.0, noise=axes)
        truth = TRUE_TC + np.array([[a.bias, 0, 0, 0] for a in axes])
        for i, axis_fit in enumerate(fit.axes):
            lo, hi = axis_fit.intervals.T
            hits[i] += (lo <= truth[i]) & (truth[i] <= hi)
    assert hits.min() >= 44, hits


def test_without_a_noise_model_the_residuals_give_one():
    rate, temps = _thermal_record(seed=3)
    fit = fit_bias_temperature(rate, temps, RATE_HZ, reference_c=20.0)
    for i, axis_fit in enumerate(fit.axes):
        z = (axis_fit.coefficients[1:] - TRUE_TC[i, 1:]) / axis_fit.standard_errors[1:]
        assert np.all(np.abs(z) < 4), z  # the temperature terms, within 4 sd
        assert axis_fit.noise.N == pytest.approx(load_profile("paper").axes[i].N, rel=0.1)


def test_exports_to_px4_and_to_our_profile():
    rate, temps = _thermal_record(seed=1, hours=3.0)
    fit = fit_bias_temperature(rate, temps, RATE_HZ, reference_c=20.0,
                               noise=load_profile("paper").axes)
    params = fit.px4_parameters(instance=0, device_id=2490378)
    assert params["TC_G0_TREF"] == 20.0 and params["TC_G0_ID"] == 2490378
    assert params["TC_G0_X1_0"] == pytest.approx(math.radians(fit.axes[0].coefficients[1]))
    assert params["TC_G0_TMIN"] == pytest.approx(temps.min())
    text = fit.px4_params_file()
    assert "1\t1\tTC_G0_X3_2\t" in text and text.count("\n") == 2 + len(params)
    errors = fit.to_errors()
    from bmg160_emu.noise.sensor_errors import SensorErrors

    unit = SensorErrors.from_dict(errors)
    assert np.allclose(unit.bias_dps([0.0, 40.0]), fit.bias_dps([0.0, 40.0]))


@pytest.mark.parametrize(("kwargs", "message"), [
    ({"order": 4}, "order must be 0..3"),
    ({"block_s": 3600.0}, "too few for an order-3 fit"),
])
def test_records_that_cannot_be_fitted_say_why(kwargs, message):
    rate, temps = _thermal_record(seed=0, hours=1.0)
    with pytest.raises(ThermalFitError, match=message):
        fit_bias_temperature(rate, temps, RATE_HZ, **kwargs)


def test_a_record_at_one_temperature_is_refused():
    rate = np.zeros((200_000, 3))
    with pytest.raises(ThermalFitError, match="spans only 0.00 K"):
        fit_bias_temperature(rate, np.full(200_000, 25.0), RATE_HZ)


def test_the_thermal_command_fits_a_chamber_log_and_exports(tmp_path, capsys):
    import tomllib

    from bmg160_emu.cli import main
    from bmg160_emu.noise.sensor_errors import SensorErrors

    rate, temps = _thermal_record(seed=5, hours=3.0)
    t = np.arange(len(temps)) / RATE_HZ
    log = tmp_path / "chamber.csv"
    np.savetxt(log, np.column_stack([t, rate, temps]), delimiter=",", fmt="%.9g",
               header="t_s,x_dps,y_dps,z_dps,temp_c", comments="")
    params, errors = tmp_path / "tc.params", tmp_path / "unit.toml"
    assert main(["thermal", str(log), "--reference", "20", "--noise-profile", "paper",
                 "--px4-params", str(params), "--errors-out", str(errors)]) == 0
    out = capsys.readouterr().out
    assert "x  c1 = " in out and "reduced chi-square" in out
    # each coefficient is quoted to the place of its standard error's second significant digit
    # (GUM 7.2.6), no further: the digits beyond differ with the machine's BLAS kernel
    assert main(["thermal", str(log), "--reference", "20", "--noise-profile", "paper",
                 "--json"]) == 0
    axes = json.loads(capsys.readouterr().out)["axes"]
    quoted = re.findall(r"^  ([xyz])  c(\d) = +(\S+) ", out, flags=re.MULTILINE)
    assert len(quoted) == 12
    for axis, k, text in quoted:
        value = axes[axis]["coefficients"][int(k)]
        lo, hi = axes[axis]["intervals_95"][int(k)]
        place = math.floor(math.log10((hi - lo) / 2 / 1.959964)) - 1
        assert abs(float(text) - value) <= 0.5001 * 10.0 ** place, (axis, k, text, value)
        mantissa = text.split("e")[0].lstrip("-")
        digits = len(mantissa.replace(".", "").lstrip("0"))
        exponent = int(text.split("e")[1]) if "e" in text else 0
        last_place = exponent - (len(mantissa.split(".")[1]) if "." in mantissa else 0)
        assert last_place == place or digits == 1, (axis, k, text, place)
    assert "\tTC_G0_X1_0\t" in params.read_text()
    table = tomllib.loads(errors.read_text())["errors"]
    unit = SensorErrors.from_dict(table)
    # the fitted c1 of x, within 4 of its standard errors (3 h record) of the truth
    assert abs(unit.bias_tc_dps_per_k[0][0] - TRUE_TC[0, 1]) < 0.003


def test_the_thermal_command_names_what_a_log_lacks(tmp_path, capsys):
    from bmg160_emu.cli import main

    log = tmp_path / "no-temp.csv"
    log.write_text("t_s,x_dps,y_dps,z_dps\n0,1,2,3\n0.01,1,2,3\n")
    assert main(["thermal", str(log)]) == 2
    assert "no temperature column" in capsys.readouterr().err
