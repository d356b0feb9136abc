"""A session's transaction trace: opened with the header of the session's devices, closed
complete when the session ended by itself and marked partial when it was cut short.

``run``, ``script`` and ``vhost-user-i2c`` record their sessions with ``--trace``; what the
file holds and how a reader tells a cut session is docs/outputs.md and
docs/trace-format.md.
"""

from __future__ import annotations

import sys
from collections.abc import Iterable
from pathlib import Path
from typing import Any

from bmg160_emu.io.trace import TraceHeader, TraceWriter


def session_header(seed: int | None, configs: Iterable[Any]) -> TraceHeader:
    """The trace header of a session of master seed ``seed`` on the devices ``configs``
    (ChipConfig, StandinConfig): every option they set is carried to replay."""
    header = TraceHeader(seed)
    for config in configs:
        header.add_config(config)
    return header


def open_session_trace(path: str | Path, seed: int | None, configs: Iterable[Any]) -> TraceWriter:
    """The trace of a session, its header written (OSError: the path cannot be written)."""
    return TraceWriter(path, session_header(seed, configs))


def close_session_trace(writer: TraceWriter, path: str | Path) -> None:
    """Close a session's trace from where the session ends (a ``finally`` block): complete
    (its end line) when it ended by itself, marked partial (no end line) when an exception
    (a signal, an error) is on its way out. On a signal the exception carries what the file
    keeps (``kept``: the command line prints it). A write error (a full disk) is an OSError,
    and no temporary file is left."""
    stopping = sys.exc_info()[1]
    writer.close(complete=stopping is None)
    if isinstance(stopping, KeyboardInterrupt) and not getattr(stopping, "kept", None):
        stopping.kept = (  # type: ignore[attr-defined]
            f"{path} holds the {writer.count} transactions so far, marked partial (no end line)"
            if writer.count else f"no transaction recorded; {path} not written")
