"""Deprecated package: the Linux front ends moved to ``bmg160_emu.bus`` (``umockdev``,
``i2c_stub``, ``kernel_abi``); these names stay for one release (issue 10's layout)."""
