"""Build and run a Zephyr application for native_sim with this repository's Zephyr module.

Why in the package: the Zephyr test (tests/test_zephyr_build.py), the one-command figure
(tools/bench_zephyr.py) and a user's own script do the same steps docs/zephyr.md gives by
hand: plain ``cmake -GNinja`` with the host toolchain (no SDK, no west workspace), the
module passed with ``-DZEPHYR_MODULES``, then ``zephyr.exe --no-rt`` against a running
``bmg160-emu serve``. Nothing here is Zephyr's: the tree is the user's ``ZEPHYR_BASE``.
"""

from __future__ import annotations

import os
import resource
import shutil
import subprocess
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

MODULE_ROOT = Path(__file__).resolve().parents[2]  # the repository: zephyr/module.yml in it
BOARD = "native_sim/native/64"
PYTHON_MODULES = ("elftools", "yaml", "pykwalify", "packaging", "anytree", "intelhex")
TOOLS = ("cmake", "ninja", "dtc")


@dataclass(frozen=True)
class Timed:
    """Wall and CPU seconds of a step (CPU: the step's child processes, user + system)."""

    wall_s: float
    cpu_s: float


@dataclass(frozen=True)
class Build:
    build_dir: Path
    executable: Path
    configure: Timed
    build: Timed


class ZephyrError(Exception):
    """A build or run that failed; the message names the step and where its log is."""


def zephyr_base(environ: Mapping[str, str] = os.environ) -> Path | None:
    """The Zephyr tree ZEPHYR_BASE names, if it holds one (its VERSION file)."""
    base = environ.get("ZEPHYR_BASE")
    if not base or not (Path(base) / "VERSION").is_file():
        return None
    return Path(base)


def zephyr_version(base: Path) -> str:
    """``4.1.99`` from the tree's VERSION file."""
    fields = dict(line.replace(" ", "").split("=", 1)
                  for line in (base / "VERSION").read_text().splitlines() if "=" in line)
    return ".".join(fields.get(k, "?") for k in ("VERSION_MAJOR", "VERSION_MINOR", "PATCHLEVEL"))


def missing() -> list[str]:
    """What a native_sim build needs and this host lacks (tools, Python modules, the module)."""
    import importlib.util

    lacking = [tool for tool in TOOLS if shutil.which(tool) is None]
    lacking += [f"python module {m}" for m in PYTHON_MODULES
                if importlib.util.find_spec(m) is None]
    if shutil.which("west") is None:
        lacking.append("west (Zephyr's cmake looks for it)")
    if not (MODULE_ROOT / "zephyr" / "module.yml").is_file():
        lacking.append(f"the Zephyr module (zephyr/module.yml) in {MODULE_ROOT}: a source "
                       "checkout of bmg160-emu")
    return lacking


def _timed(argv: Sequence[str], log: Path, env: Mapping[str, str], what: str) -> Timed:
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    started = time.monotonic()
    with log.open("w") as out:
        done = subprocess.run(list(argv), stdout=out, stderr=subprocess.STDOUT, env=dict(env),
                              check=False)
    wall = time.monotonic() - started
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if done.returncode != 0:
        raise ZephyrError(f"{what} failed (exit {done.returncode}); see {log}")
    return Timed(wall, after.ru_utime - before.ru_utime + after.ru_stime - before.ru_stime)


def build_app(app: Path, build_dir: Path, base: Path, *, overlay: Path | None = None,
              options: Mapping[str, str] | None = None, board: str = BOARD) -> Build:
    """Configure and build ``app`` for ``board`` (native_sim/native/64) with the module;
    ``overlay`` replaces the app's device tree overlay, ``options`` are -D settings."""
    env = {**os.environ, "ZEPHYR_BASE": str(base), "ZEPHYR_TOOLCHAIN_VARIANT": "host"}
    import sys

    # Zephyr's scripts run in this Python (whose modules missing() checked), not in the
    # first python3 on PATH
    argv = ["cmake", "-GNinja", "-B", str(build_dir), "-S", str(app), f"-DBOARD={board}",
            f"-DZEPHYR_MODULES={MODULE_ROOT}", f"-DPython3_EXECUTABLE={sys.executable}"]
    if overlay is not None:
        argv.append(f"-DDTC_OVERLAY_FILE={overlay}")
    argv += [f"-D{k}={v}" for k, v in (options or {}).items()]
    build_dir.mkdir(parents=True, exist_ok=True)
    configure = _timed(argv, build_dir.parent / f"{build_dir.name}.configure.log", env,
                       f"configuring {app}")
    build = _timed(["ninja", "-C", str(build_dir)], build_dir.parent / f"{build_dir.name}.build.log",
                   env, f"building {app}")
    return Build(build_dir, build_dir / "zephyr" / "zephyr.exe", configure, build)


def run_app(executable: Path, socket: str, *, stop_at_s: float, timeout_s: float = 600,
            extra: Sequence[str] = ()) -> tuple[str, Timed]:
    """Run a native_sim executable as fast as the host allows (--no-rt) against the server
    at ``socket`` until ``stop_at_s`` of simulated time: (its output, wall and CPU time)."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    started = time.monotonic()
    done = subprocess.run([str(executable), "--no-rt", f"--stop_at={stop_at_s}",
                           f"--bmg160-emu={socket}", *extra], capture_output=True, text=True,
                          timeout=timeout_s, check=False)
    wall = time.monotonic() - started
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if done.returncode != 0:
        raise ZephyrError(f"{executable} exited {done.returncode}: "
                          f"{(done.stderr or done.stdout).strip().splitlines()[-1:]}")
    return done.stdout + done.stderr, Timed(
        wall, after.ru_utime - before.ru_utime + after.ru_stime - before.ru_stime)


def gyro_samples(output: str) -> list[tuple[float, float, float]]:
    """The rad/s triples of gyro_stats's ``S i x1 x2 y1 y2 z1 z2`` lines, in order."""
    rows = []
    for line in output.splitlines():
        parts = line.split()
        if len(parts) == 8 and parts[0] == "S":
            v = [int(x) for x in parts[2:]]
            rows.append((v[0] + v[1] / 1e6, v[2] + v[3] / 1e6, v[4] + v[5] / 1e6))
    return rows


def serve_process(folder: Path, *options: str, timeout_s: float = 60) -> tuple[
        subprocess.Popen[str], str]:
    """``bmg160-emu serve`` in a child process on ``folder``/serve.sock (``folder`` is made
    private), returned once it listens: (the process, the socket path). Stop it with
    SIGTERM; its stderr holds its one-line notes."""
    import sys

    folder.mkdir(mode=0o700, parents=True, exist_ok=True)
    socket = str(folder / "serve.sock")
    ready = folder / "ready"
    ready.unlink(missing_ok=True)
    proc = subprocess.Popen([sys.executable, "-m", "bmg160_emu", "serve", "--socket", socket,
                             "--ready-file", str(ready), *options],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    deadline = time.monotonic() + timeout_s
    while not ready.exists():
        if proc.poll() is not None or time.monotonic() > deadline:
            proc.kill()
            raise ZephyrError(f"bmg160-emu serve did not start: {proc.communicate()[1].strip()}")
        time.sleep(0.05)
    return proc, socket
