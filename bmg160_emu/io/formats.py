"""The one registry of file formats, and the base classes of their readers and writers.

Every kind of file the tools read or write (``rates`` that identify reads, a ``recording``
that record writes, the ``replay`` data that replay plays, the ``rate stream`` generate
writes, a scenario's ``rate table``, a ``trace``) registers, per suffix, its reader and its
writer here; callers find them by kind and file name (:func:`format_for`, :func:`read_file`,
:func:`write_file`), and a suffix no format of that kind has is one error naming the ones
there are. python-can's ``LogReader()`` and ``Logger()`` are the model: one suffix registry
serves every caller, over common base classes.

- :class:`FileReader`: a path checked once (a directory, a missing file), then ``read``.
- :class:`FileWriter`: a whole file written complete or not at all (under a temporary name,
  io.atomic), then renamed into place.
- :class:`BlockWriter`: a record streamed block by block into an open file, made an honest
  shorter record (``end_short``) when it is cut short.

Each format module registers its own at import; this module imports them when a kind is
first looked up, so that asking for a format never depends on what was imported before.
"""

from __future__ import annotations

import importlib
from abc import ABC, abstractmethod
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import IO, Any, ClassVar

from bmg160_emu.io.errors import FormatError

# kind -> the module that registers its formats (imported on the first lookup of the kind)
KIND_MODULES = {
    "rates": "bmg160_emu.io.rates",
    "rate table": "bmg160_emu.io.rates",
    "rate stream": "bmg160_emu.io.rate_stream",
    "recording": "bmg160_emu.io.recording",
    "replay": "bmg160_emu.io.replay_data",
    "trace": "bmg160_emu.io.trace",
}


def check_file(path: str | Path, noun: str = "file", error: type[FormatError] = FormatError
               ) -> None:
    """``error`` naming ``path`` when it is a directory or no file at all."""
    path = Path(path)
    if path.is_dir():
        raise error(f"{path}: is a directory, not a {noun}")
    if not path.is_file():
        raise error(f"no such {noun}: {path}")


class FileReader(ABC):
    """The reader of one format of one kind: ``Reader(path).read(**options)`` gives the
    kind's record. ``noun`` names the file in messages; ``error`` is the kind's FormatError."""

    noun: ClassVar[str] = "file"
    error: ClassVar[type[FormatError]] = FormatError

    def __init__(self, path: str | Path) -> None:
        self.path = Path(path)

    def check_path(self) -> None:
        """A directory or a missing file is the kind's error, naming it, before any read."""
        check_file(self.path, self.noun, self.error)

    @abstractmethod
    def read(self, *args: Any, **options: Any) -> Any:
        """The file's record (the kind says what it is); the kind's error on bad content."""


class FileWriter(ABC):
    """The writer of one format of one kind: ``Writer(path).write(record, **options)``
    writes the whole file under a temporary name and renames it into place, so the target
    is complete or untouched (io.atomic), whatever stops the writing."""

    def __init__(self, path: str | Path) -> None:
        self.path = Path(path)

    def write(self, *args: Any, **options: Any) -> None:
        from bmg160_emu.io.atomic import atomic_path

        with atomic_path(self.path) as partial:
            self.write_to(partial, *args, **options)

    @abstractmethod
    def write_to(self, *args: Any, **options: Any) -> None:
        """Write ``write``'s record to ``path``, its first argument (the temporary file
        ``write`` renames)."""


class BlockWriter(ABC):
    """A record of ``total`` samples at ``rate_hz`` streamed into an open binary ``handle``
    block by block (a day of samples is never in memory at once): ``write(start, block)``
    for samples start .. start + len(block) - 1, ``samples`` the complete ones written.
    After an interruption ``end_short(note)`` leaves an honest shorter record; the note is
    in the file when ``notes_inside``, else the caller puts it beside the file
    (io.partial's sidecar)."""

    notes_inside: ClassVar[bool] = True

    def __init__(self, handle: IO[bytes], total: int, rate_hz: float,
                 comments: Sequence[str] = ()) -> None:
        self.handle, self.total, self.rate_hz = handle, total, rate_hz
        self.comments = list(comments)
        self.samples = 0

    @abstractmethod
    def write(self, *args: Any, **options: Any) -> None:
        """Samples ``start`` .. ``start + len(block) - 1``: ``write(start, block)``."""

    @abstractmethod
    def end_short(self, note: str) -> None: ...

    @staticmethod
    @abstractmethod
    def size_bytes(total: int) -> int:
        """What ``total`` samples take: exact, or a low estimate (a free-space check must
        never refuse what would fit)."""


@dataclass(frozen=True)
class FileFormat:
    """One kind of file under one suffix: its reader and writer (None: not read, or not
    written, in this format), a FileReader/FileWriter/BlockWriter class or a function."""

    kind: str
    suffix: str
    reader: Callable[..., Any] | None
    writer: Callable[..., Any] | None
    description: str = ""

    def read(self, path: str | Path, *args: Any, **options: Any) -> Any:
        """The record of ``path`` (its format's reader, a class or a function)."""
        reader: Any = self.reader
        if reader is None:
            raise FormatError(f"{self.kind} files are not read as {self.suffix}", path=path)
        if isinstance(reader, type) and issubclass(reader, FileReader):
            return reader(path).read(*args, **options)
        return reader(path, *args, **options)

    def write(self, path: str | Path, *args: Any, **options: Any) -> Any:
        """Write ``path`` (a FileWriter's ``write``, or the writer function or class)."""
        writer: Any = self.writer
        if writer is None:
            raise FormatError(f"{self.kind} files are not written as {self.suffix}", path=path)
        if isinstance(writer, type) and issubclass(writer, FileWriter):
            return writer(path).write(*args, **options)
        return writer(path, *args, **options)


_REGISTRY: dict[tuple[str, str], FileFormat] = {}


def register_format(fmt: FileFormat) -> FileFormat:
    """Add a format to the registry (each format module registers its own at import)."""
    _REGISTRY[(fmt.kind, fmt.suffix.lower())] = fmt
    return fmt


def _load(kind: str) -> None:
    module = KIND_MODULES.get(kind)
    if module is not None:
        importlib.import_module(module)


def suffixes(kind: str, *, reading: bool = False, writing: bool = False) -> tuple[str, ...]:
    """The suffixes registered for ``kind`` in registration order: those read (``reading``),
    written (``writing``), or all."""
    _load(kind)
    return tuple(f.suffix for (k, _), f in _REGISTRY.items() if k == kind
                 and (not reading or f.reader is not None)
                 and (not writing or f.writer is not None))


def suffix_text(known: Sequence[str]) -> str:
    """``.a, .b or .c``: the suffixes as a message lists them."""
    if not known:
        return "?"
    return ", ".join(known[:-1]) + (" or " if len(known) > 1 else "") + known[-1]


def format_for(kind: str, path: str | Path, error: type[FormatError] = FormatError, *,
               reading: bool = False, writing: bool = False, what: str | None = None
               ) -> FileFormat:
    """The format of ``kind`` registered for ``path``'s suffix (one that is read with
    ``reading``, written with ``writing``), or ``error``: "WHAT must end in .a, .b or .c,
    not 'NAME'" (``what`` defaults to "KIND file")."""
    path = Path(path)
    _load(kind)
    fmt = _REGISTRY.get((kind, path.suffix.lower()))
    if fmt is None or (reading and fmt.reader is None) or (writing and fmt.writer is None):
        known = suffixes(kind, reading=reading, writing=writing)
        raise error(f"{what or kind + ' file'} must end in {suffix_text(known)}, "
                    f"not {path.name!r}")
    return fmt


def block_writer_for(kind: str, path: str | Path, error: type[FormatError] = FormatError, *,
                     what: str | None = None) -> type[BlockWriter]:
    """The BlockWriter class of ``kind`` for ``path``'s suffix (``format_for``'s error)."""
    writer = format_for(kind, path, error, writing=True, what=what).writer
    if not (isinstance(writer, type) and issubclass(writer, BlockWriter)):
        raise error(f"{kind} files are not streamed block by block", path=path)
    return writer


def read_file(kind: str, path: str | Path, *args: Any, **options: Any) -> Any:
    """Read ``path`` as a file of ``kind`` with the reader its suffix has."""
    return format_for(kind, path, reading=True).read(path, *args, **options)


def write_file(kind: str, path: str | Path, *args: Any, **options: Any) -> Any:
    """Write ``path`` as a file of ``kind`` with the writer its suffix has."""
    return format_for(kind, path, writing=True).write(path, *args, **options)
