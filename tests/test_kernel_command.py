"""``bmg160-emu kernel run``: a disposable guest runs a command beside the emulated chips.

The usage errors need no kernel; the rest boot a guest each (``kernel`` marker): the
kernel's bmg160 driver bound with its IRQ, a user's module built from a Kbuild folder (our
stand-in driver, examples/kernel_driver) and the kernel's own bmg160 driver built out of
tree from Debian's linux-source as if it were the user's.
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

import bmg160_emu

REPO = Path(bmg160_emu.__file__).resolve().parents[1]


def kernel(*words: str, cwd: Path | None = None) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "bmg160_emu", "kernel", *words], capture_output=True,
        text=True, cwd=cwd, env={**os.environ, "PYTHONPATH": str(REPO)}, timeout=900, check=False)


def test_run_without_a_command_is_a_usage_error():
    result = kernel("run", "--seed", "7")
    assert result.returncode == 2
    assert result.stderr.strip().splitlines() == [
        "bmg160-emu kernel: error: no COMMAND given (bmg160-emu kernel run [options] -- COMMAND)"]


def test_a_missing_module_path_is_named(tmp_path):
    result = kernel("run", "--module", str(tmp_path / "nope.ko"), "--", "true")
    assert result.returncode == 2
    assert f"--module {tmp_path / 'nope.ko'}: no such file or folder" in result.stderr
    assert "Traceback" not in result.stderr


def test_an_unknown_engine_is_named():
    result = kernel("run", "--engine", "bochs", "--", "true")
    assert result.returncode == 2
    assert "unknown engine 'bochs'" in result.stderr and "Traceback" not in result.stderr


def test_prepare_fails_when_no_engine_is_ready_and_says_a_missing_tool_once(tmp_path):
    """A host with apt-cache and dpkg but no depmod (and no QEMU): QEMU's prepare stops at
    depmod, its list of what is missing names it too; the line comes once, exit status 1."""
    import shutil

    bin_dir = tmp_path / "bin"
    bin_dir.mkdir()
    for tool in ("apt-cache", "dpkg"):
        found = shutil.which(tool)
        if found is None:
            pytest.skip(f"{tool} is not on this host")
        (bin_dir / tool).symlink_to(found)
    result = subprocess.run(
        [sys.executable, "-m", "bmg160_emu", "kernel", "prepare", "--engine", "qemu"],
        capture_output=True, text=True, timeout=120, check=False,
        env={**os.environ, "PYTHONPATH": str(REPO), "PATH": str(bin_dir),
             "BMG160_EMU_CACHE": str(tmp_path / "cache")})
    assert result.returncode == 1, result.stderr
    assert result.stdout.strip() == "qemu: not ready"
    assert result.stderr.count("depmod is missing (Debian package kmod)") == 1, result.stderr
    assert "Traceback" not in result.stderr


def _ready() -> None:
    from bmg160_emu.linux.guest.engine import EngineError, choose

    try:
        choose(os.environ.get("BMG160_KERNEL_ENGINE"))
    except EngineError as exc:
        pytest.skip(str(exc))


@pytest.mark.kernel
def test_the_command_runs_beside_the_bound_driver_with_a_read_only_host(tmp_path):
    _ready()
    results = tmp_path / "results"
    result = kernel(
        "run", "--seed", "7", "--true-rate", "20", "-10", "5", "--results", str(results), "--",
        "sh", "-c", 'cat $IIO/name $IIO/in_anglvel_x_raw; grep -c bmg160 /proc/interrupts; '
        'echo kept > $BMG160_RESULTS/note; touch /etc/bmg160-probe || echo read-only; exit 3',
        cwd=tmp_path)
    assert result.returncode == 3, result.stderr
    lines = result.stdout.split()
    assert lines[0] == "bmg160"
    # 20 deg/s at the driver's 500 deg/s range is 1311 counts; noise ~13 counts rms
    assert abs(int(lines[1]) - round(20 * 32768 / 500)) < 70, lines
    assert int(lines[2]) >= 1  # its data-ready IRQ on the virtio-gpio line
    assert lines[3] == "read-only"
    assert (results / "note").read_text() == "kept\n"
    assert not (results / ".agent").exists()


@pytest.mark.kernel
def test_a_users_module_from_a_kbuild_folder_binds_and_reads_the_chip(tmp_path):
    _ready()
    result = kernel("run", "--seed", "7", "--module", str(REPO / "examples" / "kernel_driver"),
                    "--", "sh", "-c", "d=/sys/bus/i2c/devices/$GUEST_I2C_BUS-0068; "
                    "cat $d/name $d/chip_id $d/rate_x; basename $(readlink $d/driver)",
                    cwd=tmp_path)
    assert result.returncode == 0, result.stderr
    name, chip_id, rate_x, driver = result.stdout.split()
    assert (name, chip_id, driver) == ("gyro_chipid", "0x0f", "gyro_chipid")
    assert abs(int(rate_x)) < 200  # at rest, range 2000 deg/s: noise and bias only


@pytest.mark.kernel
def test_the_kernels_bmg160_driver_built_out_of_tree_as_a_users_module(tmp_path):
    _ready()
    import shutil

    from bmg160_emu.linux.guest.engine import choose

    files = ["drivers/iio/gyro/bmg160_core.c", "drivers/iio/gyro/bmg160_i2c.c",
             "drivers/iio/gyro/bmg160.h"]
    source = tmp_path / "bmg160"
    source.mkdir()
    engine = choose(os.environ.get("BMG160_KERNEL_ENGINE"))
    if engine.name == "uml":  # the sources of the engine's own kernel: its build tree
        for name in files:
            shutil.copy(engine.kernel().tree / name, source)  # type: ignore[attr-defined]
    else:
        from bmg160_emu.linux.guest.debian import build_tree, find_kernel
        from bmg160_emu.linux.guest.debian_modules import extract_sources

        guest_kernel = find_kernel()
        if guest_kernel is None:
            pytest.skip("no Debian kernel in the cache (bmg160-emu kernel prepare --engine qemu)")
        extract_sources(guest_kernel, build_tree(guest_kernel), files, source)
    (source / "Kbuild").write_text("obj-m += bmg160_core.o bmg160_i2c.o\n")
    result = kernel("run", "--seed", "7", "--true-rate", "0", "0", "30", "--module",
                    str(source), "--", "sh", "-c",
                    "cat $IIO/name $IIO/in_anglvel_z_raw; modinfo -F filename bmg160_i2c "
                    "2>/dev/null; cat /sys/module/bmg160_i2c/taint", cwd=tmp_path)
    assert result.returncode == 0, result.stderr
    words = result.stdout.split()
    assert words[0] == "bmg160"
    assert abs(int(words[1]) - round(30 * 32768 / 500)) < 70, words  # 1966 counts
    assert "O" in words[-1]  # the out-of-tree module is what runs, not the kernel's own


@pytest.mark.kernel
def test_the_i2c_stub_route_serves_the_kernels_driver_from_inside_the_guest(tmp_path):
    _ready()
    result = kernel("run", "--route", "stub", "--seed", "7", "--true-rate", "20", "-10", "5",
                    "--", "cat $IIO/name $IIO/in_anglvel_x_raw; "
                    "i2cget -f -y $GUEST_I2C_BUS 0x68 0x0f; cat /sys/bus/i2c/devices/"
                    "i2c-$GUEST_I2C_BUS/name", cwd=tmp_path)
    assert result.returncode == 0, result.stderr
    lines = result.stdout.splitlines()
    assert lines[0] == "bmg160"
    assert abs(int(lines[1]) - round(20 * 32768 / 500)) < 70, lines  # 1311 counts
    assert lines[2] == "0x02"  # RANGE as the driver wrote it, in i2c-stub's memory
    assert "SMBus stub driver" in lines[3]
