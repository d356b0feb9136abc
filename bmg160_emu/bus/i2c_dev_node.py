"""The in-process ``/dev/i2c-N``: every pure-Python I2C stack reaches the emulated buses.

Why at the system-call boundary: smbus2, smbus3, Adafruit_PureIO (Blinka's ``busio.I2C`` on
Linux), python-periphery and hand-written ``fcntl`` code differ in everything except the
calls they end in: ``os.open``/``open`` of ``/dev/i2c-N``, ``fcntl.ioctl`` on its descriptor
(I2C_SLAVE, I2C_SLAVE_FORCE, I2C_FUNCS, I2C_RDWR, I2C_SMBUS, I2C_PEC ...), ``read``/``write``
on it, ``close``. While :class:`patch_i2c_dev` is active those calls are answered by
:class:`~bmg160_emu.bus.i2c_dev.I2CDevFile` (the kernel's i2c-dev driver, the same emulation
the umockdev node uses) for the emulated bus numbers only; every other path and descriptor
goes to the real OS untouched.

How: ``os.open``, ``os.close``, ``os.read``, ``os.write``, ``fcntl.ioctl`` and
``builtins.open``/``io.open`` are replaced for the duration, and so is every module-level
name bound to one of them (``from fcntl import ioctl`` in smbus2 and smbus3, PureIO), then
all of it is restored, on exit, on an exception, after a failing test; a name a module bound
to a replacement while the patch was active is put back too. An emulated node holds a real
descriptor (``/dev/null`` opened), so its number collides with nothing. The replacements are
process-wide: every thread sees one bus (the chips' locks order their transactions).

Not reached: C extensions (python3-smbus, spidev) call ``open``/``ioctl`` from C; they need
the LD_PRELOAD route, ``bmg160-emu run`` (docs/umockdev.md).
"""

from __future__ import annotations

import builtins
import ctypes
import errno
import fcntl
import io
import operator
import os
import struct
import sys
import threading
from collections.abc import Callable, Mapping
from contextlib import ContextDecorator
from typing import Any

from bmg160_emu.bus.i2c import I2CBus, emulated_bus_for_path, os_error, register_bus, unregister_bus
from bmg160_emu.bus.i2c_dev import ULONG_MASK, I2CDevFile

__all__ = ["KERNEL", "I2cDevKernel", "buses_from_mapping", "patch_i2c_dev"]

IOCTL_BUFSZ = 1024  # CPython's fcntl.ioctl copies a buffer argument through 1024 bytes
USER_POINTER = 0x7FFF_0000_0000  # what the kernel sees as the argument when it is a buffer
PAGE_SIZE = 4096  # st_blksize of a character device: io.open's default buffer size


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


def _descriptor(fd: Any) -> int:
    """What fcntl makes of its first argument (PyObject_AsFileDescriptor)."""
    if isinstance(fd, int):
        return fd
    fileno = getattr(fd, "fileno", None)
    if fileno is None:
        raise TypeError("argument must be an int, or have a fileno() method.")
    return operator.index(fileno())


class _Node:
    """One open emulated node: the kernel's file (client address, PEC) and its access mode."""

    __slots__ = ("file", "readable", "writable")

    def __init__(self, bus: I2CBus, flags: int) -> None:
        access = flags & os.O_ACCMODE
        self.file = I2CDevFile(bus)
        self.readable = access in (os.O_RDONLY, os.O_RDWR)
        self.writable = access in (os.O_WRONLY, os.O_RDWR)


class I2cDevKernel:
    """The i2c-dev character device as this process sees it: ``open`` of emulated paths,
    then ``ioctl``/``read``/``write``/``close`` on their descriptors, marshalled to
    :class:`~bmg160_emu.bus.i2c_dev.I2CDevFile` (argument conversions and buffer copies as
    CPython's ``os`` and ``fcntl`` make them). The real calls are kept for everything else."""

    def __init__(self) -> None:
        self.nodes: dict[int, _Node] = {}
        self.lock = threading.Lock()
        self.real_open = os.open
        self.real_close = os.close
        self.real_read = os.read
        self.real_write = os.write
        self.real_ioctl = fcntl.ioctl
        self.real_io_open = io.open

    @property
    def files(self) -> dict[int, I2CDevFile]:
        """The open emulated nodes, descriptor -> I2CDevFile."""
        return {fd: node.file for fd, node in self.nodes.items()}

    # ------------------------------------------------------------------ os

    def open(self, path: Any, flags: int, mode: int = 0o777, *, dir_fd: int | None = None) -> int:
        bus = _bus_for(path)
        if bus is None:
            return self.real_open(path, flags, mode, dir_fd=dir_fd)
        if flags & os.O_CREAT and flags & os.O_EXCL:
            raise FileExistsError(errno.EEXIST, os.strerror(errno.EEXIST), os.fsdecode(path))
        if flags & getattr(os, "O_DIRECTORY", 0):
            raise NotADirectoryError(errno.ENOTDIR, os.strerror(errno.ENOTDIR), os.fsdecode(path))
        fd = self.real_open(os.devnull, os.O_RDWR | os.O_CLOEXEC)  # a real, unique number
        with self.lock:
            self.nodes[fd] = _Node(bus, flags)
        return fd

    def close(self, fd: int) -> None:
        with self.lock:
            self.nodes.pop(fd, None)
        self.real_close(fd)

    def read(self, fd: int, count: int) -> bytes:
        node = self.nodes.get(fd)
        if node is None:
            return self.real_read(fd, count)
        count = operator.index(count)  # os.read's Py_ssize_t argument, as CPython converts it
        if count > sys.maxsize:
            raise OverflowError("Python int too large to convert to C ssize_t")
        if count < 0:
            raise os_error(errno.EINVAL)
        if not node.readable:
            raise os_error(errno.EBADF)
        return node.file.read(count)

    def write(self, fd: int, data: Any) -> int:
        node = self.nodes.get(fd)
        if node is None:
            return self.real_write(fd, data)
        payload = memoryview(data).cast("B").tobytes()  # os.write's "y*": any buffer
        if not node.writable:
            raise os_error(errno.EBADF)
        return node.file.write(payload)

    # ------------------------------------------------------------------ fcntl

    def ioctl(self, fd: Any, request: int, arg: Any = 0, mutate_flag: bool = True) -> Any:
        node = self.nodes.get(fd) if fd.__class__ is int else self.nodes.get(_descriptor(fd))
        if node is None:
            return self.real_ioctl(fd, request, arg, mutate_flag)
        request = operator.index(request) & 0xFFFFFFFF  # fcntl's "I": unsigned, unchecked
        handle = node.file
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

    # ------------------------------------------------------------------ io

    def io_open(self, file: Any, mode: str = "r", buffering: int = -1, encoding: str | None = None,
                errors: str | None = None, newline: str | None = None, closefd: bool = True,
                opener: Callable[[str, int], int] | None = None) -> Any:
        """``open()``: a file object over an emulated node (a path, or the descriptor of one
        when ``open(fd)`` wraps it), built as io.open builds one; anything else is io.open's."""
        emulated = (file.__class__ is int and file in self.nodes) or (
            file.__class__ is not int and opener is None and _bus_for(file) is not None)
        if not emulated:
            return self.real_io_open(file, mode, buffering, encoding, errors, newline, closefd,
                                     opener)
        return _open_file_object(self, file, mode, buffering, encoding, errors, newline, closefd)


def _bus_for(path: Any) -> I2CBus | None:
    """The emulated bus a path names (``/dev/i2c-N``, also as bytes or a PathLike)."""
    if isinstance(path, str):
        text = path
    elif isinstance(path, (bytes, os.PathLike)):
        try:
            text = os.fsdecode(path)
        except TypeError:
            return None
    else:
        return None
    if not text.startswith("/dev/"):
        return None
    return emulated_bus_for_path(os.path.normpath(text))


class I2cDevFileIO(io.RawIOBase):
    """``open('/dev/i2c-N', 'r+b', buffering=0)`` on an emulated node: reads and writes are
    plain I2C transfers at the address set with I2C_SLAVE; the node cannot seek (ESPIPE)."""

    def __init__(self, kernel: I2cDevKernel, fd: int, name: Any, mode: str, closefd: bool) -> None:
        super().__init__()
        self._kernel, self._fd, self.name, self.mode, self._closefd = kernel, fd, name, mode, closefd

    def fileno(self) -> int:
        self._checkClosed()  # type: ignore[attr-defined]
        return self._fd

    def readable(self) -> bool:
        self._checkClosed()  # type: ignore[attr-defined]
        return "r" in self.mode or "+" in self.mode

    def writable(self) -> bool:
        self._checkClosed()  # type: ignore[attr-defined]
        return "r" not in self.mode or "+" in self.mode

    def seekable(self) -> bool:
        return False

    def seek(self, offset: int, whence: int = 0) -> int:
        raise os_error(errno.ESPIPE)

    def tell(self) -> int:
        raise os_error(errno.ESPIPE)

    def readinto(self, buffer: Any) -> int:
        self._checkClosed()  # type: ignore[attr-defined]
        if not self.readable():
            raise io.UnsupportedOperation("File not open for reading")
        view = memoryview(buffer).cast("B")
        data = self._kernel.read(self._fd, len(view))
        view[: len(data)] = data
        return len(data)

    def write(self, data: Any) -> int:
        self._checkClosed()  # type: ignore[attr-defined]
        if not self.writable():
            raise io.UnsupportedOperation("File not open for writing")
        return self._kernel.write(self._fd, data)

    def close(self) -> None:
        if not self.closed and self._closefd:
            self._kernel.close(self._fd)
        super().close()

    def __repr__(self) -> str:
        return f"<I2cDevFileIO name={self.name!r} mode={self.mode!r} (emulated)>"


_OPEN_FLAGS = {"r": os.O_RDONLY, "w": os.O_WRONLY | os.O_CREAT | os.O_TRUNC,
               "a": os.O_WRONLY | os.O_CREAT | os.O_APPEND, "x": os.O_WRONLY | os.O_CREAT | os.O_EXCL}


def _open_file_object(kernel: I2cDevKernel, file: Any, mode: str, buffering: int,
                      encoding: str | None, errors: str | None, newline: str | None,
                      closefd: bool) -> Any:
    """io.open's steps (Lib/_pyio.py open) over an emulated node, its checks and messages."""
    if not isinstance(mode, str):
        raise TypeError(f"open() argument 'mode' must be str, not {type(mode).__name__}")
    modes = set(mode)
    if modes - set("axrwb+t") or len(mode) > len(modes):
        raise ValueError(f"invalid mode: '{mode}'")
    kinds = [c for c in "rwax" if c in modes]
    if len(kinds) != 1:
        raise ValueError("must have exactly one of create/read/write/append mode")
    if "t" in modes and "b" in modes:
        raise ValueError("can't have text and binary mode at once")
    binary = "b" in modes
    if binary and (encoding is not None or errors is not None or newline is not None):
        raise ValueError("binary mode doesn't take an encoding, errors or newline argument")
    updating = "+" in modes
    flags = _OPEN_FLAGS[kinds[0]]
    if updating:
        flags = (flags & ~os.O_ACCMODE) | os.O_RDWR
    fd = file if file.__class__ is int else kernel.open(file, flags)
    raw_mode = kinds[0] + ("+" if updating else "")
    raw = I2cDevFileIO(kernel, fd, file, raw_mode + "b", closefd or file.__class__ is not int)
    try:
        line_buffering = buffering == 1 or (buffering < 0 and not binary and raw.isatty())
        if buffering == 1 or buffering < 0:
            buffering = PAGE_SIZE
        if buffering == 0:
            if not binary:  # checked once the file is open, as _io.open does
                raise ValueError("can't have unbuffered text I/O")
            return raw
        if updating:
            buffer: Any = io.BufferedRandom(raw, buffering)  # "not seekable": as on a real node
        elif kinds[0] == "r":
            buffer = io.BufferedReader(raw, buffering)
        else:
            buffer = io.BufferedWriter(raw, buffering)
        if binary:
            return buffer
        text = io.TextIOWrapper(buffer, encoding, errors, newline, line_buffering)
        text.mode = mode  # type: ignore[misc]  # io.open sets it so on TextIOWrapper
        return text
    except BaseException:
        raw.close()
        raise


KERNEL = I2cDevKernel()


class _Replacements:
    """The process's calls and their replacements, installed once however deeply nested."""

    def __init__(self, kernel: I2cDevKernel) -> None:
        self.kernel = kernel
        self.lock = threading.RLock()
        self.depth = 0
        self.pairs: list[tuple[Any, str, Any, Any]] = [  # (owner, name, real, replacement)
            (os, "open", kernel.real_open, kernel.open),
            (os, "close", kernel.real_close, kernel.close),
            (os, "read", kernel.real_read, kernel.read),
            (os, "write", kernel.real_write, kernel.write),
            (fcntl, "ioctl", kernel.real_ioctl, kernel.ioctl),
            (io, "open", kernel.real_io_open, kernel.io_open),
            (builtins, "open", kernel.real_io_open, kernel.io_open),
        ]
        self.names = _BoundNames({id(real) for _, _, real, _ in self.pairs}
                                 | {id(new) for _, _, _, new in self.pairs})
        self.bound: list[tuple[dict[str, Any], str, Any]] = []  # module names rebound

    def install(self) -> None:
        with self.lock:
            self.depth += 1
            if self.depth > 1:
                return
            for owner, name, _, replacement in self.pairs:
                setattr(owner, name, replacement)
            self.bound = self.names.rebind({id(real): new for _, _, real, new in self.pairs})

    def remove(self) -> None:
        with self.lock:
            self.depth -= 1
            if self.depth > 0:
                return
            for owner, name, real, _ in self.pairs:
                setattr(owner, name, real)
            for namespace, name, real in self.bound:
                namespace[name] = real
            # names bound to a replacement while the patch was active (a module imported then)
            self.names.rebind({id(new): real for _, _, real, new in self.pairs})
            self.bound = []
            with self.kernel.lock:  # descriptor numbers get reused: forget the emulated ones
                self.kernel.nodes.clear()


_OWN_MODULES = frozenset({"os", "posix", "fcntl", "io", "_io", "builtins", __name__})


class _BoundNames:
    """Where modules bound the calls at module level (``from fcntl import ioctl``).

    A full look through every module's names costs ~15 ms with a test session's ~1000
    modules loaded, too much for a fixture that runs per test; so each module is read once
    and only the names found are watched, and a module is read again when its namespace
    changed size or it is a new module object."""

    def __init__(self, watched: set[int]) -> None:
        self.watched = watched  # ids of the real calls and of their replacements
        self.seen: dict[str, tuple[Any, int, tuple[str, ...]]] = {}  # name -> (module, size, hits)

    def _hits(self, module_name: str, module: Any, namespace: dict[str, Any]) -> tuple[str, ...]:
        known = self.seen.get(module_name)
        if known is not None and known[0] is module and known[1] == len(namespace):
            return known[2]
        watched = self.watched
        hits = tuple(name for name, value in list(namespace.items()) if id(value) in watched)
        self.seen[module_name] = (module, len(namespace), hits)
        return hits

    def rebind(self, swap: dict[int, Any]) -> list[tuple[dict[str, Any], str, Any]]:
        """Point every module-level name whose value is a key of ``swap`` (by identity) at
        its replacement; returns (namespace, name, old value) to undo it."""
        changed = []
        for module_name, module in list(sys.modules.items()):
            if module is None or module_name in _OWN_MODULES:
                continue
            namespace = getattr(module, "__dict__", None)
            if not isinstance(namespace, dict):
                continue
            for name in self._hits(module_name, module, namespace):
                value = namespace.get(name)
                replacement = swap.get(id(value))
                if replacement is not None:
                    namespace[name] = replacement
                    changed.append((namespace, name, value))
        return changed


_REPLACEMENTS = _Replacements(KERNEL)


def buses_from_mapping(buses: Mapping[int, Mapping[int, Any] | I2CBus], who: str) -> dict[int, I2CBus]:
    """``{number: {address: chip}}`` or ``{number: I2CBus}`` as I2CBus objects, checked."""
    if not isinstance(buses, Mapping):
        raise TypeError(f"{who} wants {{bus number: {{address: chip}}}}")
    out: dict[int, I2CBus] = {}
    for number, devices in buses.items():
        if isinstance(devices, I2CBus):
            if devices.number != number:
                raise ValueError(f"I2CBus {devices.number} given as bus {number}")
            out[number] = devices
        elif isinstance(devices, Mapping):
            out[number] = I2CBus(number, devices)
        else:
            raise TypeError(f"bus {number}: expected {{address: chip}} or an I2CBus, not {devices!r}")
    return out


class patch_i2c_dev(ContextDecorator):
    """Context manager (and decorator): opening ``/dev/i2c-N`` for an emulated bus number
    reaches the chips ``{N: {address: chip}}`` (or ``{N: I2CBus}``), whatever Python stack
    opens it (smbus2, smbus3, Adafruit_PureIO, periphery, ``os``/``fcntl`` code).

    ``with patch_i2c_dev({1: {0x68: chip}}) as buses:`` gives ``{1: I2CBus}`` (logs, hooks).
    Patches nest; the innermost bus of a number wins.
    """

    def __init__(self, buses: Mapping[int, Mapping[int, Any] | I2CBus]) -> None:
        self.buses = buses_from_mapping(buses, type(self).__name__)

    def __enter__(self) -> dict[int, I2CBus]:
        for bus in self.buses.values():
            register_bus(bus)
        try:
            _REPLACEMENTS.install()
        except BaseException:
            for bus in self.buses.values():
                unregister_bus(bus)
            raise
        return dict(self.buses)

    def __exit__(self, *exc: object) -> None:
        try:
            _REPLACEMENTS.remove()
        finally:
            for bus in self.buses.values():
                unregister_bus(bus)
