"""patch_spidev: code that builds spidev.SpiDev reaches the chip (spidev need not exist)."""

from __future__ import annotations

import importlib
import sys

import pytest
from _standin_chip import RegisterFileChip

from bmg160_emu.bus.patching import patch_spidev


def test_spidev_spidev_reaches_the_chip_and_the_module_goes_away_after():
    had_spidev = importlib.util.find_spec("spidev") is not None
    chip = RegisterFileChip(bytes([0x0F]) + bytes(63))
    with patch_spidev({(0, 0): chip}):
        import spidev

        dev = spidev.SpiDev(0, 0)
        assert dev.xfer2([0x80, 0x00]) == [0x00, 0x0F]
        other = spidev.SpiDev()
        other.open(0, 0)
        assert other.readbytes(1) == [0x00]
        with pytest.raises(FileNotFoundError):
            spidev.SpiDev(1, 0)
    if not had_spidev:
        assert "spidev" not in sys.modules


def test_device_keys_must_be_bus_device_pairs():
    with pytest.raises(TypeError):
        patch_spidev({0: RegisterFileChip()})
