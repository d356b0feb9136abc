"""Imports only go down the layers (docs/architecture.md); an ast check, no import needed.

Layer order, highest first; a module may import its own layer and any lower one:

    commands (cli, pytest_plugin) > adcs > tools (script, record, playback, replay, decode,
    faults, firmware, watch) > io > bus > device > base (clock, durations, noise)

adcs sits above the other tools: it builds rigs from them, and no tool imports adcs (the
fault engine moved from adcs to ``bmg160_emu.faults`` for that). Every import statement
counts, also the lazy ones inside functions and those under ``TYPE_CHECKING``. Exempt: the
deprecated one-release re-export modules (they point at a new place by design) and the
package's top-level ``__init__`` (lazy public names). A module in no layer fails the test,
so a new top-level module has to be placed.
"""

from __future__ import annotations

import ast
from pathlib import Path

PACKAGE = "bmg160_emu"
ROOT = Path(__file__).resolve().parents[1] / PACKAGE

LAYERS = {  # first name under bmg160_emu -> layer (higher imports lower)
    "commands": 7, "cli": 7, "pytest_plugin": 7, "__main__": 7,
    "adcs": 6,
    "script": 5, "record": 5, "playback": 5, "replay": 5, "decode": 5, "faults": 5,
    "firmware": 5, "watch": 5,  # watch: the live view's session side and viewer
    "io": 4,
    "bus": 3,
    "device": 2,
    "clock": 1, "durations": 1, "noise": 1,
}

# Re-export modules kept for one release (old import paths); they import their new home.
SHIMS = {
    "bmg160_emu", "bmg160_emu.chip", "bmg160_emu.smbus", "bmg160_emu.i2c_bus", "bmg160_emu.spi",
    "bmg160_emu.patching", "bmg160_emu.transactions", "bmg160_emu.linux",
    "bmg160_emu.linux.i2c_dev_structs", "bmg160_emu.linux.i2c_stub_adapter",
    "bmg160_emu.linux.umockdev_node",
    "bmg160_emu.noise.rate_record",  # the rate-file reader moved to io.rates
}


def module_name(path: Path, root: Path, package: str) -> str:
    parts = path.relative_to(root).with_suffix("").parts
    name = ".".join((package, *parts))
    return name.removesuffix(".__init__")


def layer_of(module: str, package: str, layers: dict[str, int]) -> int | None:
    """The layer of a module of ``package`` (None for other packages' modules)."""
    parts = module.split(".")
    if parts[0] != package or len(parts) == 1:
        return None
    return layers.get(parts[1], -1)


def upward_imports(root: Path, package: str = PACKAGE, layers: dict[str, int] = LAYERS,
                   exempt: set[str] = SHIMS) -> list[str]:
    """Every import in ``root`` of a higher layer, and every module in no layer."""
    problems = []
    for path in sorted(root.rglob("*.py")):
        me = module_name(path, root, package)
        if me in exempt:
            continue
        mine = layer_of(me, package, layers)
        if mine == -1:
            problems.append(f"{me}: in no layer (add it to LAYERS)")
            continue
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"), str(path))):
            if isinstance(node, ast.Import):
                targets = [alias.name for alias in node.names]
            elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
                targets = [node.module]
                if node.module == package:  # from bmg160_emu import io
                    targets = [f"{package}.{alias.name}" for alias in node.names]
            else:
                continue
            for target in targets:
                theirs = layer_of(target, package, layers)
                if mine is not None and theirs is not None and theirs > mine:
                    problems.append(f"{path.relative_to(root.parent)}:{node.lineno}: {me} "
                                    f"(layer {mine}) imports {target} (layer {theirs})")
    return problems


def test_no_module_imports_a_higher_layer():
    assert upward_imports(ROOT) == []


def test_the_check_finds_an_upward_import_and_an_unplaced_module(tmp_path):
    root = tmp_path / PACKAGE
    (root / "device").mkdir(parents=True)
    (root / "commands").mkdir()
    (root / "device" / "__init__.py").write_text("")
    (root / "device" / "good.py").write_text("from bmg160_emu.clock import VirtualClock\n")
    (root / "device" / "bad.py").write_text(
        "def f():\n    from bmg160_emu.commands.run import run\n    import bmg160_emu.io.trace\n"
    )
    (root / "commands" / "run.py").write_text("from bmg160_emu import device, io\n")
    (root / "newthing.py").write_text("")
    problems = upward_imports(root)
    bad = f"{PACKAGE}/device/bad.py"
    assert problems == [
        f"{bad}:2: bmg160_emu.device.bad (layer 2) imports bmg160_emu.commands.run (layer 7)",
        f"{bad}:3: bmg160_emu.device.bad (layer 2) imports bmg160_emu.io.trace (layer 4)",
        "bmg160_emu.newthing: in no layer (add it to LAYERS)",
    ]


def test_every_layer_name_exists():
    # a renamed package must not leave a layer entry that matches nothing
    for name in LAYERS:
        assert (ROOT / name).is_dir() or (ROOT / f"{name}.py").is_file(), name
