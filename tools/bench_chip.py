"""Per-operation cost of the device model, against references measured in the same run.

Measures chip.advance(one output period) + chip.read(0x02, 6) (one new sample per read, noise
on) and prints it beside a plain dict lookup loop and a dict-backed 6-byte "read"; then the
same loop without noise and with a moving true rate, and the low-pass filter alone per
sample, as shares of it; then a closed-loop step, a new constant true rate + advance + read
(a simulator feeding the chip its body rate each step, issue 15) through
chip.stream_true_rate and through chip.set_true_rate, beside advance + read alone, timed in
alternation. Times are this thread's CPU time (time spent descheduled on a shared machine
does not count).

    python tools/bench_chip.py [--n 100000] [--steps 5000] [--bw 4] [--repeat 5]
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from bmg160_emu.device.chip import BMG160


def _per_op(func, n: int, repeat: int) -> float:
    """Best of ``repeat`` timed loops, per operation (as timeit does: the least disturbed)."""
    best = float("inf")
    for _ in range(repeat):
        start = time.thread_time()
        func(n)
        best = min(best, time.thread_time() - start)
    return best / n


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--n", type=int, default=100_000, help="operations per measurement")
    parser.add_argument("--steps", type=int, default=5000, help="closed-loop steps per measurement")
    parser.add_argument("--bw", type=int, default=4, help="BW code (ODR) for the chip")
    parser.add_argument("--repeat", type=int, default=5, help="timed loops, best kept")
    args = parser.parse_args()

    regs = {r: r & 0xFF for r in range(64)}

    def dict_lookup(n: int) -> None:
        d = regs
        for _ in range(n):
            d[2]

    def dict_read6(n: int) -> None:
        d = regs
        for _ in range(n):
            bytes(d[r] for r in range(2, 8))

    chip = BMG160(seed=1)
    chip.write(0x10, bytes([args.bw]))
    period = 1.0 / chip.odr_hz

    def chip_advance_read(n: int) -> None:
        adv, rd = chip.advance, chip.read
        for _ in range(n):
            adv(period)
            rd(2, 6)

    def chip_read_only(n: int) -> None:
        rd = chip.read
        for _ in range(n):
            rd(2, 6)

    chip_advance_read(1000)  # warm up: first block, filter design
    before = chip.state.k
    results = {
        "dict lookup": _per_op(dict_lookup, args.n, args.repeat),
        "dict-backed 6-byte read": _per_op(dict_read6, args.n, args.repeat),
        "chip.read(0x02, 6)": _per_op(chip_read_only, args.n, args.repeat),
        "chip.advance(period) + chip.read(0x02, 6)": _per_op(chip_advance_read, args.n,
                                                             args.repeat),
    }
    new_samples = chip.state.k - before

    # Where advance+read goes (speed section of issue 10): the same loop on chips without
    # noise and with a moving true rate (the low-pass then runs on every block), and the
    # low-pass alone per sample on blocks of 1024 as the chip runs it.
    quiet = BMG160(seed=1, noise=False)
    ramp = np.linspace(0.0, 100.0, 3 * 4096).reshape(4096, 3)  # per-sample rates (vectorised)
    moving = BMG160(seed=1, true_rate=ramp)
    for other in (quiet, moving):
        other.write(0x10, bytes([args.bw]))

    def advance_read_of(c: BMG160):
        def loop(n: int) -> None:
            adv, rd = c.advance, c.read
            for _ in range(n):
                adv(period)
                rd(2, 6)
        return loop

    block = np.random.default_rng(0).standard_normal((1024, 3))
    filt = moving.state.path.filter

    def lowpass_blocks(n: int) -> None:
        for _ in range(n // len(block)):
            filt.run(block)

    for c in (quiet, moving):
        advance_read_of(c)(1000)
    shares = {
        "advance+read, noise off": _per_op(advance_read_of(quiet), args.n, args.repeat),
        "advance+read, moving true rate": _per_op(advance_read_of(moving), args.n, args.repeat),
        "low-pass per sample (blocks of 1024)": _per_op(lowpass_blocks, 64 * 1024, args.repeat),
    }
    ref = results["dict lookup"]
    for name, cost in results.items():
        print(f"{name:45s} {cost * 1e6:8.3f} us/op  {cost / ref:7.1f} x dict lookup")
    adv = results["chip.advance(period) + chip.read(0x02, 6)"]
    print(f"{'advance+read vs dict-backed 6-byte read':45s} "
          f"{adv / results['dict-backed 6-byte read']:7.2f} x")
    print(f"new samples produced: {new_samples} for {args.repeat} x {args.n} advance+read")
    for name, cost in shares.items():
        print(f"{name:45s} {cost * 1e6:8.3f} us/op  {cost / adv:7.1%} of advance+read")
    closed_loop(args.steps, args.bw, args.repeat)
    return 0


def closed_loop(steps: int, bw: int, repeat: int) -> None:
    """Per step: a new rate (stream_true_rate or set_true_rate) + advance(period) + read(0x02,
    6), against advance(period) + read(0x02, 6), each on its own chip, the loops alternated."""
    chips = {}
    for name in ("stream_true_rate", "set_true_rate", "plain"):
        chip = BMG160(seed=1)
        chip.write(0x10, bytes([bw]))
        chips[name] = chip
    period = 1.0 / chips["plain"].odr_hz
    rates = [(0.001 * i, -0.5, 2.0 + 0.0001 * i) for i in range(steps)]

    def with_rate(name: str):
        def loop(n: int) -> None:
            chip = chips[name]
            feed = getattr(chip, name)
            for rate in rates[:n]:
                feed(rate)
                chip.advance(period)
                chip.read(2, 6)
        return loop

    def without_rate(n: int) -> None:
        chip = chips["plain"]
        for _ in range(n):
            chip.advance(period)
            chip.read(2, 6)

    loops = {"stream_true_rate": with_rate("stream_true_rate"),
             "set_true_rate": with_rate("set_true_rate"), "plain": without_rate}
    for loop in loops.values():
        loop(100)
    best = dict.fromkeys(loops, float("inf"))
    for _ in range(repeat):  # alternated, so all see the same machine load
        for name, loop in loops.items():
            best[name] = min(best[name], _per_op(loop, steps, 1))
    plain = best["plain"]
    for name in ("stream_true_rate", "set_true_rate"):
        print(f"{name + ' + advance + read (per step)':45s} {best[name] * 1e6:8.3f} us/step"
              f"  {best[name] / plain:6.2f} x advance + read")
    print(f"{'advance + read (per step)':45s} {plain * 1e6:8.3f} us/step")


if __name__ == "__main__":
    raise SystemExit(main())
