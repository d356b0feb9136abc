"""Output files that are complete or absent: written beside the target, renamed into place.

Why: a command stopped half-way (SIGINT, SIGTERM, a full disk, an exception) must not leave a
file that looks like a result: an ``.npy`` whose header claims the full shape, a CSV cut short
under a header that still gives the full sample count, a zip holding half its arrays. Every
command that writes a file writes it through :func:`atomic_path` or :func:`atomic_open`: the
data goes to a temporary file in the target's folder (same file system, so ``os.replace`` is
atomic), is flushed to disk, and only then replaces the target. On any exception the
temporary file is removed and the target is left as it was.

A target that exists and is not a regular file (``/dev/stdout``, a FIFO, ``/dev/full``) cannot
be replaced: it is written in place at the end, from a temporary file, and a write error
(ENOSPC on ``/dev/full``) is raised, never swallowed. A symbolic link is followed: the file it
names is replaced and the link kept.
"""

from __future__ import annotations

import contextlib
import os
import shutil
import signal
import stat
import tempfile
import threading
from collections.abc import Callable, Iterator, Sequence
from pathlib import Path
from typing import IO, Any

__all__ = [
    "AtomicFile", "OutputError", "atomic_open", "atomic_path", "atomic_paths", "check_free_space",
    "check_writable",
    "held_signals", "name_problem", "outputs_so_far", "shown_path", "size_text", "write_together",
]

# every target this process put in place, and every one whose temporary file was removed
# unfinished, in order: what a stopped command says it kept (issue 35: identify said
# "unfinished outputs removed" with 4 of its 5 outputs written)
_WRITTEN: list[Path] = []
_DISCARDED: list[Path] = []


def outputs_so_far() -> tuple[list[Path], list[Path]]:
    """Copies of the lists of outputs written whole and of outputs removed unfinished by
    this process so far (a caller compares them before and after its work)."""
    return list(_WRITTEN), list(_DISCARDED)


class OutputError(OSError):
    """An output file cannot be written: the message names the file and the reason."""


def _resolved(path: str | os.PathLike[str]) -> Path:
    return Path(os.path.realpath(os.fspath(path)))


def _is_special(target: Path) -> bool:
    """An existing target that is not a regular file (device, FIFO, socket)."""
    try:
        return not stat.S_ISREG(target.stat().st_mode)
    except FileNotFoundError:
        return False


NAME_MAX = 255  # bytes in one path component on Linux's file systems (limits.h)
PATH_MAX = 4096  # bytes in a whole path given to the kernel (limits.h)


def shown_path(path: str | os.PathLike[str], width: int = 80) -> str:
    """A path for a one-line message: whole when short, else its start and end around
    ``...`` (a 300-character name must not fill the screen)."""
    text = os.fspath(path)
    if isinstance(text, bytes):  # pragma: no cover - the commands give str paths
        text = text.decode(errors="replace")
    if len(text) <= width:
        return text
    keep = (width - 3) // 2
    return text[:keep] + "..." + text[-keep:]


def name_problem(path: str | os.PathLike[str]) -> str | None:
    """Why the kernel would refuse ``path`` by its length alone (ENAMETOOLONG), or None: a
    component over NAME_MAX bytes, or the whole over PATH_MAX (issue 35: a 300-character
    name was an OSError traceback in identify, generate, thermal and firmware capture)."""
    text = os.fsencode(path)
    if len(text) >= PATH_MAX:
        return f"the path is {len(text):,} bytes; Linux takes at most {PATH_MAX - 1:,}"
    longest = max(text.split(b"/"), key=len)
    if len(longest) > NAME_MAX:
        return (f"a name in it is {len(longest):,} bytes; a file name is at most "
                f"{NAME_MAX} bytes")
    return None


def check_writable(path: str | os.PathLike[str]) -> None:
    """Refuse, before any work, a path whose folder is missing or not writable, or that is a
    folder, or whose name is too long: :class:`OutputError` naming the path."""
    problem = name_problem(path)
    if problem is not None:
        raise OutputError(f"cannot write {shown_path(path)}: {problem}")
    target = _resolved(path)
    if target.is_dir():
        raise OutputError(f"cannot write {os.fspath(path)}: it is a folder")
    if _is_special(target):
        if not os.access(target, os.W_OK):
            raise OutputError(f"cannot write {os.fspath(path)}: permission denied")
        return
    folder = target.parent
    if not folder.is_dir():
        raise OutputError(f"cannot write {os.fspath(path)}: folder {folder} does not exist")
    if not os.access(folder, os.W_OK | os.X_OK):
        raise OutputError(f"cannot write {os.fspath(path)}: permission denied on {folder}")


def check_free_space(path: str | os.PathLike[str], size_bytes: int) -> None:
    """Refuse, before any work, an output of a known size that the target's file system has
    no room for (the temporary file and the target share it): :class:`OutputError` naming
    the path, the size needed and the space free."""
    target = _resolved(path)
    if _is_special(target):
        return
    free = shutil.disk_usage(target.parent).free
    if size_bytes > free:
        raise OutputError(
            f"cannot write {os.fspath(path)}: it needs {size_text(size_bytes)} and "
            f"{target.parent} has {size_text(free)} free"
        )


def size_text(n: int) -> str:
    """A byte count for a message: ``812 bytes``, ``5.6 GB``."""
    for unit in ("bytes", "kB", "MB", "GB", "TB"):
        if n < 1000 or unit == "TB":
            return f"{n:,} {unit}" if unit == "bytes" else f"{n:.1f} {unit}"
        n /= 1000  # type: ignore[assignment]
    raise AssertionError  # pragma: no cover


@contextlib.contextmanager
def held_signals() -> Iterator[list[int]]:
    """SIGINT and SIGTERM held while an output is being finished: a signal that arrives in the
    block is noted (the yielded list) and delivered again, to the handler it would have
    reached, when the block ends. Why: a ^C while a recording is written out used to remove
    the half-written file and with it every sample recorded (issue 24); held, the file is
    finished first and the command then stops as the signal says. Only the main thread can
    hold signals; elsewhere the block runs unchanged."""
    if threading.current_thread() is not threading.main_thread():
        yield []
        return
    arrived: list[int] = []
    numbers = (signal.SIGINT, signal.SIGTERM)
    previous = {n: signal.signal(n, lambda number, frame: arrived.append(number)) for n in numbers}
    try:
        yield arrived
    finally:
        for number, handler in previous.items():
            signal.signal(number, signal.SIG_DFL if handler is None else handler)
        if arrived:
            signal.raise_signal(arrived[0])  # the restored handler acts on it


def _mode_for_new_file() -> int:
    umask = os.umask(0)
    os.umask(umask)
    return 0o666 & ~umask


@contextlib.contextmanager
def atomic_path(path: str | os.PathLike[str], suffix: str | None = None) -> Iterator[Path]:
    """A temporary path to write the whole output to; it replaces ``path`` when the block
    ends without an exception, and is removed otherwise. ``suffix`` (default: the target's)
    is kept because some writers choose the format from it (``np.save`` adds ``.npy``)."""
    target = _resolved(path)
    special = _is_special(target)
    suffix = target.suffix if suffix is None else suffix
    folder = None if special else target.parent
    try:
        fd, temp_name = tempfile.mkstemp(prefix=f".{target.name}.", suffix=f".part{suffix}",
                                         dir=folder)
    except OSError as exc:  # named by the output asked for, not by its temporary name
        raise OSError(exc.errno, exc.strerror, os.fspath(path)) from None
    os.close(fd)
    temp = Path(temp_name)
    placed = False
    try:
        yield temp
        if special:
            try:
                with temp.open("rb") as source, target.open("wb") as sink:
                    shutil.copyfileobj(source, sink)
            except OSError as exc:  # /dev/full: ENOSPC, named by the target
                raise OSError(exc.errno, exc.strerror, os.fspath(path)) from None
        else:
            with temp.open("rb+") as done:
                os.fsync(done.fileno())
            if target.exists():
                os.chmod(temp, stat.S_IMODE(target.stat().st_mode))
            else:
                os.chmod(temp, _mode_for_new_file())
            os.replace(temp, target)
        placed = True
        _WRITTEN.append(Path(os.fspath(path)))
    finally:
        with contextlib.suppress(FileNotFoundError):
            temp.unlink()
        if not placed:
            _DISCARDED.append(Path(os.fspath(path)))


@contextlib.contextmanager
def atomic_paths(paths: list[Path]) -> Iterator[list[Path]]:
    """Temporary paths for several outputs that appear together or not at all: each is
    written in the block (the slow part, a full disk or a signal may stop it: then every
    temporary file is removed and no target changes), and the targets are renamed into place
    together at its end with the signals held, so that a signal cannot leave some of them
    new and the rest old (issue 35: identify wrote 4 of its 5 outputs and said "unfinished
    outputs removed")."""
    held = None
    # a special target (/dev/full, a FIFO) is written at its commit and may fail there: the
    # stack closes it first (entered last), so that its failure discards the regular ones
    order = sorted(range(len(paths)), key=lambda i: _is_special(_resolved(paths[i])))
    try:
        with contextlib.ExitStack() as stack:
            temps: list[Path] = [Path()] * len(paths)
            for i in order:
                temps[i] = stack.enter_context(atomic_path(paths[i]))
            yield temps
            held = held_signals()
            held.__enter__()  # from here to the last rename a signal waits
    finally:
        if held is not None:
            held.__exit__(None, None, None)  # then acts: every target is in place


def write_together(jobs: Sequence[tuple[Path, Callable[[Path], None]]],
                   folder: Path | None = None) -> list[Path]:
    """Run each ``(target, write(temporary path))`` job and put every target in place together
    (:func:`atomic_paths`): all of them, or none and the old files as they were; the targets
    are returned. ``folder``: the folder they go into, made here when missing and removed
    again when nothing could be written into it (a half-full --figures folder, issue 35).
    Raises OutputError naming the output that could not be written."""
    if not jobs:
        return []
    made = folder is not None and not folder.exists()
    try:
        if made:
            assert folder is not None
            folder.mkdir(parents=True)
        with atomic_paths([target for target, _ in jobs]) as temps:
            for (target, write), temp in zip(jobs, temps):
                try:
                    write(temp)
                except OSError as exc:  # named by the output, not by its temporary file
                    raise OutputError(f"cannot write {target}: {exc.strerror or exc}; "
                                      "no output written") from None
    except (OSError, KeyboardInterrupt) as exc:
        if made and folder is not None:
            with contextlib.suppress(OSError):
                folder.rmdir()  # only when empty: the run wrote nothing into it
        if isinstance(exc, OSError) and not isinstance(exc, OutputError):
            raise OutputError(f"cannot write {exc.filename or folder}: "
                              f"{exc.strerror or exc}; no output written") from None
        raise
    return [target for target, _ in jobs]


@contextlib.contextmanager
def atomic_open(path: str | os.PathLike[str], mode: str = "w", **kwargs: Any) -> Iterator[IO[Any]]:
    """``open(path, mode)`` for writing, through :func:`atomic_path`: the target appears, whole,
    only when the block completes."""
    if not mode.startswith("w"):
        raise ValueError(f"atomic_open writes new files: mode must start with 'w', not {mode!r}")
    with atomic_path(path) as temp, temp.open(mode, **kwargs) as handle:
        yield handle


class AtomicFile:
    """A file written over a long session under a temporary name beside ``path``, renamed into
    place by :meth:`commit` (a complete file, or the honest part of one: every line written so
    far) and removed by :meth:`discard`. A process killed outright (SIGKILL) leaves only the
    hidden ``.NAME.*.part*`` file, never a half-written one under the target's name."""

    def __init__(self, path: str | os.PathLike[str], mode: str = "w", **kwargs: Any) -> None:
        if not mode.startswith("w"):
            raise ValueError(f"AtomicFile writes new files: mode must start with 'w', not {mode!r}")
        self.path = Path(os.fspath(path))
        self._context = atomic_path(path)
        temp = self._context.__enter__()
        try:
            self.file: IO[Any] = temp.open(mode, **kwargs)
        except BaseException:
            self._context.__exit__(None, None, None)
            raise
        self._done = False

    def commit(self) -> None:
        """Close and rename into place (a write error, such as a full disk, is raised)."""
        if self._done:
            return
        self._done = True
        try:
            self.file.close()
        except BaseException as exc:
            self._context.__exit__(type(exc), exc, exc.__traceback__)
            raise
        self._context.__exit__(None, None, None)

    def discard(self) -> None:
        """Close and remove; the target is left as it was."""
        if self._done:
            return
        self._done = True
        with contextlib.suppress(OSError):
            self.file.close()
        error = RuntimeError("discarded")
        with contextlib.suppress(RuntimeError):
            self._context.__exit__(RuntimeError, error, None)
