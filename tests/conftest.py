"""The kernel fixture's plugin, where the installed package predates its entry point
(``bmg160_emu_kernel`` in pyproject's pytest11; a reinstall registers it)."""

from importlib.metadata import entry_points

if not any(ep.name == "bmg160_emu_kernel" for ep in entry_points(group="pytest11")):
    pytest_plugins = ["bmg160_emu.pytest_kernel"]
