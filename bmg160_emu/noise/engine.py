"""PLACEHOLDER white-noise generator with the interface of the real noise engine.

Interface (kept by the real engine):
    gen = NoiseGenerator(profile="paper", rate_hz=200.0, seed=7, mode="physical")
    gen.generate(n) -> ndarray (n, 3) float64, deg/s, constant bias included; chunk invariant
    gen.set_rate(rate_hz)   # continue the same realisation at a new output data rate
"""

from __future__ import annotations

import numpy as np

_PAPER_N = 1.779073e-2  # deg/s/sqrt(Hz), paper section 2.5
_PAPER_BIAS = 0.116359  # deg/s, paper section 2.5


def load_profile(name: str = "paper") -> dict:
    if name != "paper":
        raise ValueError(f"unknown noise profile {name!r}")
    return {"N": [_PAPER_N] * 3, "bias": [_PAPER_BIAS] * 3}


class NoiseGenerator:
    def __init__(self, profile="paper", rate_hz: float = 200.0, seed=None, mode: str = "physical"):
        self.profile = load_profile(profile) if isinstance(profile, str) else profile
        self.rate_hz = float(rate_hz)
        self._rng = np.random.Generator(np.random.PCG64(seed))

    def set_rate(self, rate_hz: float) -> None:
        self.rate_hz = float(rate_hz)

    def generate(self, n: int) -> np.ndarray:
        sigma = np.asarray(self.profile["N"]) * np.sqrt(self.rate_hz)
        return self._rng.standard_normal((n, 3)) * sigma + np.asarray(self.profile["bias"])
