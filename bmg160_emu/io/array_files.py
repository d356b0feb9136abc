"""NPY and NPZ files read safely: a damaged array, a damaged archive member, or a header
that declares more data than the file holds is the caller's FormatError naming the file and
the key, never numpy's exception or a huge allocation.

Why the declared size is checked: numpy allocates the array a header declares before it
reads the data, so a 4 kB file whose header claims 1e11 x 3 float64 rows asked for 2.2 TiB
(issue 24). Reading the header alone and comparing its size with the file's (or the NPZ
member's) costs nothing. NPZ arrays are read one key at a time.
"""

from __future__ import annotations

import math
import os
import tokenize
import typing
import zipfile
import zlib
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from bmg160_emu.io.errors import FormatError
from bmg160_emu.io.rate_table import RateFileError

# what numpy and zipfile raise on a damaged file: np.load's header parser (tokenize), a zip
# member with an unknown compression method, a cut or corrupt archive
ARRAY_ERRORS = (OSError, ValueError, KeyError, EOFError, zipfile.BadZipFile, zlib.error,
                tokenize.TokenError, SyntaxError, NotImplementedError)
# what numpy's header parser raises on a damaged header
HEADER_ERRORS = (OSError, ValueError, EOFError, SyntaxError, NotImplementedError)


def check_declared_size(handle: typing.BinaryIO, available: int, path: str | Path,
                        error: type[FormatError], place: str | None = None) -> None:
    """Refuse (``error``, naming ``path`` and ``place``) an .npy header at ``handle`` whose
    shape needs more bytes than the ``available`` ones of the file or member."""
    try:
        version = np.lib.format.read_magic(handle)
        read = (np.lib.format.read_array_header_1_0 if version == (1, 0)
                else np.lib.format.read_array_header_2_0)
        shape, _fortran, dtype = read(handle)
        header = handle.tell()
    except HEADER_ERRORS as exc:
        raise error(f"not a readable .npy array ({exc})", path=path, place=place) from None
    need = math.prod(int(n) for n in shape) * dtype.itemsize
    if need > available - header:
        raise error(f"its header declares shape {tuple(shape)} ({need:,} bytes) but the file "
                    f"holds {max(0, available - header):,} bytes of data", path=path, place=place)


def open_npz(path: str | Path):
    """The archive of an NPZ file (arrays read lazily, one key at a time). The file is
    opened here and handed to the archive, which closes it; when the archive cannot be
    read, it is closed here (``np.load`` of a truncated zip left its file open, a
    ResourceWarning, issue 35)."""
    from numpy.lib.npyio import NpzFile

    handle = open(path, "rb")  # noqa: SIM115 - owned by the archive from here on
    try:
        if handle.read(6).startswith(b"\x93NUMPY"):
            raise RateFileError("not an NPZ archive (a .npy array)", path=path)
        handle.seek(0)
        return NpzFile(handle, own_fid=True, allow_pickle=False)
    except BaseException as exc:
        handle.close()
        if isinstance(exc, ARRAY_ERRORS) and not isinstance(exc, RateFileError):
            raise RateFileError(f"not a readable NPZ archive ({exc})", path=path) from None
        raise


def npz_array(archive, key: str, path: str | Path) -> np.ndarray:
    """One array of the archive; a damaged member, or one whose header declares more data
    than the member holds, is an error naming the key."""
    try:
        name = key if key in archive.zip.namelist() else f"{key}.npy"
        with archive.zip.open(name) as member:
            check_declared_size(member, archive.zip.getinfo(name).file_size, path,
                                RateFileError, f"key {key}")
    except RateFileError:
        raise
    except (AttributeError, *ARRAY_ERRORS):
        pass  # a damaged member: numpy's own error below names it
    try:
        return archive[key]
    except ARRAY_ERRORS as exc:
        raise RateFileError(f"unreadable array ({exc})", path=path, place=f"key {key}") from None


def npz_columns(archive, keys: Sequence[str], path: str | Path) -> np.ndarray:
    """Stack 1-D arrays ``keys`` into one (n, k) float64 array, one key in memory at a time."""
    out: np.ndarray | None = None
    for j, key in enumerate(keys):
        column = numeric(npz_array(archive, key, path), path, f"key {key}").reshape(-1)
        if out is None:
            out = np.empty((len(column), len(keys)))
        elif len(column) != len(out):
            raise RateFileError(f"{len(column)} values, {keys[0]!r} has {len(out)}",
                                path=path, place=f"key {key}")
        out[:, j] = column
    assert out is not None
    return out


def numeric(data: np.ndarray, path: str | Path, place: str | None = None) -> np.ndarray:
    """``data`` as float64 (no copy when it already is); refuse anything but numbers."""
    if data.dtype.kind not in "fiu":
        raise RateFileError(f"the record must hold numbers, not {data.dtype}", path=path,
                            place=place)
    return np.asarray(data, dtype=float)


def first_non_finite(data: np.ndarray, chunk: int = 1 << 20) -> int | None:
    """The first row holding NaN or an infinity, or None; in chunks, so checking a 24 h
    record costs a few MB, not a copy."""
    if data.size == 0:
        return None
    rows = data.reshape(data.shape[0], -1)
    for start in range(0, rows.shape[0], chunk):
        ok = np.isfinite(rows[start : start + chunk]).all(axis=1)
        if not ok.all():
            return start + int(np.argmin(ok))
    return None


def read_npy(path: str | Path) -> np.ndarray:
    try:
        with open(path, "rb") as handle:
            if handle.read(6) == b"\x93NUMPY":
                handle.seek(0)
                check_declared_size(handle, os.fstat(handle.fileno()).st_size, path, RateFileError)
        data = np.load(path, allow_pickle=False)
    except RateFileError:
        raise
    except ARRAY_ERRORS as exc:
        raise RateFileError(f"not a readable .npy array ({exc})", path=path) from None
    if not isinstance(data, np.ndarray):
        data.close()
        raise RateFileError("not a .npy array (an NPZ archive: name it .npz)", path=path)
    return numeric(data, path)


def write_npz(path: str | Path, arrays: dict[str, np.ndarray]) -> None:
    """Write the named arrays, compressed."""
    np.savez_compressed(path, **arrays)  # type: ignore[arg-type]
