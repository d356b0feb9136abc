"""The fault engine: a seeded :class:`FaultSchedule` acting :class:`Fault` entries on a rig,
or on one chip on one bus (:class:`ChipOnBus`: the pytest plugin's chip and bus).

Bus faults act in ``I2CBus.transaction_hooks``, sample faults in ``BMG160.sample_hooks``,
chip faults between two transactions; every onset is logged (see :mod:`bmg160_emu.faults`).
"""

from __future__ import annotations

import errno
import json
import math
import os
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from bmg160_emu.faults.model import (
    BUS_KINDS,
    CHIP_KINDS,
    FAULT_FLAGS,
    SATURATED_DPS,
    Fault,
    FaultError,
    FaultEvent,
    GyroTarget,
    fault_from_dict,
)
from bmg160_emu.io.trace import parse_fault_entry  # noqa: F401  (the entry format lives with the trace)


@dataclass
class _Activation:
    start_s: float
    end_s: float  # math.inf when open-ended
    gyro: int
    samples_left: int | None = None  # spike, lost_samples: a count of samples instead
    held: np.ndarray | None = None  # stuck_axis: the value it repeats
    started: bool = False
    not_before_s: float = -math.inf  # a replayed fault: the first sample it touched


# (the bus, the gyros on it, [(fault index, fault, its targets on the bus, a bus fault?)])
_BusPlan = tuple[Any, list[GyroTarget], list[tuple[int, Fault, list[GyroTarget], bool]]]

# errno and text of each failing bus fault (Linux Documentation/i2c/fault-codes.rst): a NACK
# of the address is EREMOTEIO on most adapters; ETIMEDOUT "an operation took too much
# time"; EBUSY "the bus was busy for longer than allowed ... needs some fault recovery",
# what an adapter reports while a device holds SDA low (a stuck bus)
_BUS_ERRORS = {"nack": errno.EREMOTEIO, "timeout": errno.ETIMEDOUT, "stuck_bus": errno.EBUSY}


@dataclass
class ChipOnBus:
    """One chip on one I2C bus as a fault target, outside any rig (the pytest plugin's
    chip on its bus): bus faults act on that bus, the others on the chip."""

    chip: Any
    bus: Any
    address: int = -1  # the chip's own address unless given
    index: int = 0

    def __post_init__(self) -> None:
        if self.address < 0:
            self.address = int(getattr(self.chip, "address", 0x68))


class _BusHook:
    """The schedule's transaction hook: it needs the register a transaction names
    (``on_register``) and may change the bytes read (``corrupt_byte``)."""

    takes_register = True

    def __init__(self, schedule: FaultSchedule) -> None:
        self.schedule = schedule

    def __call__(self, bus: Any, index: int, address: int, kind: str,
                 register: int | None = None) -> Callable[[int, bytes], bytes] | None:
        return self.schedule._transaction_hook(bus, index, address, kind, register)


class FaultSchedule:
    """Faults to inject into a rig of gyros; seeded, so a run can be repeated exactly."""

    def __init__(self, faults: Iterable[Fault | dict[str, Any]] = (), seed: int | None = 0,
                 log_to_bus: bool = True):
        self.faults = [f if isinstance(f, Fault) else fault_from_dict(f, f"fault {i + 1}")
                       for i, f in enumerate(faults)]
        self.seed = seed
        self.log_to_bus = log_to_bus
        root = np.random.SeedSequence(seed)
        self._rngs = [np.random.default_rng(s) for s in root.spawn(len(self.faults))]
        self.events: list[FaultEvent] = []
        self._gyros: list[GyroTarget] = []
        self._bus_plans: dict[int, _BusPlan] = {}  # id(bus) -> its plan
        self._fired: list[int] = [0] * len(self.faults)
        self._time_done: set[tuple[int, int]] = set()  # (fault, id(bus)) already fired
        self._bus_windows: list[list[tuple[float, float]]] = [[] for _ in self.faults]
        self._activations: list[list[_Activation]] = [[] for _ in self.faults]
        self._last_rate: dict[int, np.ndarray] = {}
        self._sample_flags: dict[int, dict[float, int]] = {}
        self._base_temperature: dict[int, float] = {}
        # gyro -> (time, flag) of bus and chip faults not yet on a sample
        self._pending: dict[int, list[tuple[float, int]]] = {}
        self._hook = _BusHook(self)
        self._installed: list[tuple[list[Any], Any]] = []  # (hook list, hook) to remove

    # ----------------------------------------------------------------- installation

    def install(self, gyros: Sequence[GyroTarget]) -> None:
        """Hook the schedule into the gyros' chips and buses (each bus once)."""
        self._gyros = list(gyros)
        self._bus_plans = {}
        for fault in self.faults:
            if fault.gyro is not None and not 0 <= fault.gyro < len(self._gyros):
                raise FaultError(
                    f"{fault.kind}: gyro {fault.gyro} does not exist (the rig has "
                    f"{len(self._gyros)})"
                )
        for fault in self.faults:
            if fault.layer == "bus" and any(g.bus is None for g in self._targets(fault)):
                raise FaultError(f"{fault.kind}: a bus fault needs an I2C bus; these chips are "
                                 "reached without one (SPI)")
        seen: set[int] = set()
        for gyro in self._gyros:
            self._sample_flags[gyro.index] = {}
            sample_hook = self._sample_hook_for(gyro)
            gyro.chip.sample_hooks.append(sample_hook)
            self._installed.append((gyro.chip.sample_hooks, sample_hook))
            if gyro.bus is not None and id(gyro.bus) not in seen:
                seen.add(id(gyro.bus))
                gyro.bus.transaction_hooks.append(self._hook)
                self._installed.append((gyro.bus.transaction_hooks, self._hook))
            # time-triggered sample faults act on exact sample times, so they are known now
        for i, fault in enumerate(self.faults):
            if fault.layer == "sample" and fault.at_s is not None:
                for gyro in self._targets(fault):
                    self._activate(i, gyro, fault.at_s, None)

    def remove(self) -> None:
        """Take the schedule's hooks out of the chips and buses (a fault window still open
        ends here); its events and flags stay readable."""
        for hooks, hook in self._installed:
            for i in range(len(hooks) - 1, -1, -1):
                if hooks[i] is hook:
                    del hooks[i]
                    break
        self._installed = []

    def _targets(self, fault: Fault) -> list[GyroTarget]:
        if fault.gyro is None:
            return self._gyros
        return [self._gyros[fault.gyro]]

    # ----------------------------------------------------------------- bus side

    def _bus_plan(self, bus: Any) -> _BusPlan:
        """What a transaction on ``bus`` must look at, worked out once per bus (the hook runs
        on every transaction: a polling loop's hot path): the gyros on it and, for each fault
        with a target there that is not placed on sample times at install, (index, fault,
        its targets on this bus, whether it is a bus fault)."""
        plan = self._bus_plans.get(id(bus))
        if plan is not None and plan[0] is bus:
            return plan
        gyros_here = [g for g in self._gyros if g.bus is bus]
        entries = []
        for i, fault in enumerate(self.faults):
            if fault.layer == "sample" and fault.at_s is not None:
                continue  # placed on exact sample times at install
            targets = [g for g in self._targets(fault) if g.bus is bus]
            if targets:
                entries.append((i, fault, targets, fault.layer == "bus"))
        plan = self._bus_plans[id(bus)] = (bus, gyros_here, entries)
        return plan

    def _transaction_hook(self, bus: Any, index: int, address: int, kind: str,
                          register: int | None = None) -> Callable[[int, bytes], bytes] | None:
        _, gyros_here, entries = self._bus_plan(bus)
        now = _clock_time(gyros_here[0].chip) if gyros_here else 0.0
        failure: OSError | None = None
        wire: Callable[[int, bytes], bytes] | None = None
        for i, fault, targets, is_bus_fault in entries:
            if (fault.conditional or fault.kind == "corrupt_byte") and not fault.selects(
                    address, register, kind):
                continue
            if is_bus_fault:
                addressed = [g for g in targets if g.address == address]
                if fault.gyro is not None and not addressed and fault.kind != "stuck_bus":
                    continue
                if not self._bus_fault_now(i, fault, bus, index, now) or failure is not None:
                    continue
                event = self._bus_event(fault, index, now, address, addressed, gyros_here)
                if fault.kind == "corrupt_byte":
                    wire = wire or _flip(fault.byte, fault.bit)
                else:
                    failure = OSError(event, os.strerror(event))
            elif self._triggered(i, fault, bus, index, now):
                for gyro in targets:
                    self._activate(i, gyro, now, index)
        if failure is not None:
            raise failure
        return wire

    def _triggered(self, i: int, fault: Fault, bus: Any, index: int, now: float) -> bool:
        """One-shot or random trigger of a sample or chip fault at this transaction."""
        if fault.max_count is not None and self._fired[i] >= fault.max_count:
            return False
        if fault.at_s is not None:
            if (i, id(bus)) in self._time_done or now < fault.at_s:
                return False
            self._time_done.add((i, id(bus)))
            return True
        if fault.on_transaction is not None:
            return index == fault.on_transaction
        return bool(self._rngs[i].random() < (fault.probability or 0.0))

    def _bus_fault_now(self, i: int, fault: Fault, bus: Any, index: int, now: float) -> bool:
        if any(start <= now < end for start, end in self._bus_windows[i]):
            return True
        if not self._triggered(i, fault, bus, index, now):
            return False
        if fault.duration_s is not None or fault.kind == "stuck_bus":  # stuck: for ever
            start = now if fault.at_s is None else fault.at_s
            length = math.inf if fault.duration_s is None else fault.duration_s
            self._bus_windows[i].append((start, start + length))
        self._fired[i] += 1
        return True

    def _bus_event(self, fault: Fault, index: int, now: float, address: int,
                   addressed: list[GyroTarget], gyros_here: list[GyroTarget]) -> int:
        """Record a bus fault acting on a transaction; its errno (0: the transaction goes on
        with a corrupted byte)."""
        gyro = addressed[0].index if addressed else None
        code = _BUS_ERRORS.get(fault.kind, 0)
        if fault.kind in ("timeout", "stuck_bus") and fault.stall_s > 0 and gyros_here:
            _stall(gyros_here[0].chip, fault.stall_s)
        self.events.append(FaultEvent(now, fault.kind, gyro, index,
                                      f"{fault.describe()} at address 0x{address:02x}"))
        if gyro is not None:
            self._pending.setdefault(gyro, []).append((now, FAULT_FLAGS[fault.kind]))
        if not code and self.log_to_bus and gyro is not None:
            self._note(self.events[-1], addressed[0], fault, event_too=False)
        return code

    # ----------------------------------------------------------------- chip and sample side

    def _activate(self, i: int, gyro: GyroTarget, now: float, index: int | None) -> None:
        fault = self.faults[i]
        if fault.layer == "chip":
            self._fired[i] += 1
            self._chip_fault(fault, gyro, now, index)
            return
        if index is not None:
            self._fired[i] += 1
        end = math.inf if fault.duration_s is None else now + fault.duration_s
        count = fault.samples if fault.kind in ("spike", "lost_samples") else None
        self._activations[i].append(_Activation(now, end, gyro.index, count))
        if index is not None or fault.at_s is None:  # its bus-log entry waits for its first sample
            self._note(FaultEvent(now, fault.kind, gyro.index, index, fault.describe()), gyro,
                       log=False)

    def _chip_fault(self, fault: Fault, gyro: GyroTarget, now: float, index: int | None) -> None:
        chip = gyro.chip
        if fault.kind == "brownout":
            chip.power_on_reset()
            detail = "brown-out: registers back to reset values"
        else:
            assert fault.register is not None
            before = chip.peek(fault.register)
            after = before ^ (1 << fault.bit)
            _poke(chip, fault.register, after)
            detail = (f"SEU register 0x{fault.register:02x} bit {fault.bit}: "
                      f"0x{before:02x} -> 0x{chip.peek(fault.register):02x}")
        self._note(FaultEvent(now, fault.kind, gyro.index, index, detail), gyro, fault)

    def _sample_hook_for(self, gyro: GyroTarget):
        def hook(chip: Any, t: float, rate_dps: np.ndarray) -> np.ndarray | None:
            return self._apply(gyro, t, rate_dps)

        return hook

    def _apply(self, gyro: GyroTarget, t: float, rate_dps: np.ndarray) -> np.ndarray | None:
        rate = np.array(rate_dps, dtype=float)
        flags = 0
        pending = self._pending.get(gyro.index)
        if pending:  # bus and chip faults: flag the first sample at or after them
            for when, bits in pending:
                if when <= t:
                    flags |= bits
            pending[:] = [(when, bits) for when, bits in pending if when > t]
        lost = False
        for i, fault in enumerate(self.faults):
            for act in self._activations[i]:
                if act.gyro != gyro.index or t < act.start_s or t < act.not_before_s:
                    continue
                if not act.started:
                    act.started = True
                    if fault.kind == "stuck_axis" and act.held is None:
                        act.held = self._last_rate.get(gyro.index, rate).copy()
                    event = FaultEvent(t, fault.kind, gyro.index, None, fault.describe())
                    # time-triggered: the onset is this sample; every sample fault's bus-log
                    # entry is written here, where what it does (held value ...) is known
                    self._note(event, gyro, fault, act, event_too=fault.at_s is not None)
                if act.samples_left is not None:
                    if act.samples_left <= 0:
                        continue
                    act.samples_left -= 1
                elif t >= act.end_s and fault.kind != "temperature_ramp":
                    continue
                flags |= FAULT_FLAGS[fault.kind]
                lost |= self._effect(fault, act, gyro, t, rate)
        if flags:
            self._sample_flags[gyro.index][t] = flags
        if lost:
            return None
        self._last_rate[gyro.index] = rate.copy()
        return rate

    def _effect(self, fault: Fault, act: _Activation, gyro: GyroTarget, t: float,
                rate: np.ndarray) -> bool:
        """Change ``rate`` in place for one sample; True when the sample is lost."""
        axes = slice(None) if fault.axis is None else fault.axis
        if fault.kind == "stuck_axis":
            assert act.held is not None
            rate[axes] = act.held[axes]
        elif fault.kind == "bias_step":
            rate[axes] += fault.step_dps
        elif fault.kind == "spike":
            rate[axes] += fault.amplitude_dps
        elif fault.kind == "saturation":
            rate[axes] = math.copysign(SATURATED_DPS, fault.amplitude_dps or 1.0)
        elif fault.kind == "lost_samples":
            return True
        elif fault.kind == "temperature_ramp":
            elapsed = min(t, act.end_s) - act.start_s
            rise_c = fault.rate_c_per_s * elapsed
            base = self._base_temperature.setdefault(gyro.index, _base_temperature(gyro))
            _set_temperature(gyro.chip, base + rise_c)
            rate += fault.tc_bias_dps_per_c * rise_c
        return False

    def _note(self, event: FaultEvent, gyro: GyroTarget, fault: Fault | None = None,
              activation: _Activation | None = None, *, log: bool = True,
              event_too: bool = True) -> None:
        """Record an onset, and put it in the gyro's bus log as a ``fault:<kind>`` entry
        (its description, then the parameters a trace replay needs: :func:`fault_entry_text`)."""
        if event_too:
            self.events.append(event)
            if event.kind in CHIP_KINDS:  # flagged on the gyro's next output sample
                self._pending.setdefault(gyro.index, []).append(
                    (event.time_s, FAULT_FLAGS[event.kind]))
        bus_log = getattr(gyro.bus, "log", None)
        if log and self.log_to_bus and bus_log is not None and getattr(bus_log, "enabled", True):
            from bmg160_emu.bus.transactions import Transaction

            base_c = _base_temperature(gyro) if event.kind == "temperature_ramp" else None
            text = fault_entry_text(event.detail, fault, activation, event.time_s, base_c)
            bus_log.append(Transaction(event.time_s, getattr(gyro.bus, "number", 0), gyro.address,
                                   f"fault:{event.kind}", written=text.encode()))

    # ----------------------------------------------------------------- truth

    def flags_at(self, gyro: int, t: float) -> int:
        """The :data:`FAULT_FLAGS` bits of the faults that touched gyro's sample at ``t``."""
        return self._sample_flags.get(gyro, {}).get(t, 0)


# ----------------------------------------------------------------- fault entries in a bus log

# Effect parameters of a Fault; its trigger is replaced by the onset (at_s) in a log entry.
_EFFECT_KEYS = ("duration_s", "axis", "step_dps", "amplitude_dps", "samples", "register", "bit",
                "rate_c_per_s", "tc_bias_dps_per_c")


def fault_entry_text(detail: str, fault: Fault | None = None,
                     activation: _Activation | None = None, first_sample_s: float | None = None,
                     base_temperature_c: float | None = None) -> str:
    """The written bytes of a ``fault:<kind>`` log entry: the description for a person, then
    (when the fault is known) one JSON line with what the fault did, for trace replay:
    ``{"fault": {kind, effect parameters}, "activation": {start_s, end_s, first_sample_s,
    held_dps}, "base_temperature_c": ...}`` (activation for sample faults only).
    """
    if fault is None:
        return detail
    params: dict[str, Any] = {"kind": fault.kind}
    defaults = Fault.__dataclass_fields__
    for key in _EFFECT_KEYS:
        value = getattr(fault, key)
        if key == "tc_bias_dps_per_c":
            if np.any(value):
                params[key] = [float(v) for v in value]
        elif value != defaults[key].default:
            params[key] = value
    entry: dict[str, Any] = {"fault": params}
    if activation is not None:
        entry["activation"] = {
            "start_s": activation.start_s,
            "end_s": None if math.isinf(activation.end_s) else activation.end_s,
            "first_sample_s": first_sample_s,
            "held_dps": None if activation.held is None else [float(v) for v in activation.held],
        }
    if base_temperature_c is not None:
        entry["base_temperature_c"] = float(base_temperature_c)
    return detail + "\n" + json.dumps(entry, sort_keys=True)


def replay_schedule(entries: Sequence[dict[str, Any]], target: GyroTarget) -> FaultSchedule:
    """A schedule that acts recorded sample faults again on ``target``, each on exactly the
    samples it touched in the session (same start, end, first sample and held value).

    ``entries`` are the parameters :func:`parse_fault_entry` gives for ``fault:<kind>``
    entries of sample faults, in the order of the log. The schedule writes nothing to the bus
    log; install nothing else for these faults.
    """
    faults: list[Fault] = []
    activations: list[_Activation] = []
    for entry in entries:
        act = entry.get("activation")
        if not isinstance(act, dict) or act.get("start_s") is None:
            raise FaultError(f"{entry.get('fault')}: the entry does not say when the fault acted")
        fault = fault_from_dict({**entry["fault"], "at_s": float(act["start_s"])}, "replayed fault")
        if fault.layer != "sample":
            raise FaultError(f"{fault.kind} is not a sample fault")
        end = math.inf if act.get("end_s") is None else float(act["end_s"])
        count = fault.samples if fault.kind in ("spike", "lost_samples") else None
        held = None if act.get("held_dps") is None else np.array(act["held_dps"], dtype=float)
        first = -math.inf if act.get("first_sample_s") is None else float(act["first_sample_s"])
        faults.append(fault)
        activations.append(_Activation(fault.at_s or 0.0, end, target.index, count, held,
                                       not_before_s=first))
    schedule = FaultSchedule(faults, log_to_bus=False)
    schedule._gyros = [target]
    schedule._sample_flags[target.index] = {}
    target.chip.sample_hooks.append(schedule._sample_hook_for(target))
    for i, act in enumerate(activations):
        schedule._activations[i].append(act)
    return schedule


def _flip(byte: int, bit: int) -> Callable[[int, bytes], bytes]:
    """The wire filter of a corrupt_byte fault: bit ``bit`` of the ``byte``-th byte the host
    reads in the transaction is inverted (a glitch the host samples)."""
    def wire(offset: int, data: bytes) -> bytes:
        place = byte - offset
        if not 0 <= place < len(data):
            return data
        out = bytearray(data)
        out[place] ^= 1 << bit
        return bytes(out)

    return wire


# ----------------------------------------------------------------- chip access, in one place


def _clock_time(chip: Any) -> float:
    clock = getattr(chip, "clock", None)
    if clock is not None and hasattr(clock, "now"):
        return float(clock.now())
    return float(chip.time)


def _stall(chip: Any, seconds: float) -> None:
    """A timed-out transfer takes the adapter's timeout: virtual time moves on by that much."""
    clock = getattr(chip, "clock", None)
    if clock is not None and hasattr(clock, "advance"):
        clock.advance(seconds)


def _poke(chip: Any, register: int, value: int) -> None:
    """Change register content as radiation would: no bus, no access rules (the chip's
    ``poke`` primitive, device/contract.py). A device without it cannot take an upset."""
    poke = getattr(chip, "poke", None)
    if poke is None:
        raise TypeError(f"{type(chip).__name__} has no poke(register, value): a register "
                        f"upset needs it (docs/architecture.md, the chip's primitives)")
    poke(register, value)


def _base_temperature(gyro: Any) -> float:
    spec = getattr(gyro, "spec", None)
    return float(getattr(spec, "temperature_c", 23.0))


def _set_temperature(chip: Any, celsius: float) -> None:
    if hasattr(chip, "set_temperature"):
        chip.set_temperature(celsius)
    else:
        chip.temperature_c = celsius


# ----------------------------------------------------------------- one chip, right now


@dataclass
class _LoneChip:
    """A chip outside any rig, as a fault target (no bus: bus faults need a rig)."""

    chip: Any
    index: int = 0
    bus: Any = None

    @property
    def address(self) -> int:
        return int(getattr(self.chip, "address", 0x68))


def _parse_value(text: str) -> Any:
    for convert in (int, float):
        try:
            return convert(text, 0) if convert is int else convert(text)  # type: ignore[call-arg]
        except ValueError:
            pass
    if "," in text:
        return [_parse_value(part) for part in text.split(",")]
    return text


def inject(chip: Any, kind: str, *args: str, bus: Any = None, seed: int | None = 0,
           **params: Any) -> FaultSchedule:
    """Inject one fault into a lone chip from now on: ``inject(chip, "stuck_axis", "axis=y")``.

    Arguments are ``key=value`` strings (as a script line gives them) or keywords. Without a
    trigger the fault starts at the chip's current time. With ``bus`` (the ``I2CBus`` the
    chip is on, such as the pytest plugin's) every kind is accepted, bus faults included,
    and transactions trigger and count as on a rig's bus (``seed``: the random stream of a
    ``probability`` trigger); without it bus faults are refused.
    """
    for arg in args:
        key, sep, value = arg.partition("=")
        if not sep or not key:
            raise FaultError(f"{kind}: expected key=value, not {arg!r}")
        params[key] = _parse_value(value)
    if bus is not None:
        if not {"at_s", "on_transaction", "probability", "address", "on_register"} & set(params):
            params["at_s"] = float(chip.time)
        schedule = FaultSchedule([fault_from_dict({"kind": kind, **params}, kind)], seed=seed)
        schedule.install([ChipOnBus(chip, bus)])
        return schedule
    if kind in BUS_KINDS:
        raise FaultError(f"{kind} is a bus fault: give the bus the chip is on, "
                         f"inject(chip, {kind!r}, bus=...) (the pytest plugin's bmg160_smbus), "
                         "or use a GyroRig")
    if {"on_transaction", "probability"} & set(params):
        raise FaultError(f"{kind}: a lone chip has no transactions to count; give at_s")
    now = float(chip.time)
    params.setdefault("at_s", now)
    fault = fault_from_dict({"kind": kind, **params}, kind)
    assert fault.at_s is not None
    if fault.layer == "chip" and fault.at_s > now:
        raise FaultError(f"{kind}: acts at once on a lone chip; at_s cannot be in the future")
    schedule = FaultSchedule([fault], log_to_bus=False)
    target = _LoneChip(chip)
    schedule._gyros = [target]
    schedule._sample_flags[0] = {}
    chip.sample_hooks.append(schedule._sample_hook_for(target))
    if fault.layer == "sample":
        schedule._activate(0, target, fault.at_s, None)
    else:
        schedule._chip_fault(fault, target, now, None)
    return schedule
