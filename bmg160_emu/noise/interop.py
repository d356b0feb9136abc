"""Curves and parameters in the formats other tools use: ADEV curve CSV, Kalibr, MATLAB.

Mappings (deg/s internally; d = pi / 180 rad per degree):

- Kalibr ``imu.yaml`` (the continuous-time noise model of its IMU camera calibration):
  ``gyroscope_noise_density`` = N d [rad/s/sqrt(Hz)] (white rate noise, our N);
  ``gyroscope_random_walk`` = K d [rad/s^2/sqrt(Hz)] (the bias random walk, our K: the
  same rate random walk written per sqrt(Hz)). Kalibr has no Gauss-Markov term and one value
  for the three axes: the export writes the largest axis (conservative, as Kalibr users
  inflate), the import gives every axis N and K with no Gauss-Markov term.
- MATLAB ``gyroparams`` (Sensor Fusion and Tracking Toolbox): ``NoiseDensity`` = N d
  [rad/s/sqrt(Hz)], ``RandomWalk`` = K d [(rad/s) sqrt(Hz)], ``ConstantBias`` = mean d
  [rad/s], and ``BiasInstability`` = the flicker read-off min ADEV / 0.664 (its definition:
  the flat part of the Allan deviation, sqrt(2 ln 2 / pi) = 0.664 times it), in rad/s. It is
  NOT our Gauss-Markov B (a stationary std): on a Gauss-Markov bias the read-off is about
  1.4 B. The import turns BiasInstability into a fixed bank of Gauss-Markov poles whose
  Allan deviation is flat at 0.664 BiasInstability from 1 s to 1000 s (fit.py's 1/f bank).
- ADEV curve CSV: first column tau in s, then per axis the Allan deviation, optionally
  followed by its interval (low, high); allan_variance_ros's layout (tau, 3 accelerometer,
  3 gyroscope columns) is recognised by its 7 columns and the gyroscope columns used: its
  source (AllanVarianceComputor.cpp) averages disjoint clusters (non-overlapping), converts
  the gyroscope's rad/s to deg/s before averaging, and writes 9,999 taus 0.1 s apart.
  Tools that write tau and each axis as separate one-column files (imu_utils) are read
  after pasting the columns together (``paste -d, tau.txt x.txt y.txt z.txt``); curves in
  rad/s or deg/h are read with units="rad/s" / "deg/h". Each axis read says its kind when
  the file does ("overlapping", "non-overlapping"; None: not said).
"""

from __future__ import annotations

import math
import re
from pathlib import Path
from typing import Any

import numpy as np

from bmg160_emu.limits import ALLAN_DEVIATION_DPS, TAU_S
from bmg160_emu.noise.allan import FLICKER_ADEV_FACTOR, gauss_markov_avar_unit

DEG = math.pi / 180.0  # rad per degree
UNIT_SCALES = {"deg/s": 1.0, "rad/s": DEG, "deg/h": 3600.0}  # value in the unit per deg/s


class InteropError(ValueError):
    """A curve or parameter file that cannot be read (named file and place in the message)."""


# -- Allan deviation curves --------------------------------------------------------------


def write_adev_csv(path: str | Path, identification: Any, units: str = "deg/s") -> None:
    """Per-axis curve with its confidence interval: tau_s, then adev, low, high per axis."""
    s = UNIT_SCALES[units]
    axes = identification.axes
    taus = axes[0].allan.taus
    cols = [taus]
    names = ["tau_s"]
    for a in axes:
        c = a.allan
        k = min(c.taus.size, taus.size)
        cols = [col[:k] for col in cols]
        cols += [c.adev[:k] * s, c.ci_low[:k] * s, c.ci_high[:k] * s]
        names += [f"{a.axis}_adev", f"{a.axis}_low", f"{a.axis}_high"]
    ci = axes[0].allan.ci
    header = (
        f"# {axes[0].allan.kind} Allan deviation in {units}, interval at {ci * 100:.1f} % "
        f"(Greenhall edf), {identification.samples} samples at {identification.rate_hz:g} Hz\n"
        + ",".join(names)
    )
    np.savetxt(path, np.column_stack(cols), delimiter=",", header=header, comments="",
               fmt="%.10g")


def read_adev_csv(path: str | Path, units: str = "deg/s") -> tuple[np.ndarray, list[dict]]:
    """(taus, [{"name", "adev", "ci": (low, high) | None}, ...]) in deg/s."""
    path = Path(path)
    s = UNIT_SCALES[units]
    try:
        lines = path.read_text(encoding="utf-8", errors="replace").splitlines()
    except OSError as exc:
        raise InteropError(f"cannot read Allan deviation curve {path}: {exc.strerror}") from None
    header: list[str] | None = None
    rows = []
    kind: str | None = None
    for number, line in enumerate(lines, 1):
        text = line.strip()
        if not text or text.startswith(("#", "%")):
            said = re.search(r"\b(non-overlapping|overlapping) Allan", text)
            kind = said.group(1) if said and kind is None else kind
            continue
        cells = [c.strip() for c in re.split(r"[,;\s]+", text) if c.strip()]
        try:
            rows.append([float(c) for c in cells])
        except ValueError:
            if rows or header is not None:
                raise InteropError(f"{path}:{number}: not a number in {text!r}") from None
            header = [c.lower() for c in cells]
            continue
        if len(rows[-1]) != len(rows[0]):
            raise InteropError(f"{path}:{number}: {len(rows[-1])} columns, the first row had "
                               f"{len(rows[0])}")
    if len(rows) < 4:
        raise InteropError(f"{path}: an Allan deviation curve needs at least 4 rows of tau, adev")
    table = np.array(rows)
    taus = table[:, 0]
    if not (np.all(np.isfinite(table)) and np.all(taus > 0) and np.all(np.diff(taus) > 0)):
        raise InteropError(f"{path}: tau must be positive and increasing, and every value finite")
    width = table.shape[1]
    names = header[1:] if header else []
    groups: list[tuple[int, tuple[int, int] | None]]
    if width == 7:  # allan_variance_ros: tau, accelerometer x y z, gyroscope x y z
        groups = [(4 + i, None) for i in range(3)]
        labels = ["x", "y", "z"]
        kind = kind or "non-overlapping"  # its clusters are disjoint (module docstring)
    elif (width - 1) % 3 == 0 and width > 2 and _looks_like_intervals(table):
        groups = [(1 + 3 * i, (2 + 3 * i, 3 + 3 * i)) for i in range((width - 1) // 3)]
        labels = [_label(names, 3 * i, i) for i in range(len(groups))]
    else:
        groups = [(1 + i, None) for i in range(width - 1)]
        labels = [_label(names, i, i) for i in range(width - 1)]
    if not 1 <= len(groups) <= 3:
        raise InteropError(f"{path}: {width - 1} value columns; expected 1 to 3 axes")
    out = []
    for (col, ci), label in zip(groups, labels):
        adev = table[:, col] / s
        if np.any(adev <= 0):
            raise InteropError(f"{path}: column {col + 1} has an Allan deviation <= 0")
        beyond = np.flatnonzero((adev > ALLAN_DEVIATION_DPS.high) | (taus > TAU_S.high)
                                | (adev < ALLAN_DEVIATION_DPS.low) | (taus < TAU_S.low))
        if beyond.size:  # squared in the fit: 1e308 became inf there, 1e-320 zero
            raise InteropError(f"{path}: row {int(beyond[0]) + 1}: {ALLAN_DEVIATION_DPS.name} "
                               f"must be {ALLAN_DEVIATION_DPS.low:g} to "
                               f"{ALLAN_DEVIATION_DPS.high:g} deg/s and tau {TAU_S.low:g} to "
                               f"{TAU_S.high:g} s")
        interval = (table[:, ci[0]] / s, table[:, ci[1]] / s) if ci else None
        out.append({"name": label, "adev": adev, "ci": interval, "kind": kind})
    return taus, out


def _looks_like_intervals(table: np.ndarray) -> bool:
    groups = (table.shape[1] - 1) // 3
    return all(
        np.all(table[:, 2 + 3 * i] <= table[:, 1 + 3 * i])
        and np.all(table[:, 1 + 3 * i] <= table[:, 3 + 3 * i])
        for i in range(groups)
    )


def _label(names: list[str], index: int, axis: int) -> str:
    if index < len(names):
        return names[index].removesuffix("_adev").removesuffix("_dps") or "xyz"[axis]
    return "xyz"[axis]


# -- Kalibr imu.yaml -----------------------------------------------------------------------


def kalibr_yaml(identification: Any, rate_hz: float, topic: str = "/imu0") -> str:
    """The gyroscope fields of a Kalibr imu.yaml (largest axis, rad/s units)."""
    N = max(a.N.value for a in identification.axes) * DEG
    K = max(a.K.value for a in identification.axes) * DEG
    return (
        "# Kalibr imu.yaml gyroscope fields, written by bmg160-emu identify\n"
        "# gyroscope_noise_density = N pi/180, gyroscope_random_walk = K pi/180 (largest axis);\n"
        "# Kalibr has no Gauss-Markov bias term: the identified B, T are not represented.\n"
        "# Accelerometer fields are placeholders: this file describes a gyroscope only.\n"
        f"rostopic: {topic}\n"
        f"update_rate: {rate_hz:g}  # Hz\n"
        f"gyroscope_noise_density: {N:.6e}  # rad/s/sqrt(Hz)\n"
        f"gyroscope_random_walk: {K:.6e}  # rad/s^2/sqrt(Hz)\n"
        "accelerometer_noise_density: 0.0  # not identified\n"
        "accelerometer_random_walk: 0.0  # not identified\n"
    )


def kalibr_profile_mapping(path: str | Path) -> dict[str, Any]:
    """N and K of a Kalibr imu.yaml on every axis (no Gauss-Markov term, bias 0), as the
    mapping a profile TOML file holds (``profile.load_profile`` checks it as it checks one)."""
    path = Path(path)
    values = _flat_yaml(path)
    try:
        N = float(values["gyroscope_noise_density"]) / DEG
        K = float(values["gyroscope_random_walk"]) / DEG
    except KeyError as exc:
        raise InteropError(f"{path}: no {exc.args[0]} field (a Kalibr imu.yaml)") from None
    except ValueError:
        raise InteropError(f"{path}: gyroscope fields must be numbers") from None
    if not (N > 0 and math.isfinite(N) and K >= 0 and math.isfinite(K)):
        raise InteropError(f"{path}: gyroscope_noise_density must be > 0 and "
                           "gyroscope_random_walk >= 0")
    axis = {"N": N, "B": 0.0, "T": 0.0, "K": K, "bias": 0.0}
    return {"name": path.stem, "description": f"from Kalibr {path.name}",
            "x": dict(axis), "y": dict(axis), "z": dict(axis)}


def _flat_yaml(path: Path) -> dict[str, str]:
    """key: value lines of a flat YAML file (Kalibr's imu.yaml needs no more)."""
    try:
        text = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise InteropError(f"cannot read {path}: {exc}") from None
    out = {}
    for line in text.splitlines():
        body = line.split("#", 1)[0].strip()
        if ":" in body:
            key, value = body.split(":", 1)
            out[key.strip()] = value.strip()
    return out


# -- MATLAB gyroparams ---------------------------------------------------------------------

_MATLAB_FIELDS = ("NoiseDensity", "BiasInstability", "RandomWalk", "ConstantBias")


def matlab_gyroparams(identification: Any) -> str:
    """A MATLAB gyroparams(...) call with per-axis values in rad/s units."""

    def vec(values: list[float]) -> str:
        return "[" + " ".join(f"{v:.6e}" for v in values) + "]"

    axes = identification.axes
    nd = [a.N.value * DEG for a in axes]
    bi = [a.readoffs["B_flicker"]["value"] * DEG for a in axes]
    rw = [a.K.value * DEG for a in axes]
    cb = [a.mean * DEG for a in axes]
    return (
        "% MATLAB gyroparams, written by bmg160-emu identify (rad/s units)\n"
        "% NoiseDensity = N pi/180; RandomWalk = K pi/180; ConstantBias = mean pi/180;\n"
        "% BiasInstability = min ADEV / 0.664 pi/180 (the flicker read-off, MATLAB's\n"
        "% definition), not the Gauss-Markov B of the bmg160-emu profile.\n"
        "params = gyroparams( ...\n"
        f"    'NoiseDensity', {vec(nd)}, ...  % (rad/s)/sqrt(Hz)\n"
        f"    'BiasInstability', {vec(bi)}, ...  % rad/s\n"
        f"    'RandomWalk', {vec(rw)}, ...  % (rad/s)*sqrt(Hz)\n"
        f"    'ConstantBias', {vec(cb)});  % rad/s\n"
    )


def matlab_profile_mapping(path: str | Path) -> dict[str, Any]:
    """A gyroparams block's N, K, bias, and BiasInstability as a 1/f bank, as the mapping a
    profile TOML file holds (``profile.load_profile`` checks it as it checks one)."""
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise InteropError(f"cannot read {path}: {exc}") from None
    found: dict[str, list[float]] = {}
    for name in _MATLAB_FIELDS:
        m = re.search(rf"'{name}'\s*,\s*(\[[^\]]*\]|[-+0-9.eE]+)", text)
        if m is None:
            continue
        try:
            numbers = [float(v) for v in re.split(r"[\s,;]+", m.group(1).strip("[]").strip()) if v]
        except ValueError:
            raise InteropError(f"{path}: {name} must be numbers, got {m.group(1)!r}") from None
        if len(numbers) not in (1, 3):
            raise InteropError(f"{path}: {name} needs 1 or 3 values, got {len(numbers)}")
        found[name] = numbers * 3 if len(numbers) == 1 else numbers
    if "NoiseDensity" not in found:
        raise InteropError(f"{path}: no 'NoiseDensity' in a gyroparams(...) block")
    out: dict[str, Any] = {"name": path.stem,
                           "description": f"from MATLAB gyroparams {path.name}"}
    for i, axis in enumerate(("x", "y", "z")):
        bank = flicker_poles(found.get("BiasInstability", [0.0] * 3)[i] / DEG)
        out[axis] = {
            "N": found["NoiseDensity"][i] / DEG, "B": 0.0, "T": 0.0,
            "K": found.get("RandomWalk", [0.0] * 3)[i] / DEG,
            "bias": found.get("ConstantBias", [0.0] * 3)[i] / DEG,
            "gm": [{"B": B, "T": T} for B, T in bank],
        }
    return out


def flicker_poles(B_flicker: float, span_s: tuple[float, float] = (1.0, 1000.0),
                  step: float = 4.0) -> tuple[tuple[float, float], ...]:
    """Gauss-Markov poles (B_i, T_i), T a factor `step` apart from span/10 to span*10,
    equal B_i, whose Allan deviation is flat at 0.664 B_flicker over the span (mean level)."""
    if B_flicker <= 0:
        return ()
    Ts = np.geomspace(span_s[0] / 10, span_s[1] * 10,
                      round(math.log(100 * span_s[1] / span_s[0], step)) + 1)
    tau = np.geomspace(span_s[0], span_s[1], 31)
    raw = np.sum([gauss_markov_avar_unit(tau, T) for T in Ts], axis=0)
    b2 = (FLICKER_ADEV_FACTOR * B_flicker) ** 2 / float(np.mean(raw))
    return tuple((math.sqrt(b2), float(T)) for T in Ts)
