"""The firmware running in simavr, as a device behind the chip primitives.

``SimulatedFirmwareChip`` starts the harness (``firmware/sim/bmg160_sim.c``) on a built ELF
and turns each primitive into real I2C transactions on the simulated ATmega328P's TWI unit,
so ``I2CBus``/``FakeSMBus``/``patch_smbus`` drive the firmware exactly as they drive the Python
model. Time is the simulated CPU's: ``advance(seconds)`` runs that many cycles at 16 MHz and
every bus transaction takes its real duration at the chosen SCL frequency.

``peek`` and ``dump`` read the firmware's RAM (register file, FIFO and shadow state) through
simavr, so they have no side effect on the chip, as the contract asks.
"""

from __future__ import annotations

import contextlib
import errno
import os
import subprocess
import threading
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING

from bmg160_emu.device.contract import check_count, check_data, check_register
from bmg160_emu.firmware.build import (
    FirmwareBuild,
    FirmwareToolError,
    build_firmware,
    build_simulator,
    elf_symbols,
)

if TYPE_CHECKING:
    from typing_extensions import Self

F_CPU_HZ = 16_000_000  # the board's crystal (firmware/src/config.h)
BOOT_TIME_S = 0.040  # reset to first sample: boot plus the 30 ms start-up time (spec 6.6)
FIFO_CAPACITY = 100
_OUTSIDE_MAP = 0x40
_BIST_TIME_MS = 5  # firmware/src/regmap.c BIST_TIME_MS: the self-test takes 5 ms


class SimulatedFirmwareChip:
    """A BMG160 made of the bmg160-emu firmware in simavr (chip primitives of the contract).

    ``build`` is a :class:`FirmwareBuild`; without it the firmware is built for ``profile``,
    ``address``, ``noise_mode`` and ``seed``. ``scl_hz`` is the bus clock (400 kHz fast mode by
    default). ``time`` starts at 0 when the firmware has booted and produced its first sample
    period, as a Python ``BMG160`` that is already powered.
    """

    def __init__(
        self,
        build: FirmwareBuild | None = None,
        *,
        profile: str | Path = "paper",
        address: int = 0x68,
        noise_mode: str = "physical",
        seed: int = 1,
        scl_hz: int = 400_000,
    ) -> None:
        if build is None:
            build = build_firmware(profile=profile, address=address, mode=noise_mode, seed=seed)
        if not 1_000 <= int(scl_hz) <= 1_000_000:
            raise ValueError(f"scl_hz must be 1 kHz..1 MHz, not {scl_hz!r}")
        self.build = build
        self.address = _address_from_header(build.header)
        self.lock = threading.RLock()
        self.sample_hooks: list = []  # accepted for API parity; the firmware has no hooks
        self.truth_hooks: list = []
        self._symbols = elf_symbols(build.elf)
        simulator = build_simulator()
        self._proc = subprocess.Popen(
            [str(simulator), str(build.elf), "--scl", str(int(scl_hz))],
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
            bufsize=1,
        )
        self._cycle = 0
        self._origin = 0
        self._run_cycles(round(BOOT_TIME_S * F_CPU_HZ))
        self._origin = self._cycle

    # ------------------------------------------------------------------ harness protocol

    def _request(self, line: str) -> str:
        proc = self._proc
        if proc.poll() is not None:
            raise FirmwareToolError(f"the simavr harness has exited: {self._stderr()}")
        assert proc.stdin is not None and proc.stdout is not None
        proc.stdin.write(line + "\n")
        proc.stdin.flush()
        answer = proc.stdout.readline().strip()
        if not answer:
            raise FirmwareToolError(f"the simavr harness stopped answering: {self._stderr()}")
        return answer

    def _stderr(self) -> str:
        try:
            _, err = self._proc.communicate(timeout=1)
        except (subprocess.TimeoutExpired, ValueError):
            return "(no message)"
        return (err or "").strip().splitlines()[-1] if err and err.strip() else "(no message)"

    def _ok(self, answer: str, what: str) -> str:
        if answer == "ok" or answer.startswith("ok "):
            return answer[3:]
        if answer.startswith("nack"):
            raise OSError(errno.EREMOTEIO, f"{os.strerror(errno.EREMOTEIO)} ({what}: {answer})")
        raise FirmwareToolError(f"{what}: {answer}")

    def _run_cycles(self, cycles: int) -> None:
        self._cycle = int(self._ok(self._request(f"run {int(cycles)}"), "run"))

    def _sync_cycle(self) -> None:
        self._cycle = int(self._ok(self._request("cycle"), "cycle"))

    def _transaction(self, request: str, what: str) -> bytes:
        answer = self._ok(self._request(request), what)
        self._sync_cycle()
        return bytes.fromhex(answer) if answer else b""

    def close(self) -> None:
        """Stop the harness process."""
        proc = getattr(self, "_proc", None)
        if proc is not None and proc.poll() is None:
            try:
                assert proc.stdin is not None
                proc.stdin.write("quit\n")
                proc.stdin.flush()
                proc.wait(timeout=5)
            except (OSError, subprocess.TimeoutExpired):
                proc.kill()
                proc.wait()
        for stream in (proc.stdin, proc.stdout, proc.stderr) if proc else ():
            if stream:
                stream.close()

    def __enter__(self) -> Self:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def __del__(self) -> None:
        with contextlib.suppress(Exception):  # interpreter shutdown: streams may be gone
            self.close()

    # ------------------------------------------------------------------ the primitives

    @property
    def time(self) -> float:
        """Simulated seconds since the firmware was ready."""
        return (self._cycle - self._origin) / F_CPU_HZ

    @property
    def cycle(self) -> int:
        return self._cycle

    def write(self, reg: int, data: bytes | Sequence[int]) -> None:
        """One I2C write transaction: register address, then ``data`` (auto-increment)."""
        reg = check_register(reg)
        payload = check_data(data)
        with self.lock:
            self._transaction(f"w {self.address:x} {bytes([reg]).hex()}{payload.hex()}", "write")

    def read(self, reg: int, n: int = 1) -> bytes:
        """One combined transaction: register address, repeated START, ``n`` bytes."""
        reg = check_register(reg)
        n = _check_count(n)
        with self.lock:
            if n == 0:
                self.i2c_write(bytes([reg]))
                return b""
            return self._transaction(f"wr {self.address:x} {reg:02x} {n}", "read")

    def i2c_write(self, data: bytes | Sequence[int]) -> None:
        """I2C write: ``data[0]`` sets the register pointer, the rest is written from it."""
        payload = check_data(data)
        if not payload:
            return
        with self.lock:
            self._transaction(f"w {self.address:x} {payload.hex()}", "write")

    def i2c_read(self, n: int) -> bytes:
        """I2C read transaction of ``n`` bytes from the firmware's register pointer."""
        n = _check_count(n)
        if n == 0:
            return b""
        with self.lock:
            return self._transaction(f"r {self.address:x} {n}", "read")

    def advance(self, seconds: float) -> None:
        """Run the simulated CPU for ``seconds``."""
        seconds = float(seconds)
        if not seconds >= 0:
            raise ValueError(f"cannot advance by {seconds!r} s")
        with self.lock:
            self._run_cycles(round(seconds * F_CPU_HZ))

    def set_true_rate(self, rate: object) -> None:
        raise NotImplementedError(
            "the firmware generates a static gyro (true rate 0 deg/s): it has no rate input"
        )

    # ------------------------------------------------------------------ side-effect-free views

    def _ram(self, symbol: str) -> bytes:
        address, size = self._symbols[symbol]
        answer = self._ok(self._request(f"peek {address:x} {size}"), "peek")
        return bytes.fromhex(answer)

    def peek(self, reg: int) -> int:
        """Register content without side effects, from the firmware's RAM."""
        reg = check_register(reg)
        with self.lock:
            return self._peek_all()[reg] if reg < _OUTSIDE_MAP else 0

    def dump(self) -> bytes:
        """The 64 registers 0x00..0x3F without side effects."""
        with self.lock:
            return bytes(self._peek_all())

    def _peek_all(self) -> list[int]:
        regs = list(self._ram("bmg_regs"))
        locked = self._ram("msb_locked")[0]
        shadow = self._ram("msb_shadow")
        if not regs[0x13] & 0x40:
            for axis in range(3):
                if locked >> axis & 1:
                    regs[3 + 2 * axis] = shadow[axis]
        count = self._ram("fifo_count")[0]
        overrun = self._ram("fifo_overrun_flag")[0]
        regs[0x0E] = overrun << 7 | count
        status = 0
        if regs[0x15] & 0x40:
            level = max(regs[0x3D] & 0x7F, 1) if regs[0x1E] & 0x80 else FIFO_CAPACITY
            status |= 0x10 if count >= level else 0
        regs[0x0A] = status  # data_int is a 300 us pulse: not reconstructed here
        regs[0x3F] = self._fifo_next_byte(regs, count)
        regs[0x3C] = self._bist_byte()
        return regs

    def _ram_u16(self, symbol: str) -> int:
        return int.from_bytes(self._ram(symbol), "little")

    def _bist_byte(self) -> int:
        """BIST as a read returns it: the firmware computes it on each read from the sampler
        state and the self-test timer (firmware/src/regmap.c), so its RAM copy is stale."""
        value = 0x10 if self._ram("running")[0] and not self._ram_u16("startup_ticks") else 0
        if self._ram("bist_triggered")[0]:
            elapsed_ms = (self._ram_u16("ms") - self._ram_u16("bist_start_ms")) & 0xFFFF
            if elapsed_ms >= _BIST_TIME_MS:
                value |= 0x02  # bist_rdy; the firmware never reports bist_fail
        return value

    def _fifo_next_byte(self, regs: list[int], count: int) -> int:
        select = regs[0x3E] & 3
        data_bytes = 2 if select else 6
        pos = self._ram("fifo_byte_pos")[0]
        if pos >= data_bytes:
            return 0x00
        if not count:
            return 0x80 if pos & 1 else 0x00
        head = self._ram("fifo_head")[0]
        offset = 2 * (select - 1) + pos if select else pos
        address, _ = self._symbols["fifo_frames"]
        answer = self._ok(self._request(f"peek {address + 6 * head + offset:x} 1"), "peek")
        return bytes.fromhex(answer)[0]

    def stats(self) -> dict[str, int]:
        """Firmware counters: sample index, produced, missed, UART lines dropped, transactions."""
        with self.lock:
            raw = self._ram("sampler_stats")
            names = ("index", "produced", "missed", "uart_dropped")
            out = {n: int.from_bytes(raw[4 * i : 4 * i + 4], "little") for i, n in enumerate(names)}
            out["twi_transactions"] = int.from_bytes(self._ram("twi_transactions"), "little")
            return out

    def uart(self) -> bytes:
        """Bytes the firmware sent on its UART since the last call."""
        with self.lock:
            return bytes.fromhex(self._ok(self._request("uart"), "uart"))

    def __repr__(self) -> str:
        return f"SimulatedFirmwareChip(address=0x{self.address:02X}, t={self.time:.6f} s)"


def _address_from_header(header: Path) -> int:
    for line in Path(header).read_text(encoding="utf-8").splitlines():
        if line.startswith("#define BMG_I2C_ADDRESS"):
            return int(line.split()[2], 16)
    raise FirmwareToolError(f"{header} has no BMG_I2C_ADDRESS")


def _check_count(n: object) -> int:
    n = check_count(n)
    if n > 4096:
        raise ValueError("byte count must be <= 4096 for the simulated bus")
    return n
