"""The watched side of ``bmg160-emu watch``: a session publishes snapshots on a Unix socket.

A running session (``run``, ``script``, a test) makes a :class:`WatchServer` with its chips and
transaction logs; viewers connect to its socket and receive one JSON line per snapshot, about
ten a second. The socket lives in a directory only the user can enter (mode 0700, checked
before use) and is itself mode 0600: nothing listens on a network port, and no other user can
connect. Snapshots read the chips without side effects (``dump``: no MSB latch, no FIFO pop),
so watching a session never changes what its driver reads.
"""

from __future__ import annotations

import contextlib
import itertools
import json
import os
import select
import shlex
import shutil
import socket
import stat
import subprocess
import sys
import tempfile
import threading
import time
from collections.abc import Iterator, Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

from bmg160_emu.device.registers import address_of, field_of

if TYPE_CHECKING:
    from typing_extensions import Self

SNAPSHOT_VERSION = 1
PERIOD_S = 0.1  # ten snapshots a second: smooth enough for a person, cheap for the session
LAST_TRANSACTIONS = 10
SOCKET_SUFFIX = ".sock"
SUN_PATH_MAX = 107  # bytes of a Unix socket path (sockaddr_un.sun_path is 108, NUL included)
_SERIAL = itertools.count()


class WatchError(RuntimeError):
    """The watch socket or its directory cannot be used safely."""


def socket_dir() -> Path:
    """The user's private directory for watch sockets, made (0700) if missing.

    ``$XDG_RUNTIME_DIR/bmg160-emu`` (a per-user tmpfs on systemd machines), else
    ``<tmp>/bmg160-emu-<uid>``. A directory that another user owns, or that group or others
    can enter, is refused: its sockets could be swapped for someone else's.
    """
    runtime = os.environ.get("XDG_RUNTIME_DIR")
    if runtime and Path(runtime).is_dir():
        folder = Path(runtime) / "bmg160-emu"
    else:
        folder = Path(tempfile.gettempdir()) / f"bmg160-emu-{os.getuid()}"
    with contextlib.suppress(FileExistsError):
        folder.mkdir(mode=0o700)
    check_private_dir(folder)
    return folder


def check_private_dir(folder: Path) -> None:
    info = os.lstat(folder)
    if not stat.S_ISDIR(info.st_mode):
        raise WatchError(f"{folder} is not a directory")
    if info.st_uid != os.getuid():
        raise WatchError(f"{folder} belongs to another user (uid {info.st_uid})")
    if info.st_mode & 0o077:
        raise WatchError(
            f"{folder} can be entered by other users (mode {stat.S_IMODE(info.st_mode):03o}); "
            "it must be 0700"
        )


def live_sockets(folder: Path | None = None) -> list[Path]:
    """Sockets in the private directory whose session still answers, newest first."""
    folder = socket_dir() if folder is None else folder
    found = []
    for path in folder.glob(f"*{SOCKET_SUFFIX}"):
        probe = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
        try:
            probe.connect(str(path))
        except OSError:
            continue  # a session that ended without removing its socket
        finally:
            probe.close()
        found.append(path)
    return sorted(found, key=lambda p: p.stat().st_mtime, reverse=True)


class WatchServer:
    """Serve snapshots of ``chips`` ({name or I2C address: chip}) and ``logs`` (transaction logs) to viewers.

    ``with WatchServer(chips, logs, title="script bringup.script") as server:`` starts a daemon
    thread; ``server.path`` is the socket. The socket is removed when the server stops.
    """

    def __init__(
        self,
        chips: Mapping[Any, Any],
        logs: Sequence[Any] = (),
        *,
        title: str = "",
        path: Path | None = None,
    ) -> None:
        # {name: chip}; an int key is an I2C address (commands keep chips by address)
        self.chips = {f"0x{k:02x}" if isinstance(k, int) else str(k): c for k, c in chips.items()}
        self.logs = list(logs)
        self.title = title
        if path is None:
            path = socket_dir() / f"{os.getpid()}-{next(_SERIAL)}{SOCKET_SUFFIX}"
        else:
            check_private_dir(path.parent)
        if len(os.fsencode(path)) > SUN_PATH_MAX:
            raise WatchError(
                f"socket path {path} is too long for a Unix socket ({len(os.fsencode(path))} "
                f"bytes, at most {SUN_PATH_MAX}): set XDG_RUNTIME_DIR to a shorter directory"
            )
        self.path = path
        self._listener: socket.socket | None = None
        self._clients: list[socket.socket] = []
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._rate: list[tuple[float, int]] = []  # (wall time, transactions so far)

    def start(self) -> Self:
        listener = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
        old_umask = os.umask(0o177)  # the socket file is created 0600
        try:
            listener.bind(str(self.path))
        finally:
            os.umask(old_umask)
        listener.listen(4)
        listener.setblocking(False)
        self._listener = listener
        self._thread = threading.Thread(target=self._serve, name="bmg160-watch", daemon=True)
        self._thread.start()
        return self

    def stop(self) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=2.0)
        for client in self._clients:
            client.close()
        self._clients.clear()
        if self._listener is not None:
            self._listener.close()
            self._listener = None
        with contextlib.suppress(FileNotFoundError):
            self.path.unlink()

    def __enter__(self) -> Self:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.stop()

    def _serve(self) -> None:
        assert self._listener is not None
        while not self._stop.is_set():
            readable, _, _ = select.select([self._listener], [], [], PERIOD_S)
            if readable:
                with contextlib.suppress(BlockingIOError, InterruptedError):
                    client, _ = self._listener.accept()
                    client.setblocking(True)
                    client.settimeout(1.0)  # a stuck viewer is dropped, never waited for
                    self._clients.append(client)
            if self._clients:
                line = (json.dumps(self.snapshot(), separators=(",", ":")) + "\n").encode()
                for client in list(self._clients):
                    try:
                        client.sendall(line)
                    except OSError:
                        client.close()
                        self._clients.remove(client)

    def transactions_per_second(self, total: int, now: float) -> float:
        """Bus transactions per wall-clock second over the last second or so."""
        self._rate.append((now, total))
        while len(self._rate) > 2 and now - self._rate[1][0] >= 1.0:
            self._rate.pop(0)
        (t0, n0), (t1, n1) = self._rate[0], self._rate[-1]
        return (n1 - n0) / (t1 - t0) if t1 > t0 else 0.0

    def snapshot(self) -> dict[str, Any]:
        """What a viewer shows, as JSON-ready data."""
        chips = []
        for name, chip in self.chips.items():
            registers = chip.dump()
            sensitivity = float(chip.sensitivity)
            rate_x = address_of("RATE_X_LSB")
            counts = [
                int.from_bytes(registers[rate_x + 2 * i : rate_x + 2 * i + 2], "little", signed=True)
                for i in range(3)
            ]
            fifo = field_of("FIFO_STATUS", "fifo_frame_counter")
            chips.append({
                "name": name,
                "time_s": float(chip.time),
                "registers": list(registers),
                "rate_dps": [c / sensitivity for c in counts],
                "fifo_frames": fifo.extract(registers[address_of("FIFO_STATUS")]),
                "int1": bool(chip.int1),
                "int2": bool(chip.int2),
                "odr_hz": float(chip.odr_hz),
                "power_mode": str(getattr(chip, "power_mode", "")),
            })  # fmt: skip
        total = sum(log.total for log in self.logs)
        last: list[str] = []
        for log in self.logs:
            count = len(log)
            for index in range(max(0, count - LAST_TRANSACTIONS), count):
                with contextlib.suppress(IndexError):  # the bus thread may drop old entries
                    last.append(str(log[index]))
        return {
            "version": SNAPSHOT_VERSION,
            "title": self.title,
            "pid": os.getpid(),
            "chips": chips,
            "transactions": total,
            "transactions_per_s": self.transactions_per_second(total, time.monotonic()),
            "last": last[-LAST_TRANSACTIONS:],
        }


class SnapshotConnection:
    """A viewer's end of a watch socket: ``fileno`` for ``select`` (so a viewer can wait on the
    socket and its keyboard at once), ``read`` the snapshots that have arrived."""

    def __init__(self, path: Path) -> None:
        check_private_dir(path.parent)
        self.path = path
        self._socket = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
        try:
            self._socket.connect(str(path))
        except OSError as exc:
            self._socket.close()
            raise WatchError(f"cannot attach to {path}: {exc.strerror or exc}") from None
        self._socket.setblocking(False)
        self._pending = b""

    def fileno(self) -> int:
        return self._socket.fileno()

    def read(self) -> list[dict[str, Any]] | None:
        """The whole snapshots received so far ([] when none is complete yet), or None once
        the session has ended (closed or reset its end)."""
        chunks: list[bytes] = []
        while True:
            try:
                chunk = self._socket.recv(1 << 16)
            except (BlockingIOError, InterruptedError):
                break
            except OSError:
                return None
            if not chunk:
                if chunks:
                    break  # what came before the end is shown; the end is seen next time
                return None
            chunks.append(chunk)
        *lines, self._pending = (self._pending + b"".join(chunks)).split(b"\n")
        try:
            return [json.loads(line) for line in lines if line]
        except json.JSONDecodeError:
            raise WatchError(f"{self.path}: not a bmg160-emu watch socket") from None

    def close(self) -> None:
        self._socket.close()

    def __enter__(self) -> Self:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def read_snapshots(path: Path, timeout_s: float = 5.0) -> Any:
    """Connect to a watch socket and yield its snapshots (dicts) until the session ends."""
    with SnapshotConnection(path) as connection:
        while True:
            ready, _, _ = select.select([connection], [], [], timeout_s)
            if not ready:
                raise WatchError(f"{path}: the session stopped answering")
            snapshots = connection.read()
            if snapshots is None:
                return
            yield from snapshots


@contextlib.contextmanager
def watched(chips: Mapping[Any, Any], logs: Sequence[Any], title: str) -> Iterator[WatchServer]:
    """A command's ``--watch``: serve the session, say how to attach, and inside tmux open the
    view in a new pane beside the session (the session keeps its own terminal)."""
    with WatchServer(chips, logs, title=title) as server:
        command = f"bmg160-emu watch --socket {shlex.quote(str(server.path))}"
        print(f"bmg160-emu: watch this session with: {command}", file=sys.stderr)
        if os.environ.get("TMUX") and shutil.which("tmux"):
            viewer = f"{shlex.quote(sys.executable)} -m bmg160_emu watch --socket "
            viewer += shlex.quote(str(server.path))
            subprocess.run(["tmux", "split-window", "-d", "-h", viewer], check=False)
        yield server
