"""I2CBus: the SMBus and plain-I2C transaction kinds of a Linux adapter, mapped onto the chip.

Every I2C front end (FakeSMBus, the smbus2 patch, the umockdev /dev/i2c-N handler) calls one
method per transaction kind here, so errors, PEC, fault hooks and the transaction log are the
same whichever front end carried the traffic.

Mapping (spec 2.1): the chip has no SMBus protocol of its own. A command byte is a register
address, reads auto-increment, and a host SMBus block read takes the first byte returned (the
content of the register) as the count. Errors are the errno values the Linux i2c core and a
typical adapter give: no device at an address -> EREMOTEIO (121, the address is NACKed),
malformed request -> EINVAL, bad block count -> EPROTO, PEC mismatch -> EBADMSG.
"""

from __future__ import annotations

import errno
import itertools
import os
from collections.abc import Callable, Iterable, Mapping, Sequence
from typing import Any

from bmg160_emu.bus.kernel_abi import (
    I2C_DEV_MAX_TRANSFER,
    I2C_FUNC_SMBUS_EMUL,
    I2C_RDWR_IOCTL_MAX_MSGS,
    I2C_SMBUS_BLOCK_MAX,
)
from bmg160_emu.bus.wire import WiredChip, WireFault
from bmg160_emu.bus.wrote import check_wrote
from bmg160_emu.traffic.kinds import (
    I2C_FUNC_I2C,
    I2C_FUNC_SMBUS_BLOCK_PROC_CALL,
    I2C_FUNC_SMBUS_READ_BLOCK_DATA,
    KIND_FUNCS,
)
from bmg160_emu.traffic.transaction import TransactionLog, errno_name

__all__ = [
    "DEFAULT_FUNCS",
    "I2C_SMBUS_BLOCK_MAX",
    "I2CBus",
    "I2CMessage",
    "os_error",
    "smbus_pec",
]

I2C_RDWR_MAX_MSG_LEN = I2C_DEV_MAX_TRANSFER  # i2c-dev refuses longer messages
SCAN_FIRST, SCAN_LAST = 0x08, 0x77  # the addresses a scan probes

# A plain-I2C adapter with the core's SMBus emulation plus receive-length support (so SMBus
# block reads and block process calls work, as the spec's mapping asks).
DEFAULT_FUNCS = (
    I2C_FUNC_I2C
    | I2C_FUNC_SMBUS_EMUL
    | I2C_FUNC_SMBUS_READ_BLOCK_DATA
    | I2C_FUNC_SMBUS_BLOCK_PROC_CALL
)

TransactionHook = Callable[["I2CBus", int, int, str], None]


def os_error(code: int) -> OSError:
    """The OSError fcntl.ioctl raises for a failed ioctl: ``OSError(121, 'Remote I/O error')``."""
    return OSError(code, os.strerror(code))


def _crc8_table() -> list[int]:
    table = []
    for byte in range(256):
        crc = byte
        for _ in range(8):
            crc = ((crc << 1) ^ 0x07) & 0xFF if crc & 0x80 else (crc << 1) & 0xFF
        table.append(crc)
    return table


_CRC8 = _crc8_table()


def smbus_pec(data: Iterable[int], crc: int = 0) -> int:
    """SMBus packet error code: CRC-8, polynomial x^8 + x^2 + x + 1, over the address bytes
    (7-bit address << 1 | R/W) and data bytes of every message (SMBus 2.0, 5.4.1)."""
    for byte in data:
        crc = _CRC8[crc ^ byte]
    return crc


class I2CMessage:
    """One message of a plain-I2C combined transfer (``struct i2c_msg``): a write of
    ``data`` or a read of ``length`` bytes; after the transfer a read message holds ``data``."""

    __slots__ = ("address", "data", "length", "read")

    def __init__(self, address: int, read: bool, data: bytes = b"", length: int = 0) -> None:
        self.address = address
        self.read = read
        self.data = bytes(data)
        self.length = length if read else len(self.data)

    @classmethod
    def write(cls, address: int, data: bytes | Sequence[int]) -> I2CMessage:
        return cls(address, False, bytes(data))

    @classmethod
    def read_message(cls, address: int, length: int) -> I2CMessage:
        return cls(address, True, b"", length)

    def __repr__(self) -> str:
        if self.read:
            return f"I2CMessage.read(0x{self.address:02x}, {self.length}) -> {self.data.hex(' ')}"
        return f"I2CMessage.write(0x{self.address:02x}, {self.data.hex(' ')})"


class I2CBus:
    """One emulated I2C adapter: bus number, ``devices`` {7-bit address: chip}, the log.

    ``transaction_hooks``: callables ``hook(bus, index, address, kind)`` run before each
    transaction (``index`` counts transactions on this bus from 0); an ``OSError`` raised by a
    hook fails the transaction as a real adapter would (NACK = EREMOTEIO, timeout = ETIMEDOUT).
    A hook whose attribute ``takes_register`` is true is called as ``hook(bus, index, address,
    kind, register)`` (the register the transaction names, or None) and may return a
    :class:`~bmg160_emu.bus.wire.WireFault`: the bytes the host reads and the data bytes the
    device receives pass through it (a corrupted byte on the wire; the PEC is checked after
    it, as the host's adapter checks it).

    A transaction is what an SMBus call is on the wire: one kind, one index, one log entry.
    In a plain-I2C transfer (``i2c_transfer``) a write followed by a read of the same
    address is one transaction too, of kind ``i2c_read`` naming the register its write
    set (``register``, the write's other bytes in ``written``): a register read, the same
    whether smbus2, Blinka, periphery or MicroPython sent it. Every other message is a
    transaction of its own (``i2c_write``, or ``i2c_read`` from the current pointer,
    ``register`` None).
    ``claimed``: addresses a kernel driver has bound; ``I2C_SLAVE`` on them gives EBUSY unless
    forced. ``funcs``: the adapter's functionality mask; a kind whose bit is missing fails with
    EOPNOTSUPP. ``nack_errno``: the errno of an address nobody acknowledges (EREMOTEIO).
    """

    def __init__(
        self,
        number: int = 1,
        devices: Mapping[int, Any] | None = None,
        *,
        funcs: int = DEFAULT_FUNCS,
        log: TransactionLog | None = None,
        claimed: Iterable[int] = (),
    ) -> None:
        if not isinstance(number, int) or number < 0:
            raise ValueError(f"I2C bus number must be an integer >= 0, not {number!r}")
        self.number = number
        self.devices: dict[int, Any] = {}
        for address, chip in (devices or {}).items():
            self.attach(address, chip)
        self.log = log if log is not None else TransactionLog()
        self.transaction_hooks: list[TransactionHook] = []
        self.claimed: set[int] = set(claimed)
        # errno of an address NACK: EREMOTEIO on i2c-bcm2835 (Raspberry Pi) and most
        # adapters; some (i2c-designware, i2c-i801) give ENXIO. Set it to match a target.
        self.nack_errno = errno.EREMOTEIO
        self.indices = itertools.count()  # transaction indices; next() is atomic across threads
        self.funcs = funcs

    # ------------------------------------------------------------------ configuration

    @property
    def funcs(self) -> int:
        return self._funcs

    @funcs.setter
    def funcs(self, value: int) -> None:
        """The adapter's I2C_FUNC_* bits; ``unsupported`` follows: the transaction kinds
        they leave out (read, with ``indices``, by FakeSMBus's polling lane)."""
        self._funcs = int(value)
        self.unsupported = frozenset(k for k, bit in KIND_FUNCS.items() if not value & bit)

    @property
    def path(self) -> str:
        """The device node a Linux program would open for this bus."""
        return f"/dev/i2c-{self.number}"

    def attach(self, address: int, chip: Any) -> None:
        """Put ``chip`` on the bus at the 7-bit ``address``."""
        if not isinstance(address, int) or not 0 <= address <= 0x7F:
            raise ValueError(f"I2C address must be a 7-bit integer 0x00..0x7f, not {address!r}")
        for name in ("read", "write", "i2c_read", "i2c_write", "lock"):
            if not hasattr(chip, name):
                raise TypeError(f"device at 0x{address:02x} has no {name!r}: not a chip model")
        self.devices[address] = chip

    def detach(self, address: int) -> None:
        self.devices.pop(address, None)

    def check_address(self, address: int, force: bool = False) -> None:
        """What ``ioctl(I2C_SLAVE[_FORCE], address)`` checks: EINVAL above 0x7f, EBUSY when a
        kernel driver holds the address and the call is not forced."""
        if not 0 <= address <= 0x7F:
            raise os_error(errno.EINVAL)
        if not force and address in self.claimed:
            raise os_error(errno.EBUSY)

    # ------------------------------------------------------------------ bookkeeping

    def _time(self, chip: Any) -> float:
        if chip is None:
            chip = next(iter(self.devices.values()), None)
        return float(chip.time) if chip is not None else 0.0

    def _record(
        self,
        chip: Any,
        address: int,
        kind: str,
        register: int | None,
        written: bytes = b"",
        read: bytes = b"",
        error: str | None = None,
    ) -> None:
        if chip.__class__ is WiredChip:
            chip.finish()  # its faults report before the transaction's entry
        if self.log.enabled:
            self.log.record(
                self._time(chip), self.number, address, kind, register, written, read, error
            )

    def _fail(
        self,
        chip: Any,
        address: int,
        kind: str,
        register: int | None,
        code: int,
        written: bytes = b"",
        read: bytes = b"",
    ) -> OSError:
        self._record(chip, address, kind, register, written, read, errno_name(code))
        return os_error(code)

    def _begin(
        self, address: int, kind: str, register: int | None = None, written: bytes = b""
    ) -> Any:
        """Run the hooks and find the device; raise the adapter's error if there is none."""
        index = next(self.indices)
        if kind in self.unsupported:
            raise os_error(errno.EOPNOTSUPP)
        chip = self.devices.get(address)
        if self.transaction_hooks:
            wires: list[WireFault] = []
            for hook in list(self.transaction_hooks):
                try:
                    if getattr(hook, "takes_register", False):
                        wire = hook(self, index, address, kind, register)  # type: ignore[call-arg]
                        if wire is not None:
                            wires.append(wire)
                    else:
                        hook(self, index, address, kind)
                except OSError as exc:
                    self._record(
                        chip, address, kind, register, written, b"", errno_name(exc.errno or 0)
                    )
                    raise
            if wires and chip is not None:
                return WiredChip(chip, wires)
        if chip is None:
            raise self._fail(None, address, kind, register, self.nack_errno, written)
        return chip

    @staticmethod
    def _check_pec(address: int, prefix: bytes, received: bytes) -> bool:
        """True if the last byte of ``received`` is the PEC of the whole transaction."""
        crc = smbus_pec(prefix) if prefix else 0
        crc = smbus_pec(bytes([address << 1 | 1]) + received[:-1], crc)
        return crc == received[-1]

    def _read_with_pec(
        self,
        chip: Any,
        address: int,
        kind: str,
        register: int | None,
        written: bytes,
        data: bytes,
        pec: bool,
    ) -> bytes:
        """Strip and verify the PEC byte of a read (i2c core: i2c_smbus_check_pec)."""
        if not pec:
            return data
        prefix = bytes([address << 1]) + written if written else b""
        if not self._check_pec(address, prefix, data):
            raise self._fail(chip, address, kind, register, errno.EBADMSG, written[1:], data)
        return data[:-1]

    @staticmethod
    def _pec_suffix(address: int, message: bytes, pec: bool) -> bytes:
        return bytes([smbus_pec(bytes([address << 1]) + message)]) if pec else b""

    # ------------------------------------------------------------------ SMBus kinds

    def write_quick(self, address: int, read: bool = False) -> None:
        """SMBus quick command: the address alone, no data; only the ACK matters."""
        kind = "read_quick" if read else "write_quick"
        chip = self._begin(address, kind)
        self._record(chip, address, kind, None)

    def read_byte(self, address: int, pec: bool = False) -> int:
        """SMBus receive byte: a read from the chip's current register pointer."""
        chip = self._begin(address, "read_byte")
        with chip.lock:
            data = chip.i2c_read(1 + pec)
        data = self._read_with_pec(chip, address, "read_byte", None, b"", data, pec)
        self._record(chip, address, "read_byte", None, b"", data)
        return data[0]

    def write_byte(self, address: int, value: int, pec: bool = False) -> None:
        """SMBus send byte: one byte that the chip takes as a register address (pointer)."""
        chip = self._begin(address, "write_byte", value)
        message = bytes([value])
        chip.i2c_write(message + self._pec_suffix(address, message, pec))
        self._record(chip, address, "write_byte", value)

    def read_byte_data(self, address: int, register: int, pec: bool = False) -> int:
        chip = self._begin(address, "read_byte_data", register)
        data = chip.read(register, 1 + pec)
        data = self._read_with_pec(
            chip, address, "read_byte_data", register, bytes([register]), data, pec
        )
        self._record(chip, address, "read_byte_data", register, b"", data)
        return data[0]

    def write_byte_data(self, address: int, register: int, value: int, pec: bool = False) -> None:
        chip = self._begin(address, "write_byte_data", register)
        data = bytes([value])
        # With PEC the chip, which knows no PEC, takes the extra byte as data for register+1.
        chip.write(register, data + self._pec_suffix(address, bytes([register]) + data, pec))
        self._record(chip, address, "write_byte_data", register, data)

    def read_word_data(self, address: int, register: int, pec: bool = False) -> int:
        """Two bytes from ``register`` on, returned as byte0 | byte1 << 8 (spec 2.1)."""
        chip = self._begin(address, "read_word_data", register)
        data = chip.read(register, 2 + pec)
        data = self._read_with_pec(
            chip, address, "read_word_data", register, bytes([register]), data, pec
        )
        self._record(chip, address, "read_word_data", register, b"", data)
        return data[0] | data[1] << 8

    def write_word_data(self, address: int, register: int, value: int, pec: bool = False) -> None:
        chip = self._begin(address, "write_word_data", register)
        data = bytes([value & 0xFF, value >> 8 & 0xFF])
        chip.write(register, data + self._pec_suffix(address, bytes([register]) + data, pec))
        self._record(chip, address, "write_word_data", register, data)

    def process_call(self, address: int, register: int, value: int, pec: bool = False) -> int:
        """Write a word from ``register`` on, then (repeated start) read a word from where the
        chip's pointer went: register + 2."""
        chip = self._begin(address, "process_call", register)
        data = bytes([value & 0xFF, value >> 8 & 0xFF])
        written = bytes([register]) + data
        with chip.lock:
            chip.i2c_write(written)
            received = chip.i2c_read(2 + pec)
        received = self._read_with_pec(
            chip, address, "process_call", register, written, received, pec
        )
        self._record(chip, address, "process_call", register, data, received)
        return received[0] | received[1] << 8

    def read_block_data(self, address: int, register: int, pec: bool = False) -> bytes:
        """SMBus block read: the first byte (the content of ``register``) is the count, then
        that many bytes follow in the same burst. A count above 32 fails with EPROTO."""
        chip = self._begin(address, "read_block_data", register)
        with chip.lock:
            chip.i2c_write(bytes([register]))
            head = chip.i2c_read(1)
            count = head[0]
            if count > I2C_SMBUS_BLOCK_MAX:
                raise self._fail(
                    chip, address, "read_block_data", register, errno.EPROTO, b"", head
                )
            received = head + chip.i2c_read(count + pec)
        received = self._read_with_pec(
            chip, address, "read_block_data", register, bytes([register]), received, pec
        )
        self._record(chip, address, "read_block_data", register, b"", received)
        return received[1:]

    def write_block_data(self, address: int, register: int, data: bytes, pec: bool = False) -> None:
        """SMBus block write: count byte then data, all taken by the chip as register data."""
        if len(data) > I2C_SMBUS_BLOCK_MAX:
            raise os_error(errno.EINVAL)
        chip = self._begin(address, "write_block_data", register)
        payload = bytes([len(data)]) + bytes(data)
        chip.write(register, payload + self._pec_suffix(address, bytes([register]) + payload, pec))
        self._record(chip, address, "write_block_data", register, payload)

    def block_process_call(
        self, address: int, register: int, data: bytes, pec: bool = False
    ) -> bytes:
        """Block write then block read in one transaction (count byte first both ways)."""
        if len(data) > I2C_SMBUS_BLOCK_MAX:
            raise os_error(errno.EINVAL)
        chip = self._begin(address, "block_process_call", register)
        payload = bytes([len(data)]) + bytes(data)
        written = bytes([register]) + payload
        with chip.lock:
            chip.i2c_write(written)
            head = chip.i2c_read(1)
            if head[0] > I2C_SMBUS_BLOCK_MAX:
                raise self._fail(
                    chip, address, "block_process_call", register, errno.EPROTO, payload, head
                )
            received = head + chip.i2c_read(head[0] + pec)
        received = self._read_with_pec(
            chip, address, "block_process_call", register, written, received, pec
        )
        self._record(chip, address, "block_process_call", register, payload, received)
        return received[1:]

    def read_i2c_block_data(self, address: int, register: int, length: int) -> bytes:
        """The burst read drivers use: ``length`` (0..32) bytes from ``register`` on. The i2c
        core sends no PEC for this kind."""
        if not 0 <= length <= I2C_SMBUS_BLOCK_MAX:
            raise os_error(errno.EINVAL)
        chip = self._begin(address, "read_i2c_block_data", register)  # (FakeSMBus inlines
        data = chip.read(register, length)  # this for a polling driver's hot path)
        self._record(chip, address, "read_i2c_block_data", register, b"", data)
        return data

    def write_i2c_block_data(self, address: int, register: int, data: bytes) -> None:
        if len(data) > I2C_SMBUS_BLOCK_MAX:
            raise os_error(errno.EINVAL)
        chip = self._begin(address, "write_i2c_block_data", register)
        data = bytes(data)
        chip.write(register, data)
        self._record(chip, address, "write_i2c_block_data", register, data)

    # ------------------------------------------------------------------ plain I2C

    def i2c_transfer(self, messages: Sequence[I2CMessage], *,
                     kernel_limits: bool = True) -> list[I2CMessage]:
        """A combined transfer (``I2C_RDWR``): messages separated by repeated starts, one stop
        at the end. Read messages get their ``data`` filled in. A message to an address
        without a device stops the transfer with EREMOTEIO; earlier messages took effect
        (the error's ``messages_done`` counts them).
        ``kernel_limits``: i2c-dev's 1..42 messages of at most 8192 bytes (EINVAL); a
        microcontroller's bus (MicroPython, CircuitPython) has none of them."""
        if kernel_limits and not 1 <= len(messages) <= I2C_RDWR_IOCTL_MAX_MSGS:
            raise os_error(errno.EINVAL)
        for message in messages:
            if ((kernel_limits and message.length > I2C_RDWR_MAX_MSG_LEN)
                    or not 0 <= message.address <= 0x7F):
                raise os_error(errno.EINVAL)
        chips = {id(c): c for m in messages if (c := self.devices.get(m.address)) is not None}
        # one transfer: no other thread between its messages (the chips' locks held, taken in
        # one order; acquire and release, not an ExitStack: 2-3 us of a FIFO read)
        locks = [chips[key].lock for key in sorted(chips)]
        for lock in locks:
            lock.acquire()
        i = 0
        try:
            while i < len(messages):
                message = messages[i]
                following = messages[i + 1] if i + 1 < len(messages) else None
                if (not message.read and message.data and following is not None
                        and following.read and following.address == message.address):
                    self._register_read(message, following)  # write, restart, read
                    i += 2
                    continue
                if message.read:
                    chip = self._begin(message.address, "i2c_read")
                    message.data = chip.i2c_read(message.length) if message.length else b""
                    self._record(chip, message.address, "i2c_read", None, b"", message.data)
                else:
                    data = message.data
                    register = data[0] if data else None
                    chip = self._begin(message.address, "i2c_write", register, data[1:])
                    if data:
                        chip.i2c_write(data)
                    self._record(chip, message.address, "i2c_write", register, data[1:])
                i += 1
        except OSError as exc:
            exc.messages_done = i  # type: ignore[attr-defined]  # those took effect
            raise
        finally:
            for lock in reversed(locks):
                lock.release()
        return list(messages)

    def _register_read(self, write: I2CMessage, read: I2CMessage) -> None:
        """A write then (repeated start) a read of one address: one transaction, a register
        read (kind ``i2c_read`` naming the register the write set)."""
        address, data = write.address, write.data
        register, written = data[0], data[1:]
        chip = self._begin(address, "i2c_read", register, written)
        chip.i2c_write(data)
        read.data = chip.i2c_read(read.length) if read.length else b""
        self._record(chip, address, "i2c_read", register, written, read.data)

    def probe(self, address: int) -> bool:
        """Whether a device acknowledges ``address``: a write of no data, its NACK caught
        (MicroPython's and CircuitPython's ``scan``/``probe``)."""
        try:
            self.i2c_transfer([I2CMessage.write(address, b"")])
        except OSError:
            return False
        return True

    def scan(self) -> list[int]:
        """The 7-bit addresses 0x08..0x77 that acknowledge (0b0000xxx and 0b1111xxx are
        reserved; MicroPython's and CircuitPython's ``scan`` probe the same range)."""
        return [address for address in range(SCAN_FIRST, SCAN_LAST + 1) if self.probe(address)]

    def i2c_write(self, address: int, data: bytes | Sequence[int]) -> None:
        """A plain I2C write (``write()`` on /dev/i2c-N): data[0] sets the pointer."""
        self.i2c_transfer([I2CMessage.write(address, data)])

    def i2c_read(self, address: int, length: int) -> bytes:
        """A plain I2C read (``read()`` on /dev/i2c-N) from the chip's current pointer."""
        return self.i2c_transfer([I2CMessage.read_message(address, length)])[0].data

    def writes(self, address: int | None = None) -> list[tuple[int, int]]:
        """``(register, value)`` of every byte written into the device at ``address`` (the
        first attached by default), one pair per register, whichever kind carried it."""
        return self.log.register_writes(self._device_address(address))

    def assert_wrote(self, before: str | None = None, address: int | None = None,
                     **values: int) -> None:
        """Assert the driver wrote each ``NAME=value`` (the device's register names) to the
        device at ``address`` (the first attached by default) and, with ``before="NAME"``,
        each before its first write of NAME; the failure lists every write."""
        __tracebackhide__ = True
        address = self._device_address(address)
        check_wrote(self.writes(address), self.devices[address], values, before)

    def _device_address(self, address: int | None) -> int:
        if address is None:
            if not self.devices:
                raise ValueError(f"bus {self.number} has no device")
            return next(iter(self.devices))
        if address not in self.devices:
            raise ValueError(f"no device at 0x{address:02x} on bus {self.number}")
        return address

    def __repr__(self) -> str:
        devices = ", ".join(f"0x{a:02x}" for a in sorted(self.devices))
        return f"<I2CBus {self.number} devices [{devices}]>"
