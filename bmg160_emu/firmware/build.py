"""Build driver: write the parameter header, run the firmware Makefile, build the simavr harness.

The firmware sources live in the repository's ``firmware/`` folder (C with avr-libc, a
Makefile for Debian's gcc-avr). Builds go to a folder per configuration, so the header of one
profile never clobbers another's.
"""

from __future__ import annotations

import contextlib
import hashlib
import math
import os
import re
import shutil
import subprocess
import tempfile
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path

from bmg160_emu.firmware.params_header import render_params_header
from bmg160_emu.firmware.register_table import REGISTERS_HEADER, render_registers_header
from bmg160_emu.io.uart_stream import CAPTURE_LINE

# The sources: the copy a wheel ships (setup.py puts firmware/ there), else the checkout's
# firmware/ folder (editable installs). Builds of a shipped copy go to the user's cache, not
# into site-packages.
_PACKAGED_DIR = Path(__file__).resolve().parent / "sources"
_PACKAGED = (_PACKAGED_DIR / "Makefile").is_file()
FIRMWARE_DIR = _PACKAGED_DIR if _PACKAGED else Path(__file__).resolve().parents[2] / "firmware"
BUILD_ROOT = (
    Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache") / "bmg160-emu" / "firmware"
    if _PACKAGED
    else FIRMWARE_DIR / "build"
)
AVR_TOOLS = ("avr-gcc", "avr-objcopy", "avr-size")
AVR_PACKAGES = "gcc-avr avr-libc binutils-avr"
SIM_PACKAGES = "simavr libsimavr-dev libelf-dev"
ATMEGA328P_FLASH = 32768  # bytes, data sheet
ATMEGA328P_SRAM = 2048  # bytes, data sheet
NORMAL_METHODS = ("ziggurat", "polar", "box-muller")
NORMAL_FLAGS = {
    "ziggurat": "",
    "polar": "-DBMG_NORMAL_POLAR",
    "box-muller": "-DBMG_NORMAL_BOX_MULLER",
}


class FirmwareToolError(RuntimeError):
    """A tool or source needed to build or simulate the firmware is missing or failed."""


@dataclass(frozen=True)
class FirmwareBuild:
    """What a firmware build produced."""

    directory: Path
    header: Path
    elf: Path
    hex: Path
    flash_bytes: int  # .text + .data
    ram_bytes: int  # .data + .bss (static RAM; the stack comes on top)


def missing_avr_tools() -> list[str]:
    return [tool for tool in AVR_TOOLS if shutil.which(tool) is None]


def simavr_available() -> bool:
    """True if the simavr library and headers needed by the harness are installed."""
    return (
        shutil.which("cc") is not None
        and Path("/usr/include/simavr/sim_avr.h").is_file()
        and any(Path(d).glob("libsimavr.so*") for d in _library_dirs())
    )


def _library_dirs() -> list[str]:
    return ["/usr/lib", "/usr/lib/x86_64-linux-gnu", "/usr/lib/aarch64-linux-gnu", "/usr/local/lib"]


def _check_sources() -> None:
    if not (FIRMWARE_DIR / "Makefile").is_file():
        raise FirmwareToolError(
            f"firmware sources not found in {FIRMWARE_DIR}: the firmware is built from a "
            "checkout of the bmg160-emu repository (pip install -e .)"
        )


# GNU make splits targets and prerequisites at white space, reads : # $ % = ; and \ itself,
# and hands its recipes to /bin/sh, which reads quotes and the rest: a build folder whose
# path holds any of them (a home folder "/home/Ann Lee", ``--out "fw 2"``) made the build
# fail with make's own words. Such a folder is built in a temporary one and the products
# copied over (_make_folder).
_MAKE_SAFE = re.compile(r"[\w./+,@-]+")


@contextlib.contextmanager
def _make_folder(directory: Path) -> Iterator[Path]:
    """The folder make builds in for ``directory``: itself when make can name it, else a
    temporary folder whose files are copied into ``directory`` when the build succeeds."""
    resolved = directory.resolve()
    if _MAKE_SAFE.fullmatch(str(resolved)):
        yield resolved
        return
    with tempfile.TemporaryDirectory(prefix="bmg160-firmware-") as temp:
        if not _MAKE_SAFE.fullmatch(temp):
            raise FirmwareToolError(
                f"make cannot build in {directory} (a space or a character make or the shell "
                f"reads itself), nor in the temporary folder {temp}: set TMPDIR to a plain path")
        yield Path(temp)
        for product in Path(temp).iterdir():
            if product.is_file():
                shutil.copy2(product, directory / product.name)


def _run(cmd: list[str], what: str) -> str:
    # text as make prints it, a file name's undecodable bytes included
    proc = subprocess.run(cmd, capture_output=True, text=True, errors="replace", check=False)
    if proc.returncode != 0:
        tail = "\n".join((proc.stdout + proc.stderr).strip().splitlines()[-15:])
        raise FirmwareToolError(f"{what} failed (exit {proc.returncode}):\n{tail}")
    return proc.stdout


def default_build_dir(header_text: str, normal: str) -> Path:
    key = hashlib.sha256((header_text + normal).encode()).hexdigest()[:12]
    return BUILD_ROOT / key


def build_firmware(
    profile: str | Path = "paper",
    address: int = 0x68,
    mode: str = "physical",
    seed: int = 1,
    normal: str = "ziggurat",
    out_dir: str | Path | None = None,
) -> FirmwareBuild:
    """Write bmg160_params.h for the profile and bmg160_registers.h from the register table,
    and build bmg160.elf and bmg160.hex.

    Raises ValueError for a bad profile/address/mode and FirmwareToolError when gcc-avr is
    missing or the build fails.
    """
    if normal not in NORMAL_METHODS:
        raise ValueError(f"unknown normal generator {normal!r}: use {', '.join(NORMAL_METHODS)}")
    header_text = render_params_header(profile=profile, address=address, mode=mode, seed=seed)
    registers_text = render_registers_header()
    missing = missing_avr_tools()
    if missing:
        raise FirmwareToolError(
            f"{', '.join(missing)} not found: install the Debian packages {AVR_PACKAGES} "
            "(apt-get install gcc-avr avr-libc binutils-avr)"
        )
    _check_sources()
    directory = (Path(out_dir) if out_dir is not None
                 else default_build_dir(header_text + registers_text, normal))
    directory.mkdir(parents=True, exist_ok=True)
    header = directory / "bmg160_params.h"
    flags = NORMAL_FLAGS[normal]
    with _make_folder(directory) as build:
        for path, text in ((build / header.name, header_text),
                           (build / REGISTERS_HEADER, registers_text)):
            if not path.is_file() or path.read_text(encoding="utf-8") != text:
                path.write_text(text, encoding="utf-8")  # unchanged header: no rebuild
        _run(
            [
                "make", "--no-print-directory", "-C", str(FIRMWARE_DIR),
                f"BUILD_DIR={build}", f"PARAMS_DIR={build}", f"NORMAL={flags}",
                f"{build}/bmg160.hex",
            ],
            "firmware build",
        )  # fmt: skip
    elf = directory / "bmg160.elf"
    flash, ram = elf_memory_use(elf)
    return FirmwareBuild(directory, header, elf, directory / "bmg160.hex", flash, ram)


def elf_memory_use(elf: str | Path) -> tuple[int, int]:
    """(flash bytes, static RAM bytes) of a firmware ELF, from avr-size's section sizes."""
    out = _run(["avr-size", "-A", str(elf)], "avr-size")
    sizes: dict[str, int] = {}
    for line in out.splitlines():
        parts = line.split()
        if len(parts) >= 2 and parts[0].startswith(".") and parts[1].isdigit():
            sizes[parts[0]] = int(parts[1])
    flash = sizes.get(".text", 0) + sizes.get(".data", 0)
    ram = sizes.get(".data", 0) + sizes.get(".bss", 0) + sizes.get(".noinit", 0)
    return flash, ram


def build_simulator(out_dir: str | Path | None = None) -> Path:
    """Build the simavr harness (firmware/sim/bmg160_sim.c) and return its path."""
    if not simavr_available():
        raise FirmwareToolError(
            f"simavr development files not found: install the Debian packages {SIM_PACKAGES}"
        )
    _check_sources()
    directory = Path(out_dir) if out_dir is not None else BUILD_ROOT / "sim"
    directory.mkdir(parents=True, exist_ok=True)
    with _make_folder(directory) as build:
        _run(
            ["make", "--no-print-directory", "-C", str(FIRMWARE_DIR),
             f"BUILD_DIR={build}", f"{build}/bmg160_sim"],
            "simavr harness build",
        )  # fmt: skip
    return directory.resolve() / "bmg160_sim"


def elf_symbols(elf: str | Path) -> dict[str, tuple[int, int]]:
    """Data-memory symbols of the ELF: name -> (SRAM address, size in bytes)."""
    out = _run(["avr-nm", "-S", str(elf)], "avr-nm")
    symbols: dict[str, tuple[int, int]] = {}
    for line in out.splitlines():
        parts = line.split()
        if len(parts) == 4 and parts[2] in "bBdD":
            address = int(parts[0], 16)
            if address >= 0x800000:  # avr-gcc's data-space offset
                symbols[parts[3]] = (address - 0x800000, int(parts[1], 16))
    return symbols


# BW code with the 200 Hz ODR and the lowest filter that keeps it, for each ODR (spec 5.3).
BW_CODE_FOR_ODR = {100: 5, 200: 4, 400: 3, 1000: 2, 2000: 1}


def capture_uart(
    build: FirmwareBuild, seconds: float, output: str | Path, odr_hz: int = 200,
    progress: Callable[[int, int], None] | None = None,
) -> Path:
    """Run the firmware in simavr for ``seconds`` of simulated time at ``odr_hz`` and write
    its UART stream to ``output`` (the BW register is set over I2C after boot), after a first
    ``#`` line that names the ODR: the firmware's own banner cannot (the ODR is chosen over
    I2C after it is sent), and with it ``identify`` needs no --rate (io/uart_stream.py).

    The stream comes through a pipe and goes to the file as it comes (a 30-day capture is
    about 10 GB: it used to be read back whole to put the first line before it), and
    ``progress(lines, lines_expected)`` is told as the lines arrive (issue 35: a 30-day
    capture ran for days without a sign)."""
    if odr_hz not in BW_CODE_FOR_ODR:
        raise ValueError(f"ODR must be one of {sorted(BW_CODE_FOR_ODR)} Hz, not {odr_hz!r}")
    if not (math.isfinite(seconds) and seconds > 0):  # inf would "capture" a 2-line header
        raise ValueError(f"capture length must be a positive finite time, not {seconds!r} s")
    simulator = build_simulator()
    address = 0x69 if "BMG_I2C_ADDRESS 0x69" in build.header.read_text() else 0x68
    command = [str(simulator), str(build.elf), "--capture", repr(float(seconds)), "--uart",
               "/dev/stdout", "--bw", str(BW_CODE_FOR_ODR[odr_hz]), "--address", hex(address)]
    path = Path(output)
    expected = round(seconds * odr_hz)
    with path.open("wb") as sink, tempfile.TemporaryFile() as errors:
        sink.write(CAPTURE_LINE.format(odr_hz=odr_hz, seconds=float(seconds)).encode("ascii")
                   + b"\n")
        process = subprocess.Popen(command, stdout=subprocess.PIPE, stderr=errors)
        assert process.stdout is not None
        lines = 0
        try:
            while chunk := os.read(process.stdout.fileno(), 1 << 16):
                sink.write(chunk)
                lines += chunk.count(b"\n")
                if progress is not None:
                    progress(min(lines, expected), expected)
        finally:
            if process.poll() is None:  # stopped early (a signal): the simulator too
                process.kill()
            process.wait()
            process.stdout.close()
        if process.returncode != 0:
            errors.seek(0)
            tail = "\n".join(errors.read().decode(errors="replace").strip().splitlines()[-15:])
            raise FirmwareToolError(f"firmware capture failed (exit {process.returncode}):\n"
                                    f"{tail}")
    return path
