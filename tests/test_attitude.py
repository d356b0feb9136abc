"""The true attitude: quaternion integration of the body rate."""

from __future__ import annotations

import numpy as np
import pytest

from bmg160_emu.adcs.attitude import (
    IDENTITY,
    AttitudeIntegrator,
    angle_between_deg,
    integrate_attitude,
    quat_from_axis_angle,
    quat_from_rotation_vector,
    quat_multiply,
    rotate,
)
from bmg160_emu.adcs.scenarios import scenario_from_dict


def test_constant_rate_gives_the_exact_rotation():
    rate = np.array([3.0, -4.0, 12.0])  # |rate| = 13 deg/s
    times = np.array([1.0, 10.0])
    q = integrate_attitude(lambda t: np.broadcast_to(rate, (t.size, 3)), times, t0=0.0)
    expected = quat_from_axis_angle(rate, 130.0)
    assert angle_between_deg(q[1], expected) < 1e-9


def test_body_vectors_are_mapped_to_the_reference_frame():
    # a body rotated by +90 deg about z carries its x axis onto the reference y axis
    q = quat_from_axis_angle([0, 0, 1], 90.0)
    assert np.allclose(rotate(q, [1.0, 0.0, 0.0]), [0.0, 1.0, 0.0])


def _analytic(t):
    """q(t) = Rz(phi(t)) Rx(theta(t)) with phi = 0.3 t + 0.2 t^2, theta = 0.5 sin 2t."""
    phi = 0.3 * t + 0.2 * t * t
    theta = 0.5 * np.sin(2 * t)
    return quat_multiply(quat_from_rotation_vector(np.array([0, 0, phi])),
                         quat_from_rotation_vector(np.array([theta, 0, 0])))


def _analytic_body_rate_dps(t):
    t = np.atleast_1d(t)
    phi_dot = 0.3 + 0.4 * t
    theta = 0.5 * np.sin(2 * t)
    theta_dot = np.cos(2 * t)
    # w_body = Rx(theta)^T (phi_dot z) + theta_dot x
    return np.degrees(np.stack([theta_dot, phi_dot * np.sin(theta), phi_dot * np.cos(theta)], 1))


def test_varying_rate_with_coning_matches_the_analytic_attitude_to_fourth_order():
    times = np.linspace(0.05, 10.0, 40)
    errors = []
    for step in (0.02, 0.01):
        q = integrate_attitude(_analytic_body_rate_dps, times, q0=_analytic(0.0), t0=0.0,
                               max_step_s=step)
        errors.append(max(angle_between_deg(q[i], _analytic(t)) for i, t in enumerate(times)))
    assert errors[1] < 1e-5
    # fourth order: halving the step divides the error by about 16 (a second-order method,
    # e.g. one without the coning term, would give 4)
    assert errors[0] / errors[1] > 10


def test_slew_ends_rotated_by_its_angle_about_its_axis():
    scenario = scenario_from_dict({"duration_s": 60.0, "motion": [
        {"kind": "slew", "axis": [0, 1, 1], "angle_deg": 90.0, "max_rate_dps": 5.0,
         "max_accel_dps2": 1.0, "start_s": 2.0}]})
    q = integrate_attitude(scenario.rate_dps, np.array([1.0, 60.0]), t0=0.0)
    assert angle_between_deg(q[0], IDENTITY) == 0.0
    assert angle_between_deg(q[1], quat_from_axis_angle([0, 1, 1], 90.0)) < 1e-8


def test_step_by_step_integration_equals_the_batch_one():
    scenario = scenario_from_dict({"duration_s": 5.0, "motion": [
        {"kind": "jitter", "amplitude_dps": [5, 3, 1], "frequency_hz": 1.5}]})
    times = np.arange(1, 501) * 0.01
    batch = integrate_attitude(scenario.rate_dps, times, t0=0.0)
    stepper = AttitudeIntegrator(scenario.rate_dps)
    stream = np.array([stepper.advance_to(t) for t in times])
    assert np.max(angle_between_deg(batch, stream)) < 1e-9
    with pytest.raises(ValueError, match="backwards"):
        stepper.advance_to(1.0)


def test_quaternions_stay_unit_norm_over_a_long_tumble():
    scenario = scenario_from_dict({"duration_s": 600.0, "motion": [
        {"kind": "tumble", "initial_rate_dps": [30, -20, 45], "inertia_kg_m2": [1, 2, 3]}]})
    q = integrate_attitude(scenario.rate_dps, np.array([600.0]), t0=0.0, max_step_s=0.01)
    assert np.linalg.norm(q[0]) == pytest.approx(1.0, abs=1e-12)
