"""Speed of the Basilisk closed loop with an emulated 200 Hz gyro, against bare Basilisk.

Measured in the same run, ``--repeat`` times each, the cases interleaved (so that the load
of a shared machine falls on all of them alike), median and best reported:

- bare: the example's spacecraft and three reaction wheels in Basilisk alone (C++ modules,
  5 ms task), no gyro, no flight software;
- loop, the example: the whole example (examples/basilisk_detumble): emulated gyro, star
  tracker, the Python flight software reading the gyro's FIFO over smbus2 at 20 Hz, faults
  on; the rate handed over through ``queue_true_rate`` (EmulatedGyro's default: samples
  computed when the flight software reads them) when it moved by 1/4 LSB (the example's
  ``rate_resolution_dps``);
- loop, every step: the same with a new true rate at every step (resolution 0);
- loop, every step, stream_true_rate / set_true_rate: the same through the inputs that
  compute each sample as it falls due (the same samples as each other, bit for bit; as the
  queued input's to rounding);
- per step, chip alone: the rate + ``advance(5 ms)`` + a 6-byte smbus2 read, for both
  inputs, against ``advance`` + read.

Real-time factor = simulated seconds / seconds taken, in wall time and in the process's
CPU time (Basilisk steps its task in a thread of its own; CPU time leaves out the time the
process waited for a core, which on a shared machine is most of the difference).
``--breakdown`` adds, for the loop, the CPU time per step inside each Python module and,
of the gyro module's, inside the chip's rate input (with the sample it makes due); and the
bare simulation with 0, 1 and 3 empty Python modules (what a module costs by itself).

    python tools/bench_basilisk.py [--duration 30] [--repeat 5] [--breakdown]

With another checkout of the package first on PYTHONPATH (``PYTHONPATH=../old python
tools/bench_basilisk.py``) it measures that model, with that checkout's example, the same
way, for a before/after figure (``tools/bench_pair.py`` runs both alternately).
``--breakdown`` also times the empty modules with the simulation thread's Python state kept
(``bmg160_emu.adcs.thread_state``, what EmulatedGyro does).
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np


def _example() -> Path:
    """The example of the package being measured: the checkout first on PYTHONPATH (an older
    model is measured with its own example), else this one's."""
    import bmg160_emu

    for root in (Path(bmg160_emu.__file__).resolve().parent.parent,
                 Path(__file__).resolve().parent.parent):
        if (root / "examples" / "basilisk_detumble").is_dir():
            return root / "examples" / "basilisk_detumble"
    raise SystemExit("examples/basilisk_detumble not found")


EXAMPLE = _example()
sys.path.insert(0, str(EXAMPLE))

STEP_S = 0.005


def _timed(func: Callable[[], None]) -> tuple[float, float]:
    """(wall seconds, process CPU seconds) of one call."""
    wall, cpu = time.perf_counter(), time.process_time()
    func()
    return time.perf_counter() - wall, time.process_time() - cpu


def bare_basilisk(duration_s: float, empty_modules: int = 0, keep_state: bool = False) -> None:
    """The spacecraft and wheels alone; with ``empty_modules`` Python modules in the task
    whose ``UpdateState`` returns at once (what a Python module costs Basilisk by itself),
    the first keeping the simulation thread's Python state with ``keep_state``
    (bmg160_emu.adcs.thread_state, as EmulatedGyro does)."""
    from Basilisk.architecture import sysModel
    from Basilisk.simulation import reactionWheelStateEffector, spacecraft
    from Basilisk.utilities import SimulationBaseClass, macros, simIncludeRW
    from scenario import INERTIA

    keep = None
    if keep_state:
        from bmg160_emu.adcs.thread_state import keep_thread_state as keep

    class Empty(sysModel.SysModel):
        def UpdateState(self, CurrentSimNanos: int) -> None:
            if keep is not None:
                keep()

        def Reset(self, CurrentSimNanos: int) -> None:
            pass

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
    empties = [Empty() for _ in range(empty_modules)]
    for i, module in enumerate(empties):
        module.ModelTag = f"empty{i}"
        sim.AddModelToTask("loop", module, 50 - i)
    sim.InitializeSimulation()
    sim.ConfigureStopTime(macros.sec2nano(duration_s))
    sim.ExecuteSimulation()


def closed_loop(duration_s: float, feed: str | None,
                resolution_dps: float | None = None) -> None:
    """The example's run (scenario.run) with the gyro's rate input (a chip method's name;
    None: EmulatedGyro's default) and resolution chosen (None: the example's)."""
    import scenario
    from Basilisk.utilities import macros

    from bmg160_emu.bus.patching import patch_smbus

    setup = scenario.Setup(duration_s=duration_s)
    if resolution_dps is not None:
        setup.rate_resolution_dps = resolution_dps
    sim, parts = scenario.build(setup)
    gyro = parts["gyro"]
    if feed is not None:
        gyro._feeds = [getattr(g.chip, feed) for g in gyro.gyros]
    with patch_smbus(gyro.buses):
        sim.InitializeSimulation()
        sim.ConfigureStopTime(macros.sec2nano(duration_s))
        sim.ExecuteSimulation()


def breakdown(duration_s: float, feed: str) -> dict[str, float]:
    """CPU microseconds per step inside each Python module's UpdateState (thread time, in
    Basilisk's thread), and the rest of the process's CPU time; a new rate every step."""
    import flight_software
    import scenario

    from bmg160_emu.adcs.basilisk import EmulatedGyro
    from bmg160_emu.device.chip import BMG160

    spent = {"EmulatedGyro": 0.0, "FlightSoftware": 0.0, "StarTracker": 0.0, feed: 0.0}
    methods = {"EmulatedGyro": (EmulatedGyro, "UpdateState"),
               "FlightSoftware": (flight_software.FlightSoftware, "UpdateState"),
               "StarTracker": (scenario.StarTracker, "UpdateState"), feed: (BMG160, feed)}
    originals = {name: getattr(cls, method) for name, (cls, method) in methods.items()}

    def wrap(name: str, call: Callable[..., None]) -> Callable[..., None]:
        def timed(self: object, arg: object) -> None:
            start = time.thread_time()
            call(self, arg)
            spent[name] += time.thread_time() - start
        return timed

    for name, (cls, method) in methods.items():
        setattr(cls, method, wrap(name, originals[name]))
    try:
        _, cpu = _timed(lambda: closed_loop(duration_s, feed, 0.0))
    finally:
        for name, (cls, method) in methods.items():
            setattr(cls, method, originals[name])
    steps = duration_s / STEP_S
    out = {name: value / steps * 1e6 for name, value in spent.items()}
    out["Basilisk and the rest"] = (cpu - sum(spent.values()) + spent[feed]) / steps * 1e6
    out[f"(of EmulatedGyro: {feed})"] = out.pop(feed)
    return out


def chip_step_costs(n: int, repeat: int) -> dict[str, float]:
    """Microseconds per step (thread CPU time, best of ``repeat``) of the chip alone."""
    from bmg160_emu.bus.i2c import I2CBus
    from bmg160_emu.bus.patching import patch_smbus
    from bmg160_emu.device.chip import BMG160

    chip = BMG160(seed=1)
    chip.write(0x0F, bytes([3]))  # RANGE +-250 deg/s
    chip.write(0x10, bytes([4]))  # ODR 200 Hz
    bus = I2CBus(1)
    bus.attach(0x68, chip)
    rates = np.random.default_rng(0).normal(0.0, 1.0, (n, 3))
    with patch_smbus({1: bus}):
        import smbus2

        read = smbus2.SMBus(1).read_i2c_block_data
        advance = chip.advance

        def loop(feed: Callable[[np.ndarray], None] | None) -> float:
            start = time.thread_time()
            for i in range(n):
                if feed is not None:
                    feed(rates[i])
                advance(STEP_S)
                read(0x68, 0x02, 6)
            return (time.thread_time() - start) / n * 1e6

        cases = {"set_true_rate": chip.set_true_rate, "none": None}
        if hasattr(chip, "stream_true_rate"):
            cases["stream_true_rate"] = chip.stream_true_rate
        best = dict.fromkeys(cases, float("inf"))
        for _ in range(repeat):
            for name, feed in cases.items():
                best[name] = min(best[name], loop(feed))
    return best


def _thread_state_names() -> set[str]:
    """What bmg160_emu.adcs.thread_state offers (nothing in a model older than issue 36)."""
    try:
        from bmg160_emu.adcs import thread_state
    except ImportError:
        return set()
    return set(dir(thread_state))


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--duration", type=float, default=30.0, help="simulated seconds")
    parser.add_argument("--repeat", type=int, default=5, help="timed runs of each case")
    parser.add_argument("--steps", type=int, default=2000, help="chip steps per measurement")
    parser.add_argument("--breakdown", action="store_true",
                        help="CPU time per step inside each Python module of the loop")
    args = parser.parse_args()
    d = args.duration
    from bmg160_emu.device.chip import BMG160

    # a model without stream_true_rate (an older checkout on PYTHONPATH): set_true_rate only
    stream = "stream_true_rate" if hasattr(BMG160, "stream_true_rate") else "set_true_rate"
    queue = "queue_true_rate" if hasattr(BMG160, "queue_true_rate") else stream
    cases = {"bare": lambda: bare_basilisk(d),
             "loop, the example": lambda: closed_loop(d, queue),
             "loop, every step": lambda: closed_loop(d, queue, 0.0),
             "loop, every step, stream_true_rate": lambda: closed_loop(d, stream, 0.0),
             "loop, every step, set_true_rate": lambda: closed_loop(d, "set_true_rate", 0.0)}
    if stream == "set_true_rate":
        print("(this model has no stream_true_rate: set_true_rate in every case)")
    closed_loop(1.0, queue)  # imports, filter designs, first noise blocks
    bare_basilisk(1.0)
    load_before = os.getloadavg()[0]
    wall: dict[str, list[float]] = {name: [] for name in cases}
    cpu: dict[str, list[float]] = {name: [] for name in cases}
    for _ in range(args.repeat):
        for name, case in cases.items():
            w, c = _timed(case)
            wall[name].append(w)
            cpu[name].append(c)
    load_after = os.getloadavg()[0]
    print(f"simulated {d:g} s, 5 ms task, 200 Hz gyro; {args.repeat} interleaved runs each; "
          f"load average {load_before:.1f} -> {load_after:.1f}")
    print(f"  {'':34s} {'wall median':>12s} {'x real time':>12s} {'(best)':>8s}   "
          f"{'CPU median':>11s} {'x real time':>12s}")
    for name in cases:
        wm, cm = statistics.median(wall[name]), statistics.median(cpu[name])
        print(f"  {name:34s} {wm:10.3f} s {d / wm:11.1f}x {d / min(wall[name]):7.1f}x   "
              f"{cm:9.3f} s {d / cm:11.1f}x")
    for name in list(cases)[1:]:
        print(f"  {name} / bare: wall {statistics.median(wall[name]) / statistics.median(wall['bare']):.1f}x, "
              f"CPU {statistics.median(cpu[name]) / statistics.median(cpu['bare']):.1f}x")
    if args.breakdown:
        parts = breakdown(d, queue)
        print("  loop, every step, CPU per 5 ms step: " + ", ".join(f"{k} {v:.1f} us" for k, v in parts.items()))
        kept = "keep_thread_state" in _thread_state_names()
        shapes = [(0, False), (1, False), (3, False)] + ([(3, True)] if kept else [])
        runs: dict[tuple[int, bool], list[float]] = {shape: [] for shape in shapes}
        for _ in range(args.repeat):  # interleaved; median of repeat runs, CPU time
            for n, keep in shapes:
                runs[(n, keep)].append(_timed(lambda n=n, keep=keep: bare_basilisk(d, n, keep))[1])
        us = {shape: statistics.median(v) / (d / STEP_S) * 1e6 for shape, v in runs.items()}
        line = ("  Basilisk with empty Python modules, CPU per step: "
                + ", ".join(f"{n} modules {us[(n, False)]:.1f} us" for n in (0, 1, 3))
                + f" ({(us[(3, False)] - us[(0, False)]) / 3:.1f} us per module)")
        if kept:
            line += (f"; 3 modules, the thread state kept: {us[(3, True)]:.1f} us "
                     f"({(us[(3, True)] - us[(0, False)]) / 3:.1f} us per module)")
        print(line)
    steps = chip_step_costs(args.steps, args.repeat)
    streamed = f"stream_true_rate {steps['stream_true_rate']:.1f} us, " if "stream_true_rate" in steps else ""
    print(f"  chip step (rate + advance + smbus2 read, thread CPU, best of {args.repeat}): "
          f"{streamed}set_true_rate {steps['set_true_rate']:.1f} us; advance + read alone "
          f"{steps['none']:.1f} us")
    return 0


if __name__ == "__main__":
    sys.exit(main())
