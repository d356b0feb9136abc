"""What a user installs: the license, the version it reports, the files a wheel must carry."""

from __future__ import annotations

import importlib.metadata
import re
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent


def test_distribution_declares_the_mit_license_and_ships_the_text():
    meta = importlib.metadata.metadata("bmg160-emu")
    assert meta["License-Expression"] == "MIT"
    assert "LICENSE" in (meta.get_all("License-File") or [])
    assert (ROOT / "LICENSE").read_text(encoding="utf-8").startswith("MIT License")


def test_kernel_module_sources_carry_the_gpl_spdx_header():
    # The README's rule: a Linux kernel module is GPL-2.0 and says so on its first line.
    # Kernel code is recognised by the header every module includes.
    offenders = []
    for source in ROOT.rglob("*.[ch]"):
        if any(part in {".venv", "build", "site"} for part in source.relative_to(ROOT).parts):
            continue
        text = source.read_text(encoding="utf-8", errors="replace")
        if re.search(r"#include\s*<linux/module\.h>", text):
            first = text.splitlines()[0] if text else ""
            if "SPDX-License-Identifier: GPL-2.0" not in first:
                offenders.append(str(source.relative_to(ROOT)))
    assert offenders == []
