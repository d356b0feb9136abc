"""docs/architecture.md names every module of the package (one line each in its tree)."""

from __future__ import annotations

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PACKAGE = ROOT / "bmg160_emu"
# Deprecated re-export modules: named together in one sentence of the page, not in the tree.
OLD_PATHS = {"chip.py", "smbus.py", "i2c_bus.py", "spi.py", "patching.py", "transactions.py"}


def test_every_module_is_in_the_architecture_tree():
    page = (ROOT / "docs" / "architecture.md").read_text(encoding="utf-8")
    tree = page[page.index("## Modules"):page.index("## Layers")]
    words = set(re.findall(r"[A-Za-z_][A-Za-z0-9_]*", tree))
    missing = []
    for path in sorted(PACKAGE.rglob("*.py")):
        rel = path.relative_to(PACKAGE)
        if rel.parts[0] == "linux" or (len(rel.parts) == 1 and rel.name in OLD_PATHS):
            continue
        if path.name == "__init__.py" and len(rel.parts) > 1:
            name = rel.parts[-2]  # a package is named by its directory
        else:
            name = path.stem
        if name not in words:
            missing.append(rel.as_posix())
    assert missing == []


def test_no_module_is_over_600_lines_and_the_chip_under_500():
    # issue 10's layout rule: one idea per module; the chip holds only lock, catch-up,
    # primitives, hooks, reset and emission
    from pathlib import Path

    package = Path(__file__).resolve().parents[1] / "bmg160_emu"
    lengths = {p.relative_to(package).as_posix(): len(p.read_text(encoding="utf-8").splitlines())
               for p in package.rglob("*.py")}
    assert {name: n for name, n in lengths.items() if n > 600} == {}
    assert lengths["device/chip.py"] < 500
