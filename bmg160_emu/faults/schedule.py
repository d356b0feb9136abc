"""The fault engine: a seeded :class:`FaultSchedule` acting :class:`Fault` entries on a rig,
or on one chip on one bus (:class:`~bmg160_emu.faults.targets.ChipOnBus`: the pytest
plugin's chip and bus).

Bus faults act in ``I2CBus.transaction_hooks``, sample faults in ``BMG160.sample_hooks``,
chip faults between two transactions; every onset is logged (see :mod:`bmg160_emu.faults`).
What a sample fault does to a sample is :mod:`.sample_effects`; acting a log's faults again
is :mod:`.replay`; one fault into one chip from a script line is :mod:`.inject`.
"""

from __future__ import annotations

import errno
import math
import os
from collections.abc import Callable, Iterable, Sequence
from typing import Any

import numpy as np

from bmg160_emu.faults.corrupt import CorruptWire
from bmg160_emu.faults.model import (
    CHIP_KINDS,
    FAULT_FLAGS,
    Fault,
    FaultError,
    FaultEvent,
    GyroTarget,
    effect_parameters,
    fault_from_dict,
)
from bmg160_emu.faults.sample_effects import Activation, apply_effect, counts_samples
from bmg160_emu.faults.targets import base_temperature, clock_time, poke, stall
from bmg160_emu.traffic.fault_entry import fault_entry_text
from bmg160_emu.traffic.kinds import FAULT_KIND_PREFIX
from bmg160_emu.traffic.transaction import Transaction

# (the bus, the gyros on it, [(fault index, fault, its targets on the bus, a bus fault?)])
_BusPlan = tuple[Any, list[GyroTarget], list[tuple[int, Fault, list[GyroTarget], bool]]]

# errno and text of each failing bus fault (Linux Documentation/i2c/fault-codes.rst): a NACK
# of the address is EREMOTEIO on most adapters; ETIMEDOUT "an operation took too much
# time"; EBUSY "the bus was busy for longer than allowed ... needs some fault recovery",
# what an adapter reports while a device holds SDA low (a stuck bus)
_BUS_ERRORS = {"nack": errno.EREMOTEIO, "timeout": errno.ETIMEDOUT, "stuck_bus": errno.EBUSY}


class _BusHook:
    """The schedule's transaction hook: it needs the register a transaction names
    (``on_register``) and may change the bytes read (``corrupt_byte``)."""

    takes_register = True

    def __init__(self, schedule: FaultSchedule) -> None:
        self.schedule = schedule

    def __call__(self, bus: Any, index: int, address: int, kind: str,
                 register: int | None = None) -> CorruptWire | None:
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
        self._activations: list[list[Activation]] = [[] for _ in self.faults]
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
                    self.activate(i, gyro, fault.at_s)

    def install_on_samples(self, target: GyroTarget) -> None:
        """Hook the schedule into one chip's samples alone (no bus, no install-time
        activations): a lone chip, or a replay that places its activations itself."""
        self._gyros = [target]
        self._sample_flags[target.index] = {}
        hook = self._sample_hook_for(target)
        target.chip.sample_hooks.append(hook)
        self._installed.append((target.chip.sample_hooks, hook))

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
                          register: int | None = None) -> CorruptWire | None:
        _, gyros_here, entries = self._bus_plan(bus)
        now = clock_time(gyros_here[0].chip) if gyros_here else 0.0
        failure: OSError | None = None
        wire: CorruptWire | None = None
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
                if fault.kind == "corrupt_byte":
                    if wire is None:  # one corruption per transaction; reported when it ends
                        wire = CorruptWire(fault, kind, self._corruption_reporter(
                            bus, index, now, address, addressed))
                    continue
                code = self._bus_event(fault, index, now, address, addressed, gyros_here)
                failure = OSError(code, os.strerror(code))
            elif self._triggered(i, fault, bus, index, now):
                for gyro in targets:
                    self.activate(i, gyro, now, index)
        if failure is not None:
            if wire is not None:  # the transaction fails: nothing crossed the wire
                wire.what = "not acted: the transaction failed"
                wire.report(wire)
            raise failure
        return wire

    def _corruption_reporter(self, bus: Any, index: int, now: float, address: int,
                             addressed: list[GyroTarget]) -> Callable[[CorruptWire], None]:
        """What a corrupt_byte does once its transaction is over: its event (what it changed,
        or that it found nothing to change), the gyro's flag, and its ``fault:corrupt_byte``
        log entry, just before the transaction's own (replay acts it again from there)."""
        def report(wire: CorruptWire) -> None:
            fault = wire.fault
            gyro = addressed[0].index if addressed else None
            detail = f"{fault.describe()} at address 0x{address:02x}: {wire.what}"
            event = FaultEvent(now, fault.kind, gyro, index, detail)
            self.events.append(event)
            if gyro is not None and wire.acted:
                self._pending.setdefault(gyro, []).append((now, FAULT_FLAGS[fault.kind]))
            log = getattr(bus, "log", None)
            if self.log_to_bus and log is not None and getattr(log, "enabled", True):
                text = fault_entry_text(detail, effect_parameters(fault))
                log.append(Transaction(now, getattr(bus, "number", 0), address,
                                       FAULT_KIND_PREFIX + fault.kind, written=text.encode()))
        return report

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
        """Record a bus fault failing a transaction; its errno (the failed transaction, with
        that errno, is its record in the log)."""
        gyro = addressed[0].index if addressed else None
        code = _BUS_ERRORS[fault.kind]
        if fault.kind in ("timeout", "stuck_bus") and fault.stall_s > 0 and gyros_here:
            stall(gyros_here[0].chip, fault.stall_s)
        self.events.append(FaultEvent(now, fault.kind, gyro, index,
                                      f"{fault.describe()} at address 0x{address:02x}"))
        if gyro is not None:
            self._pending.setdefault(gyro, []).append((now, FAULT_FLAGS[fault.kind]))
        return code

    # ----------------------------------------------------------------- chip and sample side

    def activate(self, i: int, gyro: GyroTarget, now: float, index: int | None = None,
                 activation: Activation | None = None) -> None:
        """Fault ``i`` acts on ``gyro`` from ``now`` (``index``: the transaction that
        triggered it); a sample fault may be given its ``activation`` (a replay's)."""
        fault = self.faults[i]
        if fault.layer == "chip":
            self._fired[i] += 1
            self.act_chip_fault(fault, gyro, now, index)
            return
        if activation is not None:
            self._activations[i].append(activation)
            return
        if index is not None:
            self._fired[i] += 1
        end = math.inf if fault.duration_s is None else now + fault.duration_s
        count = fault.samples if counts_samples(fault) else None
        self._activations[i].append(Activation(now, end, gyro.index, count))
        if index is not None or fault.at_s is None:  # its bus-log entry waits for its first sample
            self._note(FaultEvent(now, fault.kind, gyro.index, index, fault.describe()), gyro,
                       log=False)

    def act_chip_fault(self, fault: Fault, gyro: GyroTarget, now: float,
                       index: int | None = None) -> None:
        """A chip fault acts now: a brown-out resets the chip, an SEU flips its bit."""
        chip = gyro.chip
        if fault.kind == "brownout":
            chip.power_on_reset()
            detail = "brown-out: registers back to reset values"
        else:
            assert fault.register is not None
            before = chip.peek(fault.register)
            after = before ^ (1 << fault.bit)
            poke(chip, fault.register, after)
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
                base = (self._base_temperature.setdefault(gyro.index, base_temperature(gyro))
                        if fault.kind == "temperature_ramp" else 0.0)
                lost |= apply_effect(fault, act, gyro.chip, t, rate, base)
        if flags:
            self._sample_flags[gyro.index][t] = flags
        if lost:
            return None
        self._last_rate[gyro.index] = rate.copy()
        return rate

    def _note(self, event: FaultEvent, gyro: GyroTarget, fault: Fault | None = None,
              activation: Activation | None = None, *, log: bool = True,
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
            text = entry_text(event, fault, activation, gyro)
            bus_log.append(Transaction(event.time_s, getattr(gyro.bus, "number", 0), gyro.address,
                                       FAULT_KIND_PREFIX + event.kind, written=text.encode()))

    # ----------------------------------------------------------------- truth

    def flags_at(self, gyro: int, t: float) -> int:
        """The :data:`FAULT_FLAGS` bits of the faults that touched gyro's sample at ``t``."""
        return self._sample_flags.get(gyro, {}).get(t, 0)


def entry_text(event: FaultEvent, fault: Fault | None, activation: Activation | None,
               gyro: GyroTarget) -> str:
    """The written bytes of the ``fault:<kind>`` log entry of ``event`` (traffic.fault_entry)."""
    if fault is None:
        return event.detail
    base_c = base_temperature(gyro) if event.kind == "temperature_ramp" else None
    if activation is None:
        return fault_entry_text(event.detail, effect_parameters(fault), base_temperature_c=base_c)
    return fault_entry_text(
        event.detail, effect_parameters(fault), activation=True, start_s=activation.start_s,
        end_s=None if math.isinf(activation.end_s) else activation.end_s,
        first_sample_s=event.time_s,
        held_dps=None if activation.held is None else activation.held.tolist(),
        base_temperature_c=base_c)
