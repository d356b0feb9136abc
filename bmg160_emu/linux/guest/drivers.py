"""A driver in the guest: its modules in load order with the kernel modules they need, and
the agent's requests that bind it to the emulated chips (and unbind it).

Why a board module for the IRQ: ``new_device`` in sysfs gives a client no interrupt, and the
bmg160 driver (as many IIO drivers) registers its data-ready trigger and events only with
one; bmg160-board declares the clients with their INT1 line's IRQ as a board file or
device tree would (module_sources/bmg160-board.c).
"""

from __future__ import annotations

import subprocess
from collections.abc import Sequence
from pathlib import Path

from bmg160_emu.linux.guest import agent
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


def bind_ops(name: str, addresses: Sequence[int], bus: int, lines: Sequence[int] | None = None,
             board: Path | None = None, gpio_base: int | None = None,
             kernel_driver: bool = False, timeout_s: float = 5.0) -> list[agent.Op]:
    """Agent requests that bind driver ``name`` to the chips on I2C bus ``bus`` and wait
    (``timeout_s`` of the guest's clock at most) until each has a driver: with each chip's
    INT1 line as its IRQ through bmg160-board when ``lines``, ``board`` and ``gpio_base``
    are given, else through ``new_device`` (no IRQ). ``kernel_driver``: first load the guest
    kernel's own module for ``name`` by its alias (the guest runs no udev, so nothing loads
    it on its own; a built-in one needs nothing). The batch stops at the first failure."""
    ops = [agent.modprobe(f"i2c:{name}", check=False)] if kernel_driver else []
    if lines is not None and board is not None and gpio_base is not None:
        ops.append(agent.insmod(board, f"bus={bus} gpio_base={gpio_base} "
                                f"addr={','.join(f'0x{a:02x}' for a in addresses)} "
                                f"line={','.join(str(n) for n in lines)} name={name}"))
    else:
        ops += [agent.write(f"/sys/bus/i2c/devices/i2c-{bus}/new_device", f"{name} 0x{a:02x}\n",
                            check=True) for a in addresses]
    ops += [agent.wait(f"/sys/bus/i2c/devices/{bus}-{a:04x}/driver", timeout_s)
            for a in addresses]
    return ops


def unbind_ops(addresses: Sequence[int], bus: int, board: bool) -> list[agent.Op]:
    """Agent requests that take the chips' clients away again (the driver's remove runs)."""
    if board:
        return [agent.rmmod("bmg160_board")]
    return [agent.write(f"/sys/bus/i2c/devices/i2c-{bus}/delete_device", f"0x{a:02x}\n")
            for a in addresses]


def bind_failure(replies: Sequence[agent.Reply], ops: Sequence[agent.Op]) -> str | None:
    """What went wrong in a bind batch, in one line, or None when it all worked."""
    for op, reply in zip(ops, replies):
        if reply.status and op.check:
            what = op.subject
            if op.name == "wait":
                return f"no driver bound ({what} did not appear)"
            return f"{op.name} {what}: {reply.error()}"
    return None
