"""What every guest engine offers: the ``Boot`` a guest is started with, the ``Engine``
protocol, and the registry that picks the first engine that is ready on this host.

An engine boots a Linux guest in which the host's root file system is mounted (read-only
unless ``Boot.host_root_readonly`` is False) and either ``Boot.script`` runs with ``/bin/sh``
or the agent (:mod:`.agent`) serves ``Boot.agent``'s folder, chrooted in it, so the host's
own Python, i2c-tools and the project run unchanged. The contract every engine keeps, so
that the harness and the tests need not know which one runs:

- ``Boot.results`` is writable at the same path inside the guest (the only writable host
  folder); the script's environment has ``BMG160_RESULTS`` (that path), ``GUEST_ENGINE``
  (the engine's name), ``GUEST_I2C_BUS`` / ``GUEST_GPIO_BASE`` (the virtio-i2c adapter's
  number and the global number of the virtio-gpio controller's line 0, when the sockets
  were given), ``HOME`` and ``TMPDIR`` (a guest tmpfs under ``/run``), ``PATH``, and every
  ``Boot.environment`` word (passed as KEY=VAL on the kernel command line, so values must
  not contain spaces);
- before the script runs, the engine has brought up virtio-i2c (and virtio-gpio with
  interrupts) on ``Boot.i2c_socket`` (``Boot.gpio_socket``), and loaded ``Boot.modules``
  in order: a name is a module of the guest kernel (``modprobe``; a built-in one is
  already there), a path is a ``.ko`` file built for that kernel (``insmod``);
- the script's exit status (or the agent's, once a request told it to stop) is written to
  ``$BMG160_RESULTS/exit-status``, the results folder is synced, and the guest powers off,
  which ends the process ``start`` returned (its stdout carries the console);
- the process does not outlive the thread that started it (``agent orphan-guard``: SIGTERM
  when its parent ends), so a harness that dies takes its guest with it;
- with ``Boot.time_travel`` (an engine that can: uml), the guest's clock is the calendar
  listening on that socket (UML's ``time-travel=ext``); an engine that cannot refuses it.

Optional, where an engine can: ``build_module(path, progress) -> list[Path]`` (a user's
``.ko`` or Kbuild source folder made ready for this engine's kernel) and ``board_module() ->
Path | None`` (bmg160-board built for it: binds a driver with its IRQ on a virtio-gpio line).

Engines register by name in :data:`ENGINE_MODULES`: each module exposes ``engine()``
returning an instance. A module that is absent (or fails to import) is not an engine here.
"""

from __future__ import annotations

import importlib
import subprocess
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Protocol, runtime_checkable

# Preference order: the first that is ready is the default (user-mode Linux boots in about
# 1 s where QEMU under TCG takes about 6 s; linux-kernel-notes.md, "User-mode Linux").
ENGINE_MODULES = ("uml", "qemu")

Progress = Callable[[str], None]


@dataclass(frozen=True)
class AgentBoot:
    """The agent's folder (inside the results folder) and its two virtio-gpio lines
    (offsets; "fifo" and "fifo" for named pipes in the folder)."""

    folder: Path
    request_line: str
    reply_line: str

    @property
    def words(self) -> tuple[str, str, str]:
        return str(self.folder.resolve()), self.request_line, self.reply_line


@dataclass(frozen=True)
class Boot:
    """One guest's start: what it serves, what it runs, what it may write."""

    results: Path  # writable in the guest at the same path; exit-status lands here
    script: Path | None = None  # run with /bin/sh inside the guest, chrooted in the host's root
    agent: AgentBoot | None = None  # or: the agent serves this folder (the harness's guests)
    time_travel: Path | None = None  # the calendar's socket: the guest's clock (uml only)
    i2c_socket: Path | None = None  # vhost-user virtio-i2c back end (listening already)
    gpio_socket: Path | None = None  # vhost-user virtio-gpio back end (the chips' INT lines)
    host_root_readonly: bool = True
    environment: Mapping[str, str] = field(default_factory=dict)  # KEY=VAL for the script
    modules: Sequence[str | Path] = ()  # kernel module names (modprobe) or .ko paths (insmod)
    memory_mb: int = 512
    cpus: int = 1


@runtime_checkable
class Engine(Protocol):
    """A way to boot a guest kernel on this host."""

    name: str

    def missing(self) -> list[str]:
        """What this host lacks, one line each naming the Debian package (or the command
        that fetches it into the cache); [] when the engine can boot now."""
        ...

    def prepare(self, progress: Progress) -> None:
        """Fetch and build into the cache what :meth:`start` needs (idempotent), saying each
        step through ``progress``."""
        ...

    def start(self, boot: Boot) -> subprocess.Popen[bytes]:
        """Start the guest; the process ends when the guest powers off."""
        ...


class EngineError(RuntimeError):
    """An engine cannot do what was asked; the message is one line for the user."""


def engines() -> dict[str, Engine]:
    """Every engine this installation has, by name, in preference order."""
    found: dict[str, Engine] = {}
    for name in ENGINE_MODULES:
        try:
            module = importlib.import_module(f"{__package__}.{name}")
        except ImportError:
            continue
        factory = getattr(module, "engine", None)
        if callable(factory):
            instance = factory()
            found[instance.name] = instance
    return found


def default_engine(available: Mapping[str, Engine] | None = None) -> Engine | None:
    """The first engine that is ready (nothing missing), or None."""
    for candidate in (engines() if available is None else available).values():
        if not candidate.missing():
            return candidate
    return None


def choose(name: str | None) -> Engine:
    """The engine called ``name`` (or the default): ready, else an :class:`EngineError`
    saying what is missing."""
    available = engines()
    if name is None:
        chosen = default_engine(available)
        if chosen is None:
            lines = [f"{n}: {m}" for n, e in available.items() for m in e.missing()]
            raise EngineError("no guest engine is ready here: " + "; ".join(lines))
        return chosen
    if name not in available:
        raise EngineError(f"unknown engine {name!r} (have: {', '.join(available) or 'none'})")
    chosen = available[name]
    missing = chosen.missing()
    if missing:
        raise EngineError(f"engine {name} is not ready: " + "; ".join(missing))
    return chosen
