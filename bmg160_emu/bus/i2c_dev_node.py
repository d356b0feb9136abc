"""The in-process ``/dev/i2c-N``: every pure-Python I2C stack reaches the emulated buses.

Why at the system-call boundary: smbus2, smbus3, Adafruit_PureIO (Blinka's ``busio.I2C`` on
Linux), python-periphery and hand-written ``fcntl`` code differ in everything except the
calls they end in: ``os.open``/``open`` of ``/dev/i2c-N``, ``fcntl.ioctl`` on its descriptor
(I2C_SLAVE, I2C_SLAVE_FORCE, I2C_FUNCS, I2C_RDWR, I2C_SMBUS, I2C_PEC ...), ``read``/``write``
on it, ``close``. While :class:`patch_i2c_dev` is active those calls are answered by
:class:`~bmg160_emu.bus.i2c_dev.I2CDevFile` (the kernel's i2c-dev driver, the same emulation
the umockdev node uses) for the emulated bus numbers only; every other path and descriptor
goes to the real OS untouched.

How: ``os.open``, ``os.close``, ``os.read``, ``os.write``, ``os.pread``, ``os.pwrite``,
``os.dup``, ``os.dup2``, ``os.lseek``, ``os.fstat``, ``os.stat``, ``os.lstat``, ``os.access``,
``os.listdir``, ``os.scandir``, ``fcntl.ioctl``, ``builtins.open``/``io.open`` and
``io.FileIO`` are replaced for the duration, and so is every module-level name bound to one
of them (``from fcntl import ioctl`` in smbus2 and smbus3, PureIO), then all of it is
restored, on exit, on an exception, after a failing test; a name a module bound to a
replacement while the patch was active is put back too. An emulated node holds a real
descriptor (``/dev/null`` opened with the same flags), so its number collides with nothing
and ``fcntl(F_GETFL)``, ``select`` and ``set_inheritable`` work on it. The replacements are
process-wide: every thread sees one bus (the chips' locks order their transactions).

As the kernel answers: a bad pointer in an ioctl argument is EFAULT, never a crash
(:mod:`.user_memory`); ``os.dup`` of a node shares its open file (address, PEC), as a dup
shares the kernel's ``struct file``; ``lseek`` is ESPIPE (``no_llseek``); ``pread``/``pwrite``
read and write like ``read``/``write`` (the offset ignored, a negative one EINVAL); the node
exists for ``os.stat``, ``os.path.exists``, ``os.listdir('/dev')`` and ``glob('/dev/i2c-*')``,
a character device 89:N (I2C_MAJOR, the bus number as minor) with mode 0600 (devtmpfs's
default), owned by the user running the program, since the emulated node opens for anyone.

Not reached: C extensions (python3-smbus, spidev) call ``open``/``ioctl`` from C; they need
the LD_PRELOAD route, ``bmg160-emu run`` (docs/umockdev.md).
"""

from __future__ import annotations

import builtins
import errno
import fcntl
import io
import operator
import os
import stat
import sys
import threading
import time
import weakref
from collections.abc import Callable, Iterator, Mapping
from contextlib import ContextDecorator
from typing import Any

from bmg160_emu.bus.i2c import I2CBus, os_error
from bmg160_emu.bus.i2c_dev import I2CDevFile
from bmg160_emu.bus.i2c_dev_files import REAL_FILE_IO, file_io_type, open_file_object
from bmg160_emu.bus.registry import (
    emulated_bus_for_path,
    emulated_bus_numbers,
    register_bus,
    unregister_bus,
)
from bmg160_emu.bus.user_memory import IOCTL_BUFSZ, IoctlArgument, KeptAlive

__all__ = ["I2C_MAJOR", "KERNEL", "I2cDevKernel", "buses_from_mapping", "patch_i2c_dev"]

I2C_MAJOR = 89  # include/uapi/linux/major.h: every /dev/i2c-N is char device 89:N
NODE_MODE = stat.S_IFCHR | 0o600  # devtmpfs creates device nodes 0600 unless told otherwise
DEV_DIR = "/dev"


def _descriptor(fd: Any) -> int:
    """What fcntl makes of its first argument (PyObject_AsFileDescriptor)."""
    if isinstance(fd, int):
        return fd
    fileno = getattr(fd, "fileno", None)
    if fileno is None:
        raise TypeError("argument must be an int, or have a fileno() method.")
    return operator.index(fileno())


class _Node:
    """One open emulated node: the kernel's ``struct file`` (the client: address, PEC) and
    its access mode, shared by every descriptor dup'ed from it."""

    __slots__ = ("bus", "file", "readable", "writable")

    def __init__(self, bus: I2CBus, flags: int) -> None:
        access = flags & os.O_ACCMODE
        self.bus = bus
        self.file = I2CDevFile(bus)
        self.readable = access in (os.O_RDONLY, os.O_RDWR)
        self.writable = access in (os.O_WRONLY, os.O_RDWR)


def _path_text(path: Any) -> str | None:
    """A path argument as text (str, bytes or PathLike), or None for anything else."""
    if isinstance(path, str):
        return path
    if isinstance(path, (bytes, os.PathLike)):
        try:
            return os.fsdecode(path)
        except TypeError:
            return None
    return None


def _bus_for(path: Any) -> I2CBus | None:
    """The emulated bus a path names (``/dev/i2c-N``, also as bytes or a PathLike)."""
    text = _path_text(path)
    if text is None or not text.startswith("/dev/"):
        return None
    return emulated_bus_for_path(os.path.normpath(text))


class _DevEntry:
    """An emulated node as ``os.scandir('/dev')`` lists it (an ``os.DirEntry`` look-alike)."""

    __slots__ = ("kernel", "name", "number", "path")

    def __init__(self, kernel: I2cDevKernel, directory: Any, number: int) -> None:
        name = f"i2c-{number}"
        self.kernel, self.number = kernel, number
        self.name: Any = os.fsencode(name) if isinstance(directory, bytes) else name
        self.path: Any = os.path.join(directory, self.name)

    def inode(self) -> int:
        return self.stat().st_ino

    def is_dir(self, *, follow_symlinks: bool = True) -> bool:
        return False

    def is_file(self, *, follow_symlinks: bool = True) -> bool:
        return False

    def is_symlink(self) -> bool:
        return False

    def is_junction(self) -> bool:
        return False

    def stat(self, *, follow_symlinks: bool = True) -> os.stat_result:
        bus = emulated_bus_for_path(f"/dev/i2c-{self.number}")
        if bus is None:
            raise FileNotFoundError(errno.ENOENT, os.strerror(errno.ENOENT), self.path)
        return self.kernel.node_stat(bus)

    def __fspath__(self) -> Any:
        return self.path

    def __repr__(self) -> str:
        return f"<DirEntry {self.name!r}>"


class _DevScandir:
    """``os.scandir('/dev')`` with the emulated nodes in it (each listed once)."""

    def __init__(self, real: Any, extra: list[_DevEntry]) -> None:
        self.real, self.extra = real, extra
        self.names = {entry.name for entry in extra}

    def __iter__(self) -> Iterator[Any]:
        return self

    def __next__(self) -> Any:
        for entry in self.real:
            if entry.name not in self.names:
                return entry
        if self.extra:
            return self.extra.pop(0)
        raise StopIteration

    def close(self) -> None:
        self.real.close()

    def __enter__(self) -> Any:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


class I2cDevKernel:
    """The i2c-dev character device as this process sees it: ``open`` of emulated paths,
    then ``ioctl``/``read``/``write``/``dup``/``close`` on their descriptors, marshalled to
    :class:`~bmg160_emu.bus.i2c_dev.I2CDevFile` (argument conversions and buffer copies as
    CPython's ``os`` and ``fcntl`` make them), and the node in the file system (``stat``,
    ``/dev`` listings). The real calls are kept for everything else."""

    def __init__(self) -> None:
        self.nodes: dict[int, _Node] = {}
        self.lock = threading.Lock()
        self.real_open = os.open
        self.real_close = os.close
        self.real_read = os.read
        self.real_write = os.write
        self.real_pread = os.pread
        self.real_pwrite = os.pwrite
        self.real_dup = os.dup
        self.real_dup2 = os.dup2
        self.real_lseek = os.lseek
        self.real_fstat = os.fstat
        self.real_stat = os.stat
        self.real_lstat = os.lstat
        self.real_access = os.access
        self.real_listdir = os.listdir
        self.real_scandir = os.scandir
        self.real_ioctl = fcntl.ioctl
        self.real_io_open = io.open
        self.file_io = file_io_type(self)
        self.born: weakref.WeakKeyDictionary[I2CBus, float] = weakref.WeakKeyDictionary()

    @property
    def files(self) -> dict[int, I2CDevFile]:
        """The open emulated nodes, descriptor -> I2CDevFile."""
        return {fd: node.file for fd, node in self.nodes.items()}

    def emulated(self, file: Any, opener: Any = None) -> bool:
        """Whether ``open``/``FileIO`` of ``file`` is an emulated node (a path or descriptor)."""
        if file.__class__ is int:
            return file in self.nodes
        return opener is None and _bus_for(file) is not None

    # ------------------------------------------------------------------ the node on disk

    def node_stat(self, bus: I2CBus) -> os.stat_result:
        """``stat`` of /dev/i2c-N: a character device 89:N made when the bus was first seen."""
        made = self.born.setdefault(bus, time.time())
        seconds = int(made)
        nanoseconds = int(made * 1e9)
        try:
            device = self.real_stat(DEV_DIR).st_dev
        except OSError:
            device = 0
        fields = (NODE_MODE, 0x10000 + bus.number, device, 1, os.getuid(), os.getgid(), 0,
                  seconds, seconds, seconds)
        extra: dict[str, float] = {"st_rdev": os.makedev(I2C_MAJOR, bus.number),
                                   "st_blksize": 4096, "st_blocks": 0}
        for name in ("atime", "mtime", "ctime"):
            extra[f"st_{name}"] = made
            extra[f"st_{name}_ns"] = nanoseconds
        return os.stat_result(fields, extra)

    def stat(self, path: Any, *, dir_fd: int | None = None,
             follow_symlinks: bool = True) -> os.stat_result:
        if path.__class__ is int:
            return self.fstat(path)
        bus = _bus_for(path) if dir_fd is None else None
        if bus is None:
            return self.real_stat(path, dir_fd=dir_fd, follow_symlinks=follow_symlinks)
        return self.node_stat(bus)

    def lstat(self, path: Any, *, dir_fd: int | None = None) -> os.stat_result:
        bus = _bus_for(path) if dir_fd is None else None
        if bus is None:
            return self.real_lstat(path, dir_fd=dir_fd)
        return self.node_stat(bus)

    def access(self, path: Any, mode: int, *, dir_fd: int | None = None,
               effective_ids: bool = False, follow_symlinks: bool = True) -> bool:
        bus = _bus_for(path) if dir_fd is None and path.__class__ is not int else None
        if bus is None:
            return self.real_access(path, mode, dir_fd=dir_fd, effective_ids=effective_ids,
                                    follow_symlinks=follow_symlinks)
        return not operator.index(mode) & os.X_OK  # read and write for its owner, no x bit

    def _extra_entries(self, directory: Any) -> list[_DevEntry] | None:
        """The emulated nodes a listing of ``directory`` shows, or None (not /dev)."""
        if directory.__class__ is int:
            try:
                text: str | None = os.readlink(f"/proc/self/fd/{directory}")
            except OSError:
                return None
            directory = text
        text = _path_text(directory)
        if text is None or os.path.normpath(text) != DEV_DIR:
            return None
        return [_DevEntry(self, directory, n) for n in emulated_bus_numbers()]

    def listdir(self, path: Any = None) -> list[Any]:
        names = self.real_listdir(path)
        extra = self._extra_entries(path) if path is not None else None
        if extra:
            known = set(names)
            names += [entry.name for entry in extra if entry.name not in known]
        return names

    def scandir(self, path: Any = None) -> Any:
        real = self.real_scandir(path)
        extra = self._extra_entries(path) if path is not None else None
        return _DevScandir(real, extra) if extra else real

    # ------------------------------------------------------------------ os on descriptors

    def open(self, path: Any, flags: int, mode: int = 0o777, *, dir_fd: int | None = None) -> int:
        bus = _bus_for(path)
        if bus is None:
            return self.real_open(path, flags, mode, dir_fd=dir_fd)
        if flags & os.O_CREAT and flags & os.O_EXCL:
            raise FileExistsError(errno.EEXIST, os.strerror(errno.EEXIST), os.fsdecode(path))
        if flags & getattr(os, "O_DIRECTORY", 0):
            raise NotADirectoryError(errno.ENOTDIR, os.strerror(errno.ENOTDIR), os.fsdecode(path))
        fd = self.real_open(os.devnull, flags)  # a real, unique number with the same flags
        with self.lock:
            self.nodes[fd] = _Node(bus, flags)
        return fd

    def close(self, fd: int) -> None:
        with self.lock:
            self.nodes.pop(fd, None)
        self.real_close(fd)

    def dup(self, fd: int) -> int:
        new = self.real_dup(fd)
        node = self.nodes.get(fd)
        if node is not None:
            with self.lock:
                self.nodes[new] = node  # one open file: address and PEC shared
        return new

    def dup2(self, fd: int, fd2: int, inheritable: bool = True) -> int:
        result = self.real_dup2(fd, fd2, inheritable)
        node = self.nodes.get(fd)
        with self.lock:
            if node is not None:
                self.nodes[fd2] = node
            elif fd2 != fd:
                self.nodes.pop(fd2, None)  # fd2 now names another file
        return result

    def lseek(self, fd: int, position: int, how: int) -> int:
        if fd not in self.nodes:
            return self.real_lseek(fd, position, how)
        operator.index(position), operator.index(how)  # CPython converts them first
        raise os_error(errno.ESPIPE)  # i2c-dev's llseek is no_llseek

    def fstat(self, fd: int) -> os.stat_result:
        node = self.nodes.get(fd)
        if node is None:
            return self.real_fstat(fd)
        return self.node_stat(node.bus)

    def read(self, fd: int, count: int) -> bytes:
        node = self.nodes.get(fd)
        if node is None:
            return self.real_read(fd, count)
        return self._read(node, count)

    def _read(self, node: _Node, count: int) -> bytes:
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
        return self._write(node, data)

    def _write(self, node: _Node, data: Any) -> int:
        payload = memoryview(data).cast("B").tobytes()  # os.write's "y*": any buffer
        if not node.writable:
            raise os_error(errno.EBADF)
        return node.file.write(payload)

    def pread(self, fd: int, count: int, offset: int) -> bytes:
        node = self.nodes.get(fd)
        if node is None:
            return self.real_pread(fd, count, offset)
        self._check_offset(operator.index(offset))
        return self._read(node, count)

    def pwrite(self, fd: int, data: Any, offset: int) -> int:
        node = self.nodes.get(fd)
        if node is None:
            return self.real_pwrite(fd, data, offset)
        self._check_offset(operator.index(offset))
        return self._write(node, data)

    @staticmethod
    def _check_offset(offset: int) -> None:
        """pread/pwrite on i2c-dev: the offset is ignored, but a negative one is EINVAL
        (ksys_pread64), and the node keeps FMODE_PREAD (i2cdev_open is not nonseekable)."""
        if offset < 0:
            raise os_error(errno.EINVAL)

    # ------------------------------------------------------------------ fcntl

    def ioctl(self, fd: Any, request: int, arg: Any = 0, mutate_flag: bool = True) -> Any:
        node = self.nodes.get(fd) if fd.__class__ is int else self.nodes.get(_descriptor(fd))
        if node is None:
            return self.real_ioctl(fd, request, arg, mutate_flag)
        request = operator.index(request) & 0xFFFFFFFF  # fcntl's "I": unsigned, unchecked
        handle = node.file
        if isinstance(arg, int):
            return handle.ioctl(request, IoctlArgument.from_int(arg))
        if isinstance(arg, str):
            arg = arg.encode()  # fcntl's "s*" argument: a str is passed as its UTF-8 bytes
        try:
            view = memoryview(arg).cast("B")
        except TypeError:
            operator.index(arg)  # fcntl's "i" argument: "'float' object cannot be interpreted
            raise  # as an integer", the TypeError CPython raises
        known = KeptAlive(arg)
        if view.readonly or not mutate_flag:  # fcntl works on a copy and returns it
            if len(view) > IOCTL_BUFSZ:
                raise ValueError("ioctl string arg too long")
            copy = bytearray(view)
            handle.ioctl(request, IoctlArgument(None, memoryview(copy), known))
            return bytes(copy)
        return handle.ioctl(request, IoctlArgument(None, view, known))

    # ------------------------------------------------------------------ io

    def io_open(self, file: Any, mode: str = "r", buffering: int = -1, encoding: str | None = None,
                errors: str | None = None, newline: str | None = None, closefd: bool = True,
                opener: Callable[[str, int], int] | None = None) -> Any:
        """``open()``: a file object over an emulated node (a path, or the descriptor of one
        when ``open(fd)`` wraps it), built as io.open builds one; anything else is io.open's."""
        if not self.emulated(file, opener):
            return self.real_io_open(file, mode, buffering, encoding, errors, newline, closefd,
                                     opener)
        return open_file_object(self, file, mode, buffering, encoding, errors, newline, closefd)


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
            (os, "pread", kernel.real_pread, kernel.pread),
            (os, "pwrite", kernel.real_pwrite, kernel.pwrite),
            (os, "dup", kernel.real_dup, kernel.dup),
            (os, "dup2", kernel.real_dup2, kernel.dup2),
            (os, "lseek", kernel.real_lseek, kernel.lseek),
            (os, "fstat", kernel.real_fstat, kernel.fstat),
            (os, "stat", kernel.real_stat, kernel.stat),
            (os, "lstat", kernel.real_lstat, kernel.lstat),
            (os, "access", kernel.real_access, kernel.access),
            (os, "listdir", kernel.real_listdir, kernel.listdir),
            (os, "scandir", kernel.real_scandir, kernel.scandir),
            (fcntl, "ioctl", kernel.real_ioctl, kernel.ioctl),
            (io, "open", kernel.real_io_open, kernel.io_open),
            (builtins, "open", kernel.real_io_open, kernel.io_open),
            (io, "FileIO", REAL_FILE_IO, kernel.file_io),
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


# modules whose names must keep the real calls (this one's kernel, the file objects' FileIO)
_OWN_MODULES = frozenset({"os", "posix", "fcntl", "io", "_io", "builtins", __name__,
                          "bmg160_emu.bus.i2c_dev_files"})


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
