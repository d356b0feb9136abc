"""Whether an output file says it is partial: the one check, for every format the commands
write, that readers and the signal fuzz suite share (docs/outputs.md).

Why: an output cut short by a signal is kept when what it holds is true (the samples
recorded so far, the runs finished), but it must say so in the file itself, or it is read
as the complete result. Each format carries the mark where its own readers still read it:

- trace (``.jsonl``): the end line is written only when the session ended by itself;
- rate or recording CSV: a last comment line ``# partial: ...`` (``generate`` writes
  ``# interrupted after ...``), and a recording's settings line says ``"interrupted"``;
- ``.npy``: the header's shape is the samples written, and a trailer after the array,
  ``\\n# partial: ...\\n``, which ``numpy.load`` does not read;
- NPZ recording: its ``metadata`` says ``"interrupted"``;
- Monte Carlo JSON: ``"interrupted": true``; Monte Carlo CSV: a last line ``# partial: ...``;
- RESD (``.resd``): the block's sample count is the samples written, and a sidecar file
  ``NAME.resd.incomplete`` says why (Renode reads the RESD file alone: no field of the
  format can carry the mark without changing what Renode reads).
"""

from __future__ import annotations

import contextlib
import json
import os
import zipfile
import zlib
from pathlib import Path

__all__ = ["NPY_TRAILER", "clear_sidecar", "npy_trailer", "partial_note", "sidecar_path",
           "write_sidecar"]

NPY_TRAILER = b"\n# partial: "  # after the last sample of a cut .npy
_TAIL_BYTES = 4096  # a last comment line is far shorter


def npy_trailer(note: str) -> bytes:
    """The bytes appended after the array of a cut ``.npy``."""
    return NPY_TRAILER + note.encode("utf-8", "replace") + b"\n"


def sidecar_path(path: str | os.PathLike[str]) -> Path:
    """``NAME.resd.incomplete`` beside ``NAME.resd``."""
    path = Path(path)
    return path.with_name(path.name + ".incomplete")


def write_sidecar(path: str | os.PathLike[str], note: str) -> None:
    """Say beside ``path`` that it is partial (before the file itself is renamed into place:
    a file never appears cut without its mark)."""
    from bmg160_emu.io.atomic import atomic_open

    with atomic_open(sidecar_path(path), "w", encoding="utf-8") as handle:
        handle.write(f"partial: {note}\n")


def clear_sidecar(path: str | os.PathLike[str]) -> None:
    """Remove the mark of an earlier cut run, once a complete file replaces it."""
    with contextlib.suppress(FileNotFoundError):
        sidecar_path(path).unlink()


def partial_note(path: str | os.PathLike[str]) -> str | None:
    """Why the output at ``path`` is partial, or None when it carries no mark (complete, or a
    format without one). Reads only what the mark needs; a file that cannot be read as its
    format is left to that format's reader to refuse (None here)."""
    path = Path(path)
    suffix = path.suffix.lower()
    try:
        if suffix == ".jsonl":
            from bmg160_emu.io.trace import read_trace

            header, _ = read_trace(path)
            return header.get("_partial")
        if suffix == ".npy":
            return _npy_note(path)
        if suffix == ".npz":
            return _npz_note(path)
        if suffix == ".json":
            document = json.loads(path.read_text(encoding="utf-8"))
            if isinstance(document, dict) and document.get("interrupted") is True:
                return (f"interrupted: {len(document.get('seeds') or [])} of "
                        f"{document.get('runs_planned')} runs")
            return None
        if suffix == ".resd":
            side = sidecar_path(path)
            return side.read_text(encoding="utf-8").strip() if side.is_file() else None
        if suffix == ".csv":
            return _csv_note(path)
    except (OSError, ValueError, UnicodeDecodeError, EOFError, zipfile.BadZipFile, zlib.error):
        return None  # a damaged file (a bad CRC in an NPZ member): its reader's to refuse
    except Exception as exc:  # a format reader's own error (FormatError): not ours to judge
        from bmg160_emu.io.errors import FormatError

        if isinstance(exc, FormatError):
            return None
        raise
    return None


def _csv_note(path: Path) -> str | None:
    with path.open("rb") as handle:
        head = [handle.readline() for _ in range(2)]
        handle.seek(0, os.SEEK_END)
        size = handle.tell()
        handle.seek(max(0, size - _TAIL_BYTES))
        tail = handle.read().decode("utf-8", "replace")
    lines = [line.strip() for line in tail.splitlines() if line.strip()]
    last = lines[-1] if lines else ""
    for prefix in ("# partial:", "# interrupted after"):
        if last.startswith(prefix):
            return last[2:]
    settings = head[1].decode("utf-8", "replace").strip() if len(head) > 1 else ""
    if settings.startswith("#"):  # a recording CSV: its settings line, JSON after '#'
        with contextlib.suppress(ValueError):
            meta = json.loads(settings[1:])
            if isinstance(meta, dict) and meta.get("interrupted"):
                return f"interrupted: {meta.get('samples_planned', '?')} samples were planned"
    return None


def _npy_note(path: Path) -> str | None:
    import numpy as np

    with path.open("rb") as handle:
        version = np.lib.format.read_magic(handle)
        if version == (1, 0):
            shape, _, dtype = np.lib.format.read_array_header_1_0(handle)
        else:
            shape, _, dtype = np.lib.format.read_array_header_2_0(handle)
        size = 1
        for n in shape:
            size *= int(n)
        handle.seek(handle.tell() + size * dtype.itemsize)
        tail = handle.read(_TAIL_BYTES)
    if tail.startswith(NPY_TRAILER):
        return tail[2:].decode("utf-8", "replace").strip()
    return None


def _npz_note(path: Path) -> str | None:
    from bmg160_emu.io.array_files import open_npz  # closes the file of a bad archive

    with open_npz(path) as archive:
        if "metadata" not in archive.files:
            return None
        meta = json.loads(str(archive["metadata"]))
    if isinstance(meta, dict) and meta.get("interrupted"):
        return f"interrupted: {meta.get('samples_planned', '?')} samples were planned"
    return None
