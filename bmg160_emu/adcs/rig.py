"""Several gyros on emulated I2C buses, driven by one scenario, with the truth recorded.

A :class:`GyroRig` builds one :class:`~bmg160_emu.device.chip.BMG160` per :class:`GyroSpec` (two on
one bus at 0x68/0x69, or on several buses), all on one virtual clock, all fed the scenario's
true body rate through their own mounting. Each chip gets its own noise realisation: the
master seed is split with :class:`numpy.random.SeedSequence`, so gyro ``i`` of master seed
``s`` always gets the same noise and no two gyros share one. A fault schedule (from the
scenario's ``[[fault]]`` tables or given) draws from the same master seed.

Truth: for every output sample of every gyro the rig records the time, the true body rate
(deg/s, before mounting and noise), the true attitude quaternion (integrated from the
scenario, :mod:`bmg160_emu.adcs.attitude`) and the fault flags of that sample.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from bmg160_emu.adcs.attitude import IDENTITY, integrate_attitude
from bmg160_emu.adcs.scenarios import Scenario, ScenarioError
from bmg160_emu.device.config import ChipConfig
from bmg160_emu.device.registers import address_of
from bmg160_emu.device.spec_choices import DEFAULT_PART, VALID_ADDRESSES

CHIP_ID = address_of("CHIP_ID")
from bmg160_emu.faults import Fault, FaultEvent, FaultSchedule, describe_flags


def rotation_matrix_from_euler_zyx(yaw_deg: float, pitch_deg: float, roll_deg: float) -> np.ndarray:
    """Body-to-sensor matrix of the sensor frame turned by yaw (z), pitch (y), roll (x)."""
    cz, sz = math.cos(math.radians(yaw_deg)), math.sin(math.radians(yaw_deg))
    cy, sy = math.cos(math.radians(pitch_deg)), math.sin(math.radians(pitch_deg))
    cx, sx = math.cos(math.radians(roll_deg)), math.sin(math.radians(roll_deg))
    rz = np.array([[cz, -sz, 0], [sz, cz, 0], [0, 0, 1]])
    ry = np.array([[cy, 0, sy], [0, 1, 0], [-sy, 0, cy]])
    rx = np.array([[1, 0, 0], [0, cx, -sx], [0, sx, cx]])
    # the sensor axes in body coordinates are the columns of rz ry rx; body -> sensor is its transpose
    return (rz @ ry @ rx).T


def _mounting_matrix(value: Any, where: str) -> np.ndarray:
    if value is None:
        return np.eye(3)
    if isinstance(value, dict):
        if set(value) == {"euler_zyx_deg"}:
            angles = np.asarray(value["euler_zyx_deg"], dtype=float)
            if angles.shape != (3,):
                raise ScenarioError(f"{where}: euler_zyx_deg must be [yaw, pitch, roll]")
            return rotation_matrix_from_euler_zyx(*angles)
        if set(value) == {"matrix"}:
            value = value["matrix"]
        else:
            raise ScenarioError(f"{where}: mounting takes euler_zyx_deg or matrix")
    matrix = np.asarray(value, dtype=float)
    if matrix.shape != (3, 3) or not np.allclose(matrix @ matrix.T, np.eye(3), atol=1e-6) \
            or np.linalg.det(matrix) < 0:
        raise ScenarioError(f"{where}: mounting must be a proper rotation matrix (3x3)")
    return matrix


@dataclass
class GyroSpec:
    """Where one gyro sits: bus, address, mounting, and its error terms (default off)."""

    name: str = "gyro"
    bus: int = 1
    address: int = 0x68
    mounting: np.ndarray = field(default_factory=lambda: np.eye(3))  # body -> sensor
    scale_factor_error: np.ndarray = field(default_factory=lambda: np.zeros(3))  # per axis, 1 = +100 %
    misalignment_rad: np.ndarray = field(default_factory=lambda: np.zeros((3, 3)))
    profile: Any = None  # a built-in name, a TOML path, a mapping or a Profile; None: the part's
    noise: bool = True
    noise_mode: str = "physical"
    temperature_c: float = 23.0
    errors: Any = None  # the unit's error table (bmg160_emu.noise.sensor_errors.SensorErrors)
    unit: Any = None  # k: unit k of lot ``lot``; "per-run": a new unit of the lot every run
    lot: int = 0  # the production lot's seed (device.unit_population.draw_unit)
    acceleration_g: Any = (0.0, 0.0, 0.0)  # g in the sensor frame (g-sensitivity)
    part: str = DEFAULT_PART  # a device.parts.PART_NAMES entry

    def __post_init__(self) -> None:
        from bmg160_emu.device.parts import PART_NAMES, UnknownPartError, part_profile

        try:  # None: the part's data-sheet profile (paper for the bmg160)
            self.profile = part_profile(self.part, self.profile)
        except UnknownPartError:
            raise ScenarioError(f"{self.name}: part must be one of {', '.join(PART_NAMES)}, "
                                f"not {self.part!r}") from None
        if not _is_whole(self.address) or self.address not in VALID_ADDRESSES:
            shown = f"0x{self.address:02x}" if _is_whole(self.address) else repr(self.address)
            raise ScenarioError(f"{self.name}: address must be 0x68 or 0x69 (the BMG160 answers "
                                f"at these only), not {shown}")
        if not _is_whole(self.bus) or self.bus < 0:
            raise ScenarioError(f"{self.name}: bus must be a whole number >= 0, not {self.bus!r}")
        if not isinstance(self.noise, bool):
            raise ScenarioError(f"{self.name}: noise must be true or false, not {self.noise!r}")
        if self.noise_mode not in ("physical", "paper"):
            raise ScenarioError(f"{self.name}: noise_mode must be 'physical' or 'paper', "
                                f"not {self.noise_mode!r}")
        if (isinstance(self.temperature_c, bool) or not isinstance(self.temperature_c, (int, float))
                or not math.isfinite(self.temperature_c)):
            raise ScenarioError(f"{self.name}: temperature_c must be a finite number, "
                                f"not {self.temperature_c!r}")
        self.mounting = _mounting_matrix(self.mounting, self.name)
        self.scale_factor_error = _finite_array(
            self.scale_factor_error, (3,), f"{self.name}: scale_factor_error must be one number "
            "or 3 (x, y, z), fractions of the true scale (0.01 = +1 %)")
        self.misalignment_rad = _finite_array(
            self.misalignment_rad, (3, 3), f"{self.name}: misalignment_rad must be a 3x3 matrix "
            "of finite angles in radians")
        if self.unit is not None and self.unit != "per-run" and not (
                _is_whole(self.unit) and self.unit >= 0):
            raise ScenarioError(f"{self.name}: unit must be a unit number >= 0 or \"per-run\", "
                                f"not {self.unit!r}")
        if not _is_whole(self.lot) or self.lot < 0:
            raise ScenarioError(f"{self.name}: lot must be a whole number >= 0, not {self.lot!r}")
        if self.errors is not None and self.unit is not None:
            raise ScenarioError(f"{self.name}: give errors or unit, not both")
        if self.errors is not None:
            from bmg160_emu.noise.sensor_errors import SensorErrors

            try:
                self.errors = SensorErrors.from_dict(self.errors, where=f"{self.name}: errors") \
                    if not isinstance(self.errors, SensorErrors) else self.errors
            except ValueError as exc:
                raise ScenarioError(str(exc)) from None
        self.acceleration_g = _finite_array(
            self.acceleration_g, (3,), f"{self.name}: acceleration_g must be 3 finite numbers (g)")


def _is_whole(value: Any) -> bool:
    return isinstance(value, (int, np.integer)) and not isinstance(value, bool)


def _finite_array(value: Any, shape: tuple[int, ...], message: str) -> np.ndarray:
    try:
        array = np.broadcast_to(np.asarray(value, dtype=float), shape).copy()
    except (TypeError, ValueError):
        raise ScenarioError(message) from None
    if not np.all(np.isfinite(array)):
        raise ScenarioError(message)
    return array


_SPEC_KEYS = set(GyroSpec.__dataclass_fields__)


def gyro_spec_from_dict(entry: dict[str, Any], index: int, base: Any = None) -> GyroSpec:
    """A gyro from its ``[[gyro]]`` table; a ``profile`` path is relative to ``base``, the
    scenario file's folder, as a table file and a stand-in are (issue 35: `montecarlo
    my_orbit.toml` from another folder could not find the profile named in it)."""
    from pathlib import Path

    unknown = set(entry) - _SPEC_KEYS
    if unknown:
        raise ScenarioError(f"gyro {index + 1}: unknown keys {sorted(unknown)}")
    entry = {"name": f"gyro{index}", **entry}
    profile = entry.get("profile")
    if isinstance(profile, str) and base is not None and not Path(profile).is_absolute():
        from bmg160_emu.noise.profile import builtin_profile_names

        if profile not in builtin_profile_names():
            entry["profile"] = str(Path(base) / profile)
    return GyroSpec(**entry)


_DEVICE_KEYS = {"name", "address", "bus"}


def standin_from_dict(entry: dict[str, Any], index: int, base: Any = None) -> Any:
    """A stand-in from its ``[[device]]`` table: ``name`` (a built-in stand-in, or a TOML or
    dump path, relative to the scenario file), ``address`` and ``bus`` (default 1)."""
    from pathlib import Path

    from bmg160_emu.device.standin import StandinConfig
    from bmg160_emu.io.errors import FormatError
    from bmg160_emu.io.standin_file import builtin_names, load_standin

    where = f"device {index + 1}"
    unknown = set(entry) - _DEVICE_KEYS
    if unknown:
        raise ScenarioError(f"{where}: unknown keys {sorted(unknown)} (known: address, bus, name)")
    name, bus = entry.get("name"), entry.get("bus", 1)
    address: Any = entry.get("address")
    if not isinstance(name, str) or not name:
        raise ScenarioError(f"{where}: name must be a stand-in ({', '.join(builtin_names())}) "
                            "or the path of a stand-in TOML or dump")
    if not _is_whole(address) or not 0x03 <= address <= 0x77:
        raise ScenarioError(f"{where}: address must be an I2C address 0x03..0x77, not {address!r}")
    if not _is_whole(bus) or bus < 0:
        raise ScenarioError(f"{where}: bus must be a whole number >= 0, not {bus!r}")
    if name not in builtin_names() and base is not None and not Path(name).is_absolute():
        name = str(Path(base) / name)
    try:
        spec = load_standin(name)
    except FormatError as exc:
        raise ScenarioError(f"{where}: {exc}") from None
    if spec.addresses and address not in spec.addresses:
        raise ScenarioError(f"{where}: a {spec.name} answers at "
                            f"{', '.join(f'0x{a:02x}' for a in spec.addresses)} only, "
                            f"not 0x{address:02x}")
    return StandinConfig(spec, int(address), int(bus))


@dataclass
class Gyro:
    """One emulated gyro of the rig: its place in the list, spec, chip, bus and address."""

    index: int
    spec: GyroSpec
    chip: Any
    bus: Any
    seed: int

    @property
    def address(self) -> int:
        return self.spec.address

    @property
    def name(self) -> str:
        return self.spec.name


@dataclass
class Truth:
    """The truth of one gyro's output samples, one row per sample."""

    times_s: np.ndarray
    rate_dps: np.ndarray  # true body rate
    quaternion: np.ndarray  # true attitude, scalar first, body -> reference
    fault_flags: np.ndarray
    events: list[FaultEvent] = field(default_factory=list)  # fault onsets on this gyro

    def faults_at(self, i: int) -> list[str]:
        return describe_flags(int(self.fault_flags[i]))

    def at(self, t: float) -> int:
        """Index of the last sample at or before ``t`` (-1 if none)."""
        return int(np.searchsorted(self.times_s, t, side="right")) - 1

    def to_array(self) -> np.ndarray:
        """Columns t, wx, wy, wz (deg/s), qw, qx, qy, qz, fault_flags."""
        return np.column_stack([self.times_s, self.rate_dps, self.quaternion, self.fault_flags])


class GyroRig:
    """Gyros on emulated I2C buses, one clock, one master seed, truth out."""

    def __init__(
        self,
        scenario: Scenario,
        gyros: Sequence[GyroSpec] | None = None,
        seed: int = 0,
        faults: FaultSchedule | Iterable[Fault | dict[str, Any]] | None = None,
        q0: np.ndarray = IDENTITY,
        clock: Any = None,
    ) -> None:
        from bmg160_emu.bus.i2c import I2CBus
        from bmg160_emu.clock import VirtualClock

        self.scenario = scenario
        self.seed = int(seed)
        self.q0 = np.asarray(q0, dtype=float)
        if gyros is None:
            base = scenario.source.parent if scenario.source is not None else None
            gyros = [gyro_spec_from_dict(g, i, base) for i, g in enumerate(scenario.gyros)] \
                or [GyroSpec()]
        self.specs = list(gyros)
        places = [(s.bus, s.address) for s in self.specs]
        if len(set(places)) != len(places):
            raise ScenarioError("two gyros at the same bus and address")
        self.clock = clock if clock is not None else VirtualClock()
        children = np.random.SeedSequence(self.seed).spawn(len(self.specs) + 1)
        self.buses: dict[int, Any] = {}
        self.gyros: list[Gyro] = []
        self._times: list[list[float]] = []
        self._rates: list[list[np.ndarray]] = []
        self._truth_cache: dict[int, Truth] = {}
        for index, (spec, child) in enumerate(zip(self.specs, children)):
            chip_seed = int(child.generate_state(1, dtype=np.uint64)[0])
            try:
                chip = make_chip(spec, chip_seed, self.clock, self.seed)
            except ValueError as exc:  # the profile, as the noise engine judges it
                raise ScenarioError(f"{spec.name}: {exc}") from None
            chip.set_true_rate(scenario.rate_dps)
            if scenario.thermal is not None:  # the mission's thermal profile drives every gyro
                chip.set_temperature(scenario.thermal)
            bus = self.buses.get(spec.bus)
            if bus is None:
                bus = self.buses[spec.bus] = I2CBus(spec.bus)
            bus.attach(spec.address, chip)
            gyro = Gyro(index, spec, chip, bus, chip_seed)
            self.gyros.append(gyro)
            self._times.append([])
            self._rates.append([])
            chip.truth_hooks.append(self._truth_hook(index))
        if isinstance(faults, FaultSchedule):
            self.faults = faults
        else:
            fault_list = list(faults) if faults is not None else list(scenario.faults)
            fault_seed = int(children[-1].generate_state(1, dtype=np.uint64)[0])
            self.faults = FaultSchedule(fault_list, seed=fault_seed)
        self.faults.install(self.gyros)
        base = None if scenario.source is None else scenario.source.parent
        self.standins: list[Any] = []  # the [[device]] stand-ins, on the gyros' buses
        for index, entry in enumerate(scenario.devices):
            config = standin_from_dict(entry, index, base)
            if (config.bus, config.address) in places:
                raise ScenarioError(f"device {index + 1}: bus {config.bus} already has a device "
                                    f"at 0x{config.address:02x}")
            places.append((config.bus, config.address))
            device = config.build(clock=self.clock)
            bus = self.buses.get(config.bus)
            if bus is None:
                bus = self.buses[config.bus] = I2CBus(config.bus)
            bus.attach(config.address, device)
            self.standins.append(device)

    def _truth_hook(self, index: int):
        times, rates = self._times[index], self._rates[index]

        def hook(chip: Any, t: float, true_body_rate_dps: Any) -> None:
            times.append(float(t))
            rates.append(np.asarray(true_body_rate_dps, dtype=float))

        return hook

    # ----------------------------------------------------------------- running

    @property
    def time(self) -> float:
        return float(self.clock.now())

    def advance(self, seconds: float) -> None:
        """Move the shared clock on; chips produce their samples as they are next accessed."""
        self.clock.advance(seconds)

    def bus(self, number: int | None = None) -> Any:
        """The I2CBus with that number (the only one when omitted)."""
        if number is None:
            if len(self.buses) != 1:
                raise ValueError(f"the rig has buses {sorted(self.buses)}: say which")
            return next(iter(self.buses.values()))
        return self.buses[number]

    # ----------------------------------------------------------------- truth

    def sample_times(self, gyro: int = 0) -> list[float]:
        """The live list of output sample times of ``gyro`` (grows as samples are made)."""
        return self._times[gyro]

    def truth(self, gyro: int = 0) -> Truth:
        """The truth of every output sample of ``gyro`` produced so far.

        Extended incrementally: asking after every poll costs only the new samples.
        The chip is first brought up to the rig's clock (it makes samples lazily, when next
        accessed), so the truth covers every output period up to now.
        """
        self.gyros[gyro].chip.peek(CHIP_ID)  # no side effect, catches the chip up
        cached = self._truth_cache.get(gyro)
        done = 0 if cached is None else cached.times_s.size
        new_times = np.array(self._times[gyro][done:], dtype=float)
        if cached is not None and new_times.size == 0:
            cached.events = [e for e in self.faults.events if e.gyro in (gyro, None)]
            return cached
        new_rates = np.array(self._rates[gyro][done:], dtype=float).reshape(-1, 3)
        if cached is None or done == 0:
            q_start, t_start = self.q0, 0.0
        else:
            q_start, t_start = cached.quaternion[-1], float(cached.times_s[-1])
        if new_times.size:
            new_q = integrate_attitude(self.scenario.rate_dps, new_times, q_start, t0=t_start)
        else:
            new_q = np.zeros((0, 4))
        new_flags = np.array([self.faults.flags_at(gyro, t) for t in new_times], dtype=np.int64)
        if cached is None:
            truth = Truth(new_times, new_rates, new_q, new_flags)
        else:
            truth = Truth(np.concatenate([cached.times_s, new_times]),
                          np.concatenate([cached.rate_dps, new_rates]),
                          np.concatenate([cached.quaternion, new_q]),
                          np.concatenate([cached.fault_flags, new_flags]))
        truth.events = [e for e in self.faults.events if e.gyro in (gyro, None)]
        self._truth_cache[gyro] = truth
        return truth

    def attitude_at(self, t: float) -> np.ndarray:
        """The true attitude at any time ``t`` (integrated from 0)."""
        return integrate_attitude(self.scenario.rate_dps, np.array([t]), self.q0, t0=0.0)[0]


def chip_config(spec: GyroSpec, rig_seed: int = 0) -> ChipConfig:
    """The chip options of one gyro spec (error terms only when they are not zero)."""
    errors = spec.errors
    if spec.unit is not None:
        from bmg160_emu.device.unit_population import draw_unit

        errors = draw_unit(spec.lot, rig_seed if spec.unit == "per-run" else spec.unit)
    return ChipConfig(
        errors=errors,
        acceleration_g=tuple(spec.acceleration_g),
        address=spec.address,
        profile=spec.profile,
        noise=spec.noise,
        noise_mode=spec.noise_mode,
        temperature_c=spec.temperature_c,
        mounting=None if np.allclose(spec.mounting, np.eye(3)) else spec.mounting,
        scale_factor=spec.scale_factor_error if np.any(spec.scale_factor_error) else None,
        misalignment=spec.misalignment_rad if np.any(spec.misalignment_rad) else None,
        part=spec.part,
    )


def make_chip(spec: GyroSpec, seed: int, clock: Any, rig_seed: int = 0) -> Any:
    """The chip model for one gyro spec, built through its :class:`ChipConfig`."""
    return chip_config(spec, rig_seed).build(seed, clock)
