"""Speed of the Basilisk closed loop with an emulated 200 Hz gyro, against bare Basilisk.

Measured in the same run, best of ``--repeat``:

- bare: the example's spacecraft and three reaction wheels in Basilisk alone (C++ modules,
  5 ms task), no gyro, no flight software;
- loop: the whole example (examples/basilisk_detumble): emulated gyro, star tracker and the
  Python flight software reading the gyro over smbus2, faults on, rate resolution 1/4 LSB;
- loop, exact feed: the same with a new true rate handed to the chip at every step;
- per step, chip alone: ``set_true_rate`` + ``advance(5 ms)`` + 6-byte smbus2 read, against
  ``advance`` + read (or the chip's ``stream_true_rate`` when it has one).

Prints the real-time factors (simulated / wall seconds) and the ratios.

    python tools/bench_basilisk.py [--duration 30] [--repeat 3]
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

EXAMPLE = Path(__file__).resolve().parent.parent / "examples" / "basilisk_detumble"
sys.path.insert(0, str(EXAMPLE))


def _best(func, repeat: int) -> float:
    best = float("inf")
    for _ in range(repeat):
        start = time.perf_counter()
        func()
        best = min(best, time.perf_counter() - start)
    return best


def bare_basilisk(duration_s: float) -> None:
    from Basilisk.simulation import reactionWheelStateEffector, spacecraft
    from Basilisk.utilities import SimulationBaseClass, macros, simIncludeRW
    from scenario import INERTIA, STEP_S

    sim = SimulationBaseClass.SimBaseClass()
    sim.CreateNewProcess("dynamics").addTask(sim.CreateNewTask("loop", macros.sec2nano(STEP_S)))
    sc = spacecraft.Spacecraft()
    sc.ModelTag = "cubesat"
    sc.hub.mHub = 4.0
    sc.hub.IHubPntBc_B = INERTIA.tolist()
    sc.hub.omega_BN_BInit = [[0.05], [-0.06], [0.03]]
    factory = simIncludeRW.rwFactory()
    for axis in np.eye(3):
        factory.create("BCT_RWP015", axis.tolist(), Omega=0.0)
    wheels = reactionWheelStateEffector.ReactionWheelStateEffector()
    factory.addToSpacecraft(sc.ModelTag, wheels, sc)
    sim.AddModelToTask("loop", sc, 100)
    sim.AddModelToTask("loop", wheels, 90)
    sim.InitializeSimulation()
    sim.ConfigureStopTime(macros.sec2nano(duration_s))
    sim.ExecuteSimulation()


def closed_loop(duration_s: float, resolution_dps: float) -> None:
    import scenario

    scenario.run(scenario.Setup(duration_s=duration_s, rate_resolution_dps=resolution_dps))


def chip_step_costs(n: int, repeat: int) -> tuple[float, float, bool]:
    """(us per step with a new true rate, us per step without, streaming input used)."""
    from bmg160_emu.bus.i2c import I2CBus
    from bmg160_emu.bus.patching import patch_smbus
    from bmg160_emu.device.chip import BMG160

    chip = BMG160(seed=1)
    chip.write(0x0F, bytes([3]))
    chip.write(0x10, bytes([4]))
    bus = I2CBus(1)
    bus.attach(0x68, chip)
    feed = getattr(chip, "stream_true_rate", None)
    streaming = feed is not None
    feed = feed or chip.set_true_rate
    rates = np.random.default_rng(0).normal(0.0, 1.0, (n, 3))
    with patch_smbus({1: bus}):
        import smbus2

        smbus = smbus2.SMBus(1)

        def with_rate() -> None:
            for i in range(n):
                feed(rates[i])
                chip.advance(0.005)
                smbus.read_i2c_block_data(0x68, 0x02, 6)

        def without_rate() -> None:
            for _ in range(n):
                chip.advance(0.005)
                smbus.read_i2c_block_data(0x68, 0x02, 6)

        a = _best(with_rate, repeat) / n * 1e6
        b = _best(without_rate, repeat) / n * 1e6
    return a, b, streaming


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--duration", type=float, default=30.0, help="simulated seconds")
    parser.add_argument("--repeat", type=int, default=3, help="timed runs, best kept")
    parser.add_argument("--steps", type=int, default=2000, help="chip steps per measurement")
    args = parser.parse_args()
    d = args.duration
    bare = _best(lambda: bare_basilisk(d), args.repeat)
    loop = _best(lambda: closed_loop(d, 0.002), args.repeat)
    exact = _best(lambda: closed_loop(d, 0.0), args.repeat)
    with_rate, without_rate, streaming = chip_step_costs(args.steps, args.repeat)
    print(f"simulated {d:g} s, 5 ms task, 200 Hz gyro (best of {args.repeat})")
    print(f"  bare Basilisk (spacecraft + 3 wheels)  {bare:8.3f} s wall  {d / bare:8.1f}x real time")
    print(f"  closed loop, rate resolution 1/4 LSB   {loop:8.3f} s wall  {d / loop:8.1f}x real time"
          f"  ({loop / bare:.1f}x bare)")
    print(f"  closed loop, new rate every step       {exact:8.3f} s wall  {d / exact:8.1f}x real "
          f"time  ({exact / bare:.1f}x bare)")
    name = "stream_true_rate" if streaming else "set_true_rate"
    print(f"  chip step: {name} + advance + smbus2 read {with_rate:7.1f} us; advance + read "
          f"{without_rate:6.1f} us (ratio {with_rate / without_rate:.1f})")
    return 0


if __name__ == "__main__":
    sys.exit(main())
