"""Size on disk of a fresh virtual environment per install (docs/install.md's table).

Builds the wheel once, then for each extra makes a venv under a temporary folder, installs
``bmg160-emu[EXTRA]`` from that wheel (the dependencies from the package index, as a user
gets them) and prints ``du -sm`` of the venv; the empty venv's size is printed first, as
the reference. Usage: ``python3 tools/install_sizes.py [EXTRA ...]`` (default: all of
them). Minutes and network: not part of the test suite.
"""

from __future__ import annotations

import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
INSTALLS = ("", "noise", "montecarlo", "basilisk", "watch", "test", "all")


def _megabytes(path: Path) -> int:
    out = subprocess.run(["du", "-sm", str(path)], capture_output=True, text=True, check=True)
    return int(out.stdout.split()[0])


def main(argv: list[str]) -> int:
    installs = argv or list(INSTALLS)
    with tempfile.TemporaryDirectory(prefix="bmg160-sizes-") as tmp:
        work = Path(tmp)
        subprocess.run([sys.executable, "-m", "pip", "wheel", "--quiet", "--no-deps", str(ROOT),
                        "-w", str(work / "dist")], check=True)
        wheel = next((work / "dist").glob("*.whl"))
        empty = work / "empty"
        subprocess.run([sys.executable, "-m", "venv", str(empty)], check=True)
        print(f"{'install':<24} {'MB':>6} {'added MB':>9} {'s':>6}")
        print(f"{'(empty venv)':<24} {_megabytes(empty):>6}")
        for extra in installs:
            venv = work / (extra or "core")
            subprocess.run([sys.executable, "-m", "venv", str(venv)], check=True)
            spec = f"{wheel}[{extra}]" if extra else str(wheel)
            start = time.monotonic()
            subprocess.run([str(venv / "bin" / "python"), "-m", "pip", "install", "--quiet",
                            spec], check=True)
            took = time.monotonic() - start
            size = _megabytes(venv)
            name = f"bmg160-emu[{extra}]" if extra else "bmg160-emu"
            print(f"{name:<24} {size:>6} {size - _megabytes(empty):>9} {took:>6.0f}", flush=True)
            subprocess.run(["rm", "-rf", str(venv)], check=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))
