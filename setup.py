"""Packaging hook; all metadata is in pyproject.toml.

The firmware sources live in the top-level ``firmware/`` folder (a C project with its own
Makefile, not a Python package). A wheel carries a copy of them as
``bmg160_emu/firmware/sources/`` so that ``bmg160-emu firmware build`` and ``capture`` work
after ``pip install .``; an editable install uses the checkout's folder instead.
"""

from __future__ import annotations

import shutil
from pathlib import Path

from setuptools import setup
from setuptools.command.build_py import build_py

FIRMWARE = Path(__file__).resolve().parent / "firmware"
# Build products that a developer's `make` may have left in the folder.
NOT_SHIPPED = shutil.ignore_patterns("build", "*.o", "*.elf", "*.hex", "__pycache__")


class BuildPyWithFirmware(build_py):
    """build_py that also copies firmware/ into the package being built."""

    def run(self) -> None:
        super().run()
        if getattr(self, "editable_mode", False):
            return  # the checkout's firmware/ folder is found directly
        if not (FIRMWARE / "Makefile").is_file():
            raise SystemExit(f"firmware sources missing: {FIRMWARE / 'Makefile'} not found")
        target = Path(self.build_lib) / "bmg160_emu" / "firmware" / "sources"
        shutil.copytree(FIRMWARE, target, ignore=NOT_SHIPPED, dirs_exist_ok=True)


setup(cmdclass={"build_py": BuildPyWithFirmware})
