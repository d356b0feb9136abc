"""A driver in the guest: its modules in load order with the kernel modules they need, and
the shell that binds it to the emulated chips (and unbinds it).

Why a board module for the IRQ: ``new_device`` in sysfs gives a client no interrupt, and the
bmg160 driver (as many IIO drivers) registers its data-ready trigger and events only with
one; bmg160-board declares the clients with their INT1 line's IRQ as a board file or
device tree would (kmod/bmg160-board.c).
"""

from __future__ import annotations

import shlex
import subprocess
from collections.abc import Sequence
from pathlib import Path

from bmg160_emu.linux.guest.engine import EngineError


def _modinfo(ko: Path, field: str) -> list[str]:
    try:
        text = subprocess.run(["modinfo", "-F", field, str(ko)], capture_output=True,
                              text=True, check=False).stdout
    except FileNotFoundError:
        raise EngineError("modinfo is missing (Debian package kmod)") from None
    return [word for line in text.splitlines() for word in line.replace(",", " ").split()]


def module_name(ko: Path) -> str:
    """The name the kernel gives a module file (dashes as underscores)."""
    return ko.stem.replace("-", "_")


def load_order(kos: Sequence[Path]) -> list[str | Path]:
    """The kernel's own modules the user's ``.ko`` files depend on (names, for modprobe),
    then the files, each after those of them it depends on."""
    own = {module_name(ko): ko for ko in kos}
    depends = {name: [d.replace("-", "_") for d in _modinfo(ko, "depends")]
               for name, ko in own.items()}
    kernel: list[str | Path] = []
    for names in depends.values():
        for dep in names:
            if dep not in own and dep not in kernel:
                kernel.append(dep)
    ordered: list[str | Path] = []
    placed: set[str] = set()
    while len(placed) < len(own):
        ready = [n for n in own if n not in placed
                 and all(d in placed or d not in own for d in depends[n])]
        if not ready:
            raise EngineError("the modules depend on each other in a circle: "
                              + ", ".join(sorted(set(own) - placed)))
        for name in ready:
            ordered.append(own[name])
            placed.add(name)
    return kernel + ordered


def driver_name(kos: Sequence[Path], prefer: Sequence[str] = ()) -> str | None:
    """The I2C device name to bind the modules' driver by: one of ``prefer`` (the emulated
    parts' names) when the id tables list it, else the first entry of the first table that
    has one (``modinfo -F alias`` lists a table's ``i2c:NAME`` aliases last entry first);
    None when no module declares one."""
    tables = [[a.split(":", 1)[1] for a in _modinfo(ko, "alias") if a.startswith("i2c:")]
              for ko in kos]
    for name in prefer:
        if any(name in table for table in tables):
            return name
    for table in tables:
        if table:
            return table[-1]
    return None


def bind_command(name: str, addresses: Sequence[int], lines: Sequence[int] | None = None,
                 board: Path | None = None, kernel_driver: bool = False) -> str:
    """Shell that binds driver ``name`` to the chips on ``$GUEST_I2C_BUS`` and waits (5 s at
    most) until each has a driver: with each chip's INT1 line as its IRQ through bmg160-board
    when ``lines`` and ``board`` are given, else through ``new_device`` (no IRQ).
    ``kernel_driver``: first load the guest kernel's own module for ``name`` by its alias
    (the guest runs no udev, so nothing loads it on its own; a built-in one needs nothing)."""
    bus = "/sys/bus/i2c/devices"
    load = (f'modprobe -q ${{GUEST_ROOT:+-d "$GUEST_ROOT"}} i2c:{shlex.quote(name)} '
            "2>/dev/null\n" if kernel_driver else "")
    if lines is not None and board is not None:
        command = (f"insmod {shlex.quote(str(board))} bus=$GUEST_I2C_BUS "
                   f"gpio_base=$GUEST_GPIO_BASE "
                   f"addr={','.join(f'0x{a:02x}' for a in addresses)} "
                   f"line={','.join(str(n) for n in lines)} name={shlex.quote(name)} || exit 1")
    else:
        command = "\n".join(f"echo {shlex.quote(name)} 0x{a:02x} > "
                            f"{bus}/i2c-$GUEST_I2C_BUS/new_device || exit 1" for a in addresses)
    waits = "\n".join(
        f"i=0; while [ ! -e {bus}/$GUEST_I2C_BUS-{a:04x}/driver ] && [ $i -lt 100 ]; do "
        f"sleep 0.05; i=$((i + 1)); done\n"
        f"[ -e {bus}/$GUEST_I2C_BUS-{a:04x}/driver ] || "
        f"{{ echo 'no driver bound to 0x{a:02x} (dmesg:)' >&2; dmesg | tail -n 5 >&2; exit 1; }}"
        for a in addresses)
    return f"{load}{command}\n{waits}\n"


def unbind_command(addresses: Sequence[int], board: bool) -> str:
    """Shell that takes the chips' clients away again (the driver's remove runs)."""
    if board:
        return "rmmod bmg160_board\n"
    return "\n".join(f"echo 0x{a:02x} > /sys/bus/i2c/devices/i2c-$GUEST_I2C_BUS/delete_device"
                     for a in addresses) + "\n"
