"""The one error type of every file format, and the safe parsing every text format reads with
(the registry of readers and writers is io/formats.py).

Every format's error derives from :class:`FormatError`, a ``ValueError`` (so code that
catches ``ValueError`` keeps working), and its message starts with the file and the place
in it: ``path:LINE:`` for text, ``path: key NAME:`` or ``path: row N:`` for arrays. The
commands print it as it is, one line, never a traceback.
"""

from __future__ import annotations

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


# --------------------------------------------------------------------------- safe parsing
# Every text format reads its file through these, so that what the parsers of the standard
# library raise on hostile input (UnicodeDecodeError, RecursionError on deep nesting,
# ValueError on 4300-digit integers, json's acceptance of NaN and Infinity) becomes the
# format's own one-line error naming the file and the place.


def read_text(path: str | Path, error: type[FormatError] = FormatError) -> str:
    """The file as UTF-8 text; bytes that are not UTF-8 are ``error`` at their line and
    column. OSError (a missing or unreadable file) passes through for the caller to word."""
    data = Path(path).read_bytes()
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError as exc:
        line = data.count(b"\n", 0, exc.start) + 1
        column = exc.start - (data.rfind(b"\n", 0, exc.start) + 1) + 1
        raise error(f"{path}:{line}:{column}: not UTF-8 text (byte 0x{data[exc.start]:02X})") \
            from None


def _no_constant(name: str) -> Any:
    raise ValueError(f"{name} is not a number JSON allows")


def loads_json(text: str, error: type[FormatError], where: str, *, lines: bool = False) -> Any:
    """``json.loads`` with NaN and Infinity refused, and nesting or integer-size limits as
    ``error`` at ``where`` (``path:LINE`` for one line of a file; ``lines=True``: ``where`` is
    the file and the message gives line and column)."""
    import json

    try:
        return json.loads(text, parse_constant=_no_constant)
    except json.JSONDecodeError as exc:
        place = f"{exc.lineno}:{exc.colno}" if lines else f"{exc.colno}"
        raise error(f"{where}:{place}: invalid JSON: {exc.msg}") from None
    except RecursionError:
        raise error(f"{where}: JSON nested too deeply") from None
    except ValueError as exc:  # int_max_str_digits, or a NaN/Infinity constant
        raise error(f"{where}: {_short(exc)}") from None


def loads_toml(text: str, error: type[FormatError], where: str) -> dict[str, Any]:
    """``tomllib.loads`` with every failure (also nesting and integer size) as ``error``."""
    try:
        import tomllib
    except ModuleNotFoundError:  # Python 3.10
        import tomli as tomllib  # type: ignore[no-redef]
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise error(f"{where}: not valid TOML: {exc}") from None
    except RecursionError:
        raise error(f"{where}: TOML nested too deeply") from None
    except ValueError as exc:
        raise error(f"{where}: {_short(exc)}") from None


def _short(exc: BaseException) -> str:
    text = str(exc)
    if "Exceeds the limit" in text:
        return "an integer with more than 4300 digits"
    return text.splitlines()[0] if text else type(exc).__name__
