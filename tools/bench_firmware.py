"""Firmware figures: flash/RAM, samples per second the ATmega328P sustains, I2C transactions
per simulated second while it generates noise at 200 Hz, and simavr's simulated-to-wall speed
against the Python model generating the same samples in the same run.

    python tools/bench_firmware.py [--seconds 2] [--capture-seconds 20]
"""

from __future__ import annotations

import argparse
import subprocess
import tempfile
import time
from pathlib import Path

from bmg160_emu.device.chip import BMG160
from bmg160_emu.firmware.build import (
    ATMEGA328P_FLASH,
    ATMEGA328P_SRAM,
    build_firmware,
    build_simulator,
    capture_uart,
)
from bmg160_emu.firmware.simulated import F_CPU_HZ, SimulatedFirmwareChip

BW_FOR_ODR = {2000: 0x01, 1000: 0x02, 400: 0x03, 200: 0x04, 100: 0x05}


def sustained_rates(build, seconds: float) -> dict[int, tuple[float, float]]:
    """ODR -> (samples produced per simulated second, periods missed per second)."""
    out = {}
    for odr, code in BW_FOR_ODR.items():
        with SimulatedFirmwareChip(build) as chip:
            chip.write(0x10, bytes([code]))
            chip.advance(0.1)
            before = chip.stats()
            chip.advance(seconds)
            after = chip.stats()
        out[odr] = (
            (after["produced"] - before["produced"]) / seconds,
            (after["missed"] - before["missed"]) / seconds,
        )
    return out


def transactions_per_second(build, seconds: float, scl_hz: int, nbytes: int) -> tuple:
    """Back-to-back combined reads of nbytes at RATE_X_LSB while sampling at 200 Hz."""
    simulator = build_simulator()
    proc = subprocess.Popen(
        [str(simulator), str(build.elf), "--scl", str(scl_hz)],
        stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True,
    )  # fmt: skip
    requests = (
        f"run {F_CPU_HZ // 10}\nw 68 1004\nrun {F_CPU_HZ // 10}\nbench {seconds:g} {nbytes}\nquit\n"
    )
    answers = proc.communicate(requests, timeout=600)[0].split("\n")
    bench = [a for a in answers if a.startswith("ok ") and len(a.split()) == 3][-1].split()
    count, cycles = int(bench[1]), int(bench[2])
    return count / (cycles / F_CPU_HZ), cycles


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=2.0, help="simulated s per measurement")
    parser.add_argument("--capture-seconds", type=float, default=20.0)
    args = parser.parse_args()

    for normal in ("ziggurat", "polar", "box-muller"):
        build = build_firmware(profile="paper", normal=normal)
        print(f"== normal generator: {normal}")
        print(f"flash {build.flash_bytes} / {ATMEGA328P_FLASH} bytes "
              f"({100 * build.flash_bytes / ATMEGA328P_FLASH:.1f} %), static RAM "
              f"{build.ram_bytes} / {ATMEGA328P_SRAM} bytes "
              f"({100 * build.ram_bytes / ATMEGA328P_SRAM:.1f} %)")  # fmt: skip
        for odr, (produced, missed) in sustained_rates(build, args.seconds).items():
            print(f"  ODR {odr:5d} Hz: {produced:7.1f} samples/s per axis produced, "
                  f"{missed:7.1f} periods/s missed")  # fmt: skip

    build = build_firmware(profile="paper")
    print("== I2C while generating noise at 200 Hz (6-byte combined reads of RATE_X..Z)")
    for scl in (100_000, 400_000, 1_000_000):
        rate, _ = transactions_per_second(build, args.seconds, scl, 6)
        with SimulatedFirmwareChip(build, scl_hz=scl) as chip:
            chip.write(0x10, b"\x04")
            chip.advance(0.1)
            before = chip.stats()
            # the same load through the Python front end, to read the firmware's counters
            end = chip.time + 0.5
            while chip.time < end:
                chip.read(0x02, 6)
            after = chip.stats()
            produced = after["produced"] - before["produced"]
            missed = after["missed"] - before["missed"]
        print(f"  SCL {scl // 1000:4d} kHz: {rate:8.0f} transactions per simulated s; "
              f"during 0.5 s of back-to-back reads: {produced} samples produced, "
              f"{missed} periods missed")  # fmt: skip

    print(f"== simulated-to-wall speed ({args.capture_seconds:g} s at 200 Hz)")
    with tempfile.TemporaryDirectory() as tmp:
        start = time.perf_counter()
        capture_uart(build, args.capture_seconds, Path(tmp) / "s.txt", odr_hz=200)
        wall_fw = time.perf_counter() - start
    chip = BMG160(seed=1)
    chip.write(0x10, b"\x04")
    n = int(args.capture_seconds * 200)
    start = time.perf_counter()
    for _ in range(n):  # the reference: the Python model, one sample and one 6-byte read each
        chip.advance(0.005)
        chip.read(0x02, 6)
    wall_py = time.perf_counter() - start
    print(f"  firmware in simavr: {args.capture_seconds / wall_fw:6.2f} x real time "
          f"({wall_fw:.2f} s wall)")  # fmt: skip
    print(
        f"  Python BMG160 (reference, same samples with a read each): "
        f"{args.capture_seconds / wall_py:6.1f} x real time ({wall_py:.2f} s wall)"
    )
    print(f"  ratio firmware / Python model speed: {wall_py / wall_fw:.3f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
