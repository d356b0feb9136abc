"""Cold start of the chip path, against ``python -c "import numpy"`` measured in the same run.

Targets (issue 26): a fresh interpreter that imports the package, builds a chip, advances
it and reads the rate registers takes at most 1.6x the time of a fresh interpreter
importing numpy (which the chip needs anyway), and with a FakeSMBus read at most 1.8x. Runs are interleaved (reference, chip, reference, ...)
so that load from other processes hits both sides alike; each figure is the median of
``--runs`` runs.

    python tools/bench_cold_start.py [--runs 5] [--why]

``--why`` adds the packages whose imports cost the chip path most (``python -X importtime``,
self time of their modules summed), the first thing to read when the ratio grows.

The runs may write .pyc files (PYTHONDONTWRITEBYTECODE is cleared for them), as an
installed package has them: without, every run compiles the package's sources again and
measures the compiler.
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import time

CHIP = (
    "import bmg160_emu; c = bmg160_emu.BMG160(seed=1); c.advance(0.01); c.read(2, 6)"
)
COMMANDS = {
    "interpreter alone (python -c pass)": "pass",
    "reference: import numpy": "import numpy",
    "chip: import, BMG160(seed=1), advance, read": CHIP,
    "chip + FakeSMBus read": CHIP
    + "; b = bmg160_emu.FakeSMBus(1, devices={0x68: c}); b.read_i2c_block_data(0x68, 2, 6)",
}
REFERENCE = "reference: import numpy"
TARGET = "chip: import, BMG160(seed=1), advance, read"
TARGETS = {TARGET: 1.6, "chip + FakeSMBus read": 1.8}
ENV = {k: v for k, v in os.environ.items() if k != "PYTHONDONTWRITEBYTECODE"}


def _run_s(code: str) -> float:
    start = time.perf_counter()
    subprocess.run([sys.executable, "-c", code], check=True, env=ENV)
    return time.perf_counter() - start


def _import_costs(code: str, top: int) -> list[tuple[int, str]]:
    """(self time in us, top-level package) of the packages whose modules cost ``code`` most."""
    result = subprocess.run(
        [sys.executable, "-X", "importtime", "-c", code],
        capture_output=True, text=True, check=True, env=ENV,
    )
    costs: dict[str, int] = {}
    for line in result.stderr.splitlines():
        if not line.startswith("import time:") or line.count("|") != 2:
            continue
        own, _, name = line[len("import time:"):].split("|")
        if not own.strip().isdigit():
            continue  # the header line
        package = name.strip().partition(".")[0]
        costs[package] = costs.get(package, 0) + int(own)
    return sorted(((us, name) for name, us in costs.items()), reverse=True)[:top]


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=5, help="interleaved runs of each command")
    parser.add_argument("--why", action="store_true", help="list the costliest imports")
    args = parser.parse_args()

    for code in COMMANDS.values():  # warm the file cache and the .pyc files
        _run_s(code)
    times: dict[str, list[float]] = {name: [] for name in COMMANDS}
    for _ in range(args.runs):
        for name, code in COMMANDS.items():
            times[name].append(_run_s(code))
    medians = {name: statistics.median(values) for name, values in times.items()}
    ref = medians[REFERENCE]
    print(f"median of {args.runs} interleaved runs each ({sys.executable})")
    for name, value in medians.items():
        spread = f"{min(times[name]) * 1e3:.0f}-{max(times[name]) * 1e3:.0f}"
        print(f"{name:45s} {value * 1e3:7.0f} ms  ({spread} ms)  {value / ref:5.2f} x numpy")
    for name, target in TARGETS.items():
        print(f"ratio {name} / import numpy: {medians[name] / ref:.2f}   (target <= {target})")
    if args.why:
        print("packages costing the chip path most (python -X importtime, self time summed):")
        for us, name in _import_costs(CHIP, 12):
            print(f"  {us / 1e3:8.1f} ms  {name}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
