"""Fault injection for robustness tests: what can go wrong with a gyro on a spacecraft bus.

A :class:`FaultSchedule` is a list of :class:`Fault` entries, each a *trigger* (at time
``at_s``, on the bus's ``on_transaction``-th transaction, or with ``probability`` per
transaction, drawn from the schedule's seed) and an *effect*:

| kind | layer | effect |
| --- | --- | --- |
| ``nack`` | bus | the transaction fails with ``OSError(EREMOTEIO)`` (121), as a NACK does |
| ``timeout`` | bus | the transaction fails with ``OSError(ETIMEDOUT)`` (110) after ``stall_s`` |
| ``stuck_axis`` | sample | ``axis`` repeats its last value for ``duration_s`` (None: for ever) |
| ``bias_step`` | sample | ``step_dps`` added to ``axis`` (or to all axes) from then on |
| ``spike`` | sample | ``amplitude_dps`` added to ``axis`` for ``samples`` output samples |
| ``saturation`` | sample | ``axis`` at full scale (sign of ``amplitude_dps``) for ``duration_s`` |
| ``lost_samples`` | sample | ``samples`` output periods without a new sample (no data-ready) |
| ``seu`` | chip | bit ``bit`` of register ``register`` flips (single-event upset) |
| ``brownout`` | chip | spontaneous reset: every register back to its reset value |
| ``temperature_ramp`` | sample | die temperature rises by ``rate_c_per_s`` for ``duration_s``, the bias follows with ``tc_bias_dps_per_c`` |

Bus faults act in ``I2CBus.transaction_hooks``, sample faults in ``BMG160.sample_hooks`` (the
rate in the sensor frame, deg/s, before scaling to counts), chip faults between two
transactions. Every onset is a :class:`FaultEvent` in :attr:`FaultSchedule.events`; a bus
fault is the failed transaction itself in the bus's transaction log, any other fault adds a
``fault:<kind>`` entry there (a chip fault when it acts, a sample fault at the first sample
it touches): its description, then a JSON line of what it did (:func:`fault_entry_text`),
from which a trace replay acts it again (:func:`replay_schedule`); every output sample a
fault touched carries its :data:`FAULT_FLAGS` bit in the rig's truth record, and a bus or
chip fault flags the gyro's next output sample.

Triggers: ``at_s`` acts exactly at that time for sample faults and at the first transaction
at or after it for bus and chip faults; ``on_transaction`` counts the transactions of the
target gyro's bus as the bus numbers them; ``probability`` is drawn once per transaction
on that bus (per transaction addressed to the gyro for bus faults) from a random stream
that depends only on the schedule's seed and the fault's place in the list.
"""

from __future__ import annotations

import errno
import json
import math
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field
from typing import Any, Protocol

import numpy as np

from bmg160_emu.io.trace import parse_fault_entry  # noqa: F401  (the entry format lives with the trace)

BUS_KINDS = ("nack", "timeout")
SAMPLE_KINDS = ("stuck_axis", "bias_step", "spike", "saturation", "lost_samples",
                "temperature_ramp")
CHIP_KINDS = ("seu", "brownout")
FAULT_KINDS = BUS_KINDS + SAMPLE_KINDS + CHIP_KINDS

# One bit per kind in the truth record's ``fault_flags`` column.
FAULT_FLAGS = {kind: 1 << i for i, kind in enumerate(FAULT_KINDS)}

SATURATED_DPS = 1.0e6  # far beyond +-2000 deg/s: the chip clips it to +-32767 counts
AXES = {"x": 0, "y": 1, "z": 2}


class FaultError(ValueError):
    """A fault description that cannot be used, with the reason."""


class GyroTarget(Protocol):
    """What a fault needs to know about a gyro (a :class:`~bmg160_emu.adcs.rig.Gyro`)."""

    @property
    def index(self) -> int: ...
    @property
    def chip(self) -> Any: ...
    @property
    def bus(self) -> Any: ...
    @property
    def address(self) -> int: ...


@dataclass
class FaultEvent:
    """The onset of a fault, as it happened: when, where and what."""

    time_s: float
    kind: str
    gyro: int | None
    transaction: int | None
    detail: str

    def to_dict(self) -> dict[str, Any]:
        return {"time_s": self.time_s, "kind": self.kind, "gyro": self.gyro,
                "transaction": self.transaction, "detail": self.detail}


_NUMBER_FIELDS = ("at_s", "probability", "duration_s", "step_dps", "amplitude_dps",
                  "rate_c_per_s", "stall_s")
_COUNT_FIELDS = ("on_transaction", "gyro", "samples", "register", "bit", "max_count")
_OPTIONAL_FIELDS = {"at_s", "probability", "duration_s", "on_transaction", "gyro", "register",
                    "max_count"}


@dataclass
class Fault:
    """One scheduled fault: a trigger, an effect and its parameters (see the module table)."""

    kind: str
    at_s: float | None = None
    on_transaction: int | None = None
    probability: float | None = None
    gyro: int | None = None
    duration_s: float | None = None
    axis: int | None = None
    step_dps: float = 0.0
    amplitude_dps: float = 0.0
    samples: int = 1
    register: int | None = None
    bit: int = 0
    rate_c_per_s: float = 0.0
    tc_bias_dps_per_c: np.ndarray = field(default_factory=lambda: np.zeros(3))
    stall_s: float = 0.0
    max_count: int | None = None

    def __post_init__(self) -> None:
        if self.kind not in FAULT_KINDS:
            raise FaultError(f"fault kind must be one of {list(FAULT_KINDS)}, not {self.kind!r}")
        self._check_types()
        triggers = [self.at_s is not None, self.on_transaction is not None,
                    self.probability is not None]
        if sum(triggers) != 1:
            raise FaultError(
                f"{self.kind}: give exactly one trigger: at_s, on_transaction or probability"
            )
        if self.probability is not None and not 0.0 <= self.probability <= 1.0:
            raise FaultError(f"{self.kind}: probability must be within 0..1, not {self.probability}")
        if self.on_transaction is not None and self.on_transaction < 0:
            raise FaultError(f"{self.kind}: on_transaction must be >= 0")
        if self.duration_s is not None and not self.duration_s > 0:
            raise FaultError(f"{self.kind}: duration_s must be positive")
        if isinstance(self.axis, str):
            if self.axis not in AXES:
                raise FaultError(f"{self.kind}: axis must be x, y, z or 0, 1, 2, not {self.axis!r}")
            self.axis = AXES[self.axis]
        if self.axis is not None and self.axis not in (0, 1, 2):
            raise FaultError(f"{self.kind}: axis must be x, y, z or 0, 1, 2, not {self.axis!r}")
        if self.kind in ("stuck_axis", "saturation") and self.axis is None:
            raise FaultError(f"{self.kind}: needs an axis")
        if self.kind in ("spike", "lost_samples") and not (
            isinstance(self.samples, int) and self.samples >= 1
        ):
            raise FaultError(f"{self.kind}: samples must be a whole number >= 1")
        if self.kind == "seu":
            if self.register is None or not 0 <= self.register <= 0x3F:
                raise FaultError("seu: register must be an address 0x00..0x3F")
            if not 0 <= self.bit <= 7:
                raise FaultError("seu: bit must be 0..7")
        try:
            self.tc_bias_dps_per_c = np.broadcast_to(
                np.asarray(self.tc_bias_dps_per_c, dtype=float), (3,)
            ).copy()
        except (TypeError, ValueError):
            raise FaultError(f"{self.kind}: tc_bias_dps_per_c must be one number or 3 (x, y, z) "
                             f"in deg/s per degC, not {self.tc_bias_dps_per_c!r}") from None
        if not np.all(np.isfinite(self.tc_bias_dps_per_c)):
            raise FaultError(f"{self.kind}: tc_bias_dps_per_c must be finite")
        if self.max_count is not None and self.max_count < 1:
            raise FaultError(f"{self.kind}: max_count must be at least 1")
        if self.stall_s < 0:
            raise FaultError(f"{self.kind}: stall_s must not be negative")

    def _check_types(self) -> None:
        """Numbers where numbers are meant, whole numbers where counts are: a quoted TOML
        value would otherwise be kept and fail mid-run (or a fractional count never fire)."""
        for name in _NUMBER_FIELDS:
            value = getattr(self, name)
            if value is None and name in _OPTIONAL_FIELDS:
                continue
            if (isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating))
                    or not math.isfinite(value)):
                raise FaultError(f"{self.kind}: {name} must be a finite number, not {value!r}")
        for name in _COUNT_FIELDS:
            value = getattr(self, name)
            if value is None and name in _OPTIONAL_FIELDS:
                continue
            if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
                raise FaultError(f"{self.kind}: {name} must be a whole number, not {value!r}")

    @property
    def layer(self) -> str:
        if self.kind in BUS_KINDS:
            return "bus"
        return "chip" if self.kind in CHIP_KINDS else "sample"

    def describe(self) -> str:
        where = "" if self.axis is None else f" axis {'xyz'[self.axis]}"
        extra = {
            "bias_step": f" {self.step_dps:+g} deg/s",
            "spike": f" {self.amplitude_dps:+g} deg/s x{self.samples}",
            "lost_samples": f" {self.samples} periods",
            "seu": f" register 0x{self.register or 0:02x} bit {self.bit}",
            "temperature_ramp": f" {self.rate_c_per_s:+g} degC/s",
        }.get(self.kind, "")
        span = "" if self.duration_s is None else f" for {self.duration_s:g} s"
        return f"{self.kind}{where}{extra}{span}"


_FAULT_KEYS = {f for f in Fault.__dataclass_fields__}


def fault_from_dict(entry: dict[str, Any], where: str = "fault") -> Fault:
    """Build a fault from its TOML table (``[[fault]]`` in a scenario file)."""
    unknown = set(entry) - _FAULT_KEYS
    if unknown:
        raise FaultError(f"{where}: unknown keys {sorted(unknown)}")
    try:
        return Fault(**entry)
    except FaultError as exc:
        raise FaultError(f"{where}: {exc}") from None
    except TypeError as exc:
        raise FaultError(f"{where}: {exc}") from None


@dataclass
class _Activation:
    start_s: float
    end_s: float  # math.inf when open-ended
    gyro: int
    samples_left: int | None = None  # spike, lost_samples: a count of samples instead
    held: np.ndarray | None = None  # stuck_axis: the value it repeats
    started: bool = False
    not_before_s: float = -math.inf  # a replayed fault: the first sample it touched


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
        self._fired: list[int] = [0] * len(self.faults)
        self._time_done: set[tuple[int, int]] = set()  # (fault, id(bus)) already fired
        self._bus_windows: list[list[tuple[float, float]]] = [[] for _ in self.faults]
        self._activations: list[list[_Activation]] = [[] for _ in self.faults]
        self._last_rate: dict[int, np.ndarray] = {}
        self._sample_flags: dict[int, dict[float, int]] = {}
        self._base_temperature: dict[int, float] = {}
        # gyro -> (time, flag) of bus and chip faults not yet on a sample
        self._pending: dict[int, list[tuple[float, int]]] = {}

    # ----------------------------------------------------------------- installation

    def install(self, gyros: Sequence[GyroTarget]) -> None:
        """Hook the schedule into the gyros' chips and buses (each bus once)."""
        self._gyros = list(gyros)
        for fault in self.faults:
            if fault.gyro is not None and not 0 <= fault.gyro < len(self._gyros):
                raise FaultError(
                    f"{fault.kind}: gyro {fault.gyro} does not exist (the rig has "
                    f"{len(self._gyros)})"
                )
        seen: set[int] = set()
        for gyro in self._gyros:
            self._sample_flags[gyro.index] = {}
            gyro.chip.sample_hooks.append(self._sample_hook_for(gyro))
            if id(gyro.bus) not in seen:
                seen.add(id(gyro.bus))
                gyro.bus.transaction_hooks.append(self._transaction_hook)
            # time-triggered sample faults act on exact sample times, so they are known now
        for i, fault in enumerate(self.faults):
            if fault.layer == "sample" and fault.at_s is not None:
                for gyro in self._targets(fault):
                    self._activate(i, gyro, fault.at_s, None)

    def _targets(self, fault: Fault) -> list[GyroTarget]:
        if fault.gyro is None:
            return self._gyros
        return [self._gyros[fault.gyro]]

    # ----------------------------------------------------------------- bus side

    def _transaction_hook(self, bus: Any, index: int, address: int, kind: str) -> None:
        gyros_here = [g for g in self._gyros if g.bus is bus]
        now = _clock_time(gyros_here[0].chip) if gyros_here else 0.0
        failure: OSError | None = None
        for i, fault in enumerate(self.faults):
            if fault.layer == "sample" and fault.at_s is not None:
                continue  # placed on exact sample times at install
            targets = [g for g in self._targets(fault) if g.bus is bus]
            if not targets:
                continue
            if fault.layer == "bus":
                addressed = [g for g in targets if g.address == address]
                if fault.gyro is not None and not addressed:
                    continue
                if self._bus_fault_now(i, fault, bus, index, now) and failure is None:
                    failure = self._bus_failure(fault, index, now, address, addressed, gyros_here)
            elif self._triggered(i, fault, bus, index, now):
                for gyro in targets:
                    self._activate(i, gyro, now, index)
        if failure is not None:
            raise failure

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
        if fault.duration_s is not None:
            start = now if fault.at_s is None else fault.at_s
            self._bus_windows[i].append((start, start + fault.duration_s))
        self._fired[i] += 1
        return True

    def _bus_failure(self, fault: Fault, index: int, now: float, address: int,
                     addressed: list[GyroTarget], gyros_here: list[GyroTarget]) -> OSError:
        gyro = addressed[0].index if addressed else None
        if fault.kind == "nack":
            code, text = errno.EREMOTEIO, "Remote I/O error"
        else:
            code, text = errno.ETIMEDOUT, "Connection timed out"
            if fault.stall_s > 0 and gyros_here:
                _stall(gyros_here[0].chip, fault.stall_s)
        self.events.append(FaultEvent(now, fault.kind, gyro, index,
                                      f"{fault.describe()} at address 0x{address:02x}"))
        if gyro is not None:
            self._pending.setdefault(gyro, []).append((now, FAULT_FLAGS[fault.kind]))
        return OSError(code, text)

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


def describe_flags(flags: int) -> list[str]:
    """Fault kinds named by a ``fault_flags`` value."""
    return [kind for kind, bit in FAULT_FLAGS.items() if flags & bit]


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
    """Change register content as radiation would: no bus, no access rules.

    The chip model has no public primitive for this yet (asked for); until it has, the
    register file is changed under the chip's lock and the computed-ahead samples are
    dropped so that a flipped RANGE or BW bit takes effect from the next sample.
    """
    if hasattr(chip, "poke"):
        chip.poke(register, value)
        return
    with chip.lock:
        chip.clock.now()  # samples due before the upset keep the old configuration
        chip.peek(register)
        chip._regs[register] = value
        if register == 0x10 and hasattr(chip, "_change_bandwidth"):  # BW (spec 4.9)
            chip._change_bandwidth()
        elif hasattr(chip, "_invalidate"):
            chip._invalidate()


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


def inject(chip: Any, kind: str, *args: str, **params: Any) -> FaultSchedule:
    """Inject one fault into a lone chip from now on: ``inject(chip, "stuck_axis", "axis=y")``.

    Arguments are ``key=value`` strings (as a script line gives them) or keywords. Without a
    trigger the fault starts at the chip's current time. Bus faults (nack, timeout) need a bus
    and are refused here: use a :class:`~bmg160_emu.adcs.rig.GyroRig`.
    """
    for arg in args:
        key, sep, value = arg.partition("=")
        if not sep or not key:
            raise FaultError(f"{kind}: expected key=value, not {arg!r}")
        params[key] = _parse_value(value)
    if kind in BUS_KINDS:
        raise FaultError(f"{kind} is a bus fault: inject it through a GyroRig's bus")
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
