"""What an .npy header declares, checked against the bytes that follow it.

Why: numpy allocates the array a header declares before it reads the data, so a 4 kB file
whose header claims 1e11 x 3 float64 rows asked for 2.2 TiB (issue 24). Reading the header
alone and comparing its size with the file's (or the NPZ member's) costs nothing.
"""

from __future__ import annotations

import math
import typing
from pathlib import Path

import numpy as np

from bmg160_emu.io.errors import FormatError

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
