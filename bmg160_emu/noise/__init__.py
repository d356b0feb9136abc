"""Gyroscope noise engine (N, B, T, K per axis) and its identification pipeline.

The generator is imported eagerly (the device model needs it); identification, plots and
recording loaders are imported from their own modules so that the chip does not pay for
allantools or matplotlib.
"""

from bmg160_emu.noise.engine import NoiseGenerator
from bmg160_emu.noise.profile import AxisNoise, Profile, ProfileError, load_profile

__all__ = ["AxisNoise", "NoiseGenerator", "Profile", "ProfileError", "load_profile"]
