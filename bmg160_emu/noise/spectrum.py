"""One-sided power spectral density (Welch) and the noise terms' one-sided model spectra.

Convention, stated wherever a PSD is printed or plotted: the estimate is ONE-SIDED
(scipy.signal.welch's default, density scaling) in (deg/s)^2/Hz. IEEE Std 952 writes the
terms as TWO-SIDED densities (white noise: N^2), so a one-sided estimate of white noise reads
2 N^2; every model spectrum here is one-sided (twice the IEEE 952 expression).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.lib.stride_tricks import sliding_window_view
from scipy.fft import rfft
from scipy.signal import get_window

PSD_CONVENTION = (
    "one-sided Welch PSD in (deg/s)^2/Hz: white noise of density N reads 2 N^2 "
    "(IEEE 952 two-sided S = N^2)"
)
DEFAULT_SEGMENT = 1 << 16  # samples per Welch segment: 328 s at 200 Hz, 3 mHz resolution
# segments transformed together: at least 8 (pocketfft's batched transform of long segments
# pays: 8 x 64 k took 135 ms a 24 h axis, one at a time 300), at least 64 k samples (short
# segments; a batch that stays in a 2 MB L2)
_BATCH_ROWS, _BATCH_SAMPLES = 8, 1 << 16


@dataclass(frozen=True)
class Spectrum:
    """One-sided PSD estimate of one axis."""

    frequency_hz: np.ndarray
    psd: np.ndarray  # (deg/s)^2/Hz, one-sided
    segment_samples: int

    convention: str = PSD_CONVENTION


def one_sided_psd(rate_dps: np.ndarray, rate_hz: float, segment: int | None = None) -> Spectrum:
    """Welch estimate (Hann window, 50 % overlap), one-sided, of the record minus its mean.

    Numerically the estimate of scipy.signal.welch(x - mean, detrend=False) (a test checks
    it), computed in batches of segments with scipy.fft: scipy's welch takes 2-3x longer on
    day-long records. The mean is removed once for the whole record rather than per segment:
    the Hann window keeps any residual segment offset within the first two bins.
    """
    x = np.asarray(rate_dps, dtype=float)
    n = x.shape[0]
    if segment is None:
        # at least ~15 half-overlapping segments on short records, 2^16 samples on long ones
        segment = min(DEFAULT_SEGMENT, max(256, 1 << max(int(n // 8).bit_length() - 1, 0)))
    nperseg = min(segment, n)
    step = nperseg - nperseg // 2
    window = get_window("hann", nperseg)
    mean = x.mean()
    segments = sliding_window_view(x, nperseg)[::step]
    total = np.zeros(nperseg // 2 + 1)
    rows = max(_BATCH_ROWS, _BATCH_SAMPLES // nperseg)
    batch = np.empty((min(rows, segments.shape[0]), nperseg))
    for first in range(0, segments.shape[0], rows):
        part = segments[first : first + rows]
        b = np.subtract(part, mean, out=batch[: part.shape[0]])
        b *= window
        spec = rfft(b, axis=-1, overwrite_x=True)
        power = spec.real * spec.real  # |X|^2 without the complex temporaries of abs()
        power += spec.imag * spec.imag
        total += power.sum(axis=0)
    psd = total / (segments.shape[0] * rate_hz * float(np.sum(window**2)))
    psd[1 : nperseg // 2 + (nperseg % 2)] *= 2.0  # one-sided: fold the negative frequencies
    f = np.fft.rfftfreq(nperseg, 1.0 / rate_hz)
    return Spectrum(f[1:], psd[1:], nperseg)  # drop DC (mean removed; log axes)


def white_level_band(rate_hz: float) -> tuple[float, float]:
    """Frequency band (Hz) where the white level is read: rate/50 .. rate/10.

    High enough to be far above the Gauss-Markov corner 1/(2 pi T) and the random walk, low
    enough to stay below the chip's low-pass filter when the recording comes from a chip.
    """
    return rate_hz / 50.0, rate_hz / 10.0


def white_density_from_psd(spectrum: Spectrum, band: tuple[float, float]) -> float:
    """N (deg/s/sqrt(Hz)) from the mean one-sided PSD in band: N = sqrt(S1 / 2)."""
    sel = (spectrum.frequency_hz >= band[0]) & (spectrum.frequency_hz <= band[1])
    if not sel.any():
        return math.nan
    return math.sqrt(float(np.mean(spectrum.psd[sel])) / 2.0)


# One-sided model spectra (deg/s)^2/Hz: twice the IEEE 952 two-sided expressions.


def white_psd(N: float, f: np.ndarray) -> np.ndarray:
    return np.full_like(np.asarray(f, dtype=float), 2.0 * N**2)


def gauss_markov_psd(B: float, T: float, f: np.ndarray) -> np.ndarray:
    """Lorentzian of a Gauss-Markov term with std B and time T: 4 B^2 T / (1 + (2 pi f T)^2)."""
    f = np.asarray(f, dtype=float)
    if not T > 0:
        return np.zeros_like(f)
    return 4.0 * B**2 * T / (1.0 + (2.0 * math.pi * f * T) ** 2)


def flicker_psd(B: float, f: np.ndarray) -> np.ndarray:
    return 2.0 * (B**2 / (2.0 * math.pi)) / np.asarray(f, dtype=float)


def random_walk_psd(K: float, f: np.ndarray) -> np.ndarray:
    return 2.0 * (K / (2.0 * math.pi)) ** 2 / np.asarray(f, dtype=float) ** 2


def quantization_psd(Q: float, f: np.ndarray, rate_hz: float) -> np.ndarray:
    return 2.0 * (2.0 * math.pi * np.asarray(f, dtype=float)) ** 2 * Q**2 / rate_hz


def rounding_floor_psd(lsb_dps: float | None, rate_hz: float) -> float:
    """The white one-sided PSD of rounding the output to ``lsb_dps``: the uniform error's
    variance LSB^2/12 spread over 0 .. rate/2 ((deg/s)^2/Hz); 0 without rounding."""
    return lsb_dps**2 / (6.0 * rate_hz) if lsb_dps else 0.0


def ramp_psd(R: float, f: np.ndarray) -> np.ndarray:
    return 2.0 * R**2 / (2.0 * math.pi * np.asarray(f, dtype=float)) ** 3
