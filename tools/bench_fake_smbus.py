"""Speed of FakeSMBus on a polling driver's hot path, against a dict-backed fake bus.

The call measured is a 6-byte ``read_i2c_block_data`` of RATE_X_LSB..RATE_Z_MSB with one new
sample per read (``chip.advance(1/ODR)`` between reads). Targets (issue 3): at least 100,000
advance+read iterations per second, and the read itself at most 4x the cost of the same call
on a plain dict-backed fake bus with no behaviour, measured in the same run.

    python tools/bench_fake_smbus.py [--reads N] [--loop L] [--repeat R]

The advance+read rate is the best of R timed loops of ``--loop`` iterations, as timeit does
(a mean: it includes the chip's block-wise noise generation, which a median would hide). The
per-call costs are medians of per-call timings (perf_counter_ns around each call, the timer's
own cost, measured around an empty call, subtracted), so that other processes on a shared
machine do not bias one side of the ratio.
"""

from __future__ import annotations

import argparse
import statistics
import time

import smbus2

from bmg160_emu.bus.patching import patch_smbus
from bmg160_emu.bus.smbus import FakeSMBus
from bmg160_emu.device.chip import BMG160

RATE_X_LSB = 0x02  # spec 4.2
BW = 0x10  # spec 4.9
BW_200HZ = 0x04  # ODR 200 Hz (spec 5.3)


class DictBus:
    """What a test double with no behaviour looks like: registers in a dict."""

    def __init__(self, registers: dict[int, dict[int, int]]) -> None:
        self.registers = registers

    def read_i2c_block_data(self, i2c_addr: int, register: int, length: int, force=None):
        regs = self.registers[i2c_addr]
        return [regs.get(register + i, 0) for i in range(length)]


def _best(loop, repeat: int) -> float:
    return min(loop() for _ in range(repeat))


def _median_call_ns(call, between, n: int) -> float:
    """Median duration of ``call()`` in ns; ``between()`` runs untimed before each call."""
    clock = time.perf_counter_ns
    samples = []
    append = samples.append
    for _ in range(n):
        between()
        t0 = clock()
        call()
        append(clock() - t0)
    return statistics.median(samples)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--reads", type=int, default=100_000)
    parser.add_argument("--loop", type=int, default=20_000)
    parser.add_argument("--repeat", type=int, default=10)
    args = parser.parse_args()
    n = args.reads

    chip = BMG160(seed=7)
    bus = FakeSMBus(1, devices={0x68: chip})
    bus.write_byte_data(0x68, BW, BW_200HZ)
    period = 1.0 / chip.odr_hz
    dict_bus = DictBus({0x68: {r: r for r in range(0x40)}})
    advance = chip.advance
    read = bus.read_i2c_block_data
    dict_read = dict_bus.read_i2c_block_data

    loop = args.loop

    def fake_loop() -> float:
        bus.i2c_bus.log.clear()
        t0 = time.perf_counter()
        for _ in range(loop):
            advance(period)
            read(0x68, RATE_X_LSB, 6)
        return time.perf_counter() - t0

    def new_sample() -> None:
        advance(period)

    def nothing() -> None:
        pass

    fake_loop()  # warm-up: noise blocks, caches
    throughput = loop / _best(fake_loop, args.repeat)
    bus.i2c_bus.log.clear()
    timer_ns = _median_call_ns(nothing, nothing, n)
    bus.i2c_bus.log.clear()
    fake_ns = _median_call_ns(lambda: read(0x68, RATE_X_LSB, 6), new_sample, n) - timer_ns
    dict_ns = _median_call_ns(lambda: dict_read(0x68, RATE_X_LSB, 6), nothing, n) - timer_ns
    bus.i2c_bus.log.enabled = False
    nolog_ns = _median_call_ns(lambda: read(0x68, RATE_X_LSB, 6), new_sample, n) - timer_ns
    # For reference, not a target: real smbus2 (ctypes, ioctl) over the emulated kernel.
    with patch_smbus({1: bus.i2c_bus}), smbus2.SMBus(1) as real:
        patched_ns = (
            _median_call_ns(lambda: real.read_i2c_block_data(0x68, RATE_X_LSB, 6), new_sample, n)
            - timer_ns
        )

    print(f"rate: best of {args.repeat} loops of {loop}; costs: medians of {n} calls each")
    print(f"FakeSMBus advance+read: {throughput:12,.0f} per second   (target >= 100,000)")
    print(f"FakeSMBus read:         {fake_ns:8.0f} ns   (transaction log off: {nolog_ns:.0f} ns)")
    print(f"dict-backed fake read:  {dict_ns:8.0f} ns")
    print(f"ratio FakeSMBus / dict: {fake_ns / dict_ns:8.2f}   (target <= 4)")
    print(f"  with the log off:     {nolog_ns / dict_ns:8.2f}")
    print(f"smbus2.SMBus under patch_smbus (reference): {patched_ns:.0f} ns")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
