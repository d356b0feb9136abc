"""The classic IEEE Std 952 read-offs of an Allan deviation curve, reported beside the fit.

Labelled as read-offs: they are not what the generator takes (noise-model.md, "Two facts";
on a Gauss-Markov bias "minimum / 0.664" returns about 1.4 B). The MATLAB-style export
(interop.py) uses the flicker read-off as its BiasInstability, as MATLAB defines it.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from bmg160_emu.noise.allan import FLICKER_ADEV_FACTOR, AllanCurve
from bmg160_emu.noise.profile import UNITS


def ieee_readoffs(curve: AllanCurve) -> dict[str, dict[str, Any]]:
    """The classic slope read-offs of the Allan deviation, each labelled with how it was read."""
    taus, adev = curve.taus, curve.adev
    i_min = int(np.argmin(adev))
    out: dict[str, dict[str, Any]] = {
        "B_flicker": {
            "label": "B flicker = min ADEV / 0.664",
            "value": float(adev[i_min] / FLICKER_ADEV_FACTOR),
            "unit": UNITS["B"],
            "tau_s": float(taus[i_min]),
        },
        "tau_at_minimum": {
            "label": "tau at the Allan minimum",
            "value": float(taus[i_min]),
            "unit": "s",
        },
    }
    slopes = np.diff(np.log(adev)) / np.diff(np.log(taus))
    mid_tau = np.sqrt(taus[1:] * taus[:-1])
    mid_dev = np.sqrt(adev[1:] * adev[:-1])
    n_value = k_value = None
    n_tau = k_tau = None
    before = np.arange(slopes.size) < i_min
    if before.any():
        j = int(np.argmin(np.where(before, np.abs(slopes + 0.5), np.inf)))
        if abs(slopes[j] + 0.5) < 0.25:
            n_value = float(mid_dev[j] * math.sqrt(mid_tau[j]))  # -1/2 line at tau = 1 s
            n_tau = float(mid_tau[j])
    after = np.arange(slopes.size) >= i_min
    if after.any():
        j = int(np.argmin(np.where(after, np.abs(slopes - 0.5), np.inf)))
        if abs(slopes[j] - 0.5) < 0.25:
            k_value = float(mid_dev[j] * math.sqrt(3.0 / mid_tau[j]))  # +1/2 line at tau = 3 s
            k_tau = float(mid_tau[j])
    out["N_at_tau_1s"] = {
        "label": "N = -1/2 slope line at tau = 1 s",
        "value": n_value,
        "unit": UNITS["N"],
        "line_through_tau_s": n_tau,
    }
    out["K_at_tau_3s"] = {
        "label": "K = +1/2 slope line at tau = 3 s",
        "value": k_value,
        "unit": UNITS["K"],
        "line_through_tau_s": k_tau,
    }
    return out
