"""``bmg160-emu demo``: a short driver-style session against the emulated chip, shown as tables.

The session is written the way a Python driver is written, against plain ``smbus2``; it runs
under ``patch_smbus`` so ``smbus2.SMBus(bus)`` reaches the emulated chip, and ``time.sleep``
advances the chip's virtual clock (unless ``--realtime``).
"""

from __future__ import annotations

import argparse
import contextlib
import time
from collections.abc import Callable, Iterator
from typing import Any

from bmg160_emu import limits
from bmg160_emu.commands._chip_options import RANGE_CODE_BY_DPS, add_chip_options, chips_from_args
from bmg160_emu.commands._common import (
    Subparsers,
    add_bus_option,
    add_command_parser,
    add_progress_options,
    bounded_option,
    integer_at_least,
    progress_for,
)
from bmg160_emu.device.registers import address_of, field_of

# Register addresses and fields from the table (spec section 3), and values the session writes.
(CHIP_ID, RATE_X_LSB, TEMP, INT_STATUS_1, FIFO_STATUS, RANGE, BW, LPM1, BGW_SOFTRESET, INT_EN_0,
 FIFO_CONFIG_1, FIFO_DATA) = (address_of(name) for name in (
    "CHIP_ID", "RATE_X_LSB", "TEMP", "INT_STATUS_1", "FIFO_STATUS", "RANGE", "BW", "LPM1",
    "BGW_SOFTRESET", "INT_EN_0", "FIFO_CONFIG_1", "FIFO_DATA"))
SOFT_RESET = 0xB6  # the reset command written to BGW_SOFTRESET (spec 4.13)
STARTUP_S = 0.030  # wait after soft reset (spec 6.6)
DATA_EN = field_of("INT_EN_0", "data_en").mask  # spec 4.14
DATA_INT = field_of("INT_STATUS_1", "data_int").mask  # spec 4.5
FIFO_MODE = field_of("FIFO_CONFIG_1", "fifo_mode").insert(0, 1)  # 1: FIFO, stops when full (4.26)
FRAME_BYTES = 6  # X, Y, Z frame without tag (spec 6.5)
BLOCK_BYTES = 30  # whole frames per SMBus block read (<= 32 bytes)
DEFAULT_BW_CODE = 4  # ODR 200 Hz, 23 Hz filter (spec 5.3)
POLL_S = 0.0005

EPILOG = """\
examples:
  bmg160-emu demo
  bmg160-emu demo --seed 7 --true-rate 10 0 -5 --range 250 --bandwidth 5 --samples 5
  bmg160-emu demo --no-noise --true-rate 100 0 0 --fifo-frames 4
"""


def register(subparsers: Subparsers) -> None:
    parser = add_command_parser(
        subparsers,
        "demo",
        "run a short driver-style session (smbus2) against the emulated chip",
        (
            "Run a driver-style session written against plain smbus2 under patch_smbus: "
            "chip ID, soft reset, normal mode, range and bandwidth, samples streamed by "
            "polling the new-data status, then a FIFO read; print what was read."
        ),
        EPILOG,
    )
    add_bus_option(parser, "I2C bus number (default 1)", default=1)
    parser.add_argument(
        "--samples",
        type=bounded_option(limits.DEMO_SAMPLES),
        default=8,
        metavar="N",
        help="samples to stream by polling (default 8)",
    )
    parser.add_argument(
        "--fifo-frames",
        type=_fifo_frames,
        default=6,
        metavar="N",
        help="frames to collect in FIFO mode and read back, 1..100 (default 6)",
    )
    add_progress_options(parser)
    add_chip_options(parser)
    parser.set_defaults(func=run)


def _fifo_frames(text: str) -> int:
    value = integer_at_least(1, "FIFO frames")(text)
    if value > 100:  # FIFO capacity (spec 6.5)
        raise argparse.ArgumentTypeError(f"the FIFO holds at most 100 frames, not {value}")
    return value


def _signed16(lsb: int, msb: int) -> int:
    value = lsb | msb << 8
    return value - 0x10000 if value & 0x8000 else value


class DemoDriver:
    """The session, written as a driver author would write it (spec 7)."""

    def __init__(self, bus: Any, address: int, out: Callable[[str], None]) -> None:
        self.bus = bus
        self.address = address
        self.out = out

    def reg(self, register: int) -> int:
        return self.bus.read_byte_data(self.address, register)

    def write(self, register: int, value: int) -> None:
        self.bus.write_byte_data(self.address, register, value)

    def bring_up(self, range_code: int, bw_code: int) -> None:
        from bmg160_emu.device.registers import register as describe

        chip_id = self.reg(CHIP_ID)
        if chip_id != 0x0F:
            raise RuntimeError(f"CHIP_ID reads 0x{chip_id:02X}, not 0x0F")
        self.write(BGW_SOFTRESET, SOFT_RESET)
        time.sleep(STARTUP_S)
        self.write(LPM1, 0x00)  # normal mode
        self.write(BW, bw_code)
        self.write(RANGE, range_code)
        self.write(INT_EN_0, DATA_EN)
        self.out("registers after bring-up:")
        for address in (CHIP_ID, RANGE, BW, LPM1, INT_EN_0):
            self.out(f"  0x{address:02X}  {describe(address).describe(self.reg(address))}")

    def stream(self, samples: int, sensitivity: float, odr_hz: float,
               done: Callable[[int], None] = lambda n: None) -> None:
        self.out("")
        self.out(
            f"streamed samples (polling INT_STATUS_1.data_int, {sensitivity:g} LSB per deg/s):"
        )
        self.out(f"  {'#':>3} {'x':>7} {'y':>7} {'z':>7}  {'x dps':>9} {'y dps':>9} {'z dps':>9}")
        deadline_s = 10.0 / odr_hz + 1.0
        for n in range(samples):
            waited = 0.0
            while not self.reg(INT_STATUS_1) & DATA_INT:
                if waited > deadline_s:
                    raise RuntimeError("no new data: the chip produced no sample")
                time.sleep(POLL_S)
                waited += POLL_S
            raw = self.bus.read_i2c_block_data(self.address, RATE_X_LSB, 6)
            counts = [_signed16(raw[i], raw[i + 1]) for i in (0, 2, 4)]
            dps = [c / sensitivity for c in counts]
            self.out(
                f"  {n:>3} {counts[0]:>7} {counts[1]:>7} {counts[2]:>7}  "
                f"{dps[0]:>9.3f} {dps[1]:>9.3f} {dps[2]:>9.3f}"
            )
            done(n + 1)
        temp = self.reg(TEMP)
        temp_signed = temp - 256 if temp & 0x80 else temp
        self.out(f"  TEMP 0x{temp:02X} -> {23 + temp_signed / 2:.1f} degC (spec 5.2)")

    def fifo(self, frames: int, sensitivity: float, odr_hz: float) -> None:
        self.write(FIFO_CONFIG_1, FIFO_MODE)  # empties the FIFO and starts FIFO mode
        waited = 0.0
        while self.reg(FIFO_STATUS) & 0x7F < frames and waited < frames / odr_hz + 1.0:
            time.sleep(1.0 / odr_hz)
            waited += 1.0 / odr_hz
        status = self.reg(FIFO_STATUS)
        count = min(status & 0x7F, frames)
        data: list[int] = []
        remaining = count * FRAME_BYTES
        while remaining:
            chunk = min(remaining, BLOCK_BYTES)
            data += self.bus.read_i2c_block_data(self.address, FIFO_DATA, chunk)
            remaining -= chunk
        self.out("")
        self.out(f"FIFO (FIFO_STATUS 0x{status:02X}: {status & 0x7F} frames stored), read {count}:")
        self.out(f"  {'#':>3} {'x':>7} {'y':>7} {'z':>7}  {'x dps':>9} {'y dps':>9} {'z dps':>9}")
        for n in range(count):
            f = data[n * FRAME_BYTES : (n + 1) * FRAME_BYTES]
            counts = [_signed16(f[i], f[i + 1]) for i in (0, 2, 4)]
            dps = [c / sensitivity for c in counts]
            self.out(
                f"  {n:>3} {counts[0]:>7} {counts[1]:>7} {counts[2]:>7}  "
                f"{dps[0]:>9.3f} {dps[1]:>9.3f} {dps[2]:>9.3f}"
            )
        self.out(f"  FIFO_STATUS after the read: 0x{self.reg(FIFO_STATUS):02X}")


@contextlib.contextmanager
def _sleep_advances(chip: Any) -> Iterator[None]:
    from bmg160_emu.clock import VirtualClock, virtual_sleep

    if isinstance(chip.clock, VirtualClock):
        with virtual_sleep(chip):
            yield
    else:
        yield


def run(args: argparse.Namespace) -> int:
    import smbus2

    from bmg160_emu.bus.patching import patch_smbus
    from bmg160_emu.commands._common import CommandError

    chips = chips_from_args(args)
    progress = progress_for(args, "demo")
    range_code = RANGE_CODE_BY_DPS[args.range_dps] if args.range_dps is not None else 0
    bw_code = args.bandwidth if args.bandwidth is not None else DEFAULT_BW_CODE
    first = next(iter(chips.values()))
    with patch_smbus({args.bus: chips}) as buses, _sleep_advances(first):
        for address, chip in chips.items():
            chip.hold_data_int = True  # emulator convenience so polling sees data_int (6.3)
            print(f"BMG160 at 0x{address:02X} on emulated /dev/i2c-{args.bus} (smbus2)")
            print(_given(args, chip, range_code, bw_code))
            print("(spec N.N below: section N.N of the BMG160 data sheet, "
                  "BST-BMG160-DS000-09)")
            with smbus2.SMBus(args.bus) as bus:
                driver = DemoDriver(bus, address, print)
                try:
                    driver.bring_up(range_code, bw_code)
                    # the progress line kept under the table's rows (both on a terminal)
                    with progress.beside(args.samples, "samples", print) as (update, say):
                        driver.out = say
                        driver.stream(args.samples, chip.sensitivity, chip.odr_hz, update)
                    driver.out = print
                    driver.fifo(args.fifo_frames, chip.sensitivity, chip.odr_hz)
                except BrokenPipeError:
                    raise  # the reader went away (e.g. `| head`): not a bus failure
                except (RuntimeError, OSError) as exc:
                    raise CommandError(f"session failed: {exc}") from None
            print()
        transactions = buses[args.bus].log.total
    print(f"{transactions} bus transactions; run with another --seed or --true-rate to vary.")
    return 0


REFERENCE_S = 20.0  # seconds of the reference chip behind the expected std (4000 samples at 200 Hz)


def _given(args: argparse.Namespace, chip: Any, range_code: int, bw_code: int) -> str:
    """What the chip is given (true rate, noise profile) and the std a reader should expect
    at rest: measured on REFERENCE_S of a second chip built from the same options (same
    seed, range and bandwidth), so the streamed values below can be judged."""
    rate = getattr(args, "true_rate", None) or (0.0, 0.0, 0.0)
    rate_text = " ".join(f"{r:g}" for r in rate)
    if getattr(args, "no_noise", False):
        return f"given: true rate {rate_text} deg/s (x y z), noise off (--no-noise)"
    from bmg160_emu.commands._chip_options import configs_from_args

    config = next(c for c in configs_from_args(args) if c.address == chip.address)
    std = _expected_std(args, config, range_code, bw_code)
    std_text = " ".join(f"{s:.3f}" for s in std)
    return (f"given: true rate {rate_text} deg/s (x y z), noise profile {config.profile!r}\n"
            f"expect: samples scattered with a std of {std_text} deg/s per axis ({REFERENCE_S:g} s "
            "of the same chip), about the true rate plus the turn-on bias")


def _expected_std(args: argparse.Namespace, config: Any, range_code: int, bw_code: int) -> Any:
    from bmg160_emu.clock import VirtualClock
    from bmg160_emu.session.record import record

    reference = config.build(args.seed, VirtualClock())
    reference.write(BGW_SOFTRESET, [SOFT_RESET])
    reference.advance(STARTUP_S)
    reference.write(BW, [bw_code])
    reference.write(RANGE, [range_code])
    rec = record(reference, REFERENCE_S)
    return (rec.counts / rec.lsb_per_dps).std(axis=0)
