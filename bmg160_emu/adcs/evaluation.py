"""The per-seed run of a Monte Carlo: a flight-software-like reader and attitude propagator.

:class:`FifoReader` configures one gyro over the bus (range, bandwidth, FIFO in stream mode)
and drains the FIFO every poll period, as an ADCS task would; failed transactions are counted
and retried at the next poll. :class:`PropagationRun` integrates the body rate read from gyro
0 into an attitude quaternion and compares it with the true attitude on a time grid.

Readout options, from the scenario's ``[readout]`` table:

| key | default | meaning |
| --- | --- | --- |
| ``range_dps`` | 2000 | full-scale range written to RANGE (125, 250, 500, 1000, 2000) |
| ``bandwidth_code`` | 4 | BW code (spec 5.3; 4 = 200 Hz ODR, 23 Hz filter) |
| ``poll_s`` | 0.1 | FIFO drain period (at most 100 frames may wait: spec 6.5) |
| ``settle_s`` | 0.5 | samples thrown away after configuration (the chip's filter settles) |
| ``bias`` | ``"none"`` | ``"none"``, ``"profile"`` (subtract the profile's constant bias) or ``"calibrate"`` |
| ``calibrate_s`` | 10.0 | with ``bias = "calibrate"``: average this long at the start (the body must be at rest) |
| ``grid_s`` | 1.0 | spacing of the times where the angle error is reported |
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from bmg160_emu.adcs.attitude import (
    angle_between_deg,
    chain_rotations,
    integrate_attitude,
    quat_from_rotation_vector,
)
from bmg160_emu.adcs.results import RunResult
from bmg160_emu.adcs.scenarios import Scenario, ScenarioError
from bmg160_emu.device.registers import address_of, field_of
from bmg160_emu.device.spec_choices import RANGE_CODE_BY_DPS
from bmg160_emu.durations import MAX_SIMULATED_S
from bmg160_emu.limits import Bounded, LimitError
from bmg160_emu.noise.bandwidths import BW_CODES

RANGE, BW, FIFO_STATUS, FIFO_CONFIG_1, FIFO_DATA = (
    address_of(name) for name in ("RANGE", "BW", "FIFO_STATUS", "FIFO_CONFIG_1", "FIFO_DATA"))
FIFO_OVERRUN = field_of("FIFO_STATUS", "fifo_overrun")  # spec 4.7
FIFO_FRAME_COUNTER = field_of("FIFO_STATUS", "fifo_frame_counter")
# FIFO_CONFIG_1: mode 2 = stream, data select 0 = X, Y and Z (spec 4.26)
STREAM_XYZ = field_of("FIFO_CONFIG_1", "fifo_mode").insert(0, 2)
FRAME_BYTES = 6  # X, Y, Z little-endian 16-bit words (spec 6.5)

READOUT_DEFAULTS: dict[str, Any] = {
    "range_dps": 2000,
    "bandwidth_code": 4,
    "poll_s": 0.1,
    "settle_s": 0.5,
    "bias": "none",
    "calibrate_s": 10.0,
    "grid_s": 1.0,
}


# [readout] times: at most the cap on simulated time; steps (poll_s, grid_s) from 0.1 ms,
# shorter than the chip's fastest output period (0.5 ms at 2000 Hz, data sheet 5.3), and at
# most MAX_READOUT_STEPS of them in a run (about 100 s of work at ~10 us a read).
READOUT_LIMITS = {
    "settle_s": Bounded("settle_s", 0.0, MAX_SIMULATED_S, "s"),
    "poll_s": Bounded("poll_s", 1e-4, MAX_SIMULATED_S, "s"),
    "calibrate_s": Bounded("calibrate_s", 1e-4, MAX_SIMULATED_S, "s"),
    "grid_s": Bounded("grid_s", 1e-4, MAX_SIMULATED_S, "s"),
}
MAX_READOUT_STEPS = 10_000_000


def readout_options(scenario: Scenario) -> dict[str, Any]:
    """The scenario's ``[readout]`` table over the defaults, checked."""
    unknown = set(scenario.readout) - set(READOUT_DEFAULTS)
    if unknown:
        raise ScenarioError(f"readout: unknown keys {sorted(unknown)}")
    options = {**READOUT_DEFAULTS, **scenario.readout}
    if not isinstance(options["range_dps"], int) or options["range_dps"] not in RANGE_CODE_BY_DPS:
        raise ScenarioError(f"readout: range_dps must be one of {sorted(RANGE_CODE_BY_DPS)}, "
                            f"not {options['range_dps']!r}"[:200])  # a list is unhashable
    code = options["bandwidth_code"]
    if isinstance(code, bool) or not isinstance(code, int) or code not in BW_CODES:
        raise ScenarioError("readout: bandwidth_code must be 0..7 (spec 5.3)")
    if not isinstance(options["bias"], str) or options["bias"] not in ("none", "profile",
                                                                        "calibrate"):
        raise ScenarioError("readout: bias must be 'none', 'profile' or 'calibrate'")
    try:  # limits.Bounded: finite, in range, one line naming the key
        for key, bounded in READOUT_LIMITS.items():
            options[key] = bounded.check(options[key], "readout")
    except LimitError as exc:
        raise ScenarioError(str(exc)) from None
    for key in ("poll_s", "grid_s"):  # a step that would read for hours
        if scenario.duration_s / options[key] > MAX_READOUT_STEPS:
            raise ScenarioError(f"readout: {key} = {options[key]:g} s gives "
                                f"{scenario.duration_s / options[key]:.3g} steps in "
                                f"duration_s; at most {MAX_READOUT_STEPS:,}")
    # the run settles, calibrates (bias = "calibrate") and then needs one grid step to
    # compare the attitude with truth: a shorter scenario has nothing to evaluate
    needed = options["settle_s"] + options["grid_s"] + (
        options["calibrate_s"] if options["bias"] == "calibrate" else 0.0)
    if scenario.duration_s < needed:
        raise ScenarioError(
            f"duration_s = {scenario.duration_s:g} s is shorter than the readout needs: settle_s "
            f"{options['settle_s']:g} s" + (f" + calibrate_s {options['calibrate_s']:g} s"
                                             if options["bias"] == "calibrate" else "")
            + f" + one grid_s step {options['grid_s']:g} s = {needed:g} s")
    return options


class FifoReader:
    """Reads one gyro's FIFO over an I2CBus, as flight software would."""

    def __init__(self, bus: Any, address: int, range_dps: int = 2000, bandwidth_code: int = 4):
        from bmg160_emu.device.spec_choices import SENSITIVITY_BINARY
        from bmg160_emu.noise.bandwidths import BANDWIDTHS

        self.bus = bus
        self.address = address
        self.range_code = RANGE_CODE_BY_DPS[range_dps]
        self.bandwidth_code = bandwidth_code
        self.odr_hz = float(BANDWIDTHS[bandwidth_code][0])
        self.lsb_per_dps = SENSITIVITY_BINARY[self.range_code]
        self.errors = 0
        self.overruns = 0

    def configure(self) -> None:
        self.bus.write_byte_data(self.address, RANGE, self.range_code)
        self.bus.write_byte_data(self.address, BW, self.bandwidth_code)
        self.bus.write_byte_data(self.address, FIFO_CONFIG_1, STREAM_XYZ)

    def read_frames(self) -> np.ndarray:
        """All complete frames waiting, as rates (k, 3) in deg/s (sensor frame)."""
        from bmg160_emu.bus.i2c import I2CMessage

        try:
            status = self.bus.read_byte_data(self.address, FIFO_STATUS)
            count = FIFO_FRAME_COUNTER.extract(status)
            if FIFO_OVERRUN.extract(status):
                self.overruns += 1
            if count == 0:
                return np.zeros((0, 3))
            write = I2CMessage.write(self.address, [FIFO_DATA])
            read = I2CMessage.read_message(self.address, count * FRAME_BYTES)
            data = self.bus.i2c_transfer([write, read])[1].data
        except OSError:
            self.errors += 1
            return np.zeros((0, 3))
        counts = np.frombuffer(bytes(data), dtype="<i2").reshape(count, 3)
        return counts / self.lsb_per_dps


def propagate(q: np.ndarray, rates_dps: np.ndarray, dt: float) -> np.ndarray:
    """Strapdown propagation: each sample's rate held over ``dt``; returns the last attitude."""
    if rates_dps.size == 0:
        return q
    increments = quat_from_rotation_vector(np.radians(rates_dps) * dt)
    return chain_rotations(q, increments)[-1]


@dataclass
class PropagationRun:
    """``run(seed)``: one noise realisation of the scenario, error of the propagated attitude."""

    scenario: Scenario

    def __post_init__(self) -> None:
        readout_options(self.scenario)  # a bad [readout] is refused before any run starts

    def __call__(self, seed: int) -> RunResult:
        from bmg160_emu.adcs.rig import GyroRig

        options = readout_options(self.scenario)
        rig = GyroRig(self.scenario, seed=seed)
        gyro = rig.gyros[0]
        reader = FifoReader(gyro.bus, gyro.address, options["range_dps"], options["bandwidth_code"])
        reader.configure()
        dt = 1.0 / reader.odr_hz
        to_body = gyro.spec.mounting.T  # sensor -> body
        bias = np.zeros(3)
        if options["bias"] == "profile":
            from bmg160_emu.noise import load_profile

            profile = load_profile(gyro.spec.profile)
            bias = np.array([axis.bias for axis in profile.axes])

        def drain_until(t_end: float) -> np.ndarray:
            chunks = []
            while rig.time < t_end - 1e-12:
                rig.advance(min(options["poll_s"], t_end - rig.time))
                chunks.append(reader.read_frames())
            return np.concatenate(chunks) if chunks else np.zeros((0, 3))

        drain_until(options["settle_s"])
        if options["bias"] == "calibrate":
            frames = drain_until(rig.time + options["calibrate_s"])
            if frames.shape[0]:
                bias = frames.mean(axis=0)
        times = rig.sample_times(0)  # truth sample times of gyro 0, growing as produced
        start = times[-1] if times else rig.time
        q = rig.attitude_at(start)
        grid = np.arange(rig.time + options["grid_s"], self.scenario.duration_s + 1e-9,
                         options["grid_s"])
        truth_times: list[float] = []
        estimates: list[np.ndarray] = []
        for t_grid in grid:
            while rig.time < t_grid - 1e-12:
                rig.advance(min(options["poll_s"], t_grid - rig.time))
                rates = reader.read_frames() - bias
                q = propagate(q, rates @ to_body.T, dt)
            truth_times.append(times[-1] if times else t_grid)
            estimates.append(q.copy())
        truth_q = integrate_attitude(self.scenario.rate_dps, np.array(truth_times), rig.q0, t0=0.0)
        error = angle_between_deg(np.array(estimates), truth_q)
        extras = {
            "bus_errors": float(reader.errors),
            "fifo_overruns": float(reader.overruns),
            "bias_x_dps": float(bias[0]),
        }
        return RunResult(int(seed), grid, error, extras)
