"""Identify real static recordings with the defaults and set each against the spread of its
profile's emulated records (issue 37): every figure per axis and record, and pooled.

    python tools/identification_real_records.py            # every known record that is present
    python tools/identification_real_records.py ../shared/data/real-gyro/adis16405_run1.npz

Without paths the tool takes the known records (KNOWN_RECORDS, under the first ``shared/data``
found beside the repository or above it); a path that is absent is skipped with a line saying
so (the recordings are not in the repository: their licenses keep them out). A file is an .npz
with ``counts`` (n, k), ``lsb_dps`` and ``rate_hz`` (the layout of ../shared/data), an .npz
with ``rate_dps`` (n, k) and ``rate_hz`` (an unquantized record), or anything
``bmg160_emu.io.rates.load_rate_record`` reads (give --rate for files without a time column).
Figures (docs/identification.md, "Real recordings"): std ratio (median emulated / recorded),
the largest autocorrelation difference at lags 1-5, PSD bins inside the recording's 95 %
band, and at octave taus 0.2 s .. L/10 the emulated median inside the recording's 95 %
Greenhall band (forward) and the recording inside the emulated 2.5-97.5 % range (reverse),
per axis and pooled over the record's axes.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

# The public static records the figures in docs/identification.md come from, relative to
# shared/data (each described, with source and license, in the README beside it).
KNOWN_RECORDS = (
    "real-gyro/adis16405_run1.npz",  # Analog Devices ADIS16405, 2.78 h at 100 Hz
    "public-gyro/mpu6050-imucalibration/mpu6050_static_tinit.npz",  # InvenSense MPU-6050
    "public-gyro/imudata-mtig-cont/mtig_cont_imu1.npz",  # Xsens MTi-G, x axis, 1.39 h
)


def shared_data() -> Path:
    """The first ``shared/data`` beside the repository or above it (a worktree sits deeper
    than the main checkout); the repository's parent's when there is none."""
    root = Path(__file__).resolve().parents[1]
    for parent in root.parents:
        if (parent / "shared" / "data").is_dir():
            return parent / "shared" / "data"
    return root.parent / "shared" / "data"


def load(path: Path, rate_hz: float | None) -> tuple[np.ndarray, float]:
    if path.suffix == ".npz":
        with np.load(path) as d:
            if "counts" in d:
                return d["counts"].astype(float) * float(d["lsb_dps"]), float(d["rate_hz"])
            if "rate_dps" in d and "rate_hz" in d:  # an unquantized record (deg/s)
                rate = np.asarray(d["rate_dps"], dtype=float)
                return rate.reshape(rate.shape[0], -1), float(d["rate_hz"])
    from bmg160_emu.io.rates import load_rate_record

    record = load_rate_record(path, rate_hz)
    return record.rate_dps, float(record.rate_hz)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("paths", nargs="*", type=Path,
                        help="record files (default: the known records under shared/data)")
    parser.add_argument("--seeds", type=int, default=40)
    parser.add_argument("--rate", type=float, default=None)
    parser.add_argument("--profile-dir", type=Path, default=None,
                        help="also write each record's identified profile here")
    args = parser.parse_args(argv)
    from bmg160_emu.noise.identify import identify
    from bmg160_emu.noise.verdict import TAU_MIN_S, compare_profile

    rows = []
    paths = args.paths or [shared_data() / name for name in KNOWN_RECORDS]
    for path in paths:
        if not path.exists():
            print(f"{path}: absent, skipped")
            continue
        data, rate = load(path, args.rate)
        started = time.perf_counter()
        result = identify(data, rate, source=path.name)
        took = time.perf_counter() - started
        profile = result.to_profile(path.stem)
        if args.profile_dir is not None:
            from bmg160_emu.noise.profile_writer import write_profile

            args.profile_dir.mkdir(parents=True, exist_ok=True)
            write_profile(profile, args.profile_dir / f"{path.stem}.toml")
        names = tuple(a.axis for a in result.axes)
        verdict = compare_profile(data, rate, profile, args.seeds, names)
        print(f"{path.name}: {data.shape[0]} samples at {rate:g} Hz ({data.shape[0] / rate / 3600:.2f} h), "
              f"identified in {took:.1f} s, {args.seeds} emulated records")
        fwd_all = rev_all = count = 0
        for a, axis in zip(verdict.axes, result.axes):
            sel = (a.taus >= TAU_MIN_S * (1 - 1e-9)) & (a.taus <= data.shape[0] / rate / 10 * (1 + 1e-9))
            n_taus = int(sel.sum())
            fwd = round(a.adev_forward * n_taus)
            rev = round(a.adev_reverse * n_taus)
            fwd_all, rev_all, count = fwd_all + fwd, rev_all + rev, count + n_taus
            lag = float(np.max(np.abs(a.acf_emulated[:5] - a.acf_recorded[:5])))
            stage = axis.stage
            kind = ("none" if stage is None else
                    "Butterworth" if stage.family is not None else
                    f"measured {len(stage.response.cosine)}-tap")
            bands = (f"{len(stage.findings.bands)}" if stage is not None else "0") + (
                f" + {len(stage.slow_bands)} slow" if stage is not None and stage.slow_bands
                else "")
            row = (path.name, a.axis, a.std_ratio, lag, a.psd_inside, fwd, rev, n_taus, kind, bands,
                   "pass" if a.passed else "FAIL")
            rows.append(row)
            print(f"  axis {a.axis}: std ratio {a.std_ratio:.4f}, acf lags 1-5 max |d| {lag:.3f}, "
                  f"PSD {a.psd_inside:.1%}, ADEV forward {fwd}/{n_taus}, reverse {rev}/{n_taus}; "
                  f"stage {kind}, {bands} band(s): {'pass' if a.passed else 'FAIL'}")
        print(f"  pooled: forward {fwd_all}/{count} = {fwd_all / count:.1%}, reverse "
              f"{rev_all}/{count} = {rev_all / count:.1%}")
    print("\n| record | axis | std ratio | acf lags 1-5 max diff | PSD bins in band | ADEV forward "
          "| ADEV reverse | output stage | bands | verdict |")
    print("| --- | --- | ---: | ---: | ---: | ---: | ---: | --- | ---: | --- |")
    for name, axis, std, lag, psd, fwd, rev, n, kind, bands, ok in rows:
        print(f"| {name} | {axis} | {std:.4f} | {lag:.3f} | {psd:.1%} | {fwd}/{n} | {rev}/{n} | "
              f"{kind} | {bands} | {ok} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
