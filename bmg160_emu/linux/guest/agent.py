"""The guest's agent seen from the host: ``agent.c`` built once into the cache (a static
program: it runs in any guest root), and the request and response files it serves.

Why a C program and not a shell or Python agent: under user-mode Linux every guest system
call is a ptrace stop, so a fork+exec costs 15-25 ms and a Python start seconds, where a
sysfs read from a running process costs 0.16 ms (linux-kernel-notes.md). The agent is PID 1
of a UML guest (it mounts, loads the modules, finds the virtio adapters), then serves
:class:`Op` batches; a test's ``attr()`` is one ``read``, not a ``cat`` started by a shell.

The channel is two lines of the host's virtio-gpio controller
(:class:`~bmg160_emu.linux.virtio_gpio.AgentLines`): a pulse on the request line wakes the
agent (it reads ``FOLDER/request``), a toggle of the reply line says ``FOLDER/response`` is
written. Wire format (agent.c's header): a ``BGQ1 SEQ COUNT`` or ``BGR1 SEQ COUNT`` line, then
per record ``NAME FLAGS NFIELDS`` or ``STATUS NFIELDS``, each field ``LENGTH\\n`` + bytes + ``\\n``.
"""

from __future__ import annotations

import errno
import os
import shutil
import subprocess
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

from bmg160_emu.linux.guest.cache import cache_dir, content_hash
from bmg160_emu.linux.guest.engine import EngineError

SOURCE = Path(__file__).with_name("agent.c")
STATIC_LIBC = Path("/usr/lib/x86_64-linux-gnu/libc.a")  # Debian's libc6-dev (amd64)
CHECK = 1  # an op's flag: the ops after it in the batch are skipped when it fails
SKIPPED = -1  # the status of an op skipped after a checked failure


def missing() -> list[str]:
    """What building the agent needs and this host lacks, one line each."""
    lines = []
    if shutil.which("gcc") is None:
        lines.append("gcc is missing (Debian package gcc)")
    if not STATIC_LIBC.exists():
        lines.append("the static C library is missing (Debian package libc6-dev)")
    return lines


def binary() -> Path:
    """The agent, built from agent.c into the cache once per content of the source."""
    target = cache_dir() / f"agent-{content_hash([SOURCE], length=10)}"
    if target.exists():
        return target
    lacking = missing()
    if lacking:
        raise EngineError("cannot build the guest agent: " + "; ".join(lacking))
    target.parent.mkdir(parents=True, exist_ok=True)
    partial = target.with_name(f"{target.name}.{os.getpid()}.tmp")
    built = subprocess.run(["gcc", "-static", "-O2", "-Wall", "-o", str(partial), str(SOURCE)],
                           capture_output=True, text=True, check=False)
    if built.returncode != 0:
        lines = [line for line in built.stderr.splitlines() if "error" in line] or [
            built.stderr.strip()]
        raise EngineError(f"building the guest agent ({SOURCE.name}) failed: {lines[0]}")
    partial.replace(target)
    return target


def guarded(command: Sequence[str]) -> list[str]:
    """``command`` run through ``agent orphan-guard``: in a process group of its own, which
    gets SIGTERM (then SIGKILL) when the thread that started the guard ends
    (PR_SET_PDEATHSIG) or the guard gets SIGTERM, and SIGKILL once ``command`` has ended (a
    UML guest's helper processes outlive its main process, holding the console open: 10
    seen here). So a guest never outlives a harness that died."""
    return [str(binary()), "orphan-guard", str(os.getpid()), "--", *command]


@dataclass(frozen=True)
class Op:
    """One request to the agent: a name agent.c knows and its fields."""

    name: str
    fields: tuple[str | bytes, ...] = ()
    check: bool = False  # skip the rest of the batch when this one fails

    @property
    def subject(self) -> str:
        """What the request is about (its path or name), for messages."""
        first = self.fields[0] if self.fields else self.name
        return first.decode(errors="replace") if isinstance(first, bytes) else first


@dataclass(frozen=True)
class Reply:
    """What the agent answered to one :class:`Op`: 0, an errno, or SKIPPED; its fields."""

    status: int
    fields: list[bytes] = field(default_factory=list)

    @property
    def text(self) -> str:
        """The first field as text (a file's content, a run's exit status)."""
        return self.fields[0].decode(errors="replace") if self.fields else ""

    def error(self) -> str:
        """The status as words: "ENOENT (No such file or directory)"."""
        if self.status == SKIPPED:
            return "skipped after an earlier failure"
        name = errno.errorcode.get(self.status, str(self.status))
        return f"{name} ({os.strerror(self.status)})"


def run(cwd: str, command: str, stdout: Path, stderr: Path, check: bool = False) -> Op:
    """``/bin/sh -c command`` in ``cwd``; its output in the two files (host paths that the
    guest sees at the same place: inside the results folder)."""
    return Op("run", (cwd, command, str(stdout), str(stderr)), check)


def read(path: str, limit: int = 1 << 20, check: bool = False) -> Op:
    return Op("read", (path, str(limit)), check)


def write(path: str, value: str | bytes, check: bool = False) -> Op:
    return Op("write", (path, value), check)


def insmod(path: str | Path, params: str = "", check: bool = True) -> Op:
    return Op("insmod", (str(path), params), check)


def modprobe(name: str, params: str = "", check: bool = True) -> Op:
    """A module of the guest kernel by name or alias (``i2c:bmg160``), after those it
    depends on (modules.dep, modules.alias and modules.builtin of GUEST_ROOT)."""
    return Op("modprobe", (name, params), check)


def rmmod(name: str, check: bool = False) -> Op:
    return Op("rmmod", (name,), check)


def wait(path: str, timeout_s: float, check: bool = True) -> Op:
    """Until ``path`` exists, at most ``timeout_s`` of the guest's clock."""
    return Op("wait", (path, str(round(timeout_s * 1e9))), check)


def glob(pattern: str) -> Op:
    return Op("glob", (pattern,))


def capture(device: str, out: Path, records: int, record_bytes: int, timeout_s: float) -> Op:
    """Read an IIO buffer into ``out`` until ``records`` records (0: no limit) or
    ``timeout_s`` of the guest's clock; fields: records read, guest ns it took."""
    return Op("capture", (device, str(out), str(records), str(record_bytes),
                          str(round(timeout_s * 1e9))))


def stop() -> Op:
    return Op("stop")


def _field(value: str | bytes) -> bytes:
    data = value.encode() if isinstance(value, str) else value
    return b"%d\n%s\n" % (len(data), data)


def encode(seq: int, ops: Sequence[Op]) -> bytes:
    """The request file for ``ops``."""
    parts = [b"BGQ1 %d %d\n" % (seq, len(ops))]
    for op in ops:
        parts.append(b"%s %d %d\n" % (op.name.encode(), CHECK if op.check else 0,
                                      len(op.fields)))
        parts += [_field(value) for value in op.fields]
    return b"".join(parts)


class ProtocolError(RuntimeError):
    """A response file that is not the answer to the request sent."""


def decode(data: bytes, seq: int) -> list[Reply]:
    """The replies in a response file, checked to answer request ``seq``."""
    head, _, rest = data.partition(b"\n")
    words = head.split()
    if len(words) != 3 or words[0] != b"BGR1" or int(words[1]) != seq:
        raise ProtocolError(f"response {head[:40]!r} does not answer request {seq}")
    replies = []
    at = 0
    try:
        for _ in range(int(words[2])):
            end = rest.index(b"\n", at)
            status, count = (int(w) for w in rest[at:end].split())
            at = end + 1
            fields = []
            for _ in range(count):
                end = rest.index(b"\n", at)
                length = int(rest[at:end])
                fields.append(rest[end + 1:end + 1 + length])
                at = end + 2 + length
            replies.append(Reply(status, fields))
    except ValueError:  # (the agent stops at a record it could not read: it said so)
        raise ProtocolError(f"response {seq} holds {len(replies)} of {int(words[2])} "
                            "replies: the agent could not read the request") from None
    return replies
