"""What ``bmg160-emu identify --method gmwm`` gives, as a library: an identification whose
N, B, T, K (Q, R) on every axis are GMWM's (gmwm.py) instead of the Allan fit's.

The Allan curve, the PSD, the output stage found on the record and the IEEE read-offs stay
as ``identify`` found them; each axis's fit, intervals and notes become GMWM's, so the
summary, the JSON and the profile (``to_profile``) carry GMWM's values.

GMWM's white term knows no output filter: on a filtered record its scales start where the
filter takes less than 1 % off white noise's Allan variance (``FILTER_DEFICIT``), unless
``tau_min_s`` says where.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from functools import partial

import numpy as np

from bmg160_emu.noise import gmwm
from bmg160_emu.noise.butterworth import white_avar_unit
from bmg160_emu.noise.estimate import Estimate
from bmg160_emu.noise.fit import Term
from bmg160_emu.noise.identification_result import Identification
from bmg160_emu.noise.identify import IdentificationError
from bmg160_emu.noise.wavelet import MIN_COEFFS_FRACTION, haar_wv

# The largest share white noise's Allan variance may lose to the output filter at a scale
# GMWM uses (it falls as 1 / tau, from 60 % at tau = dt for the chip's filters)
FILTER_DEFICIT = 0.01
J_TEST_LEVEL = 0.01  # a J test p-value below this rejects the model (a note says so)


def gmwm_identification(
    result: Identification,
    rate_dps: np.ndarray,
    *,
    with_q: bool = False,
    with_r: bool = False,
    tau_min_s: float | None = None,
    tau_max_s: float | None = None,
    bootstrap: int = 0,
    seed: int | None = None,
    progress: Callable[[int], None] | None = None,
) -> tuple[Identification, dict[str, gmwm.GMWMFit]]:
    """``result`` (``identify``'s, of the samples ``rate_dps``, (n,) or (n, k) deg/s) with
    each axis's fit replaced by GMWM's of white noise + one Gauss-Markov term + random walk
    (+ quantization with ``with_q``, + drift with ``with_r``) on the scales within
    ``tau_min_s`` .. ``tau_max_s``; ``bootstrap`` replicates (seeded) add bootstrap
    intervals; ``progress(done)`` is told the replicates done so far over all axes (10,000
    a axis took hours, issue 35). Returns the new identification and the GMWM fit of each
    axis by name. IdentificationError naming the axis when a fit fails."""
    samples = np.asarray(rate_dps, dtype=float).reshape(len(rate_dps), -1)
    rate_hz = result.rate_hz
    model = ["WN", "GM", "RW"] + ["QN"] * with_q + ["DR"] * with_r
    axes = list(result.axes)
    fits: dict[str, gmwm.GMWMFit] = {}
    for i, axis in enumerate(axes):
        wv = haar_wv(samples[:, i], rate_hz, MIN_COEFFS_FRACTION)
        keep = np.ones(wv.m.size, dtype=bool)
        if tau_min_s is not None:
            keep &= wv.taus_s >= tau_min_s
        elif axis.output_filter is not None:
            deficit = np.abs(white_avar_unit(wv.taus_s, rate_hz, axis.output_filter.design)
                             * wv.taus_s - 1.0)
            keep &= deficit < FILTER_DEFICIT
        elif axis.stage is not None and axis.stage.carries_response:
            # a measured output response (bands inside): the same 1 % rule through it
            deficit = np.abs(axis.stage.response.white_avar_unit(wv.taus_s) * wv.taus_s - 1.0)
            keep &= deficit < FILTER_DEFICIT
        if tau_max_s is not None:
            keep &= wv.taus_s <= tau_max_s
        wv = dataclasses.replace(wv, m=wv.m[keep], taus_s=wv.taus_s[keep], wv=wv.wv[keep],
                                 n_coeffs=wv.n_coeffs[keep])
        try:
            fit = gmwm.gmwm_fit(wv, model)
            if bootstrap:  # the axes' replicates, one axis after another
                told = None if progress is None else partial(_told, progress, i * bootstrap)
                fit = gmwm.bootstrap(fit, bootstrap, seed=seed, progress=told)
        except gmwm.GMWMError as exc:
            raise IdentificationError(f"axis {axis.axis}: {exc}") from None
        est = {k: Estimate(e.value, e.ci_low, e.ci_high, e.unit) for k, e in fit.estimates.items()}
        at_bound = dict(zip(fit.names, fit.at_bound))
        notes = [  # the Allan fit's notes describe that fit: replaced
            f"{k} not resolved by this record (at the edge of its search range)"
            for k, at_edge in at_bound.items() if at_edge
        ]
        if fit.p_value < J_TEST_LEVEL:
            notes.append(
                f"the J test rejects the model (p = {fit.p_value:.2g}): try --with-q/--with-r"
            )
        curve_fit = dataclasses.replace(
            axis.fit,
            N=est["N"],
            K=est["K"],
            terms=[Term(B=est["B"], T=est["T"], T_at_search_edge=bool(at_bound.get("T", False)))],
            Q=est.get("Q"),
            R=est.get("R"),
            flicker=None,
            flicker_poles=(),
            tau_range_s=(float(wv.taus_s[0]), float(wv.taus_s[-1])),
            points=int(wv.m.size),
            chi2_reduced=fit.objective / max(fit.dof, 1),
        )
        reason = axis.tau_range_reason
        if tau_min_s is None and (axis.output_filter is not None or (
                axis.stage is not None and axis.stage.carries_response)):
            reason = (f"GMWM's scales from tau = {wv.taus_s[0]:.3g} s, where the output filter "
                      "takes less than 1 % off white noise's Allan variance")
        axes[i] = dataclasses.replace(axis, fit=curve_fit, notes=notes, method="gmwm",
                                      tau_range_reason=reason)
        fits[axis.axis] = fit
    return dataclasses.replace(result, axes=axes), fits


def _told(progress: Callable[[int], None], before: int, done: int) -> None:
    """A replicate of one axis done: ``before`` are the earlier axes' replicates."""
    progress(before + done)
