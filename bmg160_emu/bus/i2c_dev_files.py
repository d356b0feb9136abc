"""File objects over the in-process /dev/i2c-N: ``open()``, ``io.open`` and ``io.FileIO``.

Why: CPython's ``io.FileIO`` reads and writes its descriptor from C, below every Python
name the in-process node replaces, so a file object over an emulated node is built here
instead, with io's own checks, messages and buffering: ``open('/dev/i2c-1', 'r+b',
buffering=0)`` (Adafruit_PureIO), ``io.FileIO(fd)`` over a descriptor ``os.open`` gave,
``os.fdopen``. Reads and writes are plain I2C transfers at the address set with I2C_SLAVE;
the node cannot seek (ESPIPE), as i2c-dev's ``no_llseek`` answers.
"""

from __future__ import annotations

import errno
import io
import os
from typing import Any, Protocol

from bmg160_emu.bus.i2c import os_error

__all__ = ["REAL_FILE_IO", "I2cDevFileIO", "NodeCalls", "file_io_type", "open_file_object"]

PAGE_SIZE = 4096  # st_blksize of a character device: io.open's default buffer size
REAL_FILE_IO = io.FileIO


class NodeCalls(Protocol):
    """The in-process node's system calls a file object makes (I2cDevKernel)."""

    def open(self, path: Any, flags: int, mode: int = 0o777) -> int: ...
    def close(self, fd: int) -> None: ...
    def read(self, fd: int, count: int) -> bytes: ...
    def write(self, fd: int, data: Any) -> int: ...


def file_io_mode(kind: str, updating: bool) -> str:
    """``FileIO.mode`` as CPython spells it: 'rb', 'wb', 'ab', 'xb', or with '+' 'rb+' ..."""
    if updating:
        return ("ab+" if kind == "a" else "xb+" if kind == "x" else "rb+")
    return kind + "b"


class I2cDevFileIO(io.RawIOBase):
    """``io.FileIO`` on an emulated node: reads and writes are plain I2C transfers at the
    address set with I2C_SLAVE; the node cannot seek (ESPIPE)."""

    def __init__(self, kernel: NodeCalls, fd: int, name: Any, mode: str, closefd: bool) -> None:
        super().__init__()
        self._kernel, self._fd, self.name, self.mode, self._closefd = kernel, fd, name, mode, closefd

    @property
    def closefd(self) -> bool:
        return self._closefd

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
        self._checkClosed()  # type: ignore[attr-defined]
        return False

    def isatty(self) -> bool:
        self._checkClosed()  # type: ignore[attr-defined]
        return False

    def seek(self, offset: int, whence: int = 0) -> int:
        self._checkClosed()  # type: ignore[attr-defined]
        raise os_error(errno.ESPIPE)

    def tell(self) -> int:
        self._checkClosed()  # type: ignore[attr-defined]
        raise os_error(errno.ESPIPE)

    def truncate(self, size: int | None = None) -> int:
        self._checkClosed()  # type: ignore[attr-defined]
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
        return (f"<_io.FileIO name={self.name!r} mode={self.mode!r} "
                f"closefd={self._closefd!r} (emulated)>")


_OPEN_FLAGS = {"r": os.O_RDONLY, "w": os.O_WRONLY | os.O_CREAT | os.O_TRUNC,
               "a": os.O_WRONLY | os.O_CREAT | os.O_APPEND, "x": os.O_WRONLY | os.O_CREAT | os.O_EXCL}


def _parse_mode(mode: Any) -> tuple[str, bool, set[str]]:
    """The checks io.open makes on ``mode``: (r/w/a/x, updating, the letters)."""
    if not isinstance(mode, str):
        raise TypeError(f"open() argument 'mode' must be str, not {type(mode).__name__}")
    modes = set(mode)
    if modes - set("axrwb+t") or len(mode) > len(modes):
        raise ValueError(f"invalid mode: '{mode}'")
    kinds = [c for c in "rwax" if c in modes]
    if len(kinds) != 1:
        raise ValueError("must have exactly one of create/read/write/append mode")
    return kinds[0], "+" in modes, modes


_BAD_FILE_IO_MODE = ("Must have exactly one of create/read/write/append mode and at most one "
                     "plus")


def _parse_file_io_mode(mode: Any) -> tuple[str, bool]:
    """FileIO's own reading of ``mode`` (Modules/_io/fileio.c): one of r/w/a/x, at most
    one '+', any number of 'b', nothing else."""
    if not isinstance(mode, str):
        raise TypeError(f"FileIO() argument 'mode' must be str, not {type(mode).__name__}")
    kind, plus = "", False
    for letter in mode:
        if letter in "rwax":
            if kind:
                raise ValueError(_BAD_FILE_IO_MODE)
            kind = letter
        elif letter == "+":
            if plus:
                raise ValueError(_BAD_FILE_IO_MODE)
            plus = True
        elif letter != "b":
            raise ValueError(f"invalid mode: {mode}")
    if not kind:
        raise ValueError(_BAD_FILE_IO_MODE)
    return kind, plus


def _flags(kind: str, updating: bool) -> int:
    flags = _OPEN_FLAGS[kind]
    return (flags & ~os.O_ACCMODE) | os.O_RDWR if updating else flags


def raw_file(kernel: NodeCalls, file: Any, mode: str, closefd: bool) -> I2cDevFileIO:
    """``io.FileIO(file, mode, closefd)`` over an emulated node (a path or a descriptor)."""
    kind, updating = _parse_file_io_mode(mode)
    if file.__class__ is not int and not closefd:
        raise ValueError("Cannot use closefd=False with file name")
    fd = file if file.__class__ is int else kernel.open(file, _flags(kind, updating) | os.O_CLOEXEC)
    return I2cDevFileIO(kernel, fd, file, file_io_mode(kind, updating), closefd)


def open_file_object(kernel: NodeCalls, file: Any, mode: str, buffering: int,
                     encoding: str | None, errors: str | None, newline: str | None,
                     closefd: bool) -> Any:
    """io.open's steps (Lib/_pyio.py open) over an emulated node, its checks and messages."""
    kind, updating, modes = _parse_mode(mode)
    if "t" in modes and "b" in modes:
        raise ValueError("can't have text and binary mode at once")
    binary = "b" in modes
    if binary and (encoding is not None or errors is not None or newline is not None):
        raise ValueError("binary mode doesn't take an encoding, errors or newline argument")
    raw = raw_file(kernel, file, kind + ("+" if updating else ""),
                   closefd or file.__class__ is not int)
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
        elif kind == "r":
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


class _FileIOType(type):
    """While the node is in place, ``io.FileIO`` is a factory; isinstance and issubclass
    still answer for CPython's FileIO and for the emulated node's."""

    def __instancecheck__(cls, obj: Any) -> bool:
        return isinstance(obj, (REAL_FILE_IO, I2cDevFileIO))

    def __subclasscheck__(cls, sub: Any) -> bool:
        return isinstance(sub, type) and issubclass(sub, (REAL_FILE_IO, I2cDevFileIO))


def file_io_type(kernel: Any) -> type:
    """The ``io.FileIO`` the in-process node installs: CPython's FileIO for every file but
    an emulated node (its path, or a descriptor of one), which gets :class:`I2cDevFileIO`."""

    class FileIO(metaclass=_FileIOType):
        __doc__ = REAL_FILE_IO.__doc__

        def __new__(cls, file: Any, mode: str = "r", closefd: bool = True,
                    opener: Any = None) -> Any:
            if kernel.emulated(file, opener):
                return raw_file(kernel, file, mode, closefd)
            return REAL_FILE_IO(file, mode, closefd, opener)

    return FileIO
