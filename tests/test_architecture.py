"""The package's structure, checked from its source (docs/architecture.md, "Layers").

One module graph is built by parsing every module (no import is executed): every import
statement counts, at module level, inside functions and under ``TYPE_CHECKING`` alike, and
relative imports are resolved. On it the test fails on

- an import cycle between modules (type-only imports included: a circle is a circle to a
  reader of the imports, whether or not Python runs it),
- an import of a higher layer, or a module in no layer,
- a private name (``_name``) of one module used in another: imported from it, or reached
  as an attribute (``x._name``, or ``getattr(x, "_name")`` and its kin) of something that is
  not ``self``/``cls`` when the module does not define that attribute on its own objects (a
  local variable of the same name does not count),
- a module over 600 lines.

The checks run on small synthetic packages too, so that each one is seen to catch what it
is for.
"""

from __future__ import annotations

import ast
import functools
import re
from dataclasses import dataclass, field
from pathlib import Path

PACKAGE = "bmg160_emu"
ROOT = Path(__file__).resolve().parents[1] / PACKAGE
MAX_LINES = 600

LAYERS = {  # first name under bmg160_emu -> layer (a module may import its layer and lower)
    "cli": 8, "__main__": 8, "pytest_plugin": 8, "pytest_kernel": 8,
    "commands": 7,
    "adcs": 6,
    "session": 5, "faults": 5, "firmware": 5, "watch": 5,
    "linux": 4, "io": 4, "serve": 4,
    "bus": 3,
    "device": 2,
    "clock": 1, "durations": 1, "noise": 1, "traffic": 1, "progress": 1,
    "limits": 0, "startup": 0,
}

# Names with a leading underscore that are public by their owner's documentation, used
# across modules on purpose; each with the reason.
PUBLIC_UNDERSCORE = {
    "_exit": "os._exit: documented; a forked child leaves without running the parent's handlers",
    "_negative_number_matcher": "argparse has no public hook for what counts as a negative "
                                "number; CPython's argparse has kept this attribute since 2.7",
    "_objects": "ctypes: documented (_CData._objects, the objects that keep a structure's "
                "pointed-to memory alive); read only, by bus.user_memory",
    "_b_base_": "ctypes: documented (_CData._b_base_, the object whose memory a field or "
                "element shares); read only, by bus.user_memory",
    "_b_needsfree_": "ctypes: documented (_CData._b_needsfree_, true when the object "
                     "allocated its memory); read only, by bus.user_memory",
}


@dataclass
class Module:
    name: str
    path: Path
    tree: ast.Module
    imports: list[tuple[int, str]] = field(default_factory=list)  # (line, module imported)
    own_private: set[str] = field(default_factory=set)  # private names this module defines


def module_name(path: Path, root: Path, package: str) -> str:
    parts = path.relative_to(root).with_suffix("").parts
    return ".".join((package, *parts)).removesuffix(".__init__")


def _resolve(node: ast.ImportFrom, me: str, is_package: bool) -> str:
    """The absolute module an ``ImportFrom`` names (relative imports resolved)."""
    if node.level == 0:
        return node.module or ""
    base = me.split(".")
    base = base if is_package else base[:-1]
    base = base[: len(base) - (node.level - 1)]
    return ".".join(base + ([node.module] if node.module else []))


def _own_private_names(tree: ast.Module) -> set[str]:
    """Private attribute names a module defines on its own objects: attributes it sets on
    ``self``/``cls``, the names of its class bodies (methods, class attributes, dataclass
    fields) and its ``__slots__``. A local variable, a parameter or a module-level name is
    no attribute of an object of this module: ``_pointer = s.chip._pointer`` does not make
    ``_pointer`` the module's own (setting ``other._x`` does not either)."""
    names: set[str] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.ClassDef):
            for item in node.body:
                if isinstance(item, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)):
                    names.add(item.name)
                elif isinstance(item, ast.Assign):
                    names.update(t.id for t in item.targets if isinstance(t, ast.Name))
                elif isinstance(item, ast.AnnAssign) and isinstance(item.target, ast.Name):
                    names.add(item.target.id)
        elif (isinstance(node, ast.Attribute) and isinstance(node.ctx, (ast.Store, ast.Del))
              and isinstance(node.value, ast.Name) and node.value.id in ("self", "cls")):
            names.add(node.attr)
        elif (isinstance(node, (ast.Assign, ast.AnnAssign))
              and any(isinstance(t, ast.Name) and t.id == "__slots__"
                      for t in (node.targets if isinstance(node, ast.Assign) else [node.target]))
              and node.value is not None):
            names.update(c.value for c in ast.walk(node.value)
                         if isinstance(c, ast.Constant) and isinstance(c.value, str))
    return {n for n in names if n.startswith("_") and not n.startswith("__")}


def read_package(root: Path, package: str = PACKAGE) -> dict[str, Module]:
    modules: dict[str, Module] = {}
    for path in sorted(root.rglob("*.py")):
        name = module_name(path, root, package)
        tree = ast.parse(path.read_text(encoding="utf-8"), str(path))
        modules[name] = Module(name, path, tree, own_private=_own_private_names(tree))
    for module in modules.values():
        is_package = module.path.name == "__init__.py"
        for node in ast.walk(module.tree):
            if isinstance(node, ast.Import):
                for alias in node.names:
                    module.imports.append((node.lineno, alias.name))
            elif isinstance(node, ast.ImportFrom):
                base = _resolve(node, module.name, is_package)
                for alias in node.names:  # "from pkg import sub" imports the submodule
                    sub = f"{base}.{alias.name}"
                    module.imports.append((node.lineno, sub if sub in modules else base))
    return modules


def _internal(target: str, modules: dict[str, Module]) -> str | None:
    """The package's module an import lands on (``a.b.c`` of a missing ``c``: ``a.b``)."""
    while target and target not in modules:
        target = target.rpartition(".")[0]
    return target or None


def import_cycles(modules: dict[str, Module]) -> list[list[str]]:
    """Every strongly connected group of two or more modules, and modules importing
    themselves (Tarjan's algorithm, iterative)."""
    graph = {name: sorted({t for _, imp in m.imports if (t := _internal(imp, modules))})
             for name, m in modules.items()}
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    groups: list[list[str]] = []
    counter = 0
    for start, imported in graph.items():
        if start in index:
            continue
        work = [(start, iter(imported))]
        index[start] = low[start] = counter
        counter += 1
        stack.append(start)
        on_stack.add(start)
        while work:
            node, children = work[-1]
            for child in children:
                if child not in index:
                    index[child] = low[child] = counter
                    counter += 1
                    stack.append(child)
                    on_stack.add(child)
                    work.append((child, iter(graph[child])))
                    break
                if child in on_stack:
                    low[node] = min(low[node], index[child])
            else:
                work.pop()
                if work:
                    low[work[-1][0]] = min(low[work[-1][0]], low[node])
                if low[node] == index[node]:
                    group = []
                    while True:
                        member = stack.pop()
                        on_stack.discard(member)
                        group.append(member)
                        if member == node:
                            break
                    if len(group) > 1 or node in graph[node]:
                        groups.append(sorted(group))
    return sorted(groups)


def _layer(name: str, package: str, layers: dict[str, int]) -> int | None:
    parts = name.split(".")
    if parts[0] != package or len(parts) == 1:
        return None  # another package, or the top-level __init__ (lazy public names)
    return layers.get(parts[1], -1)


def upward_imports(modules: dict[str, Module], package: str = PACKAGE,
                   layers: dict[str, int] = LAYERS) -> list[str]:
    problems = []
    for name, module in modules.items():
        mine = _layer(name, package, layers)
        if mine == -1:
            problems.append(f"{name}: in no layer (add it to LAYERS)")
            continue
        for line, target in module.imports:
            theirs = _layer(target, package, layers)
            if mine is not None and theirs is not None and theirs > mine:
                problems.append(f"{module.path.name}:{line}: {name} (layer {mine}) imports "
                                f"{target} (layer {theirs})")
    return problems


# getattr(obj, "_name") and its kin reach a private name as surely as obj._name does
ATTRIBUTE_FUNCTIONS = ("getattr", "setattr", "hasattr", "delattr")


def _private(name: str) -> bool:
    return name.startswith("_") and not name.startswith("__")


def private_names_across_modules(modules: dict[str, Module],
                                 allowed: dict[str, str] = PUBLIC_UNDERSCORE) -> list[str]:
    problems = []
    for name, module in modules.items():
        for node in ast.walk(module.tree):
            if isinstance(node, ast.ImportFrom):
                for alias in node.names:
                    if _private(alias.name):
                        problems.append(f"{name}:{node.lineno}: imports {alias.name} from "
                                        f"{node.module}")
            elif isinstance(node, ast.Import):
                for alias in node.names:
                    if any(_private(p) for p in alias.name.split(".")):
                        problems.append(f"{name}:{node.lineno}: imports {alias.name}")
            elif isinstance(node, ast.Attribute):
                target, attr = node.value, node.attr
            elif (isinstance(node, ast.Call) and isinstance(node.func, ast.Name)
                  and node.func.id in ATTRIBUTE_FUNCTIONS and len(node.args) >= 2
                  and isinstance(node.args[1], ast.Constant)
                  and isinstance(node.args[1].value, str)):
                target, attr = node.args[0], node.args[1].value
            else:
                continue
            if isinstance(node, (ast.Attribute, ast.Call)):
                if not _private(attr) or attr in allowed:
                    continue
                if isinstance(target, ast.Name) and target.id in ("self", "cls"):
                    continue
                if attr in module.own_private:
                    continue  # the module's own name, on another instance of its own class
                problems.append(f"{name}:{node.lineno}: {ast.unparse(node)}")
    return problems


def long_modules(modules: dict[str, Module], limit: int = MAX_LINES) -> dict[str, int]:
    lengths = {name: len(m.path.read_text(encoding="utf-8").splitlines())
               for name, m in modules.items()}
    return {name: n for name, n in lengths.items() if n > limit}


# ---------------------------------------------------------------- the package itself

@functools.cache
def _our_package() -> dict[str, Module]:
    """The package parsed once for the four checks below (each parse is seconds)."""
    return read_package(ROOT)


def test_no_import_cycle():
    assert import_cycles(_our_package()) == []


def test_no_module_imports_a_higher_layer():
    assert upward_imports(_our_package()) == []


def test_no_private_name_is_used_across_modules():
    assert private_names_across_modules(_our_package()) == []


def test_no_module_is_over_600_lines_and_the_chip_under_500():
    # one idea per module; the chip holds only lock, catch-up, primitives, hooks and reset
    modules = _our_package()
    assert long_modules(modules) == {}
    assert long_modules(modules, 499).get("bmg160_emu.device.chip") is None


def test_every_layer_name_exists():
    # a renamed package must not leave a layer entry that matches nothing
    for name in LAYERS:
        assert (ROOT / name).is_dir() or (ROOT / f"{name}.py").is_file(), name


def test_every_module_is_in_the_architecture_tree():
    page = (ROOT.parent / "docs" / "architecture.md").read_text(encoding="utf-8")
    tree = page[page.index("## Modules"):page.index("## Layers")]
    words = set(re.findall(r"[A-Za-z_][A-Za-z0-9_]*", tree))
    missing = []
    for path in sorted(ROOT.rglob("*.py")):
        rel = path.relative_to(ROOT)
        name = rel.parts[-2] if path.name == "__init__.py" and len(rel.parts) > 1 else path.stem
        if name not in words:
            missing.append(rel.as_posix())
    assert missing == []


# ---------------------------------------------------------------- the checks catch what they are for

def _package(tmp_path: Path, files: dict[str, str]) -> dict[str, Module]:
    root = tmp_path / PACKAGE
    for rel, text in files.items():
        path = root / rel
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(text)
    return read_package(root)


def test_a_type_only_circle_is_found(tmp_path):
    modules = _package(tmp_path, {
        "__init__.py": "",
        "device/__init__.py": "",
        "device/chip.py": "from bmg160_emu.device import regmap\n",
        "device/regmap.py": ("from typing import TYPE_CHECKING\nif TYPE_CHECKING:\n"
                             "    from bmg160_emu.device.chip import BMG160\n"),
        "device/fifo.py": "from . import regmap\n",  # relative, no circle
        "io/__init__.py": "",
        "io/rates.py": "def f():\n    from .resd import g\n",  # lazy, relative
        "io/resd.py": "from bmg160_emu.io.rates import f\n",
    })
    assert import_cycles(modules) == [
        ["bmg160_emu.device.chip", "bmg160_emu.device.regmap"],
        ["bmg160_emu.io.rates", "bmg160_emu.io.resd"],
    ]


def test_an_upward_import_and_an_unplaced_module_are_found(tmp_path):
    modules = _package(tmp_path, {
        "device/__init__.py": "",
        "device/good.py": "from bmg160_emu.clock import VirtualClock\n",
        "device/bad.py": ("def f():\n    from bmg160_emu.commands.run import run\n"
                          "    from ..io import trace\n"),
        "commands/__init__.py": "",
        "commands/run.py": "from bmg160_emu import device, io\n",
        "io/__init__.py": "",
        "io/trace.py": "",
        "newthing.py": "",
    })
    assert sorted(upward_imports(modules)) == [
        "bad.py:2: bmg160_emu.device.bad (layer 2) imports bmg160_emu.commands.run (layer 7)",
        "bad.py:3: bmg160_emu.device.bad (layer 2) imports bmg160_emu.io.trace (layer 4)",
        "bmg160_emu.newthing: in no layer (add it to LAYERS)",
    ]


def test_a_private_name_used_across_modules_is_found(tmp_path):
    modules = _package(tmp_path, {
        "device/chip.py": ("class Chip:\n    def __init__(self):\n        self._regs = b''\n"
                           "    def same(self, other):\n        return other._regs\n"),
        "device/regmap.py": ("from bmg160_emu.device.chip import _helper\n"
                             "def f(chip):\n    chip._k = 1\n"
                             "    return chip._regs, chip.regs, chip.__class__\n"),
        "device/fine.py": "import os\nos._exit(0)\n",
    })
    assert private_names_across_modules(modules) == [
        "bmg160_emu.device.regmap:1: imports _helper from bmg160_emu.device.chip",
        "bmg160_emu.device.regmap:3: chip._k",
        "bmg160_emu.device.regmap:4: chip._regs",
    ]


def test_a_long_module_is_found(tmp_path):
    modules = _package(tmp_path, {"device/long.py": "x = 1\n" * 601, "device/ok.py": "x = 1\n" * 600})
    assert long_modules(modules) == {"bmg160_emu.device.long": 601}


def test_a_local_of_the_same_name_does_not_make_a_private_attribute_ones_own(tmp_path):
    modules = _package(tmp_path, {
        "device/chip.py": "class Chip:\n    def __init__(self):\n        self._pointer = 0\n",
        "device/hooks.py": ("def f(s):\n    _pointer = s.chip._pointer\n    return _pointer\n"
                            "def g(s, _k):\n    return s._k\n"),
        "device/own.py": ("class Own:\n    _shared = 1\n    def peer(self, other):\n"
                          "        return other._shared\n"),
    })
    assert private_names_across_modules(modules) == [
        "bmg160_emu.device.hooks:2: s.chip._pointer",
        "bmg160_emu.device.hooks:5: s._k",
    ]


def test_a_private_name_reached_by_getattr_and_its_kin_is_found(tmp_path):
    modules = _package(tmp_path, {
        "device/chip.py": "class Chip:\n    def __init__(self):\n        self._pointer = 0\n",
        "device/peek.py": ("def f(s, name):\n    a = getattr(s.chip, '_pointer')\n"
                           "    setattr(s.chip, '_pointer', 1)\n"
                           "    return a, hasattr(s, '_k'), getattr(s, name), getattr(s, 'k')\n"),
        "device/own.py": ("class Own:\n    def __init__(self):\n        self._n = 0\n"
                          "    def peer(self, other):\n        return getattr(other, '_n')\n"),
    })
    assert private_names_across_modules(modules) == [
        "bmg160_emu.device.peek:2: getattr(s.chip, '_pointer')",
        "bmg160_emu.device.peek:3: setattr(s.chip, '_pointer', 1)",
        "bmg160_emu.device.peek:4: hasattr(s, '_k')",
    ]


def test_a_command_importing_the_dispatcher_is_found(tmp_path):
    modules = _package(tmp_path, {
        "cli.py": "from bmg160_emu.commands import run\n",
        "pytest_plugin.py": "from bmg160_emu.commands._common import CommandError\n",
        "commands/__init__.py": "",
        "commands/_common.py": "class CommandError(Exception):\n    pass\n",
        "commands/run.py": ("from bmg160_emu.cli import build_parser\n"
                            "def f():\n    from bmg160_emu import pytest_plugin\n"),
    })
    assert sorted(upward_imports(modules)) == [
        "run.py:1: bmg160_emu.commands.run (layer 7) imports bmg160_emu.cli (layer 8)",
        "run.py:3: bmg160_emu.commands.run (layer 7) imports bmg160_emu.pytest_plugin (layer 8)",
    ]
