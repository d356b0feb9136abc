"""Noise profiles: per-axis N, B, T, K, constant bias (and optional Q, R) as TOML data.

A profile is what identification of a gyroscope's output gives back and what the generator
takes. Built-in profiles live as TOML files in ``bmg160_emu/noise/profiles/``; users pass a
path to their own file with the same layout (one table per axis: ``[x]``, ``[y]``, ``[z]``).

Units are those of the data sheets and IEEE Std 952: N deg/s/sqrt(Hz), B deg/s (stationary
standard deviation of the first-order Gauss-Markov term), T s (its correlation time),
K deg/s/sqrt(s), bias deg/s, Q deg (angle quantization), R deg/s/s (rate ramp).

An axis may hold several Gauss-Markov terms (a real bias bends over more than one decade of
tau): ``gm = [{ B = 0.002, T = 5.0 }, { B = 0.001, T = 60.0 }]`` beside (or instead of) B and
T. B, T is one term; every entry of gm is one more, each with its own random stream. A
profile with B and T only (the paper's) is a one-term profile, as before. Periodic
components are IEEE 952 sinusoidal terms, ``sine = [{ A = 0.002, f = 1.3 }]`` (amplitude
deg/s, frequency Hz).

A profile may also describe the sensor's own output stage (``[output]``, OutputStage): the
low-pass its output went through (``order`` and ``corner_hz``, or ``bw_code``, a BW code of
the chip family, spec 5.3) and the step it was quantized to (``lsb_dps``). identify writes
it when it finds them; generate applies them; a chip ignores them (it has its own BW filter
and its own counts, docs/noise-engine.md).
"""

from __future__ import annotations

import functools
import math
import sys
from collections.abc import Mapping
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

from bmg160_emu.noise.bandwidths import BW_CODES
from bmg160_emu.noise.sensor_errors import SensorErrors

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover - Python 3.10
    import tomli as tomllib

AXES = ("x", "y", "z")
REQUIRED_FIELDS = ("N", "B", "T", "K", "bias")
OPTIONAL_FIELDS = ("Q", "R", "sigma_gyro", "sigma_K", "gm", "sine", "band", "slow_band", "response")
UNITS = {
    "N": "deg/s/sqrt(Hz)",
    "B": "deg/s",
    "T": "s",
    "K": "deg/s/sqrt(s)",
    "bias": "deg/s",
    "Q": "deg",
    "R": "deg/s^2",
    "sigma_gyro": "deg/s",
    "sigma_K": "1/sqrt(s)",
    "A": "deg/s",
    "f": "Hz",
    "corner_hz": "Hz",
    "lsb_dps": "deg/s",
    "rate_hz": "Hz",
    "width": "Hz",
    "response": "1",
}
GM_KEYS = ("B", "T")  # keys of one entry of an axis's gm list
SINE_KEYS = ("A", "f")  # keys of one entry of an axis's sine list: amplitude, frequency
BAND_KEYS = ("f", "width", "B")  # one resonator of a band: centre Hz, -3 dB width Hz, std deg/s
MAX_RESPONSE = 257  # coefficients of a measured output response (identify writes up to 65)
OUTPUT_KEYS = ("order", "corner_hz", "bw_code", "lsb_dps", "rate_hz")
MAX_FILTER_ORDER = 8  # the orders of a profile's own filter (identify tries 1..4)
# Largest value of each parameter (smallest T): far beyond any MEMS gyro (the BMG160's N is
# 0.014 deg/s/sqrt(Hz), its range 2000 deg/s), and small enough that every generated sample
# is finite at every ODR (N / sqrt(dt) at 2000 Hz stays below 1e4 deg/s; a random walk of
# K sqrt(t) over ten years stays below 1e7 deg/s). A value beyond is refused by name.
LIMITS = {"N": 100.0, "B": 1e3, "K": 1.0, "bias": 1e4, "Q": 1e3, "R": 1e3,
          "sigma_gyro": 1e3, "sigma_K": 1e6, "A": 1e3, "f": 1e6, "corner_hz": 1e6,
          "lsb_dps": 1e3, "rate_hz": 1e6, "width": 1e6}
T_RANGE_S = (1e-6, 1e13)  # a correlation time: below any sample period to identify's search edge


class ProfileError(ValueError):
    """A profile that cannot be used: unknown name, unreadable file, missing or bad field."""


@dataclass(frozen=True)
class AxisNoise:
    """Noise parameters of one gyroscope axis (units in the module docstring)."""

    N: float
    B: float
    T: float
    K: float
    bias: float
    Q: float = 0.0
    R: float = 0.0
    # Paper mode only (El Fatimi et al. 2023, eqs. 15-16): std of the measured record and the
    # PSD-fitted random-walk gain.
    sigma_gyro: float | None = None
    sigma_K: float | None = None
    # further Gauss-Markov terms (B_i deg/s, T_i s) beside B, T
    gm: tuple[tuple[float, float], ...] = ()
    # IEEE 952 sinusoidal terms (amplitude A deg/s, frequency f Hz)
    sine: tuple[tuple[float, float], ...] = ()
    # resonant bands (noise.resonant_bands): resonators (centre f Hz, -3 dB width Hz, std B
    # deg/s), sensing-element noise like the white term
    band: tuple[tuple[float, float, float], ...] = ()
    # bands of the slow spectrum (noise.slow_bands): resonators never inside the response
    slow_band: tuple[tuple[float, float, float], ...] = ()
    # the record's measured output response at [output] rate_hz (noise.output_response):
    # |H(f)|^2 = c0 + 2 sum c_k cos(2 pi k f / rate), c0 + 2 sum c_k = 1; () none
    response: tuple[float, ...] = ()

    def __post_init__(self) -> None:
        # lists from Python callers become tuples: the profile stays hashable and immutable
        object.__setattr__(self, "gm", tuple((float(B), float(T)) for B, T in self.gm))
        object.__setattr__(self, "sine", tuple((float(A), float(f)) for A, f in self.sine))
        object.__setattr__(self, "band", tuple((float(f), float(w), float(B))
                                               for f, w, B in self.band))
        object.__setattr__(self, "slow_band", tuple((float(f), float(w), float(B))
                                                    for f, w, B in self.slow_band))
        object.__setattr__(self, "response", tuple(float(c) for c in self.response))

    @property
    def resonators(self) -> tuple[tuple[float, float, float], ...]:
        """Every resonator the generator draws: the bands', then the slow bands'."""
        return self.band + self.slow_band

    @property
    def poles(self) -> tuple[tuple[float, float], ...]:
        """The same as gauss_markov_terms (the name thermal_fit.NoiseTerms looks for)."""
        return self.gauss_markov_terms

    @property
    def gauss_markov_terms(self) -> tuple[tuple[float, float], ...]:
        """Every Gauss-Markov term (B, T) the generator draws: B, T first, then gm."""
        first = ((self.B, self.T),) if self.B > 0 and self.T > 0 else ()
        return first + tuple((B, T) for B, T in self.gm if B > 0)


@dataclass(frozen=True)
class OutputStage:
    """The sensor's own output stage after its sensing element: the low-pass filter of its
    output (Butterworth ``order`` at ``corner_hz``, or the chip family's ``bw_code``), the
    step it quantizes the output to (``lsb_dps``) and the output data rate they were found
    at (``rate_hz``: generate's default rate); None: not there."""

    order: int | None = None
    corner_hz: float | None = None
    bw_code: int | None = None
    lsb_dps: float | None = None
    rate_hz: float | None = None

    @property
    def has_filter(self) -> bool:
        return self.corner_hz is not None or self.bw_code is not None

    def filter_text(self) -> str:
        if self.bw_code is not None:
            return f"BW code {self.bw_code}"
        if self.corner_hz is not None:
            return f"order {self.order} Butterworth at {self.corner_hz:.4g} Hz"
        return "no filter"

    def to_dict(self) -> dict[str, Any]:
        return {k: getattr(self, k) for k in OUTPUT_KEYS if getattr(self, k) is not None}


@dataclass(frozen=True)
class Profile:
    """A named set of per-axis noise parameters."""

    name: str
    x: AxisNoise
    y: AxisNoise
    z: AxisNoise
    description: str = ""
    # the unit's deterministic errors (sensor_errors.SensorErrors fields), checked on
    # loading; None: none
    errors: Mapping[str, Any] | None = None
    # the sensor's own output filter and quantization (generate applies them, a chip not)
    output: OutputStage | None = None

    @property
    def axes(self) -> tuple[AxisNoise, AxisNoise, AxisNoise]:
        return (self.x, self.y, self.z)

    def to_dict(self) -> dict[str, Any]:
        """The profile as the mapping a TOML file holds (None fields left out)."""
        out: dict[str, Any] = {"name": self.name, "description": self.description}
        for axis_name, axis in zip(AXES, self.axes):
            table = {k: v for k, v in asdict(axis).items()
                     if v is not None and k not in ("gm", "sine", "band", "slow_band", "response")}
            if axis.gm:
                table["gm"] = [{"B": B, "T": T} for B, T in axis.gm]
            if axis.sine:
                table["sine"] = [{"A": A, "f": f} for A, f in axis.sine]
            if axis.band:
                table["band"] = [{"f": f, "width": w, "B": B} for f, w, B in axis.band]
            if axis.slow_band:
                table["slow_band"] = [{"f": f, "width": w, "B": B} for f, w, B in axis.slow_band]
            if axis.response:
                table["response"] = list(axis.response)
            out[axis_name] = table
        if self.output is not None:
            out["output"] = self.output.to_dict()
        return out


# The package's own folder, not importlib.resources: that import (with tempfile, zipfile,
# shutil, lzma) was ~10 % of a chip's cold start (issue 26); the package is never zipped.
BUILTIN_FOLDER = Path(__file__).resolve().parent / "profiles"


@functools.lru_cache(maxsize=1)
def _builtin_names() -> tuple[str, ...]:
    folder = BUILTIN_FOLDER
    return tuple(sorted(p.name[:-5] for p in folder.iterdir() if p.name.endswith(".toml")))


def builtin_profile_names() -> list[str]:
    """Names of the profiles shipped inside the package."""
    return list(_builtin_names())


def load_profile(name_or_path: str | Path | Profile | Mapping[str, Any] = "paper") -> Profile:
    """Load a built-in profile by name, a user TOML file by path, or validate a mapping.

    A path ending in .yaml/.yml is read as a Kalibr imu.yaml, one ending in .m as a MATLAB
    gyroparams(...) block (interop.py has the mappings).

    Raises ProfileError (a ValueError) with a message naming what is wrong.
    """
    if isinstance(name_or_path, Profile):
        return name_or_path
    if isinstance(name_or_path, Mapping):
        return profile_from_mapping(name_or_path, origin="profile mapping")
    if not isinstance(name_or_path, (str, Path)):
        raise ProfileError(
            f"a noise profile is a name, a path or a Profile, not {type(name_or_path).__name__}"
        )
    text_name = str(name_or_path)
    builtins = builtin_profile_names()
    if isinstance(name_or_path, str) and text_name in builtins:
        return _builtin_profile(text_name)
    path = Path(name_or_path)
    if path.is_file() and path.suffix.lower() in (".yaml", ".yml", ".m"):
        # another tool's parameters (Kalibr imu.yaml, MATLAB gyroparams): interop.py
        from bmg160_emu.noise import interop

        try:
            if path.suffix.lower() == ".m":
                mapping = interop.matlab_profile_mapping(path)
            else:
                mapping = interop.kalibr_profile_mapping(path)
        except interop.InteropError as exc:
            raise ProfileError(str(exc)) from None
        return profile_from_mapping(mapping, origin=f"profile file {path}")
    if path.is_file():
        try:
            data = path.read_text(encoding="utf-8")
        except (OSError, UnicodeDecodeError) as exc:
            raise ProfileError(f"cannot read noise profile {path}: {exc}") from None
        return _parse(data, origin=f"profile file {path}", default_name=path.stem)
    raise ProfileError(
        f"unknown noise profile {text_name!r}: not a built-in profile "
        f"({', '.join(builtins)}) nor an existing TOML file"
    )


@functools.cache
def _builtin_profile(name: str) -> Profile:
    """Built-ins are parsed once (Profile is frozen, so sharing it is safe)."""
    data = (BUILTIN_FOLDER / f"{name}.toml").read_text(encoding="utf-8")
    return _parse(data, origin=f"built-in profile {name!r}", default_name=name)


def _parse(text: str, origin: str, default_name: str) -> Profile:
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ProfileError(f"{origin} is not valid TOML: {exc}") from None
    except RecursionError:
        raise ProfileError(f"{origin}: TOML nested too deeply") from None
    except ValueError as exc:  # an integer of more than 4300 digits
        raise ProfileError(f"{origin}: a number too long to read ({str(exc)[:60]})") from None
    data.setdefault("name", default_name)
    return profile_from_mapping(data, origin=origin)


def profile_from_mapping(data: Mapping[str, Any], origin: str = "profile") -> Profile:
    """Validate a mapping with tables x, y, z (the TOML layout) and build a Profile."""
    unknown = set(data) - {"name", "description", "errors", "output", *AXES}
    if unknown:
        raise ProfileError(f"{origin}: unknown top-level key(s) {sorted(unknown)}")
    axes = []
    for axis_name in AXES:
        table = data.get(axis_name)
        if not isinstance(table, Mapping):
            raise ProfileError(f"{origin}: missing table [{axis_name}] with N, B, T, K, bias")
        axes.append(_axis_from_mapping(table, f"{origin} [{axis_name}]"))
    name = data.get("name", "profile")
    description = data.get("description", "")
    if not isinstance(name, str) or not isinstance(description, str):
        raise ProfileError(f"{origin}: name and description must be strings")
    errors = data.get("errors")
    if errors is not None and not isinstance(errors, Mapping):
        raise ProfileError(f"{origin}: errors must be a table ([errors])")
    if errors is not None:  # the unit's error budget, checked here as every other table
        try:
            SensorErrors.from_dict(errors, f"{origin} [errors]")
        except ValueError as exc:
            raise ProfileError(str(exc)) from None
    output = data.get("output")
    return Profile(name, x=axes[0], y=axes[1], z=axes[2], description=description,
                   errors=None if errors is None else dict(errors),
                   output=None if output is None else output_stage(output, f"{origin} [output]"))


def output_stage(raw: Any, where: str = "[output]") -> OutputStage:
    """An [output] table checked: a filter as order with corner_hz, or bw_code; lsb_dps."""
    if isinstance(raw, OutputStage):
        return raw
    if not isinstance(raw, Mapping):
        raise ProfileError(f"{where}: output must be a table ([output])")
    unknown = set(raw) - set(OUTPUT_KEYS)
    if unknown:
        raise ProfileError(f"{where}: unknown field(s) {sorted(unknown)}; allowed: "
                           f"{', '.join(OUTPUT_KEYS)}")
    values: dict[str, Any] = {}
    for key in ("order", "bw_code"):
        if key in raw:
            value = raw[key]
            if isinstance(value, bool) or not isinstance(value, int):
                raise ProfileError(f"{where}: {key} must be a whole number, got {value!r}")
            values[key] = value
    if "bw_code" in values:
        if values["bw_code"] not in BW_CODES:
            raise ProfileError(f"{where}: bw_code must be 0..7 (register spec 5.3), got "
                               f"{values['bw_code']}")
        if "order" in raw or "corner_hz" in raw:
            raise ProfileError(f"{where}: give bw_code (the chip's filter) or order and "
                               "corner_hz, not both")
    if ("order" in raw) != ("corner_hz" in raw):
        raise ProfileError(f"{where}: a filter needs both order and corner_hz (Hz)")
    if "order" in values and not 1 <= values["order"] <= MAX_FILTER_ORDER:
        raise ProfileError(f"{where}: order must be 1..{MAX_FILTER_ORDER}, got {values['order']}")
    for key in ("corner_hz", "lsb_dps", "rate_hz"):
        if key in raw:
            value = _number(raw[key], key, where)
            if not value > 0:
                raise ProfileError(f"{where}: {key} must be positive ({UNITS[key]}), got {value}")
            values[key] = value
    return OutputStage(**values)


def _axis_from_mapping(table: Mapping[str, Any], where: str) -> AxisNoise:
    allowed = set(REQUIRED_FIELDS) | set(OPTIONAL_FIELDS)
    unknown = set(table) - allowed
    if unknown:
        raise ProfileError(
            f"{where}: unknown field(s) {sorted(unknown)}; allowed: {', '.join(sorted(allowed))}"
        )
    # with a gm list, B and T may be left out (every term in the list)
    required = [k for k in REQUIRED_FIELDS if not ("gm" in table and k in GM_KEYS)]
    missing = [k for k in required if k not in table]
    if missing:
        raise ProfileError(f"{where}: missing field(s) {', '.join(missing)}")
    values: dict[str, Any] = {"B": 0.0, "T": 0.0}
    for key, raw in table.items():
        if key == "gm":
            values["gm"] = _gm_terms(raw, where)
            continue
        if key == "sine":
            values["sine"] = _sine_terms(raw, where)
            continue
        if key in ("band", "slow_band"):
            values[key] = _band_terms(raw, where, key)
            continue
        if key == "response":
            values["response"] = _response(raw, where)
            continue
        values[key] = _number(raw, key, where)
    if values["T"] == 0 and values["B"] > 0:
        raise ProfileError(f"{where}: T must be positive when B > 0 (correlation time in s)")
    return AxisNoise(**values)


def _number(raw: Any, key: str, where: str) -> float:
    if isinstance(raw, bool) or not isinstance(raw, (int, float)):
        raise ProfileError(f"{where}: {key} must be a number ({UNITS[key]}), got {raw!r}")
    try:
        value = float(raw)
    except OverflowError:
        value = math.inf
    if not math.isfinite(value):
        raise ProfileError(f"{where}: {key} must be finite, got {value}")
    if key != "bias" and value < 0:
        raise ProfileError(f"{where}: {key} must not be negative, got {value} {UNITS[key]}")
    if key == "T":
        low, high = T_RANGE_S
        if value != 0 and not low <= value <= high:
            raise ProfileError(f"{where}: T must be within {low:g}..{high:g} s, got {value}")
    elif abs(value) > LIMITS[key]:
        raise ProfileError(f"{where}: {key} must be at most {LIMITS[key]:g} {UNITS[key]} in "
                           f"size (every sample stays finite), got {value:g}")
    return value


def _gm_terms(raw: Any, where: str) -> tuple[tuple[float, float], ...]:
    if not isinstance(raw, (list, tuple)):
        raise ProfileError(f"{where}: gm must be a list of {{ B = ..., T = ... }} tables")
    terms = []
    for i, entry in enumerate(raw):
        at = f"{where} gm[{i}]"
        if isinstance(entry, Mapping):
            if set(entry) != set(GM_KEYS):
                raise ProfileError(f"{at}: needs exactly B (deg/s) and T (s), got {sorted(entry)}")
            B, T = _number(entry["B"], "B", at), _number(entry["T"], "T", at)
        elif isinstance(entry, (list, tuple)) and len(entry) == 2:  # (B, T) pairs in Python
            B, T = _number(entry[0], "B", at), _number(entry[1], "T", at)
        else:
            raise ProfileError(f"{at}: a term is {{ B = ..., T = ... }}, got {entry!r}")
        if T == 0:
            raise ProfileError(f"{at}: T must be positive (correlation time in s)")
        terms.append((B, T))
    return tuple(terms)


def _sine_terms(raw: Any, where: str) -> tuple[tuple[float, float], ...]:
    if not isinstance(raw, (list, tuple)):
        raise ProfileError(f"{where}: sine must be a list of {{ A = ..., f = ... }} tables")
    terms = []
    for i, entry in enumerate(raw):
        at = f"{where} sine[{i}]"
        if isinstance(entry, Mapping):
            if set(entry) != set(SINE_KEYS):
                raise ProfileError(f"{at}: needs exactly A (deg/s) and f (Hz), got {sorted(entry)}")
            A, f = _number(entry["A"], "A", at), _number(entry["f"], "f", at)
        elif isinstance(entry, (list, tuple)) and len(entry) == 2:  # (A, f) pairs in Python
            A, f = _number(entry[0], "A", at), _number(entry[1], "f", at)
        else:
            raise ProfileError(f"{at}: a term is {{ A = ..., f = ... }}, got {entry!r}")
        if f == 0:
            raise ProfileError(f"{at}: f must be positive (frequency in Hz)")
        terms.append((A, f))
    return tuple(terms)


def _band_terms(raw: Any, where: str, key: str = "band"
                ) -> tuple[tuple[float, float, float], ...]:
    if not isinstance(raw, (list, tuple)):
        raise ProfileError(f"{where}: {key} must be a list of {{ f = ..., width = ..., B = ... }} "
                           "tables")
    terms = []
    for i, entry in enumerate(raw):
        at = f"{where} {key}[{i}]"
        if isinstance(entry, Mapping):
            if set(entry) != set(BAND_KEYS):
                raise ProfileError(f"{at}: needs exactly f (Hz), width (Hz) and B (deg/s), got "
                                   f"{sorted(entry)}")
            values = [entry[k] for k in BAND_KEYS]
        elif isinstance(entry, (list, tuple)) and len(entry) == 3:  # (f, width, B) in Python
            values = list(entry)
        else:
            raise ProfileError(f"{at}: a resonator is {{ f = ..., width = ..., B = ... }}, got "
                               f"{entry!r}")
        f = _number(values[0], "f", at)
        width = _number(values[1], "width", at)
        B = _number(values[2], "B", at)
        if not (f > 0 and width > 0):
            raise ProfileError(f"{at}: f and width must be positive (Hz), got {f:g}, {width:g}")
        terms.append((f, width, B))
    return tuple(terms)


def _response(raw: Any, where: str) -> tuple[float, ...]:
    """The measured output response's cosine coefficients: finite, c0 > 0, at DC 1."""
    if not isinstance(raw, (list, tuple)) or not 1 <= len(raw) <= MAX_RESPONSE:
        raise ProfileError(f"{where}: response must be a list of 1 to {MAX_RESPONSE} numbers "
                           "(identify --profile-out writes it)")
    values = []
    for i, item in enumerate(raw):
        if isinstance(item, bool) or not isinstance(item, (int, float)) or not math.isfinite(
                float(item)):
            raise ProfileError(f"{where}: response[{i}] must be a finite number, got {item!r}")
        values.append(float(item))
    dc = values[0] + 2.0 * sum(values[1:])
    if not values[0] > 0 or abs(dc - 1.0) > 1e-6:
        raise ProfileError(f"{where}: response must hold c0 > 0 with c0 + 2 (c1 + ...) = 1 (its "
                           f"gain at 0 Hz), got c0 = {values[0]:g}, sum {dc:g}")
    return tuple(values)
