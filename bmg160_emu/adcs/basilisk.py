"""Emulated BMG160 gyros inside a Basilisk simulation (AVS Lab, ``pip install bsk``).

:class:`EmulatedGyro` is a Basilisk Python module (``sysModel.SysModel``). Each task step it
reads the spacecraft state (``SCStatesMsg``: ``omega_BN_B`` in rad/s, ``sigma_BN``) and
drives one or more register-level chips with the true body rate in deg/s; each chip applies
its own mounting, scale factor and misalignment (:class:`~bmg160_emu.adcs.rig.GyroSpec`),
low-pass filter and noise. Flight code then reads the chips through their I2C buses
(``patch_smbus(module.buses)``), exactly as on the spacecraft.

Time: the chips share one :class:`~bmg160_emu.clock.VirtualClock`. Basilisk time is integer
nanoseconds, and so is the virtual clock: at each step the clock is set to
``offset + CurrentSimNanos`` exactly (the offset is the clock's time at ``Reset``), so the
chip's output samples never drift from simulation time, over an orbit or a year.

Rate input: the rate read at step ``t_j`` is held for the chips' samples in ``(t_j,
t_j+1]`` (sample and hold, one task step of delay, as a real sensor sampling a
continuous rate would see at most). With a 5 ms task and a 200 Hz gyro, one sample per step.

Outputs: optionally, every step, ``imuOutMsgs[i]`` (``IMUSensorMsg``, ``AngVelPlatform`` =
the chip's rate registers in rad/s, sensor frame) and ``imuBodyOutMsgs[i]``
(``IMUSensorBodyMsg``, the same rotated into the body frame by the nominal mounting), so
Basilisk flight-software modules (``rateMsgConverter`` ...) can use the emulated gyro.
:meth:`EmulatedGyro.truth` gives the truth of every output sample (time, true body rate,
true attitude, fault flags) as the rig does (:class:`~bmg160_emu.adcs.rig.Truth`).
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from typing import Any

import numpy as np

from bmg160_emu.adcs.attitude import quat_from_rotation_vector, quat_multiply
from bmg160_emu.adcs.faults import Fault, FaultSchedule
from bmg160_emu.adcs.rig import Gyro, GyroSpec, Truth, make_chip
from bmg160_emu.adcs.scenarios import ScenarioError
from bmg160_emu.adcs.thread_state import keep_thread_state
from bmg160_emu.clock import NS_PER_S, VirtualClock
from bmg160_emu.device.registers import address_of

try:
    from Basilisk.architecture import messaging, sysModel
except ImportError as exc:  # pragma: no cover - depends on the installation
    raise ImportError("bmg160_emu.adcs.basilisk needs Basilisk: pip install "
                      "'bmg160-emu[basilisk]' (the bsk wheel)") from exc

# spec 3: RATE_X_LSB .. RATE_Z_MSB, little-endian int16 per axis; CHIP_ID has no side effect
_RATE_REGISTERS = tuple(address_of("RATE_X_LSB") + k for k in range(6))
_CHIP_ID = address_of("CHIP_ID")
_RATE_INPUTS = {"queue": "queue_true_rate", "stream": "stream_true_rate", "set": "set_true_rate"}


def quaternion_from_mrp(sigma: Any) -> np.ndarray:
    """Scalar-first quaternion of Basilisk's MRP ``sigma_BN`` (body -> inertial, as in
    :mod:`bmg160_emu.adcs.attitude`); broadcasts over leading axes."""
    s = np.asarray(sigma, dtype=float)
    s2 = np.sum(s * s, axis=-1, keepdims=True)
    return np.concatenate([(1.0 - s2), 2.0 * s], axis=-1) / (1.0 + s2)


class EmulatedGyro(sysModel.SysModel):
    """Basilisk module driving emulated BMG160 chips from ``scStateInMsg`` each step.

    ``gyros``: the chips (default one at bus 1, 0x68, body-aligned). ``seed``: master seed,
    split per chip and for the fault schedule as in :class:`~bmg160_emu.adcs.rig.GyroRig`.
    ``faults``: a schedule or fault list (:mod:`bmg160_emu.adcs.faults`). ``publish``: write
    the IMU messages each step. ``record_truth``: keep the per-sample truth (costs a hook
    call per sample, and Basilisk's attitude and rate per step). ``rate_input``: how the
    chips take each step's rate: ``"queue"`` (default: ``queue_true_rate``, nothing computed
    until something reads the chip, then all due samples at once; a flight software reading
    the FIFO at 20 Hz pays one block per read instead of a sample per step), ``"stream"``
    (``stream_true_rate``: each sample when it falls due, bit for bit ``set_true_rate``'s)
    or ``"set"``; a chip without the method gets ``set_true_rate``.
    ``rate_resolution_dps``: hand the chips a new rate only when it moved by more than this
    on some axis (0, the default: every step; a saving with the inputs that compute each
    sample as it falls due, or a deliberately quantised rate).
    """

    def __init__(
        self,
        gyros: Sequence[GyroSpec] | None = None,
        *,
        seed: int = 0,
        faults: FaultSchedule | Iterable[Fault | dict[str, Any]] | None = None,
        clock: VirtualClock | None = None,
        publish: bool = True,
        record_truth: bool = True,
        rate_resolution_dps: float = 0.0,
        rate_input: str = "queue",
        model_tag: str = "bmg160",
    ) -> None:
        from bmg160_emu.bus.i2c import I2CBus

        super().__init__()
        self.ModelTag = model_tag
        self.specs = list(gyros) if gyros is not None else [GyroSpec()]
        if not self.specs:
            raise ScenarioError("EmulatedGyro needs at least one gyro")
        places = [(s.bus, s.address) for s in self.specs]
        if len(set(places)) != len(places):
            raise ScenarioError("two gyros at the same bus and address")
        self.seed = int(seed)
        self.clock = clock if clock is not None else VirtualClock()
        self.scStateInMsg = messaging.SCStatesMsgReader()
        self.imuOutMsgs = [messaging.IMUSensorMsg() for _ in self.specs]
        self.imuBodyOutMsgs = [messaging.IMUSensorBodyMsg() for _ in self.specs]
        self.imuOutMsg, self.imuBodyOutMsg = self.imuOutMsgs[0], self.imuBodyOutMsgs[0]
        self.publish = bool(publish)
        self.record_truth = bool(record_truth)
        if not rate_resolution_dps >= 0.0:
            raise ValueError(f"rate_resolution_dps must be >= 0, not {rate_resolution_dps!r}")
        self.rate_resolution_dps = float(rate_resolution_dps)
        self._held_dps: list[float] | None = None
        self.feeds = 0  # rate changes handed to the chips (for the benchmarks)
        children = np.random.SeedSequence(self.seed).spawn(len(self.specs) + 1)
        self.buses: dict[int, Any] = {}
        self.gyros: list[Gyro] = []
        self._sample_times: list[list[float]] = []
        self._sample_rates: list[list[np.ndarray]] = []
        for index, (spec, child) in enumerate(zip(self.specs, children)):
            chip_seed = int(child.generate_state(1, dtype=np.uint64)[0])
            try:
                chip = make_chip(spec, chip_seed, self.clock)
            except ValueError as exc:
                raise ScenarioError(f"{spec.name}: {exc}") from None
            bus = self.buses.get(spec.bus)
            if bus is None:
                bus = self.buses[spec.bus] = I2CBus(spec.bus)
            bus.attach(spec.address, chip)
            self.gyros.append(Gyro(index, spec, chip, bus, chip_seed))
            self._sample_times.append([])
            self._sample_rates.append([])
            if record_truth:
                chip.truth_hooks.append(self._truth_hook(index))
        if isinstance(faults, FaultSchedule):
            self.faults = faults
        else:
            fault_seed = int(children[-1].generate_state(1, dtype=np.uint64)[0])
            self.faults = FaultSchedule(list(faults or ()), seed=fault_seed)
        self.faults.install(self.gyros)
        # the rate input: the one asked for when the chip has it, else set_true_rate
        method = _RATE_INPUTS.get(rate_input)
        if method is None:
            raise ValueError(f"rate_input must be one of {', '.join(_RATE_INPUTS)}, "
                             f"not {rate_input!r}")
        feeds = [getattr(g.chip, method, None) for g in self.gyros]
        self.rate_input = rate_input if all(f is not None for f in feeds) else "set"
        self._feeds = [f or g.chip.set_true_rate for f, g in zip(feeds, self.gyros)]
        # nominal sensor -> body rotation (the mounting the flight software knows)
        self._to_body = [np.asarray(s.mounting, dtype=float).T for s in self.specs]
        self.offset_ns = self.clock.now_ns()
        self._state_view: Any = None  # scStateInMsg's payload, read live (UpdateState)
        self._step_ns: list[int] = []
        self._step_sigma: list[Any] = []
        self._step_rate_dps: list[list[float]] = []

    def _truth_hook(self, index: int):
        times, rates = self._sample_times[index], self._sample_rates[index]

        def hook(chip: Any, t: float, true_body_rate_dps: Any) -> None:
            times.append(float(t))
            # the chip hands each hook an array of its own (output_samples.emit_one): kept
            rates.append(true_body_rate_dps if true_body_rate_dps.__class__ is np.ndarray
                         else np.array(true_body_rate_dps, dtype=float))

        return hook

    # ----------------------------------------------------------------- Basilisk interface

    def Reset(self, CurrentSimNanos: int) -> None:
        """Fix the clock offset: chip time = offset + Basilisk time, from now on."""
        self.offset_ns = self.clock.now_ns() - int(CurrentSimNanos)
        self._state_view = None  # the subscription may have changed: a new view at the step

    def UpdateState(self, CurrentSimNanos: int) -> None:
        """Bring the chips to this step's time, then feed them this step's true rate.

        Speed (tools/bench_basilisk.py): the simulation thread keeps its Python thread state
        (``thread_state``: 8 us per Python module and step otherwise), and the spacecraft
        state is read through one live view of the message taken at the first step after
        ``Reset`` (a reader's call makes a new reader and view each time, 5-10 us): the
        subscription is the one made before the simulation was initialised."""
        keep_thread_state()
        clock = self.clock
        lag = self.offset_ns + int(CurrentSimNanos) - clock.now_ns()
        if lag < 0:
            raise RuntimeError(f"{self.ModelTag}: the chips' clock is {-lag} ns ahead of "
                               "Basilisk time (advanced by someone else)")
        if lag:
            clock.advance_ns(lag)
        state = self._state_view
        if state is None:
            state = self._state_view = self.scStateInMsg()
        # in Python floats: numpy's per-call cost on a 3-vector is most of a step's work here
        wx, wy, wz = state.omega_BN_B
        rate_dps = [math.degrees(wx), math.degrees(wy), math.degrees(wz)]
        held = self._held_dps
        resolution = self.rate_resolution_dps
        if (held is None or resolution == 0.0 or abs(rate_dps[0] - held[0]) > resolution
                or abs(rate_dps[1] - held[1]) > resolution
                or abs(rate_dps[2] - held[2]) > resolution):
            self._held_dps = rate_dps
            self.feeds += 1
            for feed in self._feeds:
                feed(rate_dps)  # catches up the samples due by now first, with the held rate
        else:
            rate_dps = held
        if self.record_truth:  # the rate the chips hold from this step on, and the attitude
            self._step_ns.append(int(CurrentSimNanos))
            self._step_sigma.append(state.sigma_BN)
            self._step_rate_dps.append(rate_dps)
        if self.publish:
            for i in range(len(self.gyros)):
                self._publish(i, int(CurrentSimNanos))

    def _publish(self, i: int, now_ns: int) -> None:
        chip = self.gyros[i].chip
        raw = bytes(chip.peek(reg) for reg in _RATE_REGISTERS)
        counts = np.frombuffer(raw, dtype="<i2").astype(float)
        sensor_rad_s = np.radians(counts / chip.sensitivity)
        payload = messaging.IMUSensorMsgPayload()
        payload.AngVelPlatform = sensor_rad_s.tolist()
        self.imuOutMsgs[i].write(payload, now_ns, self.moduleID)
        # (peek: no side effect on the driver's reads; an MSB latched by a driver that read
        # only an LSB shows here as on the bus)
        body = messaging.IMUSensorBodyMsgPayload()
        body.AngVelBody = (self._to_body[i] @ sensor_rad_s).tolist()
        self.imuBodyOutMsgs[i].write(body, now_ns, self.moduleID)

    # ----------------------------------------------------------------- truth

    @property
    def chips(self) -> list[Any]:
        return [g.chip for g in self.gyros]

    def chip_time_ns(self, sim_ns: int) -> int:
        """The chips' clock time at Basilisk time ``sim_ns``."""
        return self.offset_ns + int(sim_ns)

    def steps(self) -> dict[str, np.ndarray]:
        """Per task step: Basilisk time (ns), ``sigma_BN`` and the body rate fed (deg/s)."""
        return {"time_ns": np.array(self._step_ns, dtype=np.int64),
                "sigma_BN": np.array(self._step_sigma, dtype=float).reshape(-1, 3),
                "rate_dps": np.array(self._step_rate_dps, dtype=float).reshape(-1, 3)}

    def truth(self, gyro: int = 0) -> Truth:
        """Truth of every output sample of ``gyro`` so far (times in chip-clock seconds).

        The attitude of a sample at ``ts`` is Basilisk's attitude at the last step ``t_j <
        ts`` turned on by the held rate over ``ts - t_j`` (exact for the rate the chip saw).
        """
        self.gyros[gyro].chip.peek(_CHIP_ID)  # no side effect; catches the chip up
        times = np.array(self._sample_times[gyro], dtype=float)
        rates = np.array(self._sample_rates[gyro], dtype=float).reshape(-1, 3)
        steps = self.steps()
        quats = np.tile([1.0, 0.0, 0.0, 0.0], (times.size, 1))
        if steps["time_ns"].size and times.size:
            step_s = (steps["time_ns"] + self.offset_ns) / NS_PER_S
            j = np.searchsorted(step_s, times, side="left") - 1
            held = j >= 0
            jj = np.clip(j, 0, None)
            q_step = quaternion_from_mrp(steps["sigma_BN"][jj])
            dt = np.where(held, times - step_s[jj], 0.0)
            turn = np.radians(steps["rate_dps"][jj]) * dt[:, None]
            quats = quat_multiply(q_step, quat_from_rotation_vector(turn))
            quats[~held] = quaternion_from_mrp(steps["sigma_BN"][0])
        flags = np.array([self.faults.flags_at(gyro, t) for t in times], dtype=np.int64)
        events = [e for e in self.faults.events if e.gyro in (gyro, None)]
        return Truth(times, rates, quats, flags, events)
