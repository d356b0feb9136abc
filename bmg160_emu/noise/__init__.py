"""Gyroscope noise engine (N, B, T, K per axis) and its identification pipeline.

Names are imported lazily (PEP 562): importing one submodule (``noise.profile`` for the
firmware header, ``noise.identify`` for the identify command) does not load the
generator, and the generator does not load identification, plots or recording loaders, so
the chip pays only for what it uses.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from bmg160_emu.noise.engine import NoiseGenerator
    from bmg160_emu.noise.profile import AxisNoise, Profile, ProfileError, load_profile

# public name -> module that defines it
_EXPORTS = {
    "NoiseGenerator": "bmg160_emu.noise.engine",
    "AxisNoise": "bmg160_emu.noise.profile",
    "Profile": "bmg160_emu.noise.profile",
    "ProfileError": "bmg160_emu.noise.profile",
    "load_profile": "bmg160_emu.noise.profile",
}

__all__ = ["AxisNoise", "NoiseGenerator", "Profile", "ProfileError", "load_profile"]


def __getattr__(name: str) -> Any:
    module = _EXPORTS.get(name)
    if module is None:
        raise AttributeError(f"module 'bmg160_emu.noise' has no attribute {name!r}")
    value = getattr(importlib.import_module(module), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(__all__))
