"""patch_smbus and patch_spidev: unmodified driver code reaches the emulated chips.

``patch_smbus({1: {0x68: chip}})`` leaves ``smbus2.SMBus`` itself alone and emulates the
kernel below it: smbus2's ``os.open`` of /dev/i2c-1 and its ``ioctl`` calls are routed to an
``I2CBus``. So every way a driver can hold the class (``import smbus2``, ``from smbus2 import
SMBus``, a subclass, an ``isinstance`` check) works, and smbus2's own argument handling is the
real one. Other device paths still reach the real kernel. The legacy ``smbus`` module
(python-smbus) gets a ``LegacySMBus`` class; a ``smbus`` module is injected if none is
installed.

``patch_spidev({(0, 0): chip})`` replaces ``spidev.SpiDev`` with ``FakeSpiDev`` (spidev is a C
extension; it is usually not installed, then a ``spidev`` module is injected).
"""

from __future__ import annotations

import ctypes
import errno
import fcntl
import operator
import os
import struct
import sys
import threading
import types
from collections.abc import Mapping
from contextlib import ContextDecorator
from typing import Any

from bmg160_emu.bus.i2c import (
    I2C_SMBUS_BLOCK_MAX,
    I2CBus,
    emulated_bus_for_path,
    os_error,
    register_bus,
    unregister_bus,
)
from bmg160_emu.bus.i2c_dev import ULONG_MASK, I2CDevFile
from bmg160_emu.bus.smbus import FakeSMBus
from bmg160_emu.bus.spi import FakeSpiDev, register_spi_device, unregister_spi_device

__all__ = ["I2cDevKernel", "LegacySMBus", "patch_smbus", "patch_spidev"]

IOCTL_BUFSZ = 1024  # CPython's fcntl.ioctl copies a buffer argument through 1024 bytes
USER_POINTER = 0x7FFF_0000_0000  # what the kernel sees as the argument when it is a buffer


def _c_int(value: int) -> int:
    """fcntl.ioctl passes an integer argument as a C int."""
    if value > 0x7FFFFFFF:
        raise OverflowError("signed integer is greater than maximum")
    if value < -0x80000000:
        raise OverflowError("signed integer is less than minimum")
    return value


_POINTER = struct.Struct("=Q")
_CHAR_ARRAYS: dict[int, Any] = {}  # size -> ctypes.c_char * size (building a type is slow)


class _AddressMemory:
    """Memory of this process at an address, reached as the kernel reaches user memory."""

    __slots__ = ("address", "cells")

    def __init__(self, address: int, size: int) -> None:
        array = _CHAR_ARRAYS.get(size)
        if array is None:
            array = _CHAR_ARRAYS.setdefault(size, ctypes.c_char * size)
        self.address, self.cells = address, array.from_address(address)

    def read(self) -> bytes:
        return self.cells.raw

    def write(self, data: bytes) -> None:
        self.cells.raw = data[: len(self.cells)]

    def follow(self, offset: int, size: int) -> _AddressMemory:
        return _pointee(ctypes.c_uint64.from_address(self.address + offset).value, size)


class _BufferMemory:
    """A buffer given to ``fcntl.ioctl``: the memory the argument points to."""

    __slots__ = ("size", "view")

    def __init__(self, view: memoryview, size: int) -> None:
        self.view, self.size = view, size

    def read(self) -> bytes:
        view, size = self.view, self.size
        if len(view) == size:
            return bytes(view)
        return view[:size].tobytes().ljust(size, b"\0")  # beyond it: fcntl's zeroed copy

    def write(self, data: bytes) -> None:
        n = min(len(data), len(self.view))
        self.view[:n] = data[:n]

    def follow(self, offset: int, size: int) -> _AddressMemory:
        raw = self.view[offset : offset + 8].tobytes().ljust(8, b"\0")
        return _pointee(_POINTER.unpack(raw)[0], size)


def _pointee(address: int, size: int) -> _AddressMemory:
    if address == 0:
        raise os_error(errno.EFAULT)
    return _AddressMemory(address, size)


class _IoctlArgument:
    """``fcntl.ioctl``'s third argument as i2c-dev sees it: an integer, or a pointer to a
    buffer (a ctypes structure, a bytearray)."""

    __slots__ = ("number", "view")

    def __init__(self, number: int | None, view: memoryview | None) -> None:
        self.number, self.view = number, view

    @property
    def value(self) -> int:
        return USER_POINTER if self.number is None else self.number & ULONG_MASK

    def memory(self, size: int) -> _AddressMemory | _BufferMemory:
        if self.view is not None:
            return _BufferMemory(self.view, size)
        return _pointee(self.value, size)


class I2cDevKernel:
    """The i2c-dev character device for smbus2: ``open``/``close`` of emulated device paths,
    and ``fcntl.ioctl`` on their descriptors marshalled to :class:`~bmg160_emu.bus.i2c_dev.I2CDevFile`
    (argument conversions and buffer copies as CPython's fcntl makes them)."""

    def __init__(self) -> None:
        self.files: dict[int, I2CDevFile] = {}
        self.lock = threading.Lock()

    def open(self, path: Any, flags: int, mode: int = 0o777, *, dir_fd: int | None = None) -> int:
        text = os.fsdecode(path) if isinstance(path, (str, bytes, os.PathLike)) else None
        bus = emulated_bus_for_path(text) if text is not None else None
        if bus is None:
            return os.open(path, flags, mode, dir_fd=dir_fd)
        fd = os.open(os.devnull, os.O_RDWR)  # a real, unique descriptor number
        with self.lock:
            self.files[fd] = I2CDevFile(bus)
        return fd

    def close(self, fd: int) -> None:
        with self.lock:
            self.files.pop(fd, None)
        os.close(fd)

    def ioctl(self, fd: Any, request: int, arg: Any = 0, mutate_flag: bool = True) -> Any:
        handle = self.files.get(fd) if isinstance(fd, int) else None
        if handle is None:
            return fcntl.ioctl(fd, request, arg, mutate_flag)
        if isinstance(arg, int):
            return handle.ioctl(request, _IoctlArgument(_c_int(operator.index(arg)), None))
        if isinstance(arg, str):
            arg = arg.encode()  # fcntl's "s*" argument: a str is passed as its UTF-8 bytes
        try:
            view = memoryview(arg).cast("B")
        except TypeError:
            operator.index(arg)  # fcntl's "i" argument: "'float' object cannot be interpreted
            raise  # as an integer", the TypeError CPython raises
        if view.readonly or not mutate_flag:  # fcntl works on a copy and returns it
            if len(view) > IOCTL_BUFSZ:
                raise ValueError("ioctl string arg too long")
            copy = bytearray(view)
            handle.ioctl(request, _IoctlArgument(None, memoryview(copy)))
            return bytes(copy)
        return handle.ioctl(request, _IoctlArgument(None, view))


class _OsProxy(types.ModuleType):
    """``os`` for smbus2's module namespace: open/close of emulated nodes go to the kernel
    emulation, everything else to the real ``os``."""

    def __init__(self, kernel: I2cDevKernel) -> None:
        super().__init__("os")
        self._kernel = kernel

    def __getattr__(self, name: str) -> Any:
        return getattr(os, name)

    def open(self, path: Any, flags: int, mode: int = 0o777, *, dir_fd: int | None = None) -> int:
        return self._kernel.open(path, flags, mode, dir_fd=dir_fd)

    def close(self, fd: int) -> None:
        self._kernel.close(fd)


KERNEL = I2cDevKernel()
_install_lock = threading.RLock()
_install_count = 0
_saved_smbus2: dict[str, Any] = {}


def _install_smbus2_shim() -> None:
    global _install_count
    with _install_lock:
        _install_count += 1
        if _install_count > 1:
            return
        import smbus2.smbus2 as impl

        _saved_smbus2["os"] = getattr(impl, "os")  # noqa: B009 - module globals of smbus2
        _saved_smbus2["ioctl"] = getattr(impl, "ioctl")  # noqa: B009
        setattr(impl, "os", _OsProxy(KERNEL))  # noqa: B010
        setattr(impl, "ioctl", KERNEL.ioctl)  # noqa: B010


def _remove_smbus2_shim() -> None:
    global _install_count
    with _install_lock:
        _install_count -= 1
        if _install_count > 0:
            return
        import smbus2.smbus2 as impl

        setattr(impl, "os", _saved_smbus2.pop("os"))  # noqa: B010
        setattr(impl, "ioctl", _saved_smbus2.pop("ioctl"))  # noqa: B010
        with KERNEL.lock:  # descriptor numbers get reused: forget the emulated ones
            KERNEL.files.clear()


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
    """Context manager (and decorator): ``smbus2.SMBus(n)``, ``smbus.SMBus(n)`` and
    ``FakeSMBus(n)`` reach the emulated buses ``{n: {address: chip}}`` (or ``{n: I2CBus}``).

    ``with patch_smbus({1: {0x68: chip}}) as buses:`` gives ``{1: I2CBus}`` (logs, hooks).
    """

    def __init__(
        self, buses: Mapping[int, Mapping[int, Any] | I2CBus], *, legacy: bool = True
    ) -> None:
        if not isinstance(buses, Mapping):
            raise TypeError("patch_smbus wants {bus number: {address: chip}}")
        self.buses: dict[int, I2CBus] = {}
        for number, devices in buses.items():
            if isinstance(devices, I2CBus):
                if devices.number != number:
                    raise ValueError(f"I2CBus {devices.number} given as bus {number}")
                self.buses[number] = devices
            elif isinstance(devices, Mapping):
                self.buses[number] = I2CBus(number, devices)
            else:
                raise TypeError(
                    f"bus {number}: expected {{address: chip}} or an I2CBus, not {devices!r}"
                )
        self.legacy = legacy
        self._legacy_patch: _ModulePatch | None = None

    def __enter__(self) -> dict[int, I2CBus]:
        for bus in self.buses.values():
            register_bus(bus)
        _install_smbus2_shim()
        if self.legacy:
            self._legacy_patch = _ModulePatch("smbus", "SMBus", LegacySMBus)
            self._legacy_patch.__enter__()
        return dict(self.buses)

    def __exit__(self, *exc: object) -> None:
        if self._legacy_patch is not None:
            self._legacy_patch.__exit__(*exc)
            self._legacy_patch = None
        _remove_smbus2_shim()
        for bus in self.buses.values():
            unregister_bus(bus)


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
