"""Generate ``bmg160_params.h``: everything the firmware takes from a profile.

The firmware computes no coefficient itself: for every BW code (each with its ODR, spec
section 5.3) the header holds the per-axis coefficients of the project's discretization
(:func:`bmg160_emu.noise.discretization.axis_coefficients`), so the chip and the Python
engine run the same recursion. It also carries the sensitivities and the I2C address; the
register map is in the second generated header, ``bmg160_registers.h`` (register_table.py).
"""

from __future__ import annotations

import math
from pathlib import Path

from bmg160_emu.device.spec_choices import (
    RESERVED_RANGE_AS_CODE,
    SENSITIVITY_BINARY,
    VALID_ADDRESSES,
)
from bmg160_emu.noise.bandwidths import BANDWIDTHS
from bmg160_emu.noise.discretization import axis_coefficients, check_mode
from bmg160_emu.noise.profile import Profile, load_profile

# ODR of each BW code 0..7 (register spec section 5.3), from the model's table.
BW_ODR_HZ = tuple(float(odr) for odr, _ in BANDWIDTHS.values())
# LSB per deg/s of RANGE codes 0..7: the binary column 32768/FS of codes 0..4 (register spec
# section 5.1); reserved codes 5..7 produce data as for +-2000 deg/s (spec 4.8).
SENSITIVITY_LSB_PER_DPS = SENSITIVITY_BINARY + (SENSITIVITY_BINARY[RESERVED_RANGE_AS_CODE],) * 3
I2C_ADDRESSES = VALID_ADDRESSES  # SDO low / high (spec 2.1)


# Marsaglia and Tsang (2000), "The Ziggurat Method for Generating Random Variables", J. Stat.
# Software 5(8): 128 layers, right-most layer edge r and common layer area v.
ZIGGURAT_R = 3.442619855899
ZIGGURAT_V = 9.91256303526217e-3
ZIGGURAT_M = 2.0**31  # the layer test compares a signed 32-bit draw with kn


def ziggurat_tables() -> tuple[list[int], list[float], list[float]]:
    """kn (integer thresholds), wn (scale of a draw to x), fn (density at the layer edges)."""
    dn = tn = ZIGGURAT_R
    q = ZIGGURAT_V / math.exp(-0.5 * dn * dn)
    kn = [0] * 128
    wn = [0.0] * 128
    fn = [0.0] * 128
    kn[0] = int((dn / q) * ZIGGURAT_M)
    kn[1] = 0
    wn[0] = q / ZIGGURAT_M
    wn[127] = dn / ZIGGURAT_M
    fn[0] = 1.0
    fn[127] = math.exp(-0.5 * dn * dn)
    for i in range(126, 0, -1):
        dn = math.sqrt(-2.0 * math.log(ZIGGURAT_V / dn + math.exp(-0.5 * dn * dn)))
        kn[i + 1] = int((dn / tn) * ZIGGURAT_M)
        tn = dn
        fn[i] = math.exp(-0.5 * dn * dn)
        wn[i] = dn / ZIGGURAT_M
    return kn, wn, fn


def _c_float(value: float) -> str:
    """A C float literal (9 significant digits round-trip a float32; always with a point)."""
    text = f"{value:.9g}"
    if "." not in text and "e" not in text:
        text += ".0"
    return text + "f"


def _c_identifier_string(text: str) -> str:
    return '"' + "".join(c if c.isalnum() or c in "-_." else "_" for c in text) + '"'


def unapplied_output_note(profile: str | Path | Profile) -> str | None:
    """What the firmware leaves out of a profile with an ``[output]`` table (its sensor's
    filter and LSB), or None: the firmware has no filter model (docs/firmware.md), so its noise
    leaves unfiltered at every BW code; the build says so instead of dropping it unseen."""
    prof = load_profile(profile)
    if prof.output is None:
        return None
    return (f"note: profile {prof.name!r} carries its sensor's output stage ([output]); the "
            "firmware has no filter model and sends the noise unfiltered at every BW code")


def render_params_header(
    profile: str | Path | Profile = "paper",
    address: int = 0x68,
    mode: str = "physical",
    seed: int = 1,
) -> str:
    """The text of bmg160_params.h for a noise profile, I2C address, noise mode and seed."""
    if address not in I2C_ADDRESSES:
        raise ValueError(
            f"I2C address 0x{address:02X} is not a BMG160 address: use 0x68 (SDO low) or "
            "0x69 (SDO high)"
        )
    check_mode(mode)
    if not 0 <= int(seed) < 2**32:
        raise ValueError(f"seed must be an integer in 0..2**32-1, got {seed!r}")
    prof = load_profile(profile)
    for name, axis in zip("xyz", prof.axes):
        if len(axis.gauss_markov_terms) > 1 or (axis.gm and axis.B == 0):
            raise ValueError(
                f"profile {prof.name!r} axis {name} has {len(axis.gauss_markov_terms)} "
                "Gauss-Markov terms (a gm list): the firmware generates one (B, T); "
                "identify with --poles 1 for a firmware profile"
            )
        if axis.Q or axis.R:
            raise ValueError(
                f"profile {prof.name!r} axis {name} has Q or R: the firmware generates "
                "white, Gauss-Markov and random-walk terms only"
            )
        if axis.sine:
            raise ValueError(
                f"profile {prof.name!r} axis {name} has sine terms: the firmware generates "
                "white, Gauss-Markov and random-walk terms only"
            )
    tables: dict[str, list[list[float]]] = {k: [] for k in ("white", "alpha", "gm", "rw")}
    for odr in BW_ODR_HZ:
        coeffs = [axis_coefficients(axis, odr, mode) for axis in prof.axes]
        tables["white"].append([c.white_std for c in coeffs])
        tables["alpha"].append([c.alpha for c in coeffs])
        tables["gm"].append([c.gm_gain for c in coeffs])
        tables["rw"].append([c.rw_step for c in coeffs])

    zig_kn, zig_wn, zig_fn = ziggurat_tables()

    def table(name: str, key: str) -> str:
        rows = ",\n".join("\t{" + ", ".join(_c_float(v) for v in row) + "}" for row in tables[key])
        return f"static const float {name}[8][3] PROGMEM = {{\n{rows}\n}};"

    lines = [
        "/* Generated by `bmg160-emu firmware build`: do not edit. */",
        f"/* profile {prof.name!r}, noise mode {mode!r}, seed {seed}, address 0x{address:02X} */",
        "#ifndef BMG160_PARAMS_H",
        "#define BMG160_PARAMS_H",
        "#include <avr/pgmspace.h>",
        "#include <stdint.h>",
        "",
        f"#define BMG_I2C_ADDRESS 0x{address:02X}",
        f"#define BMG_PROFILE_NAME {_c_identifier_string(prof.name)}",
        f'#define BMG_NOISE_MODE_NAME "{mode}"',
        f"#define BMG_SEED {int(seed)}UL",
        "",
        "/* LSB per deg/s for RANGE codes 0..7 (spec 5.1, binary column). */",
        "static const float bmg_sensitivity_lsb_per_dps[8] PROGMEM = {"
        + ", ".join(_c_float(s) for s in SENSITIVITY_LSB_PER_DPS)
        + "};",
        "",
        "/* Noise recursion per BW code (ODR "
        + ", ".join(f"{o:g}" for o in BW_ODR_HZ)
        + " Hz) and axis X, Y, Z. */",
        table("bmg_noise_white", "white"),
        table("bmg_noise_alpha", "alpha"),
        table("bmg_noise_gm_drive", "gm"),
        table("bmg_noise_rw_step", "rw"),
        "static const float bmg_bias_dps[3] PROGMEM = {"
        + ", ".join(_c_float(a.bias) for a in prof.axes)
        + "};",
        "static const float bmg_gm_std_dps[3] PROGMEM = {"
        + ", ".join(_c_float(a.B if a.T > 0 else 0.0) for a in prof.axes)
        + "};",
        "",
        "/* Ziggurat tables, 128 layers (Marsaglia and Tsang 2000). */",
        f"#define BMG_ZIGGURAT_R {_c_float(ZIGGURAT_R)}",
        "static const uint32_t bmg_zig_kn[128] PROGMEM = {"
        + ", ".join(f"{k}UL" for k in zig_kn)
        + "};",
        "static const float bmg_zig_wn[128] PROGMEM = {"
        + ", ".join(_c_float(w) for w in zig_wn)
        + "};",
        "static const float bmg_zig_fn[128] PROGMEM = {"
        + ", ".join(_c_float(f) for f in zig_fn)
        + "};",
        "",
        "#endif",
        "",
    ]
    for key, rows in tables.items():
        for row in rows:
            if not all(math.isfinite(v) for v in row):
                raise ValueError(f"profile {prof.name!r} gives a non-finite {key} coefficient")
    return "\n".join(lines)


def write_params_header(path: str | Path, **kwargs) -> Path:
    """Write the header to path (a file, or a directory to hold bmg160_params.h)."""
    target = Path(path)
    if target.is_dir():
        target = target / "bmg160_params.h"
    target.parent.mkdir(parents=True, exist_ok=True)
    target.write_text(render_params_header(**kwargs), encoding="utf-8")
    return target
