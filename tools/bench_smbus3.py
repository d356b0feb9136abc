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

A third case, in the same rounds, is smbus2 with the in-process node's pointer checks off
(white-box: ``KeptAlive.covers`` answers yes to every address, so every pointer is read
directly as before issue 34, and a bad one would crash): what the checks that make a bad
pointer EFAULT cost an ordinary read.
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
from bmg160_emu.bus.user_memory import KeptAlive
from bmg160_emu.device.chip import BMG160

RATE_X_LSB = 0x02  # spec 4.2
CHECKS_OFF = "smbus2, pointer checks off"


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
        cases[CHECKS_OFF] = reference.read_i2c_block_data  # run with trusting() below
        checked = KeptAlive.covers

        def trusting(self: KeptAlive, address: int, size: int) -> bool:
            return True  # every address taken as mapped: the checks off
        for read in cases.values():  # warm-up (the checks on: the shapes found once)
            for _ in range(200):
                read(0x68, RATE_X_LSB, 6)
        best = dict.fromkeys(cases, float("inf"))
        paired: list[float] = []
        checks_paired: list[float] = []
        for _ in range(args.rounds):
            this_round = {}
            for name, read in cases.items():
                log.clear()
                if name == CHECKS_OFF:
                    KeptAlive.covers = trusting  # type: ignore[method-assign]
                try:
                    start = time.thread_time()
                    for _ in loop:
                        read(0x68, RATE_X_LSB, 6)
                    this_round[name] = (time.thread_time() - start) / args.loop
                finally:
                    KeptAlive.covers = checked  # type: ignore[method-assign]
                best[name] = min(best[name], this_round[name])
            if candidate is not None:
                paired.append(this_round["smbus3"] / this_round["smbus2"])
            checks_paired.append(this_round["smbus2"] / this_round[CHECKS_OFF])
        reference.close()
        if candidate is not None:
            candidate.close()
    load = ", ".join(f"{v:.2f}" for v in os.getloadavg())
    print(f"per 6-byte read, best of {args.rounds} interleaved rounds of {args.loop} calls "
          f"(thread CPU time); load average {load}")
    print(f"smbus2 in process (reference): {best['smbus2'] * 1e6:7.2f} us")
    off = best[CHECKS_OFF]
    low, median, high = statistics.quantiles(checks_paired, n=4)
    print(f"  pointer checks off:          {off * 1e6:7.2f} us  (the checks cost "
          f"{(best['smbus2'] - off) * 1e6:.2f} us, {best['smbus2'] / off:5.2f} x; median of "
          f"the rounds' own ratios {median:5.2f} x, quartiles {low:.2f}-{high:.2f})")
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
