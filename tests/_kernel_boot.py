"""The kernel tests' one-boot helpers: a prepared QEMU engine (or a skip saying why) and a
boot that runs one script (bmg160_emu.linux.guest)."""

from __future__ import annotations

import subprocess
from pathlib import Path

import pytest

from bmg160_emu.linux.guest import qemu
from bmg160_emu.linux.guest.engine import Boot, EngineError
from bmg160_emu.linux.guest.harness import ScriptRun, run_script

GUEST_FILES = Path(__file__).resolve().parent / "kernel_guest"  # scripts run in the guest


def qemu_engine() -> qemu.QemuEngine:
    """The QEMU engine with its kernel, initramfs and modules in the cache, or a skip."""
    engine = qemu.engine()
    try:
        engine.prepare(lambda _: None)
    except (EngineError, OSError, subprocess.CalledProcessError) as exc:
        pytest.skip(f"kernel tests need a bootable guest: {exc}")
    missing = engine.missing()
    if missing:
        pytest.skip(f"kernel tests need a bootable guest: {'; '.join(missing)}")
    return engine


def boot_script(engine: qemu.QemuEngine, script: Path, out: Path, timeout_s: float,
                console_log: Path, cpus: int = 2, i2c_socket: Path | None = None,
                gpio_socket: Path | None = None) -> ScriptRun:
    """Boot once and run ``script`` (1 GB: the guest runs the host's Python with numpy)."""
    boot = Boot(script=script, results=out, i2c_socket=i2c_socket, gpio_socket=gpio_socket,
                memory_mb=1024, cpus=cpus)
    return run_script(engine, boot, timeout_s=timeout_s, console_log=console_log)
