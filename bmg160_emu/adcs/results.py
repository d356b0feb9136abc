"""What one Monte Carlo run returns; its own module so that the runner (montecarlo) and the
default run (evaluation) both use it without importing each other."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


@dataclass
class RunResult:
    """What one run returns: the angle error of the attitude estimate on a time grid."""

    seed: int
    times_s: np.ndarray
    angle_error_deg: np.ndarray
    extras: dict[str, float] = field(default_factory=dict)
