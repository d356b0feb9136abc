"""pytest fixtures for testing driver code against the emulated BMG160.

Registered as the ``pytest11`` entry point ``bmg160_emu``, so installing the package is enough:

    def test_driver_reads_chip_id(bmg160_smbus):
        from mydriver import Gyro            # builds smbus2.SMBus(1) itself
        assert Gyro(bus=1).chip_id() == 0x0F

Fixtures: ``bmg160_chip`` (a fresh chip), ``bmg160_smbus`` (``patch_smbus`` active with the
chip at 0x68 on bus 1; gives the ``I2CBus`` with its transaction log), ``fake_smbus`` (a
``FakeSMBus`` on that chip), ``bmg160_spidev`` (``patch_spidev`` with the chip at
/dev/spidev0.0), ``fake_spidev`` (a ``FakeSpiDev`` on the chip) and ``bmg160_virtual_sleep``
(``time.sleep`` advances the chip's virtual clock).

Chip options come from the ``bmg160`` marker: ``@pytest.mark.bmg160(seed=3, noise=False,
bus=2, address=0x69)``; every keyword except ``bus`` goes to ``BMG160``.
"""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

import pytest

DEFAULT_BUS = 1
DEFAULT_SEED = 7


def pytest_configure(config: pytest.Config) -> None:
    config.addinivalue_line(
        "markers",
        "bmg160(**options): options of the emulated BMG160 for the bmg160_emu fixtures "
        "(BMG160 keywords, plus bus= for the I2C bus number)",
    )


def _options(request: pytest.FixtureRequest) -> dict[str, Any]:
    marker = request.node.get_closest_marker("bmg160")
    options: dict[str, Any] = {"seed": DEFAULT_SEED}
    if marker is not None:
        if marker.args:
            raise pytest.UsageError("@pytest.mark.bmg160 takes keyword options only")
        options.update(marker.kwargs)
    return options


@pytest.fixture
def bmg160_chip(request: pytest.FixtureRequest) -> Any:
    """A fresh BMG160 (seed 7 unless the ``bmg160`` marker says otherwise)."""
    from bmg160_emu.device.chip import BMG160

    options = _options(request)
    options.pop("bus", None)
    return BMG160(**options)


@pytest.fixture
def bmg160_smbus(request: pytest.FixtureRequest, bmg160_chip: Any) -> Iterator[Any]:
    """``patch_smbus`` with the chip on the I2C bus (1 by default); yields the ``I2CBus``."""
    from bmg160_emu.bus.patching import patch_smbus

    number = _options(request).get("bus", DEFAULT_BUS)
    with patch_smbus({number: {bmg160_chip.address: bmg160_chip}}) as buses:
        yield buses[number]


@pytest.fixture
def fake_smbus(bmg160_smbus: Any) -> Iterator[Any]:
    """A ``FakeSMBus`` open on the patched bus."""
    from bmg160_emu.bus.smbus import FakeSMBus

    with FakeSMBus(bmg160_smbus.number) as bus:
        yield bus


@pytest.fixture
def bmg160_spidev(bmg160_chip: Any) -> Iterator[Any]:
    """``patch_spidev`` with the chip at /dev/spidev0.0; yields the chip."""
    from bmg160_emu.bus.patching import patch_spidev

    with patch_spidev({(0, 0): bmg160_chip}):
        yield bmg160_chip


@pytest.fixture
def fake_spidev(bmg160_chip: Any) -> Iterator[Any]:
    """A ``FakeSpiDev`` open on the chip."""
    from bmg160_emu.bus.spi import FakeSpiDev

    with FakeSpiDev(bmg160_chip) as spi:
        yield spi


@pytest.fixture
def bmg160_virtual_sleep(bmg160_chip: Any) -> Iterator[Any]:
    """``time.sleep(s)`` advances the chip's virtual clock by s; yields the clock."""
    from bmg160_emu.clock import virtual_sleep

    with virtual_sleep(bmg160_chip) as clock:
        yield clock
