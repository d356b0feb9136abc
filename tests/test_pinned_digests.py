"""Digests (sha256) of generated noise records and of register streams, pinned (issue 36).

The house moves (the noise product out of device/, files renamed, the GMWM merge out of the
identify command) must change no sample: the same seeds give the same bits. Each digest was
computed on the commit before those moves (7fd6320) and is compared here. Everything goes
through entry points those moves leave in place (the command line, ``make_chip``,
``FakeSMBus``, ``NoiseGenerator``), so this file itself did not change with them.

A digest changes only when what a user gets changes: a deliberate change of the noise
model, the filter or identification must re-pin the figures here and say why in its commit.
"""

from __future__ import annotations

import hashlib
import json
from pathlib import Path

import numpy as np
import pytest

import bmg160_emu
from bmg160_emu import FakeSMBus, NoiseGenerator, make_chip
from bmg160_emu.cli import main

PAPER_TOML = Path(bmg160_emu.__file__).parent / "noise" / "profiles" / "paper.toml"
# BW code -> ODR in Hz (register spec 5.3): how far one sample moves the clock
ODR_HZ = {0: 2000, 1: 2000, 2: 1000, 3: 400, 4: 200, 5: 100, 6: 200, 7: 100}
ADDRESS = 0x68
BW, RATE_X_LSB, FIFO_DATA = 0x10, 0x02, 0x3F  # register spec 4.9, 4.2, 4.31


def _digest(*arrays: np.ndarray | bytes) -> str:
    """sha256 (first 16 hex digits) of register bytes as they are, and of float records on
    a grid of 2**-30 deg/s (1e-9: far below any LSB, far above the 1e-17 deg/s at which a
    matrix product's summation order, which differs between BLAS kernels, shows)."""
    h = hashlib.sha256()
    for a in arrays:
        if isinstance(a, bytes):
            h.update(a)
        else:
            h.update(repr(a.shape).encode())
            h.update(np.rint(np.asarray(a, dtype=float) * 2.0**30).astype(np.int64).tobytes())
    return h.hexdigest()[:16]


def _profile(tmp_path: Path, name: str, output: str) -> Path:
    """The paper profile with an [output] table (what identify --profile-out writes)."""
    path = tmp_path / f"{name}.toml"
    path.write_text(PAPER_TOML.read_text(encoding="utf-8") + "\n[output]\n" + output + "\n")
    return path


# ------------------------------------------------------------------ generated records

GENERATED = {  # case -> sha256 prefix of the record (np.load of the .npy) on 7fd6320
    "butterworth3-lsb-seed1": "81815c8e149ff582",
    "butterworth3-lsb-seed2": "29f603df309c3abe",
    "butterworth3-lsb-seed3": "ebb11902fb6793c5",
    "bwcode3-lsb-seed4": "536c13e65ff2b22d",
    "bandwidth2-seed5": "a9c80e0e3c3b6d5b",
    "paper-mode-seed6": "e2401fdea8374b03",
    "raw-seed7": "d8a59779bcea94cf",
    "bandwidth6-over-output-seed8": "2a5c28f876d48611",
}


def _generate_cases(tmp_path: Path) -> dict[str, list[str]]:
    butterworth = _profile(tmp_path, "bw3", "order = 3\ncorner_hz = 31.5\nlsb_dps = 0.061\n"
                           "rate_hz = 200.0")
    code = _profile(tmp_path, "code3", "bw_code = 3\nlsb_dps = 0.0305")
    cases = {f"butterworth3-lsb-seed{s}": ["--profile", str(butterworth), "--seed", str(s)]
             for s in (1, 2, 3)}
    cases["bwcode3-lsb-seed4"] = ["--profile", str(code), "--seed", "4"]
    cases["bandwidth2-seed5"] = ["--profile", "paper", "--bandwidth", "2", "--seed", "5"]
    cases["paper-mode-seed6"] = ["--profile", "paper", "--mode", "paper", "--rate", "200",
                                 "--seed", "6"]
    cases["raw-seed7"] = ["--profile", str(butterworth), "--raw", "--seed", "7"]
    cases["bandwidth6-over-output-seed8"] = ["--profile", str(code), "--bandwidth", "6",
                                             "--seed", "8"]
    return cases


def test_generated_records_are_the_pinned_bits(tmp_path):
    # 25 s: 5000 samples at 200 Hz, 10,000 at 400 Hz: several of the engine's 2048-sample
    # chunks, so the chunked filter and the checkpoints are in the digest
    got = {}
    for case, options in _generate_cases(tmp_path).items():
        out = tmp_path / f"{case}.npy"
        assert main(["generate", "--duration", "25s", *options, "-o", str(out)]) == 0
        got[case] = _digest(np.load(out))
    assert got == GENERATED


LIBRARY = {  # NoiseGenerator alone, physical and paper mode, several seeds and rates
    "physical-paper-200-seed1": "f0d2252c5f41b388",
    "physical-datasheet_unit-2000-seed2": "ad42bf40f7a446e1",
    "paper-paper-200-seed3": "6ce294bd74553da5",
}


def test_the_generator_alone_gives_the_pinned_bits():
    got = {}
    for case in LIBRARY:
        mode, profile, rate, seed = case.split("-")
        gen = NoiseGenerator(profile, rate_hz=float(rate), seed=int(seed[4:]), mode=mode)
        first = gen.generate(3000)
        gen.set_rate(100.0)  # the realisation goes on at another ODR
        got[case] = _digest(first, gen.generate(1000))
    assert got == LIBRARY


# ------------------------------------------------------------------ register streams

STREAMS = {  # part-BW code -> sha256 prefix of the RATE bytes read after every sample
    "bmg160-bw0": "5676c5c4feccecc5",
    "bmg160-bw1": "430de98a65676c1c",
    "bmg160-bw2": "5a02ec90a7419629",
    "bmg160-bw3": "c2ee2ebb891ce186",
    "bmg160-bw4": "bb814be88ac06136",
    "bmg160-bw5": "c70c58550295efb0",
    "bmg160-bw6": "bc2adcd267de5423",
    "bmg160-bw7": "d8d6788711846dc5",
    "bmi055_gyro-bw0": "dcc924fd4062a4ef",
    "bmi055_gyro-bw1": "d12b4689f5942409",
    "bmi055_gyro-bw2": "a07605be26050618",
    "bmi055_gyro-bw3": "7b7c6c75518876a2",
    "bmi055_gyro-bw4": "7441625a64811f10",
    "bmi055_gyro-bw5": "175b74e4edf15e39",
    "bmi055_gyro-bw6": "5a8122d7a7654ecd",
    "bmi055_gyro-bw7": "aa5f326018b4658c",
    "bmi088_gyro-bw0": "dd6e60b15659b991",
    "bmi088_gyro-bw1": "265279ce9eb86803",
    "bmi088_gyro-bw2": "04e912fdf7f5b458",
    "bmi088_gyro-bw3": "0095937765bc537a",
    "bmi088_gyro-bw4": "ef90ffa905501f51",
    "bmi088_gyro-bw5": "e3a17baea4b144bb",
    "bmi088_gyro-bw6": "ddf6b92e10aedc2f",
    "bmi088_gyro-bw7": "1dd74f4f3b7373b0",
}


# the BMI055's and BMI088's data-sheet profiles hold the same numbers (one stream would be
# pinned twice): the BMI055 takes the profile fitted to a D455's published figures instead
PROFILES = {"bmg160": "paper", "bmi055_gyro": "bmi055_d455", "bmi088_gyro": "bmi088_datasheet"}


def _stream(part: str, code: int, samples: int = 700) -> bytes:
    """A polling driver: BW set, then advance one output period and read the 6 RATE bytes,
    with a moving true rate (the filter's transient and the noise through it)."""
    chip = make_chip(part, seed=11 + code, profile=PROFILES[part],
                     true_rate=lambda t: (30.0 * np.sin(7.0 * t), -5.0, 2.0 * t))
    bus = FakeSMBus(1, devices={ADDRESS: chip})
    bus.write_byte_data(ADDRESS, BW, code)
    out = bytearray()
    period = 1.0 / ODR_HZ[code]
    for _ in range(samples):
        chip.advance(period)
        out += bytes(bus.read_i2c_block_data(ADDRESS, RATE_X_LSB, 6))
    return bytes(out)


@pytest.mark.parametrize("case", sorted(STREAMS))
def test_register_streams_are_the_pinned_bytes(case):
    part, code = case.rsplit("-bw", 1)
    assert _digest(_stream(part, int(code))) == STREAMS[case]


WALKS = {  # the walks a driver takes through the data path, each pinned
    "bw-written-while-running": "d8629d6e777e6d08",
    "closed-loop-set_true_rate": "b5513067ba2c6cf7",
    "unit-errors-and-temperature": "20c8cf1110a5a1f7",
    "fifo-burst": "328b676ddfdbba8a",
}


def _walk(case: str) -> bytes:
    out = bytearray()
    if case == "bw-written-while-running":  # a BW write mid-stream: the filter carries on
        chip = make_chip("bmg160", seed=21, true_rate=(10.0, -20.0, 3.0))
        bus = FakeSMBus(1, devices={ADDRESS: chip})
        for code in (4, 2, 7, 0, 5):
            bus.write_byte_data(ADDRESS, BW, code)
            for _ in range(300):
                chip.advance(1.0 / ODR_HZ[code])
                out += bytes(bus.read_i2c_block_data(ADDRESS, RATE_X_LSB, 6))
    elif case == "closed-loop-set_true_rate":  # a simulator feeding the rate every sample
        chip = make_chip("bmi055_gyro", seed=22)
        bus = FakeSMBus(1, devices={ADDRESS: chip})
        bus.write_byte_data(ADDRESS, BW, 3)
        for k in range(800):
            chip.set_true_rate((0.01 * k, -0.5 * np.cos(0.02 * k), 4.0))
            chip.advance(1.0 / 400)
            out += bytes(bus.read_i2c_block_data(ADDRESS, RATE_X_LSB, 6))
    elif case == "unit-errors-and-temperature":  # the error budget before the filter
        chip = make_chip("bmg160", seed=23, profile="datasheet_unit",
                         temperature_c=lambda t: 20.0 + 3.0 * t, true_rate=(1.0, 2.0, 3.0))
        bus = FakeSMBus(1, devices={ADDRESS: chip})
        bus.write_byte_data(ADDRESS, BW, 5)
        for _ in range(600):
            chip.advance(1.0 / 100)
            out += bytes(bus.read_i2c_block_data(ADDRESS, RATE_X_LSB, 6))
    elif case == "fifo-burst":  # FIFO stream mode, read in bursts of 5 frames (30 bytes)
        chip = make_chip("bmg160", seed=24, true_rate=lambda t: (t, -t, 0.5))
        bus = FakeSMBus(1, devices={ADDRESS: chip})
        bus.write_byte_data(ADDRESS, BW, 4)
        bus.write_byte_data(ADDRESS, 0x3E, 0x80)  # FIFO_CONFIG_1: stream mode, all axes
        for _ in range(120):
            chip.advance(5 / 200)
            out += bytes(bus.read_i2c_block_data(ADDRESS, FIFO_DATA, 30))
    return bytes(out)


@pytest.mark.parametrize("case", sorted(WALKS))
def test_the_data_path_walks_are_the_pinned_bytes(case):
    assert _digest(_walk(case)) == WALKS[case]


# ------------------------------------------------------------------ identification

IDENTIFIED = {  # identify --json of a generated record, Allan fit and GMWM: the figures
    # (issue 37 added the keys output_response and bands, null and [] on this white record,
    # and fit.selection.asked, false; without them the digests are the house's
    # 4b79499ca518d8f6 and e8ffbecaf06ca11f; the octave ADEV as sums of m samples and the
    # PSD's power summed in another order (issue 37's speed) moved the Allan fit's numbers
    # by at most 9e-6 relative, a Gauss-Markov T of 60.1994 s to 60.1999 s in a candidate
    # the AICc did not keep: it was 7fd645bb36f395a5; GMWM's figures moved by 1e-14)
    "allan": "56b7e943a763279b",
    "gmwm": "fb6b2cf47d195c92",
}


def _rounded(value: object) -> object:
    """The report with every number to 9 significant digits (as above: not the last bits)."""
    if isinstance(value, float):
        return float(f"{value:.9g}")
    if isinstance(value, dict):
        return {k: _rounded(v) for k, v in value.items()}
    if isinstance(value, list):
        return [_rounded(v) for v in value]
    return value


def _figures(report: dict) -> str:
    """What identify found on every axis (the report's other fields name the file)."""
    return json.dumps(_rounded(report["axes"]), sort_keys=True)


@pytest.mark.parametrize("method", sorted(IDENTIFIED))
def test_identification_of_a_generated_record_is_pinned(tmp_path, capsys, method):
    record = tmp_path / "r.npy"
    assert main(["generate", "--profile", "paper", "--rate", "200", "--duration", "10min",
                 "--seed", "31", "-o", str(record)]) == 0
    capsys.readouterr()
    assert main(["identify", str(record), "--rate", "200", "--method", method, "--json"]) == 0
    report = json.loads(capsys.readouterr().out)
    assert hashlib.sha256(_figures(report).encode()).hexdigest()[:16] == IDENTIFIED[method]
