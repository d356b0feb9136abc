"""Gyroscope noise engine (N, B, K) and its identification pipeline.

PLACEHOLDER until the noise-engine work lands: a white-noise source behind the final
interface, so the device model can be built against it.
"""

from bmg160_emu.noise.engine import NoiseGenerator, load_profile

__all__ = ["NoiseGenerator", "load_profile"]
