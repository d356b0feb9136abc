"""Periodic terms of an Allan deviation curve given without samples (issue 37): a line shows
on a curve as a shoulder or a ripple, A^2 sin^4(pi f tau) / (m sin(pi f / rate))^2 at tau =
m / rate (output_stage.sine_avar_unit of samples: the ripple of a line near the Nyquist
frequency at the first taus included), where a record would show it in one PSD bin.

The search: the fit of the curve (its terms and filter as found) is repeated with one free
line (its amplitude a linear coefficient beside N, B_i, K) at frequencies
from the Nyquist frequency down to 1 / (2 tau_max), two to an octave, the best by AICc
refined between its neighbours; the line is kept when it lowers AICc by more than MIN_GAIN
(two parameters, A and f, paid for). Then a second one, with the first kept. A curve-only user gets the
periodic terms a record's PSD would have given.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from bmg160_emu.noise.fit import CurveFit, FitError

PER_OCTAVE = 8  # frequencies tried per octave (the best refined between its neighbours)
MIN_GAIN = 10.0  # AICc a line must gain: strong evidence (Burnham and Anderson 2002, 2.6)
MAX_LINES = 3
REFINE = 41  # frequencies of the fine scan between the best one's neighbours
POLISH_ROUNDS = 3  # passes of coordinate descent over the lines' frequencies


def _aicc(fit: CurveFit) -> float:
    rows = [r for r in fit.selection.get("candidates", []) if r.get("chosen")]
    value = rows[0]["aicc"] if rows else None
    return float(value) if value is not None else math.inf


def _scan(base: CurveFit, rate_hz: float, found: tuple[float, ...],
          grid: np.ndarray) -> np.ndarray:
    """The weighted residual over the fitted taus with one more line at each frequency of
    ``grid``, the base fit's terms held (their T fixed, every amplitude refitted by
    non-negative least squares, weights of the base model): a fast stand-in for the full
    refit, used to find where a line pays; the full fit then decides."""
    from scipy.optimize import nnls

    from bmg160_emu.noise.allan import gauss_markov_avar_unit
    from bmg160_emu.noise.output_stage import sine_avar_unit

    curve = base.curve
    lo, hi = base.tau_range_s
    sel = (curve.taus >= lo * (1 - 1e-9)) & (curve.taus <= hi * (1 + 1e-9))
    tau, avar = curve.taus[sel], curve.avar[sel]
    model = np.maximum(base.model_avar(tau), 1e-300)
    w = np.sqrt(curve.edf[sel] / 2.0) / model
    white = (base.white_avar(tau) / base.N.value**2 if base.N.value > 0 else 1.0 / tau)
    columns = [white, tau / 3.0] + [gauss_markov_avar_unit(tau, T)
                                    for _, T in base.gauss_markov_terms()]
    columns += [sine_avar_unit(tau, f, rate_hz) for f in found]
    out = np.empty(grid.size)
    for i, f in enumerate(grid):
        a = np.column_stack(columns + [sine_avar_unit(tau, float(f), rate_hz)]) * w[:, None]
        scale = np.linalg.norm(a, axis=0)
        scale[scale == 0] = 1.0
        _, residual = nnls(a / scale, avar * w, maxiter=50 * a.shape[1])
        out[i] = residual**2
    return out


def find_periodic_terms(fit_with: Callable[[tuple[float, ...]], CurveFit], base: CurveFit,
                        rate_hz: float, tau_max_s: float) -> tuple[CurveFit, list[str]]:
    """The fit with the lines the curve supports (``fit_with(frequencies)`` refits with those
    free lines), and a note per line found."""
    found: tuple[float, ...] = ()
    best_fit = base
    nyquist = rate_hz / 2.0
    lowest = 1.0 / (2.0 * tau_max_s)
    count = int(math.log2(nyquist / lowest) * PER_OCTAVE)
    grid = nyquist * 0.999 * 2.0 ** (-np.arange(count + 1) / PER_OCTAVE)
    gains: list[float] = []
    for _ in range(MAX_LINES):
        quick = _scan(best_fit, rate_hz, found, grid)
        i = int(np.argmin(quick))
        try:
            scores = {i: _aicc(fit_with((*found, float(grid[i]))))}
        except FitError:
            break
        if not math.isfinite(scores[i]) or not _aicc(best_fit) - scores[i] > MIN_GAIN:
            break  # no frequency of the grid pays for a line: none refined
        # refined between the neighbours on a fine grid of the fast scan, then fitted whole
        f_best = _refined(best_fit, rate_hz, found, grid, i, nyquist)
        candidate = fit_with((*found, f_best))
        if _aicc(candidate) > scores[i]:
            f_best, candidate = float(grid[i]), fit_with((*found, float(grid[i])))
        gain = _aicc(best_fit) - _aicc(candidate)
        if not gain > MIN_GAIN:
            break
        found = (*found, f_best)
        best_fit = candidate
        gains.append(gain)
        if len(found) > 1:
            best_fit, found = _polish(fit_with, best_fit, found, rate_hz, grid, nyquist)
    notes: list[str] = []
    for (amplitude, frequency), gain in zip(best_fit.sines[-len(found):] if found else [], gains):
        notes.append(f"a periodic term on the curve: A = {amplitude.value:.3g} deg/s "
                     f"[{amplitude.ci_low:.3g}, {amplitude.ci_high:.3g}] at {frequency:.4g} Hz "
                     f"(its shoulder lowered AICc by {gain:.1f}); the profile carries it as a "
                     "sinusoidal term")
    return best_fit, notes


def _refined(fit: CurveFit, rate_hz: float, held: tuple[float, ...], grid: np.ndarray, i: int,
             nyquist: float) -> float:
    """The frequency of grid point i refined between its neighbours on a fine grid of the
    fast scan."""
    fine = np.geomspace(grid[min(i + 1, grid.size - 1)],
                        min(grid[max(i - 1, 0)], nyquist * 0.999), REFINE)
    return float(fine[int(np.argmin(_scan(fit, rate_hz, held, fine)))])


def _polish(fit_with: Callable[[tuple[float, ...]], CurveFit], best_fit: CurveFit,
            found: tuple[float, ...], rate_hz: float, grid: np.ndarray, nyquist: float
            ) -> tuple[CurveFit, tuple[float, ...]]:
    """The lines' frequencies moved one at a time to where the fast scan puts them with the
    others held (coordinate descent), each move kept when the whole fit's AICc falls: a line
    taken first as a compromise between two (the D435i's y axis: one at 27 Hz for two at 13
    and 31 Hz) moves once the second is there."""
    for _ in range(POLISH_ROUNDS):
        moved = False
        for k in range(len(found)):
            held = found[:k] + found[k + 1:]
            i = int(np.argmin(_scan(best_fit, rate_hz, held, grid)))
            f_new = _refined(best_fit, rate_hz, held, grid, i, nyquist)
            if abs(math.log(f_new / found[k])) < 1e-3:
                continue
            trial = found[:k] + (f_new,) + found[k + 1:]
            try:
                candidate = fit_with(trial)
            except FitError:
                continue
            if _aicc(candidate) < _aicc(best_fit):
                best_fit, found, moved = candidate, trial, True
        if not moved:
            break
    return best_fit, found
