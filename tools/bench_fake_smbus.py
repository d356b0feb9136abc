"""Speed of FakeSMBus on a polling driver's hot path, against a dict-backed fake bus.

The call measured is a 6-byte ``read_i2c_block_data`` of RATE_X_LSB..RATE_Z_MSB with one new
sample per read (``chip.advance(1/ODR)`` between reads). Targets (issue 3): at least 100,000
advance+read iterations per second, and the read itself at most 4x the cost of the same call
on a plain dict-backed fake bus with no behaviour, measured in the same run.

    python tools/bench_fake_smbus.py [--reads N] [--repeat R]

Per-read costs are medians of per-call timings (perf_counter_ns around each call, the timer's
own cost, measured the same way around an empty call, subtracted), so that other processes on
a shared machine do not bias one side. Throughput is the best of R timed loops, as timeit does.
"""

from __future__ import annotations

import argparse
import statistics
import time

from bmg160_emu.chip import BMG160
from bmg160_emu.smbus import FakeSMBus

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
    parser.add_argument("--repeat", type=int, default=5)
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

    def fake_loop() -> float:
        bus.i2c_bus.log.clear()
        t0 = time.perf_counter()
        for _ in range(n):
            advance(period)
            read(0x68, RATE_X_LSB, 6)
        return time.perf_counter() - t0

    def new_sample() -> None:
        advance(period)

    def nothing() -> None:
        pass

    fake_loop()  # warm-up: noise blocks, caches
    throughput = n / _best(fake_loop, args.repeat)
    bus.i2c_bus.log.clear()
    timer_ns = _median_call_ns(nothing, nothing, n)
    fake_ns = _median_call_ns(lambda: read(0x68, RATE_X_LSB, 6), new_sample, n) - timer_ns
    dict_ns = _median_call_ns(lambda: dict_read(0x68, RATE_X_LSB, 6), nothing, n) - timer_ns
    bus.i2c_bus.log.enabled = False
    nolog_ns = _median_call_ns(lambda: read(0x68, RATE_X_LSB, 6), new_sample, n) - timer_ns

    print(f"reads: {n}; throughput best of {args.repeat} loops; costs are per-call medians")
    print(f"FakeSMBus advance+read: {throughput:12,.0f} per second   (target >= 100,000)")
    print(f"FakeSMBus read:         {fake_ns:8.0f} ns   (transaction log off: {nolog_ns:.0f} ns)")
    print(f"dict-backed fake read:  {dict_ns:8.0f} ns")
    print(f"ratio FakeSMBus / dict: {fake_ns / dict_ns:8.2f}   (target <= 4)")
    print(f"  with the log off:     {nolog_ns / dict_ns:8.2f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
