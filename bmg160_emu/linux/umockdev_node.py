"""A virtual ``/dev/i2c-N`` for unmodified programs, answered by the emulator through umockdev.

Why: programs that were never written for the emulator (i2c-tools, smbus2, C code calling
``ioctl`` on ``/dev/i2c-N``) should see a BMG160 without root and without a kernel module.
umockdev's preload library redirects their ``open``/``ioctl``/``read``/``write`` on the
device node to a socket; :class:`I2CDevHandler` answers each request as the kernel's
i2c-dev driver would (drivers/i2c/i2c-dev.c: argument checks, the ``I2C_SMBUS`` size
conversions, per-open-file address and PEC flag) and hands the transaction itself to
:class:`~bmg160_emu.i2c_bus.I2CBus`, so SMBus semantics, errors, hooks and the transaction
log are the ones every other front end has.

Needs umockdev (Debian ``umockdev``, ``gir1.2-umockdev-1.0``) and PyGObject. The children
run with ``LD_PRELOAD=libumockdev-preload.so.0`` and the testbed's ``UMOCKDEV_DIR``.
"""

from __future__ import annotations

import errno
import os
import struct
import subprocess
from collections.abc import Iterable, Mapping, Sequence
from typing import Any

from bmg160_emu.i2c_bus import I2CBus, I2CMessage
from bmg160_emu.linux import i2c_dev_structs as abi

PRELOAD_LIBRARY = "libumockdev-preload.so.0"
I2C_DEV_MAJOR = 89  # Documentation/admin-guide/devices.txt: "89 char I2C bus interface"


class UMockdevUnavailable(RuntimeError):
    """umockdev or PyGObject is missing: the message says which package to install."""


def load_umockdev() -> Any:
    """The ``gi.repository.UMockdev`` module, or :class:`UMockdevUnavailable` saying why not."""
    try:
        import gi
    except ImportError:
        raise UMockdevUnavailable(
            "PyGObject is not importable (pip install 'PyGObject<3.50' after "
            "apt-get install libgirepository1.0-dev libcairo2-dev pkg-config gcc)"
        ) from None
    try:
        gi.require_version("UMockdev", "1.0")
        from gi.repository import UMockdev
    except (ValueError, ImportError):
        raise UMockdevUnavailable(
            "the UMockdev typelib is missing (apt-get install umockdev gir1.2-umockdev-1.0)"
        ) from None
    return UMockdev


def preload_available() -> bool:
    """True if the dynamic loader can find umockdev's preload library."""
    for folder in ("/usr/lib/x86_64-linux-gnu", "/usr/lib/aarch64-linux-gnu", "/usr/lib64",
                   "/usr/lib", "/usr/local/lib"):
        if os.path.exists(os.path.join(folder, PRELOAD_LIBRARY)):
            return True
    return False


class OpenFile:
    """What i2c-dev keeps per open file descriptor: the target address and client flags."""

    __slots__ = ("address", "pec", "tenbit")

    def __init__(self) -> None:
        self.address = 0
        self.pec = False
        self.tenbit = False


def _ulong(raw: bytes) -> int:
    return int.from_bytes(raw[:8], "little")


class I2CDevAnswers:
    """i2c-dev's ioctl, read and write semantics over one :class:`I2CBus`, free of umockdev.

    Each method takes the open file's state and plain Python values and returns the
    syscall's result or raises ``OSError(errno)``; the umockdev handler only moves bytes.
    """

    def __init__(self, bus: I2CBus) -> None:
        self.bus = bus

    def set_address(self, state: OpenFile, address: int, force: bool) -> int:
        # i2c-dev: EINVAL above 0x7f (0x3ff with I2C_TENBIT), EBUSY when a driver holds it.
        if address > (0x3FF if state.tenbit else 0x7F):
            raise OSError(errno.EINVAL, os.strerror(errno.EINVAL))
        if address <= 0x7F:
            self.bus.check_address(address, force=force)
        state.address = address
        return 0

    def smbus(
        self, state: OpenFile, read_write: int, command: int, size: int, data: bytearray | None
    ) -> tuple[int, bool]:
        """One ``I2C_SMBUS`` request; ``data`` is the 34-byte union (None for a null pointer).
        Returns (result, copy data back to the client)."""
        if size not in abi.SMBUS_SIZE_NAMES or read_write not in (abi.I2C_SMBUS_READ,
                                                                   abi.I2C_SMBUS_WRITE):
            raise OSError(errno.EINVAL, os.strerror(errno.EINVAL))
        address, pec, reading = state.address, state.pec, read_write == abi.I2C_SMBUS_READ
        bus = self.bus
        if size == abi.I2C_SMBUS_QUICK:
            bus.write_quick(address, read=reading)
            return 0, False
        if size == abi.I2C_SMBUS_BYTE and not reading:
            bus.write_byte(address, command, pec=pec)
            return 0, False
        if data is None:
            raise OSError(errno.EINVAL, os.strerror(errno.EINVAL))
        if size == abi.I2C_SMBUS_I2C_BLOCK_BROKEN:  # i2c-dev converts the old convention
            size = abi.I2C_SMBUS_I2C_BLOCK_DATA
            if reading:
                data[0] = abi.I2C_SMBUS_BLOCK_MAX
        if state.tenbit and address > 0x7F:
            raise OSError(errno.ENXIO, os.strerror(errno.ENXIO))
        word = data[0] | data[1] << 8
        count = data[0]
        if size == abi.I2C_SMBUS_BYTE:
            data[0] = bus.read_byte(address, pec=pec)
        elif size == abi.I2C_SMBUS_BYTE_DATA:
            if reading:
                data[0] = bus.read_byte_data(address, command, pec=pec)
            else:
                bus.write_byte_data(address, command, data[0], pec=pec)
        elif size == abi.I2C_SMBUS_WORD_DATA:
            if reading:
                data[0:2] = bus.read_word_data(address, command, pec=pec).to_bytes(2, "little")
            else:
                bus.write_word_data(address, command, word, pec=pec)
        elif size == abi.I2C_SMBUS_PROC_CALL:
            data[0:2] = bus.process_call(address, command, word, pec=pec).to_bytes(2, "little")
            return 0, True
        elif size == abi.I2C_SMBUS_BLOCK_DATA:
            if reading:
                block = bus.read_block_data(address, command, pec=pec)
                data[0] = len(block)
                data[1 : 1 + len(block)] = block
            else:
                if count > abi.I2C_SMBUS_BLOCK_MAX:
                    raise OSError(errno.EINVAL, os.strerror(errno.EINVAL))
                bus.write_block_data(address, command, bytes(data[1 : 1 + count]), pec=pec)
        elif size == abi.I2C_SMBUS_BLOCK_PROC_CALL:
            if count > abi.I2C_SMBUS_BLOCK_MAX:
                raise OSError(errno.EINVAL, os.strerror(errno.EINVAL))
            block = bus.block_process_call(address, command, bytes(data[1 : 1 + count]), pec=pec)
            data[0] = len(block)
            data[1 : 1 + len(block)] = block
            return 0, True
        elif size == abi.I2C_SMBUS_I2C_BLOCK_DATA:
            if count > abi.I2C_SMBUS_BLOCK_MAX:
                raise OSError(errno.EINVAL, os.strerror(errno.EINVAL))
            if reading:
                data[1 : 1 + count] = bus.read_i2c_block_data(address, command, count)
            else:
                bus.write_i2c_block_data(address, command, bytes(data[1 : 1 + count]))
        return 0, reading

    def rdwr(self, messages: Sequence[tuple[abi.I2CMessage, bytes]]) -> list[bytes]:
        """One ``I2C_RDWR`` combined transfer: (header, write data) per message; returns the
        data of each message (filled in for reads)."""
        if not 1 <= len(messages) <= abi.I2C_RDWR_IOCTL_MAX_MSGS:
            raise OSError(errno.EINVAL, os.strerror(errno.EINVAL))
        bus_messages = []
        for header, payload in messages:
            if header.length > abi.I2C_DEV_MAX_TRANSFER:
                raise OSError(errno.EINVAL, os.strerror(errno.EINVAL))
            if header.flags & abi.I2C_M_RECV_LEN:
                # The count-prefixed read needs the adapter to resize a message mid-transfer;
                # the emulated adapter does not offer it (documented limit).
                raise OSError(errno.EOPNOTSUPP, os.strerror(errno.EOPNOTSUPP))
            if header.flags & abi.I2C_M_TEN:
                raise OSError(errno.ENXIO, os.strerror(errno.ENXIO))
            if header.is_read:
                bus_messages.append(I2CMessage.read_message(header.addr, header.length))
            else:
                bus_messages.append(I2CMessage.write(header.addr, payload))
        done = self.bus.i2c_transfer(bus_messages)
        return [m.data for m in done]

    def read(self, state: OpenFile, count: int) -> bytes:
        count = min(count, abi.I2C_DEV_MAX_TRANSFER)  # i2c-dev caps read() at 8192 bytes
        return self.bus.i2c_read(state.address, count)

    def write(self, state: OpenFile, payload: bytes) -> int:
        if len(payload) > abi.I2C_DEV_MAX_TRANSFER:
            payload = payload[: abi.I2C_DEV_MAX_TRANSFER]
        self.bus.i2c_write(state.address, payload)
        return len(payload)


def _handler_class(UMockdev: Any) -> type:
    """Build the IoctlBase subclass (its base exists only once gi has loaded UMockdev)."""

    class I2CDevHandler(UMockdev.IoctlBase):
        """Moves bytes between umockdev's client and :class:`I2CDevAnswers`."""

        def __init__(self, bus: I2CBus) -> None:
            super().__init__()
            self.answers = I2CDevAnswers(bus)
            self._files: dict[int, OpenFile] = {}
            self.errors: list[str] = []

        def _state(self, client: Any) -> OpenFile:
            return self._files.setdefault(hash(client), OpenFile())

        def do_client_connected(self, client: Any) -> None:
            self._files[hash(client)] = OpenFile()  # a new open(): address 0, no PEC

        def do_handle_ioctl(self, client: Any) -> bool:
            try:
                result = self._ioctl(client, client.get_request(), client.get_arg())
            except OSError as exc:
                client.complete(-1, exc.errno or errno.EIO)
            except Exception as exc:  # noqa: BLE001 - never leave a client hanging on a bug
                self.errors.append(repr(exc))
                client.complete(-1, errno.EIO)
            else:
                client.complete(result, 0)
            return True

        def do_handle_read(self, client: Any) -> bool:
            arg = client.get_arg()
            try:
                count = len(arg.retrieve())
                data = self.answers.read(self._state(client), count)
                if data:
                    arg.update(0, list(data))
            except OSError as exc:
                client.complete(-1, exc.errno or errno.EIO)
            except Exception as exc:  # noqa: BLE001 - reported through handler_errors
                self.errors.append(repr(exc))
                client.complete(-1, errno.EIO)
            else:
                client.complete(len(data), 0)
            return True

        def do_handle_write(self, client: Any) -> bool:
            arg = client.get_arg()
            try:
                written = self.answers.write(self._state(client), bytes(arg.retrieve()))
            except OSError as exc:
                client.complete(-1, exc.errno or errno.EIO)
            except Exception as exc:  # noqa: BLE001 - reported through handler_errors
                self.errors.append(repr(exc))
                client.complete(-1, errno.EIO)
            else:
                client.complete(written, 0)
            return True

        def _ioctl(self, client: Any, request: int, arg: Any) -> int:
            state = self._state(client)
            value = _ulong(bytes(arg.retrieve()))
            if request in (abi.I2C_SLAVE, abi.I2C_SLAVE_FORCE):
                return self.answers.set_address(state, value, request == abi.I2C_SLAVE_FORCE)
            if request == abi.I2C_FUNCS:
                out = arg.resolve(0, 8)
                if out is None:
                    raise OSError(errno.EFAULT, os.strerror(errno.EFAULT))
                out.update(0, list(struct.pack("=Q", self.answers.bus.funcs)))
                return 0
            if request == abi.I2C_PEC:
                state.pec = bool(value)
                return 0
            if request == abi.I2C_TENBIT:
                state.tenbit = bool(value)
                return 0
            if request in (abi.I2C_RETRIES, abi.I2C_TIMEOUT):
                if value > 0x7FFFFFFF:
                    raise OSError(errno.EINVAL, os.strerror(errno.EINVAL))
                return 0  # the emulated adapter never retries nor times out
            if request == abi.I2C_SMBUS:
                return self._smbus(state, arg)
            if request == abi.I2C_RDWR:
                return self._rdwr(arg)
            raise OSError(errno.ENOTTY, os.strerror(errno.ENOTTY))

        def _smbus(self, state: OpenFile, arg: Any) -> int:
            request = arg.resolve(0, abi.SMBUS_IOCTL_DATA_SIZE)
            if request is None:
                raise OSError(errno.EFAULT, os.strerror(errno.EFAULT))
            header = bytes(request.retrieve())
            scalar = abi.SMBusRequest.unpack(header)
            has_data = _ulong(header[abi.SMBUS_DATA_OFFSET :]) != 0
            union = None
            data = None
            needs_data = not (
                scalar.size == abi.I2C_SMBUS_QUICK
                or (scalar.size == abi.I2C_SMBUS_BYTE and scalar.read_write == abi.I2C_SMBUS_WRITE)
            )
            if has_data and needs_data:
                union = request.resolve(abi.SMBUS_DATA_OFFSET, abi.SMBUS_DATA_SIZE)
                data = bytearray(union.retrieve())
            result, copy_back = self.answers.smbus(
                state, scalar.read_write, scalar.command, scalar.size, data
            )
            if copy_back and union is not None and data is not None:
                union.update(0, list(data))
            return result

        def _rdwr(self, arg: Any) -> int:
            request = arg.resolve(0, abi.RDWR_IOCTL_DATA_SIZE)
            if request is None:
                raise OSError(errno.EFAULT, os.strerror(errno.EFAULT))
            count = abi.unpack_rdwr_count(bytes(request.retrieve()))
            if not 1 <= count <= abi.I2C_RDWR_IOCTL_MAX_MSGS:
                raise OSError(errno.EINVAL, os.strerror(errno.EINVAL))
            table = request.resolve(0, count * abi.I2C_MSG_SIZE)
            if table is None:
                raise OSError(errno.EFAULT, os.strerror(errno.EFAULT))
            raw = bytes(table.retrieve())
            messages, buffers = [], []
            for i in range(count):
                header = abi.I2CMessage.unpack(raw, i * abi.I2C_MSG_SIZE)
                if header.length > abi.I2C_DEV_MAX_TRANSFER:
                    raise OSError(errno.EINVAL, os.strerror(errno.EINVAL))
                buffer = None
                if header.length:
                    buffer = table.resolve(i * abi.I2C_MSG_SIZE + abi.I2C_MSG_BUF_OFFSET,
                                           header.length)
                    if buffer is None:
                        raise OSError(errno.EFAULT, os.strerror(errno.EFAULT))
                payload = b"" if header.is_read or buffer is None else bytes(buffer.retrieve())
                messages.append((header, payload))
                buffers.append(buffer)
            results = self.answers.rdwr(messages)
            for (header, _), buffer, data in zip(messages, buffers, results):
                if header.is_read and buffer is not None and data:
                    buffer.update(0, list(data))
            return count  # i2c_transfer() returns the number of messages

    return I2CDevHandler


class VirtualI2CDevices:
    """A umockdev testbed holding one ``/dev/i2c-N`` per :class:`I2CBus`.

    Use as a context manager; :meth:`environment` gives what a child process needs, and
    :meth:`run` starts one and waits for it. Requests are answered on umockdev's worker
    thread while the caller waits.
    """

    def __init__(self, buses: Iterable[I2CBus]) -> None:
        self.buses = list(buses)
        numbers = [b.number for b in self.buses]
        if len(set(numbers)) != len(numbers):
            raise ValueError(f"two buses share a number: {numbers}")
        self._umockdev = load_umockdev()
        if not preload_available():
            raise UMockdevUnavailable(
                f"{PRELOAD_LIBRARY} is missing (apt-get install libumockdev0 umockdev)"
            )
        self.testbed: Any = None
        self.handlers: list[Any] = []

    def __enter__(self) -> VirtualI2CDevices:  # noqa: PYI034 - Python 3.10 has no Self
        self.open()
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def open(self) -> None:
        UMockdev = self._umockdev
        self.testbed = UMockdev.Testbed.new()
        handler_class = _handler_class(UMockdev)
        for bus in self.buses:
            n = bus.number
            description = (
                f"P: /devices/virtual/i2c-dev/i2c-{n}\n"
                f"N: i2c-{n}\n"
                "E: SUBSYSTEM=i2c-dev\n"
                f"E: DEVNAME=/dev/i2c-{n}\n"
                f"E: MAJOR={I2C_DEV_MAJOR}\nE: MINOR={n}\n"
                f"A: dev={I2C_DEV_MAJOR}:{n}\n"
                f"A: name=bmg160-emu virtual adapter {n}\n"
            )
            if not self.testbed.add_from_string(description):
                raise RuntimeError(f"umockdev refused the description of /dev/i2c-{n}")
            handler = handler_class(bus)
            if not self.testbed.attach_ioctl(f"/dev/i2c-{n}", handler):
                raise RuntimeError(f"umockdev could not attach a handler to /dev/i2c-{n}")
            self.handlers.append(handler)

    def close(self) -> None:
        if self.testbed is not None:
            for bus in self.buses:
                self.testbed.detach_ioctl(f"/dev/i2c-{bus.number}")
            self.testbed = None
            self.handlers = []

    @property
    def root_dir(self) -> str:
        return self.testbed.get_root_dir()

    def environment(self, base: Mapping[str, str] | None = None) -> dict[str, str]:
        """Environment for a child: the preload library first, the testbed's directory."""
        env = dict(os.environ if base is None else base)
        preload = env.get("LD_PRELOAD", "")
        env["LD_PRELOAD"] = PRELOAD_LIBRARY + (":" + preload if preload else "")
        env["UMOCKDEV_DIR"] = self.root_dir
        return env

    def popen(self, command: Sequence[str], **kwargs: Any) -> subprocess.Popen:
        kwargs.setdefault("env", self.environment())
        return subprocess.Popen(list(command), **kwargs)

    def run(self, command: Sequence[str], **kwargs: Any) -> subprocess.CompletedProcess:
        """``subprocess.run`` with the testbed's environment."""
        kwargs.setdefault("env", self.environment())
        return subprocess.run(list(command), check=False, **kwargs)

    def handler_errors(self) -> list[str]:
        """Unexpected exceptions the handlers turned into EIO (empty when all went well)."""
        return [e for h in self.handlers for e in h.errors]
