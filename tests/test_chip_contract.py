"""The chip contract: every device behind the buses offers the same primitives."""

from __future__ import annotations

import inspect

from _standin_chip import RegisterFileChip

from bmg160_emu.device.chip import BMG160
from bmg160_emu.device.contract import PRIMITIVES, RegisterDevice
from bmg160_emu.firmware.simulated import SimulatedFirmwareChip


def test_the_model_and_the_stand_in_are_register_devices():
    assert isinstance(BMG160(seed=1), RegisterDevice)
    assert isinstance(RegisterFileChip(), RegisterDevice)


def test_the_simulated_firmware_has_every_primitive():
    # building it needs avr-gcc and simavr: check the class, and `time` as a property
    for name in PRIMITIVES:
        assert callable(getattr(SimulatedFirmwareChip, name)), name
    assert isinstance(inspect.getattr_static(SimulatedFirmwareChip, "time"), property)


def test_an_object_missing_a_primitive_is_not_a_register_device():
    class NoPeek:
        def __init__(self) -> None:
            self._inner = RegisterFileChip()
            self.lock = self._inner.lock
            self.time = 0.0

        def __getattr__(self, name):
            if name == "peek":
                raise AttributeError(name)
            return getattr(self._inner, name)

    assert not isinstance(NoPeek(), RegisterDevice)
    assert not isinstance(object(), RegisterDevice)


def test_the_gyros_are_rate_sensors_and_a_stand_in_is_not():
    # what run --watch, a script's default chip, dump --format json and the kernel route ask
    from bmg160_emu.device.contract import RateSensor
    from bmg160_emu.device.parts import PART_NAMES, make_chip
    from bmg160_emu.device.standin import StandinDevice
    from bmg160_emu.io.standin_file import load_standin

    for part in PART_NAMES:
        assert isinstance(make_chip(part, seed=1), RateSensor), part
    assert callable(SimulatedFirmwareChip.set_true_rate)  # the firmware (without simavr)
    standin = StandinDevice(load_standin("bmm150"), address=0x10)
    assert isinstance(standin, RegisterDevice) and not isinstance(standin, RateSensor)
    assert not isinstance(RegisterFileChip(), RateSensor)


def test_the_gyros_drive_interrupt_pins_and_a_stand_in_does_not():
    # what serve asks before it carries a device's INT1/INT2 levels as events
    from bmg160_emu.device.contract import InterruptPins
    from bmg160_emu.device.parts import PART_NAMES, make_chip
    from bmg160_emu.device.standin import StandinDevice
    from bmg160_emu.io.standin_file import load_standin

    for part in PART_NAMES:
        chip = make_chip(part, seed=1)
        assert isinstance(chip, InterruptPins), part
        assert chip.int_pin_level(1) in (0, 1)
    assert not isinstance(StandinDevice(load_standin("bmm150"), address=0x10), InterruptPins)
    assert not isinstance(RegisterFileChip(), InterruptPins)
