"""Keep a Linux i2c-stub chip in step with the device model, so kernel drivers see a BMG160.

Why: the umockdev node reaches user-space programs only; a kernel driver (the kernel's own
``bmg160_i2c``) talks to an adapter in the kernel. Linux's ``i2c-stub`` module is such an
adapter: a 256-slot memory per chip address and no behaviour. This adapter process keeps
that memory current through ``/dev/i2c-N``: it preloads the register map, rewrites the
data and status registers at the output data rate, and applies what the client wrote
(range, bandwidth, power mode, soft reset, FIFO and interrupt set-up) to the model.

i2c-stub's memory model (drivers/i2c/i2c-stub.c): each slot holds 16 bits; byte and I2C
block transactions use the low byte of consecutive slots, a word read returns the whole
slot. Slot r is therefore kept as reg[r] | reg[r+1] << 8, so byte, word and block reads of
the rate registers agree. A refresh first sets the high bytes (word writes that keep each
low byte), then all low bytes of the data and status registers in one I2C block write: a
block read (what the kernel driver uses) always sees one sample, never half of two.

What i2c-stub cannot express, because it never tells the adapter about reads: FIFO pops
(FIFO_DATA does not drain), clear-on-read, and MSB shadowing between two byte reads. The
adapter shows the model's state without side effects (``chip.peek``); docs/i2c-stub.md
lists what follows.
"""

from __future__ import annotations

import errno
import itertools
import os
import time
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from bmg160_emu.bus import kernel_abi as abi
from bmg160_emu.device.power_modes import NORMAL, POWER_SAVE, power_mode
from bmg160_emu.device.registers import REGISTER_COUNT, address_of, field_of

STUB_ADAPTER_NAME = "SMBus stub driver"  # the name i2c-stub gives its adapter
DATA_FIRST, DATA_LAST = address_of("RATE_X_LSB"), address_of("FIFO_STATUS")  # refreshed every period
RANGE = address_of("RANGE")
CONFIG_FIRST, CONFIG_LAST = RANGE, address_of("FIFO_CONFIG_1")  # what a client may write
BGW_SOFTRESET = address_of("BGW_SOFTRESET")
SOFTRESET_COMMAND = 0xB6  # the reset command written to BGW_SOFTRESET (spec 4.13)
RANGE_FIELD = field_of("RANGE", "range")
POWER_MODE_REGISTERS = (address_of("LPM1"), address_of("LPM2"))
SAMPLING_MODES = (NORMAL, POWER_SAVE)  # the modes that take writes and sample (spec 6.7)


# Refreshing faster gains nothing a driver can see through sysfs and costs a core under
# QEMU's software emulation (measured in docs/i2c-stub.md); above it, samples in between
# are skipped and each refresh shows the newest.
DEFAULT_MAX_REFRESH_HZ = 500.0


class StubSetupError(RuntimeError):
    """The bus cannot carry the adapter: the message says what is wrong and what to do."""


def sysfs_adapter_name(bus: int, sysfs: Path = Path("/sys")) -> str | None:
    """The adapter's name as the kernel reports it, or None if the bus is unknown."""
    for path in (
        sysfs / "class" / "i2c-dev" / f"i2c-{bus}" / "name",
        sysfs / "bus" / "i2c" / "devices" / f"i2c-{bus}" / "name",
    ):
        try:
            return path.read_text().strip()
        except OSError:
            continue
    return None


def stub_chip_addresses(sysfs: Path = Path("/sys")) -> list[int] | None:
    """i2c-stub's ``chip_addr`` module parameter, or None when it cannot be read."""
    try:
        text = (sysfs / "module" / "i2c_stub" / "parameters" / "chip_addr").read_text()
    except OSError:
        return None
    values = [int(v, 0) for v in text.replace(",", " ").split()]
    return [v for v in values if v]


def check_stub_bus(bus: int, address: int, dev: Path = Path("/dev"),
                   sysfs: Path = Path("/sys")) -> Path:
    """The device node of i2c-stub bus ``bus`` if the adapter can run there, else
    :class:`StubSetupError` saying why (missing bus, not i2c-stub, wrong address, rights)."""
    node = dev / f"i2c-{bus}"
    name = sysfs_adapter_name(bus, sysfs)
    if not node.exists():
        if name is not None:
            raise StubSetupError(f"{node} does not exist: load the i2c-dev module (modprobe i2c-dev)")
        raise StubSetupError(
            f"I2C bus {bus} does not exist ({node} missing): load i2c-stub "
            "(modprobe i2c-stub chip_addr=0x68) and i2c-dev, then check `i2cdetect -l`"
        )
    if name is not None and not name.startswith(STUB_ADAPTER_NAME):
        raise StubSetupError(
            f"I2C bus {bus} is {name!r}, not an i2c-stub adapter: refusing to write to a real bus"
        )
    addresses = stub_chip_addresses(sysfs)
    if addresses is not None and address not in addresses:
        listed = ", ".join(f"0x{a:02x}" for a in addresses) or "none"
        raise StubSetupError(
            f"0x{address:02x} is not one of i2c-stub's chip addresses ({listed}): reload it "
            f"with chip_addr=0x{address:02x}"
        )
    if not os.access(node, os.R_OK | os.W_OK):
        raise StubSetupError(f"permission denied on {node}: run as root or join its group")
    return node


def bound_driver(bus: int, address: int, sysfs: Path = Path("/sys")) -> str | None:
    """The name of the kernel driver bound to ``address`` on bus ``bus``, or None."""
    try:
        return os.path.basename(os.readlink(
            sysfs / "bus" / "i2c" / "devices" / f"{bus}-{address:04x}" / "driver"))
    except OSError:
        return None


@dataclass
class RefreshStats:
    """Timing of the refresh loop: when each refresh started, and CPU time spent."""

    starts: deque = field(default_factory=lambda: deque(maxlen=100_000))
    odrs: deque = field(default_factory=lambda: deque(maxlen=100_000))  # ODR at each start
    cpu_s: float = 0.0
    wall_s: float = 0.0
    client_writes: int = 0
    resets: int = 0

    def periods(self) -> list[float]:
        return [b - a for a, b in itertools.pairwise(self.starts)]

    def periods_by_odr(self) -> dict[float, list[float]]:
        """Refresh periods grouped by the output data rate in force at both ends."""
        groups: dict[float, list[float]] = {}
        pairs = itertools.pairwise(zip(self.starts, self.odrs))
        for (t0, odr0), (t1, odr1) in pairs:
            if odr0 == odr1:
                groups.setdefault(odr0, []).append(t1 - t0)
        return groups

    def summary(self) -> dict[str, Any]:
        periods = self.periods()
        if not periods:
            return {"refreshes": float(len(self.starts))}
        mean = sum(periods) / len(periods)
        jitter = (sum((p - mean) ** 2 for p in periods) / len(periods)) ** 0.5
        by_odr = {}
        for odr, group in sorted(self.periods_by_odr().items()):
            m = sum(group) / len(group)
            by_odr[f"{odr:g}"] = {
                "refreshes": len(group) + 1,
                "period_mean_s": m,
                "period_median_s": sorted(group)[len(group) // 2],
                "period_jitter_s": (sum((p - m) ** 2 for p in group) / len(group)) ** 0.5,
            }
        return {
            "refreshes": float(len(self.starts)),
            "period_mean_s": mean,
            "period_jitter_s": jitter,
            "period_max_s": max(periods),
            "cpu_fraction": self.cpu_s / self.wall_s if self.wall_s else 0.0,
            "client_writes": float(self.client_writes),
            "resets": float(self.resets),
            "by_odr_hz": by_odr,
        }


class I2CStubAdapter:
    """Mirror ``chip`` into i2c-stub's memory for ``address`` on ``/dev/i2c-<bus>``.

    ``smbus`` is anything with smbus2's methods (``smbus2.SMBus(bus, force=True)`` by
    default: while a kernel driver is bound, ``I2C_SLAVE`` answers EBUSY, so the adapter
    always uses ``I2C_SLAVE_FORCE``).
    """

    def __init__(
        self,
        chip: Any,
        bus: int,
        address: int = 0x68,
        smbus: Any = None,
        max_refresh_hz: float = DEFAULT_MAX_REFRESH_HZ,
    ) -> None:
        self.chip = chip
        self.bus_number = bus
        self.address = address
        if smbus is None:
            from smbus2 import SMBus

            smbus = SMBus(bus, force=True)
        self.smbus = smbus
        # What the adapter last put in each slot's low byte (None: unknown).
        self.shadow: list[int | None] = [None] * REGISTER_COUNT
        self.high: list[int | None] = [None] * REGISTER_COUNT  # each slot's high byte
        self.stats = RefreshStats()
        self.max_refresh_hz = max_refresh_hz
        # Each client write applied to the model, with the model's state after it.
        self.events: list[dict[str, Any]] = []

    # ------------------------------------------------------------------ stub memory

    def _write_words(self, image: bytes, first: int, last: int) -> None:
        """Slots first..last: high byte = reg[r+1], low byte kept as the stub has it."""
        for r in range(first, last + 1):
            high = image[r + 1] if r + 1 < len(image) else 0
            known = self.shadow[r]
            low = image[r] if known is None else known
            if self.high[r] != high:
                self.smbus.write_word_data(self.address, r, low | high << 8)
                self.high[r] = high
                self.shadow[r] = low

    def _write_lows(self, image: bytes, first: int, last: int) -> None:
        """Low bytes first..last in as few I2C block writes as possible (32 bytes each)."""
        start = first
        while start <= last:
            end = min(last, start + abi.I2C_SMBUS_BLOCK_MAX - 1)
            chunk = image[start : end + 1]
            if any(self.shadow[start + i] != b for i, b in enumerate(chunk)):
                self.smbus.write_i2c_block_data(self.address, start, list(chunk))
                self.shadow[start : end + 1] = list(chunk)
            start = end + 1

    def preload(self) -> None:
        """Put the whole register map (reset values, or the model's current state) in place."""
        image = self.chip.dump()
        self._write_words(image, 0x00, REGISTER_COUNT - 1)
        self._write_lows(image, 0x00, REGISTER_COUNT - 1)

    def adopt(self) -> dict[int, int]:
        """Take the configuration found in the stub's memory into the model (a driver is
        bound and configured the chip before this adapter started: preloading reset values
        would silently undo its range, bandwidth and interrupt set-up). The registers that
        differ from the model's are applied as client writes; returns them."""
        config = self._read_config()
        writes = {
            CONFIG_FIRST + i: value
            for i, value in enumerate(config)
            if self.chip.peek(CONFIG_FIRST + i) != value
        }
        if writes:
            self.apply_client_writes(writes)
        return writes

    def _read_config(self) -> bytes:
        first = self.smbus.read_i2c_block_data(self.address, CONFIG_FIRST, 32)
        rest = self.smbus.read_i2c_block_data(
            self.address, CONFIG_FIRST + 32, CONFIG_LAST - CONFIG_FIRST + 1 - 32
        )
        return bytes(first + rest)

    # ------------------------------------------------------------------ one refresh

    def client_writes(self, config: bytes) -> dict[int, int]:
        """Registers whose stub content differs from what the adapter put there."""
        return {
            CONFIG_FIRST + i: value
            for i, value in enumerate(config)
            if self.shadow[CONFIG_FIRST + i] != value
        }

    def apply_client_writes(self, writes: dict[int, int]) -> None:
        """Apply the client's writes to the model in an order that loses none of them.

        i2c-stub does not say in which order the client wrote, only what changed in one
        period. A soft reset goes first (the client wrote the rest after it, or it would have
        been lost). Power-mode writes (LPM1, LPM2) go last when they enter a mode that does
        not sample (suspend ignores most writes, spec 6.7: the kernel's runtime suspend can
        land in the same period as its probe writes) and first when they leave one (the
        client woke the chip before configuring it); the others follow in address order."""
        chip = self.chip
        with chip.lock:
            if writes.get(BGW_SOFTRESET) == SOFTRESET_COMMAND:
                chip.write(BGW_SOFTRESET, bytes([SOFTRESET_COMMAND]))
                self.stats.resets += 1
            power = [r for r in sorted(writes) if r in POWER_MODE_REGISTERS]
            others = [r for r in sorted(writes) if r not in POWER_MODE_REGISTERS
                      and r != BGW_SOFTRESET]
            lpm = [chip.peek(r) for r in POWER_MODE_REGISTERS]
            for register in power:
                lpm[POWER_MODE_REGISTERS.index(register)] = writes[register]
            wakes = power_mode(*lpm) in SAMPLING_MODES
            for register in (power + others if wakes else others + power):
                chip.write(register, bytes([writes[register]]))
                self.stats.client_writes += 1
            for register in sorted(writes):
                self.events.append({
                    "time_s": time.monotonic(),
                    "register": register,
                    "value": writes[register],
                    "odr_hz": chip.odr_hz,
                    "range": RANGE_FIELD.extract(chip.peek(RANGE)),
                    "power_mode": chip.power_mode,
                })

    def refresh(self) -> None:
        """Poll the client's writes, apply them, then bring the stub up to the model."""
        config = self._read_config()
        writes = self.client_writes(config)
        if writes:
            self.apply_client_writes(writes)
            for register, value in writes.items():
                self.shadow[register] = value  # what the stub holds now
        image = self.chip.dump()
        # Data and status: word pass (high bytes), then one atomic block write of low bytes.
        self._write_words(image, 0x00, DATA_LAST)
        self._write_lows(image, DATA_FIRST, DATA_LAST)
        # Configuration: only where the model differs from the stub (a normalised client
        # write: read-only bits, self-clearing bits, the reset command, or a reset). Each is
        # re-read first so a write the client made meanwhile is never overwritten.
        for register in range(CONFIG_FIRST, CONFIG_LAST + 1):
            if self.shadow[register] == image[register]:
                continue
            expected = self.shadow[register]
            if expected is not None and (
                self.smbus.read_byte_data(self.address, register) != expected
            ):
                continue  # the client wrote again meanwhile: handle it next period
            self.smbus.write_byte_data(self.address, register, image[register])
            self.shadow[register] = image[register]
        # Word reads of a configuration slot return reg[r] | reg[r+1] << 8: when reg[r+1]
        # changed (a client write, a reset), rewrite the slot's high byte. A word write sets
        # the low byte too, so it is made only while the stub still holds the adapter's low
        # byte (re-read first), as for the write-back above.
        for register in range(CONFIG_FIRST, CONFIG_LAST + 1):
            high = image[register + 1] if register + 1 < len(image) else 0
            low = self.shadow[register]
            if self.high[register] == high or low is None:
                continue
            if self.smbus.read_byte_data(self.address, register) != low:
                continue  # the client wrote this register meanwhile: next period
            self.smbus.write_word_data(self.address, register, low | high << 8)
            self.high[register] = high

    def output_data_rate_hz(self) -> float:
        return float(self.chip.odr_hz)

    def refresh_period_s(self) -> float:
        """One output data period, but no faster than ``max_refresh_hz``."""
        return 1.0 / min(self.output_data_rate_hz(), self.max_refresh_hz)

    # ------------------------------------------------------------------ the loop

    def run(
        self,
        duration_s: float | None = None,
        should_stop: Callable[[], bool] | None = None,
        period_s: float | None = None,
        preload: bool = True,
    ) -> RefreshStats:
        """Refresh once per output period (or ``period_s``) until ``duration_s`` has passed
        or ``should_stop()`` is true. A late refresh is not made up: the next one is due
        one period after the last deadline, so the loop never bursts."""
        if preload:
            self.preload()
        wall0, cpu0 = time.monotonic(), time.process_time()
        deadline = wall0
        try:
            while True:
                now = time.monotonic()
                if duration_s is not None and now - wall0 >= duration_s:
                    break
                if should_stop is not None and should_stop():
                    break
                self.stats.starts.append(now)
                self.stats.odrs.append(self.output_data_rate_hz())
                try:
                    self.refresh()
                except OSError as exc:
                    if exc.errno not in (errno.ENXIO, errno.EAGAIN, errno.EBUSY):
                        raise
                period = period_s or self.refresh_period_s()
                deadline += period
                now = time.monotonic()
                if deadline < now:
                    deadline = now  # late: start again from now
                else:
                    time.sleep(deadline - now)
        finally:
            self.stats.wall_s += time.monotonic() - wall0
            self.stats.cpu_s += time.process_time() - cpu0
        return self.stats

    def close(self) -> None:
        close = getattr(self.smbus, "close", None)
        if close is not None:
            close()
