"""The one error type of every file format, and the suffix registry of readers and writers.

Every format's error derives from :class:`FormatError`, a ``ValueError`` (so code that
catches ``ValueError`` keeps working), and its message starts with the file and the place
in it: ``path:LINE:`` for text, ``path: key NAME:`` or ``path: row N:`` for arrays. The
commands print it as it is, one line, never a traceback.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any


class FormatError(ValueError):
    """A file that is not what its format says; the message names the file and the place."""

    def __init__(self, message: str, *, path: str | Path | None = None,
                 place: int | str | None = None) -> None:
        self.path = None if path is None else str(path)
        self.place = place
        self.detail = message
        if self.path is not None:
            if isinstance(place, int):
                message = f"{self.path}:{place}: {message}"
            elif place:
                message = f"{self.path}: {place}: {message}"
            else:
                message = f"{self.path}: {message}"
        super().__init__(message)


@dataclass(frozen=True)
class FileFormat:
    """One kind of file (``rates``, ``trace``, ...) under one suffix: its reader and writer."""

    kind: str
    suffix: str
    read: Callable[..., Any]
    write: Callable[..., Any] | None
    description: str = ""


_REGISTRY: dict[tuple[str, str], FileFormat] = {}


def register_format(fmt: FileFormat) -> FileFormat:
    """Add a format to the registry (each format module registers its own at import)."""
    _REGISTRY[(fmt.kind, fmt.suffix.lower())] = fmt
    return fmt


def suffixes(kind: str) -> tuple[str, ...]:
    """The suffixes registered for ``kind``, in registration order."""
    return tuple(s for k, s in _REGISTRY if k == kind)


def format_for(kind: str, path: str | Path, error: type[FormatError] = FormatError) -> FileFormat:
    """The format registered for ``path``'s suffix, or ``error`` naming the suffixes known."""
    path = Path(path)
    fmt = _REGISTRY.get((kind, path.suffix.lower()))
    if fmt is None:
        known = suffixes(kind)
        listed = ", ".join(known[:-1]) + (" or " if len(known) > 1 else "") + known[-1] if known else "?"
        raise error(f"{kind} file must end in {listed}, not {path.name!r}")
    return fmt
