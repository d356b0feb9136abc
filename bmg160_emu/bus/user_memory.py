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
PureIO's message buffers) whose memory is their own (allocated by them, or a buffer they
hold with ``from_buffer``, or a field of such an object) are mapped and writable for the
whole call. A kept-alive object that views other memory (``from_address``, what a pointer
points to) is anybody's address and goes through the checked copy like any other.
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
           "copy_to_user", "owned_range"]

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


_CDATA: Any = ctypes.c_char.__mro__[-2]  # _ctypes._CData: every ctypes instance
_FROM_BUFFER = "ffffffff"  # where from_buffer() keeps the memoryview it views (index -1)
_WALK_LIMIT = 256  # objects looked at per argument at most (a structure can be cyclic)

Range = tuple[int, int, Any]  # start, stop, the object that keeps that memory alive


def owned_range(item: Any) -> Range | None:
    """The memory of a ctypes object if it is there for as long as the object lives: it lies
    inside the memory of the object at the root of its ``_b_base_`` chain, and that root
    allocated its memory (``_b_needsfree_``) or views a buffer it holds on to
    (``from_buffer``). A field or an array element lies inside its root; what a pointer
    points to (``p.contents``, ``p[i]``: their base is the pointer) does not, nor does an
    object made by ``from_address`` (that address is anybody's), nor a field left behind
    by ``ctypes.resize`` of its root; those are None."""
    start = ctypes.addressof(item)
    stop = start + ctypes.sizeof(item)
    root = item
    while (base := root._b_base_) is not None:
        root = base
    if not root._b_needsfree_:
        objects = root._objects
        view = objects.get(_FROM_BUFFER) if objects.__class__ is dict else None
        if view.__class__ is not memoryview:
            return None
        try:
            view.nbytes  # noqa: B018 - released views answer ValueError
        except ValueError:
            return None
    if root is item:
        return start, stop, item
    first = ctypes.addressof(root)
    if first <= start and stop <= first + ctypes.sizeof(root):
        return start, stop, item
    return None


_INNER = "_objects"  # a step through a ctypes object to what it keeps alive
_EACH = "*"  # a step to every value of a dict keyed by id() (cast() keeps its source so)


def _walk(objects: Any) -> tuple[list[Range], list[tuple[Any, ...]]]:
    """The range of every ctypes object reachable from ``objects`` whose memory is its own,
    and the path to each (dict keys, tuple indices, _INNER and _EACH steps)."""
    ranges: list[Range] = []
    paths: list[tuple[Any, ...]] = []
    stack: list[tuple[Any, tuple[Any, ...]]] = [(objects, ())]
    seen: set[int] = set()  # PureIO's cast() objects keep themselves alive: a cycle
    looked = 0
    while stack and looked < _WALK_LIMIT:
        item, path = stack.pop()
        looked += 1
        kind = item.__class__
        if kind is dict:
            stack.extend((value, (*path, _EACH if key.__class__ is int else key))
                         for key, value in item.items())
        elif kind is tuple or kind is list:
            stack.extend((value, (*path, index)) for index, value in enumerate(item))
        elif isinstance(item, _CDATA) and id(item) not in seen:
            seen.add(id(item))
            owned = owned_range(item)
            if owned is not None:
                ranges.append(owned)
                paths.append(path)
            inner = item._objects
            if inner:
                stack.append((inner, (*path, _INNER)))
    return ranges, sorted(set(paths), key=repr)


def _follow(objects: Any, path: tuple[Any, ...], out: list[Range]) -> None:
    """Add the ranges of the objects ``path`` leads to from ``objects`` whose memory is
    theirs to ``out``. Only containers are indexed: a ctypes pointer indexed would be
    dereferenced."""
    items = [objects]
    for step in path:
        following = []
        for item in items:
            kind = item.__class__
            if step is _INNER:
                if isinstance(item, _CDATA) and item._objects:
                    following.append(item._objects)
            elif kind is dict:
                if step is _EACH:
                    following.extend(item.values())
                elif step in item:
                    following.append(item[step])
            elif (kind is tuple or kind is list) and step.__class__ is int and step < len(item):
                following.append(item[step])
        items = following
    for item in items:
        if isinstance(item, _CDATA):
            owned = owned_range(item)
            if owned is not None:
                out.append(owned)


def _lookup(objects: Any, path: tuple[Any, ...]) -> Any:
    """What a path of plain keys and indices leads to from ``objects``, or None."""
    item = objects
    for step in path:
        kind = item.__class__
        if kind is dict:
            item = item.get(step)
            if item is None:
                return None
        elif (kind is tuple or kind is list) and step.__class__ is int and step < len(item):
            item = item[step]
        else:
            return None
    return item


_KEYS = "keys"  # a path of dictionary keys alone
_PLAIN = "plain"  # of keys and sequence indices
_DEEP = "deep"  # through ctypes objects' _objects or every value of a dict (_follow)


def _kind_of(path: tuple[Any, ...]) -> str:
    if any(step is _INNER or step is _EACH for step in path):
        return _DEEP
    return _KEYS if all(step.__class__ is str for step in path) else _PLAIN


# argument type -> the paths in its ``_objects`` where objects whose memory is theirs were
# found last (its shape), each with its kind: the next request of the same library (new
# objects, the same shape) is looked up along them, not searched
_SHAPES: dict[type, list[tuple[tuple[Any, ...], str]]] = {}
_SHAPES_KEPT = 64  # argument types remembered at most


class KeptAlive:
    """The memory of the ctypes objects an ioctl argument keeps alive through its pointers
    (ctypes' ``_objects``, documented as the objects that keep its memory valid), found at
    the first question about an address and held until the call ends (a hook the transfer
    runs cannot free them): a Python buffer argument without pointers costs nothing. Only
    objects whose memory is theirs count (:func:`owned_range`). Where they lie in an
    argument is remembered per argument type, so smbus2's request (a new data union every
    call) is answered in two dictionary look-ups; an address outside what that shape finds
    gets one full search of the argument."""

    __slots__ = ("argument", "ranges", "searched")

    def __init__(self, argument: Any) -> None:
        self.argument = argument
        self.ranges: list[Range] | None = None
        self.searched = False

    def covers(self, address: int, size: int) -> bool:
        """Whether ``address`` .. ``address + size`` lies inside one such object."""
        end = address + size
        ranges = self.ranges
        if ranges is None:  # the first question: look where the shape says (inlined: this
            ranges = self.ranges = []  # is most of what a smbus2 read pays for the checks)
            shape = _SHAPES.get(self.argument.__class__)
            if shape is not None:
                objects = self.argument._objects
                for path, kind in shape:
                    if kind is _KEYS:  # dictionary keys alone, as smbus2's ('3', '1')
                        item = objects
                        for key in path:
                            item = item.get(key) if item.__class__ is dict else None
                    elif kind is _PLAIN:
                        item = _lookup(objects, path)
                    else:
                        _follow(objects, path, ranges)
                        continue
                    try:
                        if item._b_needsfree_ and item._b_base_ is None:  # its own memory,
                            start = ctypes.addressof(item)  # the usual case
                            ranges.append((start, start + ctypes.sizeof(item), item))
                            continue
                    except (AttributeError, TypeError):  # not a ctypes object (None, bytes)
                        continue
                    if isinstance(item, _CDATA):
                        owned = owned_range(item)
                        if owned is not None:
                            ranges.append(owned)
        for start, stop, _ in ranges:
            if start <= address and end <= stop:
                return True
        if self.searched:
            return False
        self.searched = True
        objects = getattr(self.argument, "_objects", None)
        if not objects:
            return False
        found, paths = _walk(objects)
        if len(_SHAPES) >= _SHAPES_KEPT:  # a program making a structure type per call
            _SHAPES.clear()
        _SHAPES[self.argument.__class__] = [(path, _kind_of(path)) for path in paths]
        ranges[:] = found
        return any(start <= address and end <= stop for start, stop, _ in found)


NOTHING_KNOWN = KeptAlive(None)
_CHAR_ARRAYS: dict[int, Any] = {}  # size -> ctypes.c_char * size (making a type is slow)


def _chars(size: int) -> Any:
    """The ctypes type of ``size`` bytes (a direct copy of known memory goes through it:
    its ``raw`` is a third cheaper than ctypes.string_at)."""
    array = _CHAR_ARRAYS.get(size)
    if array is None:
        array = _CHAR_ARRAYS.setdefault(size, ctypes.c_char * size)
    return array


class AddressMemory:
    """``size`` bytes of this process at an address, reached as the kernel reaches user
    memory: a checked copy, or a direct one inside ``known`` ranges."""

    __slots__ = ("address", "known", "size")

    def __init__(self, address: int, size: int, known: KeptAlive = NOTHING_KNOWN) -> None:
        self.address, self.size, self.known = address, size, known

    def read(self) -> bytes:
        address, size = self.address, self.size
        if self.known.covers(address, size):
            return _chars(size).from_address(address).raw
        return copy_from_user(address, size)

    def write(self, data: bytes) -> None:
        address, size = self.address, min(len(data), self.size)
        if self.known.covers(address, size):
            _chars(size).from_address(address).raw = data[:size]
            return
        copy_to_user(address, data[:size])

    def follow(self, offset: int, size: int) -> AddressMemory:
        at = self.address + offset
        if self.known.covers(at, 8):
            pointer = ctypes.c_uint64.from_address(at).value
        else:
            pointer = int.from_bytes(copy_from_user(at, 8), "little")
        return AddressMemory(pointer, size, self.known)


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
