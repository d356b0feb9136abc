"""The chip's state object and the narrow interface around it (docs/architecture.md, "Inside
the chip"): the chip's public names stay its documented API plus ``state``; the state is the
object the hooks get; the strict log still reaches the documented logger; a VirtualClock's
time is its public ``ns``."""

from __future__ import annotations

import logging
from dataclasses import replace

import pytest

from bmg160_emu.clock import VirtualClock
from bmg160_emu.device.chip import BMG160
from bmg160_emu.device.part_spec import BMG160_PART
from bmg160_emu.device.registers import address_of
from bmg160_emu.device.state import ChipState

# BMG160's public names: the primitives, inputs and views of docs/architecture.md and
# docs/device-model.md, the hook lists, and ``state`` (for the chip's parts and white-box
# tests). A name added here is a change of the chip's API: document it first.
PUBLIC = {
    "address", "advance", "clock", "dump", "hold_data_int", "i2c_read", "i2c_write",
    "inject_bist_failure", "int1", "int2", "int_pin_level", "lock", "next_pin_change_ns",
    "nvm_image", "odr_hz",
    "offset_lsb_dps", "offsets_lsb", "part", "peek", "pointer", "poke", "power_mode",
    "power_on_reset", "queue_true_rate", "read", "sample_hooks", "seed", "sensitivity",
    "sensitivity_table", "sensor_errors", "set_acceleration", "set_temperature",
    "set_true_rate", "soft_reset", "state", "stream_true_rate", "strict", "strict_log", "time",
    "truth_hooks", "turn_on_bias_dps", "virtual_clock", "write",
}


def test_the_chip_public_names_are_its_documented_api():
    chip = BMG160(seed=1)
    assert {name for name in dir(chip) if not name.startswith("_")} == PUBLIC


def test_the_register_hooks_get_the_state(monkeypatch):
    chip = BMG160(seed=1, noise=False)
    chip.advance(0.02)  # samples: bypass mode holds the newest one (6.5)
    status = address_of("FIFO_STATUS")
    hook = BMG160_PART.peek_at[status]
    assert hook is not None
    seen = []

    def spy(s, now):
        seen.append(s)
        return hook(s, now)

    peek_at = list(BMG160_PART.peek_at)
    peek_at[status] = spy
    monkeypatch.setattr(chip.state, "part", replace(BMG160_PART, peek_at=tuple(peek_at)))
    assert chip.peek(status) == 1  # one frame (6.5: fifo_frame_counter)
    assert seen == [chip.state] and isinstance(seen[0], ChipState)


def test_the_state_takes_no_attribute_it_does_not_declare():
    chip = BMG160(seed=1)
    with pytest.raises(AttributeError):
        chip.state.next_sample_ns = 0  # a typo of next_ns must not pass silently


def test_strict_mode_logs_to_the_chip_logger(caplog):
    chip = BMG160(seed=1, strict=True)
    with caplog.at_level(logging.WARNING, logger="bmg160_emu.device.chip"):
        chip.write(0x0F, b"\x00\x00")  # a multi-byte write (spec 2.1)
    assert [r.name for r in caplog.records] == ["bmg160_emu.device.chip"]
    assert "multi-byte write" in chip.strict_log[0]
    assert chip.strict_log[0] in caplog.records[0].getMessage()


def test_a_virtual_clock_time_is_its_public_ns():
    clock = VirtualClock(start_s=1.5)
    chip = BMG160(seed=1, clock=clock)
    assert clock.ns == clock.now_ns() == 1_500_000_000
    chip.advance(0.25)  # the chip moves the shared clock's ns in place (its inlined advance)
    assert clock.ns == 1_750_000_000 and chip.time == 1.75
    clock.advance(0.25)
    assert chip.time == clock.now() == 2.0
