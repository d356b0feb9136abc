"""``bmg160-emu doctor``: what each route needs on this system, and the lines that install it.

The core (the chip, the fake buses, the pytest plugin) needs numpy and smbus2 only. The
other routes need pip extras (Python packages) or Debian packages (programs, libraries,
headers): umockdev for ``run``, a kernel's i2c-stub or a QEMU guest for ``stub`` and the
kernel tests, the AVR tool chain and simavr for the firmware. The lists are those of
.ci/setup.d/*.sh, which CI runs; this command checks them without installing anything.
"""

from __future__ import annotations

import argparse
import os
import platform
import shutil
import subprocess
import sys
import sysconfig
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path

from bmg160_emu.commands._common import Subparsers, add_command_parser
from bmg160_emu.commands._extras import available

EPILOG = """\
examples:
  bmg160-emu doctor              every route
  bmg160-emu doctor umockdev     what `bmg160-emu run` needs

Exit status 0 when every route checked has what it needs, 1 otherwise. The printed lines
are for this system: apt-get for Debian and Ubuntu, pip for the Python running this command.
"""


@dataclass(frozen=True)
class Route:
    """What one way of using the emulator needs: pip extras (import name -> extra),
    Debian packages, and checks of other kinds (name -> probe)."""

    summary: str
    modules: dict[str, str] = field(default_factory=dict)  # import name -> pip requirement
    debian: tuple[str, ...] = ()
    probes: tuple[tuple[str, str], ...] = ()  # (what, probe name in PROBES)


EXTRA_ROUTES = {
    "noise": Route("generate through a filter, identify, thermal, plots",
                   {"scipy": "bmg160-emu[noise]", "allantools": "bmg160-emu[noise]",
                    "matplotlib": "bmg160-emu[noise]", "tqdm": "bmg160-emu[noise]"}),
    "montecarlo": Route("montecarlo on all cores (Dask); sync needs nothing",
                        {"dask": "bmg160-emu[montecarlo]",
                         "distributed": "bmg160-emu[montecarlo]"}),
    "watch": Route("watch: the live terminal view", {"rich": "bmg160-emu[watch]"}),
    "basilisk": Route("the Basilisk closed loop", {"Basilisk": "bmg160-emu[basilisk]"}),
}

SYSTEM_ROUTES = {
    "umockdev": Route(
        "run: unmodified programs on a virtual /dev/i2c-N",
        {"gi": "PyGObject<3.50"},  # 3.50+ needs GLib >= 2.80 (Debian 12 has 2.74)
        # the typelib and preload library; headers and a compiler to build PyGObject
        ("umockdev", "gir1.2-umockdev-1.0", "libgirepository1.0-dev", "libcairo2-dev",
         "pkg-config", "gcc"),
        (("Python headers (to build PyGObject)", "python_headers"),
         ("the UMockdev typelib from Python", "umockdev_typelib")),
    ),
    "kernel": Route(
        "stub: kernel drivers through i2c-stub; the kernel tests' QEMU guest",
        {},
        ("i2c-tools", "kmod", "qemu-system-x86", "busybox-static", "cpio", "util-linux",
         "make", "patch", "xz-utils"),
        (("the i2c-stub module of the running kernel (for stub, as root)", "i2c_stub"),),
    ),
    "firmware": Route(
        "firmware build and capture: the ATmega328P firmware in simavr",
        {},
        ("gcc-avr", "avr-libc", "binutils-avr", "simavr", "libsimavr-dev", "libelf-dev", "gcc",
         "make"),
    ),
}
ROUTES = {**EXTRA_ROUTES, **SYSTEM_ROUTES}


def _python_headers() -> bool:
    include = sysconfig.get_paths().get("include")
    return include is not None and (Path(include) / "Python.h").is_file()


def _umockdev_typelib() -> bool:
    from bmg160_emu.linux.umockdev import UMockdevUnavailable, load_umockdev

    try:
        load_umockdev()
    except UMockdevUnavailable:
        return False
    return True


def _i2c_stub() -> bool:
    release = platform.release()
    folder = Path("/lib/modules") / release
    if (Path("/sys/module/i2c_stub")).exists():
        return True  # loaded already
    return folder.is_dir() and any(folder.rglob("i2c-stub.ko*"))


PROBES: dict[str, Callable[[], bool]] = {
    "python_headers": _python_headers,
    "umockdev_typelib": _umockdev_typelib,
    "i2c_stub": _i2c_stub,
}


def debian_installed(package: str) -> bool | None:
    """Whether dpkg has ``package`` installed; None where there is no dpkg (not Debian)."""
    if shutil.which("dpkg-query") is None:
        return None
    result = subprocess.run(["dpkg-query", "-W", "-f=${Status}", package],
                            capture_output=True, text=True, check=False)
    return result.returncode == 0 and "install ok installed" in result.stdout


@dataclass
class Findings:
    """What is missing per route, and the install lines for all of it."""

    missing: dict[str, list[str]] = field(default_factory=dict)
    debian: list[str] = field(default_factory=list)
    pip: list[str] = field(default_factory=list)
    other: list[str] = field(default_factory=list)
    no_dpkg: bool = False

    def lines(self, sudo: bool) -> list[str]:
        out = []
        if self.debian:
            prefix = "sudo " if sudo else ""
            apt = f"{prefix}apt-get install -y {' '.join(self.debian)}"
            out.append(apt if not self.no_dpkg else
                       f"(no dpkg here: the equivalents of {' '.join(self.debian)})")
        for requirement in self.pip:
            out.append(f"{sys.executable} -m pip install '{requirement}'")
        return out


def check(names: Sequence[str], importable: Callable[[str], bool] = available,
          installed: Callable[[str], bool | None] = debian_installed,
          probes: dict[str, Callable[[], bool]] | None = None) -> Findings:
    """What the routes ``names`` miss on this system (the callables are the probes: tests
    give their own)."""
    probes = PROBES if probes is None else probes
    found = Findings()
    for name in names:
        route = ROUTES[name]
        missing = found.missing.setdefault(name, [])
        for module, requirement in route.modules.items():
            if not importable(module):
                missing.append(module)
                if requirement not in found.pip:
                    found.pip.append(requirement)
        for package in route.debian:
            state = installed(package)
            found.no_dpkg = found.no_dpkg or state is None
            if not state:
                missing.append(package)
                if package not in found.debian:
                    found.debian.append(package)
        for what, probe in route.probes:
            if not probes[probe]():
                missing.append(what)
                if probe == "i2c_stub":
                    found.other.append("the running kernel has no i2c-stub module (a container's "
                                       "often has none): the QEMU guest route of "
                                       "docs/i2c-stub.md needs only the Debian packages")
    if "gi" in found.missing.get("umockdev", []) and "PyGObject<3.50" in found.pip:
        # pip builds PyGObject after the Debian headers are in: apt first, then pip
        found.pip.remove("PyGObject<3.50")
        found.pip.append("PyGObject<3.50")
    return found


def report(found: Findings, sudo: bool) -> str:
    lines = [f"bmg160-emu doctor: Python {platform.python_version()} at {sys.executable}", ""]
    width = max(len(name) for name in ROUTES) + 2
    for name, missing in found.missing.items():
        state = "ok" if not missing else "missing: " + ", ".join(missing)
        label = f"[{name}]" if name in EXTRA_ROUTES else name
        lines.append(f"  {label:<{width}} {state}")
        lines.append(f"  {'':<{width}} ({ROUTES[name].summary})")
    install = found.lines(sudo)
    lines.append("")
    if install:
        lines.append("to install what is missing, in this order:")
        lines.extend(f"  {line}" for line in install)
    elif not found.other:
        lines.append("every route checked has what it needs")
    if found.other:
        lines.append("notes:")
        lines.extend(f"  {line}" for line in found.other)
    return "\n".join(lines)


def register(subparsers: Subparsers) -> None:
    parser = add_command_parser(
        subparsers,
        "doctor",
        "check what each route needs on this system and print the install lines",
        "Check the pip extras and the Debian packages each route needs (umockdev for "
        "run, i2c-stub or a QEMU guest for the kernel, the AVR tool chain for the "
        "firmware) and print the exact apt-get and pip lines for what is missing.",
        EPILOG,
    )
    parser.add_argument("routes", nargs="*", metavar="ROUTE", type=_route,
                        help=f"routes to check: {', '.join(ROUTES)} (default: all)")
    parser.set_defaults(func=run)


def _route(text: str) -> str:
    if text not in ROUTES:
        raise argparse.ArgumentTypeError(f"unknown route {text!r} (routes: {', '.join(ROUTES)})")
    return text


def run(args: argparse.Namespace) -> int:
    names = list(dict.fromkeys(args.routes)) or list(ROUTES)
    found = check(names)
    print(report(found, sudo=os.geteuid() != 0))
    return 0 if not any(found.missing.values()) else 1
