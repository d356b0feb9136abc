"""The emulated gyro as a Basilisk module: exact time mapping, rate mapping, truth, messages."""

from __future__ import annotations

import math
import threading

import numpy as np
import pytest

try:
    import Basilisk  # noqa: F401
except ImportError as exc:  # absent, or a wheel that does not load here
    pytest.skip(f"Basilisk (bsk) is not importable ({exc}): pip install 'bmg160-emu[basilisk]'",
                allow_module_level=True)

from Basilisk.architecture import messaging, sysModel
from Basilisk.fswAlgorithms import rateMsgConverter
from Basilisk.simulation import spacecraft
from Basilisk.utilities import SimulationBaseClass, macros

from bmg160_emu.adcs.attitude import angle_between_deg
from bmg160_emu.adcs.basilisk import EmulatedGyro, quaternion_from_mrp
from bmg160_emu.adcs.rig import GyroSpec, rotation_matrix_from_euler_zyx

RANGE, BW = 0x0F, 0x10
RATE_RAD_S = [0.02, -0.035, 0.05]


class ClockProbe(sysModel.SysModel):
    """Runs after the gyro module: chip clock time against Basilisk time, every step."""

    def __init__(self, gyro):
        super().__init__()
        self.gyro = gyro
        self.mismatches = 0
        self.steps = 0

    def UpdateState(self, CurrentSimNanos):
        self.steps += 1
        if self.gyro.clock.now_ns() != self.gyro.offset_ns + CurrentSimNanos:
            self.mismatches += 1


def _sim(step_s, gyro, *, inertia=(0.05, 0.05, 0.05)):
    """A spacecraft with spherical inertia (the body rate stays constant), and the gyro."""
    sim = SimulationBaseClass.SimBaseClass()
    sim.CreateNewProcess("p").addTask(sim.CreateNewTask("t", macros.sec2nano(step_s)))
    sc = spacecraft.Spacecraft()
    sc.ModelTag = "sc"
    sc.hub.mHub = 4.0
    sc.hub.IHubPntBc_B = np.diag(inertia).tolist()
    sc.hub.omega_BN_BInit = [[w] for w in RATE_RAD_S]
    sim.AddModelToTask("t", sc, 100)
    gyro.scStateInMsg.subscribeTo(sc.scStateOutMsg)
    sim.AddModelToTask("t", gyro, 50)
    return sim, sc


def _configure(chip, range_code=3, bw_code=4):
    chip.write(RANGE, bytes([range_code]))  # +-250 deg/s
    chip.write(BW, bytes([bw_code]))  # ODR 200 Hz


def test_chip_time_is_basilisk_time_to_the_nanosecond_over_an_orbit():
    # 5400 s (a low orbit) in 10 s steps: the clock matches at every step, and the chip's
    # sample grid at the end is still on the 5 ms grid it had at the start: no drift, and
    # exactly 200 samples per second in between (none lost, none extra)
    gyro = EmulatedGyro([GyroSpec(noise=False)], record_truth=False, publish=False)
    gyro.clock.advance_ns(250_000_001)  # an odd offset: chip time = Basilisk time + offset
    _configure(gyro.chips[0])
    sim, _ = _sim(10.0, gyro)
    probe = ClockProbe(gyro)
    sim.AddModelToTask("t", probe, 10)
    times: list[int] = []

    def hook(chip, t, rate):
        times.append(round(t * 1e9))

    chip = gyro.chips[0]
    chip.truth_hooks.append(hook)
    sim.InitializeSimulation()
    assert gyro.offset_ns == 250_000_001
    sim.ConfigureStopTime(macros.sec2nano(10.0))
    sim.ExecuteSimulation()
    chip.peek(0x00)  # a look at the chip: the queued rate input computes samples when read
    first, count_start = times[-1], len(times)
    chip.truth_hooks.remove(hook)
    sim.ConfigureStopTime(macros.sec2nano(5400.0))
    sim.ExecuteSimulation()
    chip.peek(0x00)
    assert probe.steps == 541 and probe.mismatches == 0
    assert gyro.clock.now_ns() == 5400 * 10**9 + 250_000_001
    chip.truth_hooks.append(hook)
    sim.ConfigureStopTime(macros.sec2nano(5410.0))
    sim.ExecuteSimulation()
    chip.peek(0x00)
    period = 5_000_000
    last = times[-1]
    assert (last - first) % period == 0  # still on the starting grid after 5400 s
    assert last == max(t for t in range(first, 5410 * 10**9 + 250_000_002, period))
    assert len(times) - count_start == 10 * 200  # the last 10 s: 200 samples a second


def test_counts_follow_the_true_rate_through_mounting_scale_factor_and_misalignment():
    mounting = rotation_matrix_from_euler_zyx(90.0, 0.0, 30.0)
    sf = np.array([0.01, -0.02, 0.005])
    mis = np.array([[0, 1e-3, -2e-3], [5e-4, 0, 1e-3], [0, -1e-3, 0]])
    spec = GyroSpec(noise=False, mounting=mounting, scale_factor_error=sf, misalignment_rad=mis)
    gyro = EmulatedGyro([spec, GyroSpec(name="aligned", address=0x69, noise=False)])
    for chip in gyro.chips:
        _configure(chip)
    sim, _ = _sim(0.005, gyro)
    converter = rateMsgConverter.rateMsgConverter()
    converter.ModelTag = "rateConverter"
    converter.imuRateInMsg.subscribeTo(gyro.imuBodyOutMsgs[1])
    sim.AddModelToTask("t", converter, 40)
    nav = converter.navRateOutMsg.recorder()
    sim.AddModelToTask("t", nav)
    sim.InitializeSimulation()
    sim.ConfigureStopTime(macros.sec2nano(1.0))  # the 23 Hz filter has long settled
    sim.ExecuteSimulation()
    rate_dps = np.degrees(RATE_RAD_S)
    sens = 32768 / 250  # LSB per deg/s at +-250 deg/s (the model's binary sensitivity)
    m = (np.eye(3) + mis) @ np.diag(1 + sf) @ mounting  # chip: misalign . scale . mount
    for chip, matrix in zip(gyro.chips, (m, np.eye(3))):
        raw = bytes(chip.peek(0x02 + k) for k in range(6))
        counts = np.frombuffer(raw, dtype="<i2")
        assert np.all(np.abs(counts - matrix @ rate_dps * sens) <= 0.5 + 1e-6)  # one rounding
    # the aligned chip reaches a Basilisk FSW module through IMUSensorBodyMsg
    assert np.allclose(nav.omega_BN_B[-1], RATE_RAD_S, atol=math.radians(0.5 / sens))
    platform = gyro.imuOutMsgs[0].read().AngVelPlatform
    assert np.allclose(platform, np.radians(m @ rate_dps), atol=math.radians(0.5 / sens))


def test_truth_per_output_sample_matches_basilisk_state():
    gyro = EmulatedGyro([GyroSpec(noise=False)], publish=False)
    _configure(gyro.chips[0])
    sim, sc = _sim(0.005, gyro, inertia=(0.04, 0.03, 0.01))  # tumbling: the rate moves
    states = sc.scStateOutMsg.recorder()
    sim.AddModelToTask("t", states)
    sim.InitializeSimulation()
    sim.ConfigureStopTime(macros.sec2nano(2.0))
    sim.ExecuteSimulation()
    truth = gyro.truth()
    assert truth.times_s.size >= 395  # 200 Hz from shortly after the BW write
    assert np.allclose(np.diff(truth.times_s), 0.005)
    t_state = states.times() * 1e-9
    sigma = np.asarray(states.sigma_BN)
    rate = np.degrees(np.asarray(states.omega_BN_B))
    for i in (10, 200, truth.times_s.size - 1):
        k = int(np.searchsorted(t_state, truth.times_s[i] - 1e-12)) - 1  # the step before
        assert np.allclose(truth.rate_dps[i], rate[k])  # the held rate the chip saw
        q_at = quaternion_from_mrp(sigma[k + 1])  # Basilisk's attitude at the sample time
        assert angle_between_deg(truth.quaternion[i], q_at) < 1e-4


def test_rate_resolution_holds_the_rate_within_the_tolerance_and_feeds_less():
    exact = EmulatedGyro([GyroSpec(noise=False)], publish=False)
    coarse = EmulatedGyro([GyroSpec(noise=False)], publish=False, rate_resolution_dps=0.002)
    results = []
    for gyro in (exact, coarse):
        _configure(gyro.chips[0])
        sim, _ = _sim(0.005, gyro, inertia=(0.04, 0.03, 0.01))
        sim.InitializeSimulation()
        sim.ConfigureStopTime(macros.sec2nano(2.0))
        sim.ExecuteSimulation()
        results.append(gyro.truth())
    assert coarse.feeds < exact.feeds / 2
    assert np.max(np.abs(results[0].rate_dps - results[1].rate_dps)) <= 0.002 + 1e-12
    with pytest.raises(ValueError, match="rate_resolution_dps"):
        EmulatedGyro(rate_resolution_dps=-1.0)


def test_messages_are_basilisk_types():
    gyro = EmulatedGyro()
    assert isinstance(gyro.imuOutMsg, messaging.IMUSensorMsg)
    assert isinstance(gyro.imuBodyOutMsg, messaging.IMUSensorBodyMsg)


def test_the_rate_inputs_give_the_same_counts_and_truth():
    # a tumbling body (unequal inertia: the rate changes every step), the FIFO read every
    # 10 steps as the example's flight software does: the queued input (computed at each
    # read) gives the counts and truth the streamed one (each sample when due) gives
    seen = {}
    for rate_input in ("queue", "stream", "set"):
        gyro = EmulatedGyro([GyroSpec()], seed=4, publish=False, rate_input=rate_input)
        assert gyro.rate_input == rate_input
        chip = gyro.chips[0]
        _configure(chip)
        chip.write(0x3E, bytes([0x80]))  # FIFO stream mode (spec 4.26)
        sim, _ = _sim(0.005, gyro, inertia=(0.04, 0.03, 0.01))
        sim.InitializeSimulation()
        frames = []
        for stop in np.arange(0.05, 1.0001, 0.05):
            sim.ConfigureStopTime(macros.sec2nano(float(stop)))
            sim.ExecuteSimulation()
            frames.append(chip.read(0x3F, 6 * (chip.peek(0x0E) & 0x7F)))
        truth = gyro.truth()
        seen[rate_input] = (frames, truth.times_s, truth.rate_dps)
    assert sum(len(f) for f in seen["queue"][0]) >= 6 * 190  # 200 Hz, from just after start
    for other in ("stream", "set"):
        assert seen["queue"][0] == seen[other][0]
        assert np.array_equal(seen["queue"][1], seen[other][1])
        assert np.array_equal(seen["queue"][2], seen[other][2])
    with pytest.raises(ValueError, match="rate_input"):
        EmulatedGyro(rate_input="push")


class ThreadStateProbe(sysModel.SysModel):
    """Per step: did a ``threading.local`` value set at the previous step survive (the
    Python thread state lasted between Basilisk's calls), and which OS thread called."""

    def __init__(self):
        super().__init__()
        self.local = threading.local()
        self.survived: list[bool] = []
        self.threads: set[int] = set()

    def UpdateState(self, CurrentSimNanos):
        self.survived.append(getattr(self.local, "mark", False))
        self.local.mark = True
        self.threads.add(threading.get_native_id())


def test_the_simulation_thread_keeps_its_python_thread_state():
    # Basilisk calls Python modules from a C++ thread of its own, and CPython makes a thread
    # state for each such call (8 us a module and step): EmulatedGyro keeps the one it runs
    # in, so from its second step on every module of the task finds the same state
    def run(with_gyro: bool) -> ThreadStateProbe:
        sim = SimulationBaseClass.SimBaseClass()
        sim.CreateNewProcess("p").addTask(sim.CreateNewTask("t", macros.sec2nano(0.005)))
        probe = ThreadStateProbe()
        sim.AddModelToTask("t", probe, 10)
        if with_gyro:
            gyro = EmulatedGyro([GyroSpec(noise=False)], record_truth=False, publish=False)
            sc = spacecraft.Spacecraft()
            sim.AddModelToTask("t", sc, 100)
            gyro.scStateInMsg.subscribeTo(sc.scStateOutMsg)
            sim.AddModelToTask("t", gyro, 50)
        sim.InitializeSimulation()
        sim.ConfigureStopTime(macros.sec2nano(0.1))
        sim.ExecuteSimulation()
        return probe

    alone = run(with_gyro=False)
    if any(alone.survived):
        pytest.skip("this Basilisk keeps Python thread states itself: nothing to keep")
    assert threading.get_native_id() not in alone.threads  # Basilisk's own thread
    kept = run(with_gyro=True)
    assert len(kept.threads) == 1 and threading.get_native_id() not in kept.threads
    # step 1 starts with nothing set; the gyro keeps the state from its second step on,
    # so the probe's mark survives from its third step
    assert kept.survived[:2] == [False, False] and all(kept.survived[2:])
    assert len(kept.survived) == 21
