"""patch_smbus and patch_spidev: unmodified driver code reaches the emulated chips.

``patch_smbus({1: {0x68: chip}})`` is the in-process ``/dev/i2c-N``
(:class:`~bmg160_emu.bus.i2c_dev_node.patch_i2c_dev`) plus the legacy ``smbus`` module: it
leaves ``smbus2.SMBus`` (and smbus3, Adafruit_PureIO, periphery) alone and emulates the
kernel below them, so every way a driver can hold the class (``import smbus2``, ``from smbus2
import SMBus``, a subclass, an ``isinstance`` check) works, and the library's own argument
handling is the real one. Other device paths still reach the real kernel. The legacy
``smbus`` module (python-smbus, a C extension that the in-process node cannot reach) gets a
``LegacySMBus`` class; a ``smbus`` module is injected if none is installed.

``patch_spidev({(0, 0): chip})`` replaces ``spidev.SpiDev`` with ``FakeSpiDev`` (spidev is a C
extension; it is usually not installed, then a ``spidev`` module is injected).
"""

from __future__ import annotations

import operator
import sys
import types
from collections.abc import Mapping
from contextlib import ContextDecorator
from typing import Any

from bmg160_emu.bus.i2c import I2C_SMBUS_BLOCK_MAX, I2CBus
from bmg160_emu.bus.i2c_dev_node import I2cDevKernel, buses_from_mapping, patch_i2c_dev
from bmg160_emu.bus.smbus import FakeSMBus, check_block_count
from bmg160_emu.bus.spi import FakeSpiDev, register_spi_device, unregister_spi_device

__all__ = ["I2cDevKernel", "LegacySMBus", "patch_i2c_dev", "patch_smbus", "patch_spidev"]

_LEGACY_LIST_MESSAGE = (
    "Third argument must be a list of at least one, but not more than 32 integers"
)


def _legacy_list(values: Any) -> list[int]:
    """python-smbus's block argument rules: a list (TypeError otherwise) of at most 32 ints
    (OverflowError), each truncated to 8 bits."""
    if not isinstance(values, list):
        raise TypeError(_LEGACY_LIST_MESSAGE)
    if len(values) > I2C_SMBUS_BLOCK_MAX:
        raise OverflowError(_LEGACY_LIST_MESSAGE)
    if not all(isinstance(v, int) for v in values):
        raise TypeError(_LEGACY_LIST_MESSAGE)
    return [v & 0xFF for v in values]


class LegacySMBus(FakeSMBus):
    """python-smbus's ``smbus.SMBus([bus])`` over the emulated buses (its C module's rules):
    ``read_i2c_block_data(addr, cmd, len=32)`` with lengths above 32 failing in the kernel
    (EINVAL), block arguments that must be lists of at most 32 ints, a boolean ``pec``."""

    def __init__(self, bus: int = -1) -> None:
        super().__init__(None if bus is None or (isinstance(bus, int) and bus < 0) else bus)

    def read_i2c_block_data(  # type: ignore[override]
        self, addr: int, cmd: int, len: int = 32
    ) -> list[int]:
        self._set_address(addr)
        count = operator.index(len) & 0xFF
        check_block_count(count)
        data = self._bus().read_i2c_block_data(self._client, operator.index(cmd) & 0xFF, count)
        return list(data)

    def write_i2c_block_data(self, addr: int, cmd: int, vals: Any) -> None:  # type: ignore[override]
        super().write_i2c_block_data(addr, cmd, _legacy_list(vals))

    def write_block_data(self, addr: int, cmd: int, vals: Any) -> None:  # type: ignore[override]
        super().write_block_data(addr, cmd, _legacy_list(vals))

    def block_process_call(self, addr: int, cmd: int, vals: Any) -> list[int]:  # type: ignore[override]
        return super().block_process_call(addr, cmd, _legacy_list(vals))

    @property
    def pec(self) -> bool:  # type: ignore[override]
        return bool(self._pec)

    @pec.setter
    def pec(self, value: Any) -> None:
        self.enable_pec(bool(value))


def _swap_references(old: Any, new: Any, skip: set[str]) -> list[tuple[Any, str, Any]]:
    """Point every module attribute that is ``old`` at ``new``; returns what to restore."""
    changed = []
    for name, module in list(sys.modules.items()):
        if module is None or name in skip:
            continue
        namespace = getattr(module, "__dict__", None)
        if not isinstance(namespace, dict):
            continue
        for attr, value in list(namespace.items()):
            if value is old:
                namespace[attr] = new
                changed.append((module, attr, old))
    return changed


class _ModulePatch:
    """Install ``cls`` as ``module_name.class_name``: inject the module if it is missing, else
    replace the class there and in every module that imported it by name."""

    def __init__(self, module_name: str, class_name: str, cls: type) -> None:
        self.module_name, self.class_name, self.cls = module_name, class_name, cls
        self.injected: types.ModuleType | None = None
        self.restore: list[tuple[Any, str, Any]] = []

    def __enter__(self) -> None:
        try:
            module = __import__(self.module_name)
        except ImportError:
            module = None
        if module is None or getattr(module, "__bmg160_emu_injected__", False):
            if module is None:
                module = types.ModuleType(
                    self.module_name, f"{self.module_name} emulated by bmg160_emu"
                )
                module.__bmg160_emu_injected__ = True  # type: ignore[attr-defined]
                sys.modules[self.module_name] = module
                self.injected = module
            self.restore.append((module, self.class_name, getattr(module, self.class_name, None)))
            setattr(module, self.class_name, self.cls)
            return
        original = getattr(module, self.class_name)
        self.restore = _swap_references(original, self.cls, skip=set())

    def __exit__(self, *exc: object) -> None:
        for namespace_owner, attr, old in reversed(self.restore):
            if old is None:
                namespace_owner.__dict__.pop(attr, None)
            else:
                setattr(namespace_owner, attr, old)
        self.restore = []
        if self.injected is not None and sys.modules.get(self.module_name) is self.injected:
            del sys.modules[self.module_name]
        self.injected = None


class patch_smbus(ContextDecorator):
    """Context manager (and decorator): ``smbus2.SMBus(n)``, ``smbus.SMBus(n)``,
    ``FakeSMBus(n)`` and every other pure-Python stack's ``/dev/i2c-n`` reach the emulated
    buses ``{n: {address: chip}}`` (or ``{n: I2CBus}``): :class:`patch_i2c_dev` plus the
    legacy ``smbus`` module.

    ``with patch_smbus({1: {0x68: chip}}) as buses:`` gives ``{1: I2CBus}`` (logs, hooks).
    """

    def __init__(
        self, buses: Mapping[int, Mapping[int, Any] | I2CBus], *, legacy: bool = True
    ) -> None:
        self._node = patch_i2c_dev(buses_from_mapping(buses, "patch_smbus"))
        self.buses: dict[int, I2CBus] = self._node.buses
        self.legacy = legacy
        self._legacy_patch: _ModulePatch | None = None

    def __enter__(self) -> dict[int, I2CBus]:
        buses = self._node.__enter__()
        if self.legacy:
            try:
                self._legacy_patch = _ModulePatch("smbus", "SMBus", LegacySMBus)
                self._legacy_patch.__enter__()
            except BaseException:
                self._node.__exit__(None, None, None)
                raise
        return buses

    def __exit__(self, *exc: object) -> None:
        try:
            if self._legacy_patch is not None:
                self._legacy_patch.__exit__(*exc)
                self._legacy_patch = None
        finally:
            self._node.__exit__(*exc)


class patch_spidev(ContextDecorator):
    """Context manager (and decorator): ``spidev.SpiDev(bus, device)`` and
    ``open(bus, device)`` reach ``{(bus, device): chip}``; yields that mapping."""

    def __init__(self, devices: Mapping[tuple[int, int], Any]) -> None:
        if not isinstance(devices, Mapping):
            raise TypeError("patch_spidev wants {(bus, device): chip}")
        self.devices = {}
        for key, chip in devices.items():
            if not (
                isinstance(key, tuple) and len(key) == 2 and all(isinstance(k, int) for k in key)
            ):
                raise TypeError(f"spidev device key must be (bus, device), not {key!r}")
            self.devices[key] = chip
        self._patch: _ModulePatch | None = None

    def __enter__(self) -> dict[tuple[int, int], Any]:
        for (bus, device), chip in self.devices.items():
            register_spi_device(bus, device, chip)
        self._patch = _ModulePatch("spidev", "SpiDev", FakeSpiDev)
        self._patch.__enter__()
        return dict(self.devices)

    def __exit__(self, *exc: object) -> None:
        if self._patch is not None:
            self._patch.__exit__(*exc)
            self._patch = None
        for (bus, device), chip in self.devices.items():
            unregister_spi_device(bus, device, chip)
