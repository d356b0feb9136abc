"""Cost of a 6-byte read through smbus3 in process against the same read through smbus2.

Both libraries run unmodified under ``patch_i2c_dev`` (the in-process /dev/i2c-N): each
``read_i2c_block_data(0x68, RATE_X_LSB, 6)`` is one I2C_SMBUS ioctl answered by the
emulated i2c-dev. smbus2 is the reference; the target (issue 25) is smbus3 <= 1.2x. The
chip is the same BMG160 for both (no advance: the read path alone), with its transaction
log on (the default).

    python tools/bench_smbus3.py [--loop L] [--rounds R]

Figures are per call, the best of R rounds of L calls each (thread CPU time, so time spent
descheduled on a shared host does not count), the two libraries alternating within every
round; beside the best-of ratio the median over the rounds of each round's own ratio. The
load average is printed with the figures. On a checkout whose patch reaches only smbus2
(before issue 25), smbus3 opens the real /dev/i2c-1 and the tool says so.
"""

from __future__ import annotations

import argparse
import os
import statistics
import time
from collections.abc import Callable

import smbus2
import smbus3

from bmg160_emu.bus.patching import patch_smbus
from bmg160_emu.device.chip import BMG160

RATE_X_LSB = 0x02  # spec 4.2


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--loop", type=int, default=2000, help="calls per timed loop")
    parser.add_argument("--rounds", type=int, default=40, help="interleaved rounds, best kept")
    args = parser.parse_args()

    chip = BMG160(seed=7)
    loop = range(args.loop)
    with patch_smbus({1: {0x68: chip}}) as buses:
        log = buses[1].log
        reference = smbus2.SMBus(1)
        try:
            candidate = smbus3.SMBus(1)
        except OSError as exc:
            print(f"smbus3 is not reached in process on this checkout ({exc}); smbus2 only")
            candidate = None
        cases: dict[str, Callable[[int, int, int], list[int]]] = {
            "smbus2": reference.read_i2c_block_data}
        if candidate is not None:
            cases["smbus3"] = candidate.read_i2c_block_data
        for read in cases.values():  # warm-up
            for _ in range(200):
                read(0x68, RATE_X_LSB, 6)
        best = dict.fromkeys(cases, float("inf"))
        paired: list[float] = []
        for _ in range(args.rounds):
            this_round = {}
            for name, read in cases.items():
                log.clear()
                start = time.thread_time()
                for _ in loop:
                    read(0x68, RATE_X_LSB, 6)
                this_round[name] = (time.thread_time() - start) / args.loop
                best[name] = min(best[name], this_round[name])
            if candidate is not None:
                paired.append(this_round["smbus3"] / this_round["smbus2"])
        reference.close()
        if candidate is not None:
            candidate.close()
    load = ", ".join(f"{v:.2f}" for v in os.getloadavg())
    print(f"per 6-byte read, best of {args.rounds} interleaved rounds of {args.loop} calls "
          f"(thread CPU time); load average {load}")
    print(f"smbus2 in process (reference): {best['smbus2'] * 1e6:7.2f} us")
    if candidate is not None:
        ratio = best["smbus3"] / best["smbus2"]
        low, median, high = statistics.quantiles(paired, n=4)
        print(f"smbus3 in process:             {best['smbus3'] * 1e6:7.2f} us  "
              f"{ratio:5.2f} x   (target <= 1.2)")
        print(f"  median over the rounds of the round's own ratio: {median:5.2f} x "
              f"(quartiles {low:.2f}-{high:.2f})")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
