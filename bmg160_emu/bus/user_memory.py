"""This process's memory as the kernel reaches a caller's memory: a bad pointer is EFAULT.

Why: the in-process /dev/i2c-N answers ``fcntl.ioctl`` in this process, and an ioctl
argument may be, or hold, any address (``ioctl(fd, I2C_FUNCS, 8)``, an ``i2c_msg`` whose
buffer points at 0x10). The kernel copies user memory with ``copy_from_user`` and
``copy_to_user``, which fail with EFAULT where the memory is not mapped (or not writable);
reading such an address from Python would crash the process instead. So every copy here is
made by the kernel itself on our behalf: ``process_vm_readv``/``process_vm_writev`` on our
own pid (no ptrace permission needed for oneself; page protections apply), or, where a
sandbox refuses those calls (EPERM, ENOSYS), through a pipe (``write(pipe, address, n)``
copies from the address, ``read(pipe, address, n)`` into it, EFAULT either way).
A copy is all or nothing, as the kernel's is: a partial copy is EFAULT. Before it, the
range is checked as x86-64's ``access_ok`` checks it: it must end at or below TASK_SIZE_MAX
(2**47 - 4096, or 2**56 - 4096 with 5-level paging), so an address in the kernel's half,
the vsyscall page included, is EFAULT whatever the host's vsyscall mode lets
``process_vm_readv`` see (other machines: the process_vm calls alone decide).

A checked copy costs a system call (a few microseconds), so memory known to be there is
read directly: the ctypes objects an ioctl argument keeps alive (``_objects``, ctypes'
record of what a structure's pointers point to: smbus2's data union, periphery's and
PureIO's message buffers) are Python's own, mapped and writable for the whole call.
"""

from __future__ import annotations

import ctypes
import errno
import operator
import os
import platform
import threading
from typing import Any

__all__ = ["AddressMemory", "BufferMemory", "IoctlArgument", "KeptAlive", "copy_from_user",
           "copy_to_user"]

ULONG_MASK = 0xFFFFFFFFFFFFFFFF  # an ioctl argument is an unsigned long (LP64)
USER_POINTER = 0x7FFF_0000_0000  # what the kernel sees as the argument when it is a buffer
IOCTL_BUFSZ = 1024  # CPython's fcntl.ioctl copies a buffer argument through 1024 bytes


def task_size_max() -> int:
    """The first address x86-64's ``access_ok`` refuses (arch/x86/include/asm/
    page_64_types.h: one page below 2**47, or 2**56 where the kernel runs 5-level page
    tables, which it shows as the ``la57`` CPU flag); past the address space elsewhere."""
    if platform.machine() not in ("x86_64", "AMD64"):
        return ULONG_MASK + 1
    flags: list[str] = []
    try:
        with open("/proc/cpuinfo", encoding="ascii", errors="replace") as cpuinfo:
            for line in cpuinfo:  # the first CPU's flags are every CPU's
                if line.startswith("flags"):
                    flags = line.split()
                    break
    except OSError:
        pass
    return (1 << (56 if "la57" in flags else 47)) - 4096


TASK_SIZE_MAX = task_size_max()


def _efault() -> OSError:
    return OSError(errno.EFAULT, os.strerror(errno.EFAULT))


class _IoVec(ctypes.Structure):
    _fields_ = [("base", ctypes.c_void_p), ("length", ctypes.c_size_t)]


class _Copier:
    """The kernel's copies between this process's addresses, chosen once: the
    process_vm calls, or a pipe where a sandbox refuses them."""

    def __init__(self) -> None:
        self.libc: Any = None
        self.use_pipe = False
        self.pipe: tuple[int, int] | None = None
        self.lock = threading.Lock()

    def _libc(self) -> Any:
        if self.libc is None:
            libc = ctypes.CDLL(None, use_errno=True)
            for name in ("process_vm_readv", "process_vm_writev"):
                function = getattr(libc, name)
                function.restype = ctypes.c_ssize_t
                function.argtypes = [ctypes.c_int, ctypes.POINTER(_IoVec), ctypes.c_ulong,
                                     ctypes.POINTER(_IoVec), ctypes.c_ulong, ctypes.c_ulong]
            for name in ("read", "write"):
                function = getattr(libc, name)
                function.restype = ctypes.c_ssize_t
                function.argtypes = [ctypes.c_int, ctypes.c_void_p, ctypes.c_size_t]
            self.libc = libc
        return self.libc

    def copy(self, address: int, local: Any, size: int, to_user: bool) -> None:
        """Copy ``size`` bytes between the user ``address`` and the ctypes buffer ``local``
        (into ``local`` unless ``to_user``); EFAULT unless every byte was copied."""
        if size == 0:
            return  # the kernel copies nothing and succeeds, whatever the address
        if not 0 <= address <= TASK_SIZE_MAX - size:  # access_ok
            raise _efault()
        libc = self._libc()
        if not self.use_pipe:
            mine = _IoVec(ctypes.addressof(local), size)
            theirs = _IoVec(address, size)
            call = libc.process_vm_writev if to_user else libc.process_vm_readv
            done = call(os.getpid(), ctypes.byref(mine), 1, ctypes.byref(theirs), 1, 0)
            if done == size:
                return
            code = ctypes.get_errno()
            if done >= 0 or code == errno.EFAULT:
                raise _efault()
            if code not in (errno.EPERM, errno.ENOSYS, errno.EACCES):
                raise OSError(code, os.strerror(code))
            self.use_pipe = True  # a sandbox without process_vm_*: the pipe route
        self._copy_through_pipe(address, local, size, to_user)

    def _copy_through_pipe(self, address: int, local: Any, size: int, to_user: bool) -> None:
        libc = self._libc()
        with self.lock:
            if self.pipe is None:
                self.pipe = os.pipe()
            reader, writer = self.pipe
            offset = 0
            while offset < size:  # a pipe holds 64 KiB at least; I2C copies are far smaller
                step = min(size - offset, 4096)
                source = ctypes.addressof(local) + offset if to_user else address + offset
                if libc.write(writer, source, step) != step:
                    raise _efault()
                target = address + offset if to_user else ctypes.addressof(local) + offset
                if libc.read(reader, target, step) != step:
                    libc.read(reader, ctypes.addressof(_DRAIN), step)  # leave the pipe empty
                    raise _efault()
                offset += step


_DRAIN = ctypes.create_string_buffer(4096)
_COPIER = _Copier()


def copy_from_user(address: int, size: int) -> bytes:
    """``size`` bytes at ``address`` of this process; OSError(EFAULT) where the kernel's
    copy_from_user would fault."""
    local = ctypes.create_string_buffer(size)
    _COPIER.copy(address, local, size, to_user=False)
    return local.raw


def copy_to_user(address: int, data: bytes) -> None:
    """Write ``data`` at ``address`` of this process; OSError(EFAULT) where the kernel's
    copy_to_user would fault (unmapped or read-only memory)."""
    local = ctypes.create_string_buffer(bytes(data), len(data))
    _COPIER.copy(address, local, len(data), to_user=True)


class KeptAlive:
    """The memory of every ctypes object an ioctl argument keeps alive through its pointers
    (ctypes' ``_objects``, documented as the objects that keep its memory valid), looked
    through when an address is asked about: a Python buffer argument without pointers
    costs nothing."""

    __slots__ = ("argument", "ranges")

    def __init__(self, argument: Any) -> None:
        self.argument = argument
        self.ranges: list[tuple[int, int]] = []  # the objects seen so far

    def covers(self, address: int, size: int) -> bool:
        """Whether ``address`` .. ``address + size`` lies inside one such object."""
        end = address + size
        for start, stop in self.ranges:
            if start <= address and end <= stop:
                return True
        if self.argument is None:
            return False
        stack: list[Any] = [getattr(self.argument, "_objects", None)]
        self.argument, self.ranges = None, []  # looked through once, completely
        found = False
        seen: set[int] = set()  # PureIO's structures point back at each other
        while stack:
            item: Any = stack.pop()
            if item is None or id(item) in seen:
                continue
            seen.add(id(item))
            kind = type(item)
            if kind is dict:
                stack.extend(item.values())
            elif kind is tuple or kind is list:
                stack.extend(item)
            else:
                try:
                    start = ctypes.addressof(item)
                except TypeError:
                    continue
                stop = start + ctypes.sizeof(item)
                self.ranges.append((start, stop))
                found = found or (start <= address and end <= stop)
                inner = getattr(item, "_objects", None)
                if inner:
                    stack.append(inner)
        return found


NOTHING_KNOWN = KeptAlive(None)


class AddressMemory:
    """``size`` bytes of this process at an address, reached as the kernel reaches user
    memory: a checked copy, or a direct one inside ``known`` ranges."""

    __slots__ = ("address", "known", "size")

    def __init__(self, address: int, size: int, known: KeptAlive = NOTHING_KNOWN) -> None:
        self.address, self.size, self.known = address, size, known

    def read(self) -> bytes:
        if self.known.covers(self.address, self.size):
            return ctypes.string_at(self.address, self.size)
        return copy_from_user(self.address, self.size)

    def write(self, data: bytes) -> None:
        data = data[: self.size]
        if self.known.covers(self.address, len(data)):
            ctypes.memmove(self.address, data, len(data))
            return
        copy_to_user(self.address, data)

    def follow(self, offset: int, size: int) -> AddressMemory:
        if self.known.covers(self.address + offset, 8):
            raw = ctypes.string_at(self.address + offset, 8)
        else:
            raw = copy_from_user(self.address + offset, 8)
        return AddressMemory(int.from_bytes(raw, "little"), size, self.known)


class BufferMemory:
    """A buffer given to ``fcntl.ioctl``: the memory the argument points to (Python owns
    it, so it is always there; the pointers stored in it are followed with checks, or
    directly into the ``known`` ranges)."""

    __slots__ = ("known", "size", "view")

    def __init__(self, view: memoryview, size: int, known: KeptAlive = NOTHING_KNOWN) -> None:
        self.view, self.size, self.known = view, size, known

    def read(self) -> bytes:
        view, size = self.view, self.size
        if len(view) == size:
            return bytes(view)
        return view[:size].tobytes().ljust(size, b"\0")  # beyond it: fcntl's zeroed copy

    def write(self, data: bytes) -> None:
        n = min(len(data), len(self.view))
        self.view[:n] = data[:n]

    def follow(self, offset: int, size: int) -> AddressMemory:
        raw = self.view[offset : offset + 8].tobytes().ljust(8, b"\0")
        return AddressMemory(int.from_bytes(raw, "little"), size, self.known)


def c_int(value: int) -> int:
    """fcntl.ioctl passes an integer argument as a C int (OverflowError beyond, as CPython)."""
    if value > 0x7FFFFFFF:
        raise OverflowError("signed integer is greater than maximum")
    if value < -0x80000000:
        raise OverflowError("signed integer is less than minimum")
    return value


class IoctlArgument:
    """``fcntl.ioctl``'s third argument as i2c-dev sees it: an integer (an unsigned long,
    perhaps a pointer), or a pointer to a buffer (a ctypes structure, a bytearray)."""

    __slots__ = ("known", "number", "view")

    def __init__(self, number: int | None, view: memoryview | None,
                 known: KeptAlive = NOTHING_KNOWN) -> None:
        self.number, self.view, self.known = number, view, known

    @classmethod
    def from_int(cls, value: Any) -> IoctlArgument:
        return cls(c_int(operator.index(value)), None)

    @property
    def value(self) -> int:
        return USER_POINTER if self.number is None else self.number & ULONG_MASK

    def memory(self, size: int) -> AddressMemory | BufferMemory:
        if self.view is not None:
            return BufferMemory(self.view, size, self.known)
        return AddressMemory(self.value, size)
