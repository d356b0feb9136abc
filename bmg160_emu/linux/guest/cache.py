"""Where the guest's downloads and builds live: outside the repository, made once.

``$BMG160_EMU_CACHE`` or ``~/.cache/bmg160-emu``: the unpacked kernel package, the
initramfs, the kernel build trees and out-of-tree modules (hundreds of MB; never in a
checkout or a wheel).
"""

from __future__ import annotations

import hashlib
import os
from collections.abc import Iterable
from pathlib import Path


def cache_dir() -> Path:
    """The cache folder (not created here)."""
    return Path(os.environ.get("BMG160_EMU_CACHE", Path.home() / ".cache" / "bmg160-emu"))


def content_hash(paths: Iterable[Path], *extra: str, length: int = 12) -> str:
    """A short SHA-256 over file names and contents (and ``extra`` words): a build's key, so
    that any change to its inputs gives a new folder and nothing stale is reused."""
    digest = hashlib.sha256()
    for word in extra:
        digest.update(word.encode() + b"\0")
    for path in sorted(paths):
        digest.update(path.name.encode() + b"\0")
        digest.update(path.read_bytes())
        digest.update(b"\0")
    return digest.hexdigest()[:length]
