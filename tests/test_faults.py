"""Fault schedule: triggers and effects, on stand-ins for the chip and the bus.

The stand-ins call the hooks exactly as docs/architecture.md specifies (sample hooks per
output sample, transaction hooks before each transaction), so these tests pin the schedule's
own logic; tests/test_faults_on_chip.py runs the same faults against the real model.
"""

from __future__ import annotations

import errno
from dataclasses import dataclass, field

import numpy as np
import pytest

from bmg160_emu.adcs.faults import (
    FAULT_FLAGS,
    SATURATED_DPS,
    Fault,
    FaultError,
    FaultSchedule,
    describe_flags,
    fault_from_dict,
)


class StubClock:
    def __init__(self):
        self.t = 0.0

    def now(self) -> float:
        return self.t

    def advance(self, seconds: float) -> None:
        self.t += seconds


class StubChip:
    def __init__(self, clock: StubClock):
        self.clock = clock
        self.sample_hooks: list = []
        self.registers = bytearray(64)
        self.registers[0x0F] = 0x02
        self.temperature_c = 23.0
        self.resets = 0

    def peek(self, reg: int) -> int:
        return self.registers[reg]

    def poke(self, reg: int, value: int) -> None:
        self.registers[reg] = value

    def power_on_reset(self) -> None:
        self.resets += 1
        self.registers[0x0F] = 0x00

    def sample(self, t: float, rate) -> np.ndarray | None:
        out = np.asarray(rate, dtype=float)
        for hook in self.sample_hooks:
            out = hook(self, t, out)
            if out is None:
                return None
        return out


class StubBus:
    def __init__(self):
        self.transaction_hooks: list = []
        self.count = 0

    def transact(self, address: int) -> str:
        index = self.count
        self.count += 1
        try:
            for hook in self.transaction_hooks:
                hook(self, index, address, "read_i2c_block_data")
        except OSError as exc:
            return errno.errorcode[exc.errno]
        return "ok"


@dataclass
class StubGyro:
    index: int
    chip: StubChip
    bus: StubBus
    address: int = 0x68
    extra: dict = field(default_factory=dict)


def _rig(faults, n=1, seed=0):
    clock = StubClock()
    bus = StubBus()
    gyros = [StubGyro(i, StubChip(clock), bus, 0x68 + i) for i in range(n)]
    schedule = FaultSchedule(faults, seed=seed)
    schedule.install(gyros)
    return clock, bus, gyros, schedule


def test_nack_on_the_nth_transaction_fails_that_one_only():
    _, bus, _, schedule = _rig([Fault("nack", on_transaction=3)])
    results = [bus.transact(0x68) for _ in range(6)]
    assert results == ["ok", "ok", "ok", "EREMOTEIO", "ok", "ok"]
    assert [(e.kind, e.transaction) for e in schedule.events] == [("nack", 3)]


def test_timeout_for_a_duration_fails_every_transaction_in_the_window_and_stalls_time():
    clock, bus, _, _ = _rig([Fault("timeout", at_s=1.0, duration_s=0.5, stall_s=0.2)])
    outcomes = []
    for _ in range(20):
        outcomes.append((clock.now(), bus.transact(0x68)))
        clock.advance(0.1)
    failed = [t for t, r in outcomes if r == "ETIMEDOUT"]
    assert failed and min(failed) >= 1.0 and max(failed) < 1.5
    assert all(r == "ok" for t, r in outcomes if t < 1.0 or t >= 1.5)
    # each timed-out transfer took stall_s of virtual time
    assert outcomes[-1][0] == pytest.approx(1.9 + 0.2 * len(failed))


def test_probability_per_transaction_is_seeded_and_near_p():
    def failures(seed):
        _, bus, _, _ = _rig([Fault("nack", probability=0.1)], seed=seed)
        return [bus.transact(0x68) == "EREMOTEIO" for _ in range(4000)]

    first = failures(11)
    assert failures(11) == first
    assert failures(12) != first
    # binomial(4000, 0.1): sd = sqrt(4000 * 0.1 * 0.9) = 19; accept 5 sd
    assert abs(sum(first) - 400) < 95


def test_a_bus_fault_aimed_at_one_gyro_spares_the_other_address():
    _, bus, _, _ = _rig([Fault("nack", probability=1.0, gyro=1)], n=2)
    assert bus.transact(0x68) == "ok"
    assert bus.transact(0x69) == "EREMOTEIO"


def test_stuck_axis_repeats_its_last_value_for_its_duration():
    _, _, (gyro,), schedule = _rig([Fault("stuck_axis", at_s=0.02, axis="y", duration_s=0.02)])
    outputs = [gyro.chip.sample(k * 0.005, [k, 10 + k, 20 + k]) for k in range(10)]
    ys = [o[1] for o in outputs]
    assert ys == [10, 11, 12, 13, 13, 13, 13, 13, 18, 19]
    assert [o[0] for o in outputs] == list(range(10))  # other axes untouched
    assert schedule.flags_at(0, 0.025) == FAULT_FLAGS["stuck_axis"]
    assert schedule.flags_at(0, 0.04) == 0
    assert [e.kind for e in schedule.events] == ["stuck_axis"]


def test_bias_step_spike_and_saturation_change_the_rate_as_described():
    faults = [
        Fault("bias_step", at_s=0.01, step_dps=0.5),
        Fault("spike", at_s=0.02, axis=0, amplitude_dps=100.0, samples=2),
        Fault("saturation", at_s=0.03, axis=2, amplitude_dps=-1.0, duration_s=0.01),
    ]
    _, _, (gyro,), schedule = _rig(faults)
    out = np.array([gyro.chip.sample(k * 0.005, [1.0, 2.0, 3.0]) for k in range(10)])
    assert np.allclose(out[:2], [1.0, 2.0, 3.0])
    assert np.allclose(out[2:4], [1.5, 2.5, 3.5])
    assert np.allclose(out[4:6, 0], 101.5)
    assert out[6, 0] == pytest.approx(1.5)
    assert np.all(out[6:8, 2] == -SATURATED_DPS)
    assert out[8, 2] == pytest.approx(3.5)
    assert describe_flags(schedule.flags_at(0, 0.03)) == ["bias_step", "saturation"]


def test_lost_samples_drop_k_periods():
    _, _, (gyro,), schedule = _rig([Fault("lost_samples", at_s=0.01, samples=3)])
    out = [gyro.chip.sample(k * 0.005, [0.0, 0.0, 0.0]) for k in range(8)]
    assert [o is None for o in out] == [False, False, True, True, True, False, False, False]
    assert schedule.flags_at(0, 0.015) == FAULT_FLAGS["lost_samples"]


def test_seu_flips_one_bit_and_brownout_resets_at_the_first_transaction_after_their_time():
    clock, bus, (gyro,), schedule = _rig(
        [Fault("seu", at_s=0.5, register=0x0F, bit=2), Fault("brownout", on_transaction=5)]
    )
    bus.transact(0x68)
    assert gyro.chip.peek(0x0F) == 0x02
    clock.advance(0.6)
    bus.transact(0x68)
    assert gyro.chip.peek(0x0F) == 0x06
    bus.transact(0x68)
    assert gyro.chip.peek(0x0F) == 0x06  # one flip only
    while bus.count < 6:
        bus.transact(0x68)
    assert gyro.chip.resets == 1
    assert [(e.kind, e.transaction) for e in schedule.events] == [("seu", 1), ("brownout", 5)]
    assert "0x02 -> 0x06" in schedule.events[0].detail


def test_temperature_ramp_moves_the_die_temperature_and_the_bias_with_its_coefficient():
    fault = Fault("temperature_ramp", at_s=1.0, rate_c_per_s=0.5, duration_s=10.0,
                  tc_bias_dps_per_c=[0.01, 0.0, -0.02])
    _, _, (gyro,), _ = _rig([fault])
    assert np.allclose(gyro.chip.sample(0.5, [0, 0, 0]), 0.0)
    out = gyro.chip.sample(5.0, [0, 0, 0])  # 4 s into the ramp: +2 degC
    assert gyro.chip.temperature_c == pytest.approx(25.0)
    assert np.allclose(out, [0.02, 0.0, -0.04])
    out = gyro.chip.sample(20.0, [0, 0, 0])  # ramp over: holds +5 degC
    assert gyro.chip.temperature_c == pytest.approx(28.0)
    assert np.allclose(out, [0.05, 0.0, -0.1])


def test_faults_from_scenario_tables_and_their_errors():
    assert fault_from_dict({"kind": "stuck_axis", "at_s": 1.0, "axis": "z"}).axis == 2
    assert Fault("nack").at_s == 0.0  # no trigger: from the start
    with pytest.raises(FaultError, match="give one trigger .* on_register and address narrow"):
        Fault("nack", at_s=1.0, probability=0.5)
    with pytest.raises(FaultError, match="needs an axis"):
        Fault("stuck_axis", at_s=1.0)
    with pytest.raises(FaultError, match="kind must be one of"):
        Fault("meteor", at_s=1.0)
    with pytest.raises(FaultError, match="probability must be within"):
        Fault("nack", probability=2.0)
    with pytest.raises(FaultError, match="register must be"):
        Fault("seu", at_s=0.0, register=0x40)
    with pytest.raises(FaultError, match="fault 2: unknown key when; a nack fault takes kind, "
                                         "at_s, on_transaction, probability, on_register"):
        fault_from_dict({"kind": "nack", "at_s": 1, "when": 3}, "fault 2")
    with pytest.raises(FaultError, match="a nack fault takes no register .to select "
                                         "transactions naming a register, give on_register"):
        fault_from_dict({"kind": "nack", "register": 0x0F})
    with pytest.raises(FaultError, match="a brownout fault takes no axis; it takes kind"):
        fault_from_dict({"kind": "brownout", "axis": "x"})
    with pytest.raises(FaultError, match="gyro 3 does not exist"):
        _rig([Fault("nack", at_s=1.0, gyro=3)])


@pytest.mark.parametrize(
    "entry, message",
    [
        ({"kind": "bias_step", "at_s": "3"}, "at_s must be a finite number"),
        ({"kind": "bias_step", "at_s": float("nan")}, "at_s must be a finite number"),
        ({"kind": "nack", "probability": "0.1"}, "probability must be a finite number"),
        ({"kind": "spike", "at_s": 1.0, "amplitude_dps": "5"}, "amplitude_dps must be a finite"),
        ({"kind": "timeout", "at_s": 1.0, "stall_s": "x"}, "stall_s must be a finite number"),
        ({"kind": "nack", "on_transaction": 1.5}, "on_transaction must be a whole number"),
        ({"kind": "nack", "at_s": 1.0, "gyro": True}, "gyro must be a whole number"),
        ({"kind": "seu", "at_s": 1.0, "register": "0x0F"}, "register must be a whole number"),
        ({"kind": "temperature_ramp", "at_s": 1.0, "tc_bias_dps_per_c": [1.0, 2.0]},
         "tc_bias_dps_per_c must be one number or 3"),
        ({"kind": "nack", "probability": 0.1, "max_count": 0}, "max_count must be"),
    ],
)
def test_fault_parameters_of_the_wrong_type_are_refused_by_name(entry, message):
    # a TOML value in quotes or a fraction where a count is meant would otherwise be kept
    # and fail later, mid-run, with a Python error (or never fire at all)
    with pytest.raises(FaultError, match=message):
        fault_from_dict(entry)
