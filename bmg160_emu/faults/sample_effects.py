"""What a sample fault does to one output sample, and when it acts (:class:`Activation`).

The rate is the sensor-frame rate in deg/s, after filter, noise and offset and before
scaling to counts, so a stuck axis or a spike reaches the RATE registers, the FIFO and the
interrupt engines like a real sample.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from bmg160_emu.faults.model import SATURATED_DPS, Fault
from bmg160_emu.faults.targets import set_temperature


@dataclass
class Activation:
    """One onset of a sample fault on one gyro: from ``start_s`` to ``end_s`` (math.inf: for
    ever), or for ``samples_left`` samples (spike, lost_samples)."""

    start_s: float
    end_s: float  # math.inf when open-ended
    gyro: int
    samples_left: int | None = None  # spike, lost_samples: a count of samples instead
    held: np.ndarray | None = None  # stuck_axis: the value it repeats
    started: bool = False
    not_before_s: float = -math.inf  # a replayed fault: the first sample it touched


def counts_samples(fault: Fault) -> bool:
    """The fault lasts a number of samples rather than a time."""
    return fault.kind in ("spike", "lost_samples")


def apply_effect(fault: Fault, act: Activation, chip: Any, t: float, rate: np.ndarray,
                 base_temperature_c: float) -> bool:
    """Change ``rate`` (deg/s, in place) for the sample at ``t``; True when the sample is
    lost. A temperature ramp also sets the chip's die temperature (from
    ``base_temperature_c``)."""
    axes = slice(None) if fault.axis is None else fault.axis
    if fault.kind == "stuck_axis":
        assert act.held is not None
        rate[axes] = act.held[axes]
    elif fault.kind == "bias_step":
        rate[axes] += fault.step_dps
    elif fault.kind == "spike":
        rate[axes] += fault.amplitude_dps
    elif fault.kind == "saturation":
        rate[axes] = math.copysign(SATURATED_DPS, fault.amplitude_dps or 1.0)
    elif fault.kind == "lost_samples":
        return True
    elif fault.kind == "temperature_ramp":
        elapsed = min(t, act.end_s) - act.start_s
        rise_c = fault.rate_c_per_s * elapsed
        set_temperature(chip, base_temperature_c + rise_c)
        rate += fault.tc_bias_dps_per_c * rise_c
    return False
