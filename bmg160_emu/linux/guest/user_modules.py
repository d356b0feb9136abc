"""A user's kernel module as ``--module`` gives it, for either engine's build: the files a
build of it is cached by, and the ``.ko`` files a build left, kept in the cache.

Why apart from the engines: the Debian kernel's build (:mod:`.debian_modules`, headers) and
the UML kernel's (:mod:`.uml_build`, its tree with ARCH=um) differ in how they make, not in
what a module folder is or what is kept from it.
"""

from __future__ import annotations

import shutil
from pathlib import Path

from bmg160_emu.linux.guest.engine import EngineError

BUILD_PRODUCTS = {".ko", ".o", ".cmd", ".mod", ".order", ".symvers"}  # what kbuild leaves


def module_sources(path: Path) -> list[Path]:
    """A user's module as given (``--module``): [the file] for a ``.ko``, else the source files
    of its folder (which must hold a Kbuild or Makefile), build products left out: what a
    build is cached by. EngineError for anything else, in one line naming the path."""
    if path.is_file():
        if path.suffix != ".ko":
            raise EngineError(f"{path}: a module is a .ko file or a folder with a Kbuild file")
        return [path.resolve()]
    if not (path / "Kbuild").is_file() and not (path / "Makefile").is_file():
        raise EngineError(f"{path}: no Kbuild (or Makefile) file: not a module source folder")
    return sorted(p for p in path.rglob("*") if p.is_file() and p.suffix not in BUILD_PRODUCTS)


def keep_modules(build: Path, out: Path, path: Path) -> list[Path]:
    """The ``.ko`` files a build of ``path`` made in ``build``, copied into the cache folder
    ``out`` (what later calls find); EngineError when it made none."""
    made = sorted(build.rglob("*.ko"))
    if not made:
        raise EngineError(f"building {path} made no .ko file (is obj-m set in Kbuild?)")
    out.mkdir(parents=True, exist_ok=True)
    for ko in made:
        shutil.copy2(ko, out / ko.name)
    return sorted(out.glob("*.ko"))
