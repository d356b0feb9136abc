"""The closed loop: a 3U CubeSat in Basilisk, three reaction wheels, an emulated BMG160.

Sim side (Basilisk): ``spacecraft`` hub (4 kg, 3U inertia), ``reactionWheelStateEffector``
with three BCT RWP015 wheels on the body axes (simIncludeRW: 4 mN m, 15 mN m s), the
emulated gyro (:class:`bmg160_emu.adcs.basilisk.EmulatedGyro`, 200 Hz, +-250 deg/s, the
paper's noise profile or a dispersed one, faults) and a star tracker (attitude with
5 mdeg rms per axis every 10 s). Flight side: :mod:`flight_software`, which reaches the
gyro only through smbus2 under ``patch_smbus``.

``run(Setup(...))`` returns a :class:`Result` with the time series and a summary.
"""

from __future__ import annotations

import json
import math
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from Basilisk.architecture import messaging, sysModel
from Basilisk.simulation import reactionWheelStateEffector, spacecraft
from Basilisk.utilities import SimulationBaseClass, macros, simIncludeRW
from flight_software import PERIOD_S, STEP_THRESHOLD_DPS, FlightConfig, FlightSoftware

from bmg160_emu.adcs.attitude import angle_between_deg
from bmg160_emu.adcs.basilisk import EmulatedGyro, quaternion_from_mrp
from bmg160_emu.adcs.rig import GyroSpec
from bmg160_emu.bus.patching import patch_smbus

HERE = Path(__file__).resolve().parent
IDENTIFICATION = HERE / "identification.json"
STEP_S = 0.005  # the dynamics and gyro task's step = the gyro's output period at 200 Hz
FSW_STEP_S = PERIOD_S  # the flight software's task (20 Hz; it reads the gyro's FIFO)
INERTIA = np.array([[0.0420, 0.0002, -0.0001],  # kg m^2: 4 kg, 10 x 10 x 34 cm (m (b^2+c^2)/12)
                    [0.0002, 0.0418, 0.0001],
                    [-0.0001, 0.0001, 0.0067]])
RATE0_DIRECTION = np.array([0.6, -0.7, 0.38])
RATE0_DPS = 5.0
ST_PERIOD_S = 10.0
ST_NOISE_DEG = 0.005  # per axis, 1 sigma (18 arcsec: a CubeSat star tracker)
RATE_LIMIT_DPS = 0.1
DETUMBLE_MARGIN = 1.15  # see detumble_limit_s


def detumble_limit_s(kd: float, rate0_dps: float = RATE0_DPS) -> float:
    """The stated detumble time: the law cancels the gyroscopic term, so the rate decays as
    exp(-Kd t) and crosses 0.1 deg/s after ln(w0 / 0.1) / Kd (78.2 s for 5 deg/s at Kd =
    0.05/s) while the wheels stay below their torque limit. The flight estimate carries a
    residual bias b_res (calibration error, about 0.012 deg/s per axis here), the rate
    settles at -b_res, so the crossing takes ln(w0 / (0.1 - |b_res|)) / Kd, +4.5 s (6 %) for
    |b_res| = 0.02 deg/s; the undetected 0.35 s of the bias step adds < 1 %. 15 % over the
    ideal time covers both, and dispersed runs."""
    return DETUMBLE_MARGIN * math.log(rate0_dps / RATE_LIMIT_DPS) / kd


SETTLE_S = 120.0  # after the switch: the slew (up to 180 deg) and ~3 loop time constants

FAULTS = [  # during detumble (docs: bmg160_emu.adcs.faults)
    {"kind": "bias_step", "at_s": 20.0, "axis": 2, "step_dps": 0.3},
    {"kind": "stuck_axis", "at_s": 35.0, "axis": 0, "duration_s": 4.0},
    {"kind": "nack", "at_s": 50.0, "duration_s": 0.25},
]


def bias_calibration_dps(setup: Setup | None = None) -> np.ndarray:
    """The ground calibration the flight software carries: the identified mean rate of each
    axis, from ``setup.identification`` (``identify --json`` output), else from the bias of
    ``setup.profile`` when it is the user's own (``identify --profile-out`` writes the
    identified mean there), else from the example's identification.json (the paper's gyro)."""
    from bmg160_emu.adcs.dispersion import identified_axes

    identification = setup.identification if setup is not None else None
    if identification is None and setup is not None and setup.profile != "paper":
        return np.array([axis.bias for axis in profile_axes(setup)])
    path = Path(identification) if identification is not None else IDENTIFICATION
    axes = identified_axes(json.loads(path.read_text()), str(path))
    return np.array([axes[a]["mean"]["value"] for a in "xyz"])


def step_threshold_dps(setup: Setup) -> float:
    """The bias-step threshold for the gyro that flies: 0.15 deg/s (set for the paper's
    gyro: about 7 times its residual's noise) scaled with the noisiest axis's N against the
    paper gyro's, never below it. A gyro three times as noisy as the paper's raised a false
    bias step every few tenths of a second at 0.15 deg/s; at its own threshold, a step
    smaller than it goes unseen, which the report and the Monte Carlo then say."""
    from bmg160_emu.noise import load_profile

    paper = max(axis.N for axis in load_profile("paper").axes)
    flown = max(axis.N for axis in profile_axes(setup))
    return STEP_THRESHOLD_DPS * max(1.0, flown / paper)


def profile_axes(setup: Setup) -> list:
    """The noise of each axis of the gyro the loop flies (noise.profile.AxisNoise: N, B, T,
    K, the Gauss-Markov terms), for the report's predictions from the user's own numbers."""
    from bmg160_emu.noise import load_profile

    return list(load_profile(setup.profile).axes)


@dataclass
class Setup:
    duration_s: float = 400.0
    seed: int = 1
    profile: Any = "paper"  # a built-in name, a profile file (identify --profile-out) or a
    # {axis: {N, B, T, K, bias}} mapping
    identification: str | None = None  # identify --json of the same record: calibration
    faults: list = field(default_factory=lambda: [dict(f) for f in FAULTS])
    rate0_dps: list = field(default_factory=lambda: (RATE0_DIRECTION / np.linalg.norm(
        RATE0_DIRECTION) * RATE0_DPS).tolist())
    sigma0: list = field(default_factory=lambda: [0.3, -0.2, 0.25])
    log_period_s: float = 0.1
    kd: float = 0.05  # 1/s, detumble gain (flight_software.FlightConfig)
    st_period_s: float = ST_PERIOD_S
    rate_resolution_dps: float = 0.002  # 1/4 LSB at +-250 deg/s (EmulatedGyro)


class StarTracker(sysModel.SysModel):
    """The true attitude with a small random rotation (seeded), every ``period_s``."""

    def __init__(self, seed: int, period_s: float = ST_PERIOD_S, noise_deg: float = ST_NOISE_DEG):
        super().__init__()
        self.ModelTag = "starTracker"
        self.scStateInMsg = messaging.SCStatesMsgReader()
        self.attOutMsg = messaging.STAttMsg()
        self.period_ns = macros.sec2nano(period_s)
        self.noise_rad = math.radians(noise_deg)
        self.rng = np.random.default_rng(seed)

    def Reset(self, CurrentSimNanos):
        pass

    def UpdateState(self, CurrentSimNanos):
        if CurrentSimNanos == 0 or CurrentSimNanos % self.period_ns:
            return
        q = quaternion_from_mrp(self.scStateInMsg().sigma_BN)
        e = self.rng.normal(0.0, self.noise_rad, 3) / 2.0
        dq = np.array([math.sqrt(max(0.0, 1.0 - e @ e)), *e])
        qw, qv, ew, ev = q[0], q[1:], dq[0], dq[1:]
        qm = np.concatenate([[qw * ew - qv @ ev], qw * ev + ew * qv + np.cross(qv, ev)])
        if qm[0] < 0:
            qm = -qm
        payload = messaging.STAttMsgPayload()
        payload.timeTag = CurrentSimNanos
        payload.MRP_BdyInrtl = (qm[1:] / (1.0 + qm[0])).tolist()
        self.attOutMsg.write(payload, CurrentSimNanos, self.moduleID)


@dataclass
class Result:
    setup: Setup
    time_s: np.ndarray
    rate_true_dps: np.ndarray
    sigma_BN: np.ndarray
    wheel_rpm: np.ndarray
    rate_est_dps: np.ndarray
    rate_model_dps: np.ndarray
    est_time_s: np.ndarray
    pointing_error_deg: np.ndarray
    flight_events: list
    injected: list
    knowledge_before_fix_deg: np.ndarray  # per axis, at each star-tracker update
    summary: dict
    wall_s: float = 0.0


def build(setup: Setup):
    """The Basilisk simulation of ``setup``; returns (sim, parts)."""
    sim = SimulationBaseClass.SimBaseClass()
    proc = sim.CreateNewProcess("dynamics")
    # at a time both tasks are due, the dynamics and the gyro first (higher priority), then
    # the star tracker and the flight software on the state and samples of that time
    proc.addTask(sim.CreateNewTask("loop", macros.sec2nano(STEP_S)), 100)
    proc.addTask(sim.CreateNewTask("flight", macros.sec2nano(FSW_STEP_S)), 50)

    sc = spacecraft.Spacecraft()
    sc.ModelTag = "cubesat"
    sc.hub.mHub = 4.0
    sc.hub.IHubPntBc_B = INERTIA.tolist()
    sc.hub.sigma_BNInit = [[s] for s in setup.sigma0]
    sc.hub.omega_BN_BInit = [[math.radians(w)] for w in setup.rate0_dps]

    rw_factory = simIncludeRW.rwFactory()
    for axis in np.eye(3):
        rw_factory.create("BCT_RWP015", axis.tolist(), Omega=0.0)
    wheels = reactionWheelStateEffector.ReactionWheelStateEffector()
    wheels.ModelTag = "wheels"
    rw_factory.addToSpacecraft(sc.ModelTag, wheels, sc)
    first = next(iter(rw_factory.rwList.values()))

    gyro = EmulatedGyro([GyroSpec(profile=setup.profile)], seed=setup.seed,
                        faults=setup.faults, publish=False,
                        rate_resolution_dps=setup.rate_resolution_dps)
    gyro.scStateInMsg.subscribeTo(sc.scStateOutMsg)
    tracker = StarTracker(seed=setup.seed + 7919,  # its own stream (a prime offset)
                          period_s=setup.st_period_s)
    tracker.scStateInMsg.subscribeTo(sc.scStateOutMsg)

    cfg = FlightConfig(inertia=INERTIA, wheel_axes=np.eye(3), wheel_js=float(first.Js),
                       wheel_u_max=float(first.u_max), bias_cal_dps=bias_calibration_dps(setup),
                       dt_s=FSW_STEP_S, kd=setup.kd,
                       step_threshold_dps=step_threshold_dps(setup))
    fsw = FlightSoftware(cfg, log_every=max(1, round(setup.log_period_s / FSW_STEP_S)))
    fsw.rwSpeedInMsg.subscribeTo(wheels.rwSpeedOutMsg)
    fsw.starTrackerInMsg.subscribeTo(tracker.attOutMsg)
    wheels.rwMotorCmdInMsg.subscribeTo(fsw.rwMotorTorqueOutMsg)

    sim.AddModelToTask("loop", sc, 100)
    sim.AddModelToTask("loop", wheels, 90)
    sim.AddModelToTask("loop", gyro, 50)
    sim.AddModelToTask("flight", tracker, 45)
    sim.AddModelToTask("flight", fsw, 40)
    log_ns = macros.sec2nano(setup.log_period_s)
    state_rec = sc.scStateOutMsg.recorder(log_ns)
    wheel_rec = wheels.rwSpeedOutMsg.recorder(log_ns)
    sim.AddModelToTask("loop", state_rec)
    sim.AddModelToTask("loop", wheel_rec)
    return sim, {"sc": sc, "wheels": wheels, "gyro": gyro, "fsw": fsw,
                 "state_rec": state_rec, "wheel_rec": wheel_rec}


def run(setup: Setup | None = None) -> Result:
    """Run the closed loop for ``setup.duration_s`` and evaluate it."""
    import time

    setup = setup or Setup()
    sim, parts = build(setup)
    gyro = parts["gyro"]
    start = time.perf_counter()
    with patch_smbus(gyro.buses):  # the flight software's smbus2 reaches the emulated bus
        sim.InitializeSimulation()
        sim.ConfigureStopTime(macros.sec2nano(setup.duration_s))
        sim.ExecuteSimulation()
    wall = time.perf_counter() - start
    return evaluate(setup, parts, wall)


def evaluate(setup: Setup, parts: dict, wall_s: float) -> Result:
    gyro, fsw = parts["gyro"], parts["fsw"]
    state_rec, wheel_rec = parts["state_rec"], parts["wheel_rec"]
    t = state_rec.times() * 1e-9
    rate = np.degrees(np.asarray(state_rec.omega_BN_B))
    sigma = np.asarray(state_rec.sigma_BN)
    wheel_rpm = np.asarray(wheel_rec.wheelSpeeds)[:, :3] * 60.0 / (2.0 * math.pi)
    q_true = quaternion_from_mrp(sigma)
    pointing = angle_between_deg(q_true, np.array([1.0, 0.0, 0.0, 0.0]))
    speed = np.linalg.norm(rate, axis=1)

    events = [asdict(e) for e in fsw.events]
    point_at = next((e["time_s"] for e in events if e["kind"] == "mode"), None)
    end_detumble = point_at if point_at is not None else t[-1]
    below = speed < RATE_LIMIT_DPS
    detumble_s = None
    for i in np.flatnonzero(below & (t <= end_detumble)):
        if np.all(below[i:][t[i:] <= end_detumble]):
            detumble_s = float(t[i])
            break

    # knowledge error just before each star-tracker fix, per axis (body frame)
    steps = gyro.steps()
    step_t = steps["time_ns"] * 1e-9
    errors = []
    for when, q_est in fsw.st_updates:
        k = int(np.searchsorted(step_t, when - 1e-9))
        q = quaternion_from_mrp(steps["sigma_BN"][min(k, len(step_t) - 1)])
        delta = _mul(_conj(q), q_est)
        errors.append(np.degrees(2.0 * delta[1:] * np.sign(delta[0])))
    knowledge = np.array(errors).reshape(-1, 3)

    settle_from = (point_at + SETTLE_S) if point_at is not None else None
    settled = (t >= settle_from) if settle_from is not None else np.zeros_like(t, dtype=bool)
    summary: dict[str, Any] = {
        "seed": setup.seed,
        "duration_s": setup.duration_s,
        "detumble_time_s": detumble_s,
        "detumble_limit_s": detumble_limit_s(setup.kd, float(np.linalg.norm(setup.rate0_dps))),
        "pointing_mode_at_s": point_at,
        "pointing_error_deg_rms_settled": float(np.sqrt(np.mean(pointing[settled] ** 2)))
        if settled.any() else None,
        "pointing_error_deg_max_settled": float(pointing[settled].max()) if settled.any() else None,
        "knowledge_growth_deg_rms_per_axis": float(np.sqrt(np.mean(knowledge[-20:] ** 2)))
        if len(knowledge) >= 5 else None,
        "star_tracker_fixes_used": len(fsw.st_updates),
        "max_wheel_rpm": float(np.abs(wheel_rpm).max()),
        "faults_detected": sorted({e["kind"] for e in events if e["kind"] != "mode"
                                   and not e["kind"].endswith("cleared")}),
        "wall_s": wall_s,
        "realtime_factor": setup.duration_s / wall_s if wall_s > 0 else None,
    }
    injected = [e.to_dict() for e in gyro.faults.events]
    return Result(setup, t, rate, sigma, wheel_rpm, np.array(fsw.log.rate_est_dps),
                  np.array(fsw.log.rate_model_dps),
                  np.array(fsw.log.time_s), pointing, events, injected, knowledge, summary,
                  wall_s)


def _mul(p, q):
    return np.concatenate([[p[0] * q[0] - p[1:] @ q[1:]],
                           p[0] * q[1:] + q[0] * p[1:] + np.cross(p[1:], q[1:])])


def _conj(q):
    return np.array([q[0], -q[1], -q[2], -q[3]])
