"""Which pip extra brings each optional package, and the one-line error naming it.

The core install is numpy and smbus2 (a driver's tests); the rest comes with extras named
by job (pyproject.toml, docs/install.md). A command that reaches an optional package that
is not installed ends with one line saying which extra to install, never a traceback.
"""

from __future__ import annotations

import importlib.util

# top-level import name -> the extra that installs it
EXTRA_OF_MODULE = {
    "scipy": "noise",
    "allantools": "noise",
    "matplotlib": "noise",
    "tqdm": "noise",
    "dask": "montecarlo",
    "distributed": "montecarlo",
    "Basilisk": "basilisk",
    "rich": "watch",
    "gi": "umockdev",
}

# a command whose own extra also brings the package: named instead of the package's default
COMMAND_EXTRA = {
    "montecarlo": ("montecarlo", {"dask", "distributed", "tqdm", "scipy"}),
    "watch": ("watch", {"rich"}),
    "run": ("umockdev", {"gi"}),
}


def extra_for(command: str, module: str) -> str | None:
    """The extra that brings ``module`` (a dotted import name) to ``command``; None when no
    extra does (then a missing module is a bug, not an install choice)."""
    top = module.partition(".")[0]
    own = COMMAND_EXTRA.get(command)
    if own is not None and top in own[1]:
        return own[0]
    return EXTRA_OF_MODULE.get(top)


def install_line(extra: str) -> str:
    return f"pip install 'bmg160-emu[{extra}]'"


def missing_message(command: str, module: str) -> str | None:
    """``identify needs the [noise] extra (scipy): pip install 'bmg160-emu[noise]'``, or None
    when ``module`` is not an optional package."""
    extra = extra_for(command, module)
    if extra is None:
        return None
    top = module.partition(".")[0]
    return f"{command} needs the [{extra}] extra ({top}): {install_line(extra)}"


def available(module: str) -> bool:
    """Whether ``module`` can be imported, without importing it (no start-up cost)."""
    try:
        return importlib.util.find_spec(module) is not None
    except (ImportError, ValueError):  # a parent missing, or a stub in sys.modules
        return False
