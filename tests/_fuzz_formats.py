"""The fuzz suite's registry: a valid file of every format the project reads, mutations of it,
and each format's loader with the one error type it may raise (issue 12).

Shared by tests/test_fuzz_loaders.py (a modest, derandomised budget in CI) and tools/fuzz.py
(long campaigns). The invariant for every format: loading a mutated file either succeeds, with
a result that is usable (finite numbers where numbers come out), or raises the format's own
error; never another exception, and never a hang beyond ``TIME_LIMIT_S``.

Valid files are made with the project's own command line (``bmg160-emu generate``, ``record``,
``script --trace``, ``dump``), so the registry follows the formats as they are written.
"""

from __future__ import annotations

import contextlib
import functools
import io
import random
import re
import signal
import tempfile
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

TIME_LIMIT_S = 10.0  # one load; the slowest valid load here takes ~0.2 s

SCRIPT_TEXT = """\
# bring-up, as a driver does it
read CHIP_ID == 0x0F
write BGW_SOFTRESET 0xB6
advance 30ms
write RANGE 0x02
write BW 0x04
write INT_EN_0 0x80
rate 10 -5 2.5
advance 50ms
poll INT_STATUS_1 bit 7 == 1 timeout 20ms every 100us
read RANGE == 0x02 mask 0x07
burst RATE_X_LSB 6
dump
"""

SCENARIO_TEXT = """\
name = "fuzz seed"
duration_s = 20.0

[[motion]]
kind = "slew"
axis = [0, 0, 1]
angle_deg = 10.0
max_rate_dps = 5.0
max_accel_dps2 = 10.0
start_s = 1.0

[[motion]]
kind = "jitter"
amplitude_dps = [0.1, 0.1, 0.1]
frequency_hz = 3.0

[[motion]]
kind = "tumble"
initial_rate_dps = [1.0, 2.0, 3.0]
inertia_kg_m2 = [0.02, 0.03, 0.04]
start_s = 10.0

[[gyro]]
address = 0x68
seed_offset = 0

[[fault]]
kind = "stuck_axis"
axis = "x"
at_s = 2.0

[readout]
range_dps = 250
grid_s = 0.5
"""


class Hang(Exception):
    """A load that did not finish within TIME_LIMIT_S."""


@contextlib.contextmanager
def time_limit(seconds: float) -> Iterator[None]:
    """Raise :class:`Hang` in the main thread after ``seconds`` (SIGALRM)."""

    def expire(signum: int, frame: object) -> None:
        raise Hang(f"no result after {seconds:g} s")

    previous = signal.signal(signal.SIGALRM, expire)
    signal.setitimer(signal.ITIMER_REAL, seconds)
    try:
        yield
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, previous)


def _cli(*args: str) -> None:
    from bmg160_emu.cli import main

    with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()):
        status = main(list(args))
    if status != 0:
        raise RuntimeError(f"bmg160-emu {' '.join(args)} failed with {status}")


@functools.lru_cache(maxsize=1)
def seed_folder() -> Path:
    """Valid files of every format, written once per process by the project's own CLI."""
    folder = Path(tempfile.mkdtemp(prefix="bmg160-fuzz-seeds-"))
    (folder / "bringup.script").write_text(SCRIPT_TEXT)
    (folder / "scenario.toml").write_text(SCENARIO_TEXT)
    _cli("generate", "--profile", "paper", "--rate", "200", "--duration", "2s", "--seed", "1",
         "-o", str(folder / "noise.csv"))
    _cli("generate", "--profile", "paper", "--rate", "200", "--duration", "2s", "--seed", "1",
         "-o", str(folder / "noise.npy"))
    _cli("record", "--duration", "0.2s", "--rate", "200", "--seed", "2", "--true-rate", "1", "2",
         "3", "-o", str(folder / "recording.csv"))
    _cli("record", "--duration", "0.2s", "--rate", "200", "--seed", "2", "-o",
         str(folder / "recording.npz"))
    _cli("generate", "--profile", "paper", "--rate", "200", "--duration", "2s", "--seed", "1",
         "-o", str(folder / "noise.resd"))
    _cli("record", "--duration", "0.2s", "--rate", "200", "--seed", "2", "--true-rate", "1", "2",
         "3", "-o", str(folder / "recording.resd"))
    # the firmware's UART stream: a recorded capture (the AVR toolchain is not needed here)
    (folder / "stream.txt").write_bytes(
        (Path(__file__).parent / "data" / "firmware_capture.txt").read_bytes())
    _cli("script", str(folder / "bringup.script"), "--seed", "3", "-q", "--trace",
         str(folder / "session.jsonl"))
    from bmg160_emu.cli import main

    for fmt in ("i2cdump", "table", "json"):
        out = io.StringIO()
        with contextlib.redirect_stdout(out):
            main(["dump", "--format", fmt, "--seed", "4"])
        (folder / f"dump.{fmt}").write_text(out.getvalue())
    # a sensor's raw output as a logger keeps it (the shared ADIS16405 record's layout)
    np.savez(folder / "counts.npz",
             counts=np.random.default_rng(5).integers(-40, 40, (400, 3)).astype(np.int16),
             lsb_dps=np.float64(0.05), rate_hz=np.float64(100.0), axes=np.array(["x", "y", "z"]))
    from importlib.resources import files

    (folder / "profile.toml").write_text(
        files("bmg160_emu.noise").joinpath("profiles/paper.toml").read_text())
    return folder


# --------------------------------------------------------------------------- loaders


def _finite(values: Any, what: str) -> None:
    array = np.asarray(values, dtype=float)
    if not np.all(np.isfinite(array)):
        raise AssertionError(f"{what}: a loaded file gave non-finite numbers")


def load_script(path: Path) -> None:
    from bmg160_emu.session.script_language import parse_script, read_script

    parse_script(read_script(path), source=str(path))


def load_trace(path: Path) -> None:
    from bmg160_emu.io.trace import read_trace
    from bmg160_emu.session.decode import describe_transaction

    _header, records = read_trace(path)
    for record in records:  # what `bmg160-emu trace` prints for a person
        describe_transaction(record)


def load_dump(path: Path) -> None:
    from bmg160_emu.io.dump import read_dumps

    for dump in read_dumps(path):
        assert len(dump.values) == 64


def load_rate_file(path: Path) -> None:
    from bmg160_emu.io.rates import load_rate_record

    record = load_rate_record(path, rate_hz=None if path.suffix != ".npy" else 200.0)
    _finite(record.rate_dps, "rate record")


def load_replay(path: Path) -> None:
    from bmg160_emu.io.replay_data import load_replay_data

    data = load_replay_data(path)
    _finite(data.rate_dps, "replay data")


def load_recording(path: Path) -> None:
    from bmg160_emu.io.recording import read_recording

    rec = read_recording(path)
    _finite(rec.counts, "recording")


def load_scenario_file(path: Path) -> None:
    from bmg160_emu.adcs.scenarios import load_scenario

    scenario = load_scenario(path)
    t = np.linspace(0.0, min(scenario.duration_s, 30.0), 61)
    _finite(scenario.rate_dps(t), "scenario rates")


def load_profile_file(path: Path) -> None:
    from bmg160_emu.noise import NoiseGenerator
    from bmg160_emu.noise.profile import load_profile

    profile = load_profile(path)
    paper = all(a.sigma_gyro is not None and a.sigma_K is not None for a in profile.axes)
    for rate_hz in (100.0, 2000.0):
        for mode in ("physical", "paper") if paper else ("physical",):
            noise = NoiseGenerator(profile=profile, rate_hz=rate_hz, seed=1, mode=mode)
            _finite(noise.generate(2000), f"noise of a loaded profile at {rate_hz:g} Hz ({mode})")


def _errors(*names: str) -> Callable[[], tuple[type[BaseException], ...]]:
    def resolve() -> tuple[type[BaseException], ...]:
        import importlib

        out = []
        for name in names:
            module, _, attr = name.rpartition(".")
            out.append(getattr(importlib.import_module(module), attr))
        return tuple(out)

    return resolve


@dataclass(frozen=True)
class FuzzFormat:
    """One format: its seed file, how it is loaded, and the only error it may raise."""

    name: str
    seed: str  # file name in seed_folder()
    load: Callable[[Path], None]
    errors: Callable[[], tuple[type[BaseException], ...]]
    text: bool = True  # a text format: line and token mutations apply


FORMATS: tuple[FuzzFormat, ...] = (
    FuzzFormat("script", "bringup.script", load_script,
               _errors("bmg160_emu.session.script_language.ScriptSyntaxError")),
    FuzzFormat("trace", "session.jsonl", load_trace,
               _errors("bmg160_emu.io.trace.TraceFormatError")),
    FuzzFormat("dump-i2cdump", "dump.i2cdump", load_dump,
               _errors("bmg160_emu.io.dump.DumpFormatError")),
    FuzzFormat("dump-table", "dump.table", load_dump,
               _errors("bmg160_emu.io.dump.DumpFormatError")),
    FuzzFormat("dump-json", "dump.json", load_dump,
               _errors("bmg160_emu.io.dump.DumpFormatError")),
    FuzzFormat("rates-csv", "noise.csv", load_rate_file,
               _errors("bmg160_emu.io.rates.RateFileError")),
    FuzzFormat("rates-npy", "noise.npy", load_rate_file,
               _errors("bmg160_emu.io.rates.RateFileError"), text=False),
    FuzzFormat("replay-csv", "recording.csv", load_replay,
               _errors("bmg160_emu.io.rates.RateFileError")),
    FuzzFormat("replay-npz", "recording.npz", load_replay,
               _errors("bmg160_emu.io.rates.RateFileError"), text=False),
    FuzzFormat("recording-csv", "recording.csv", load_recording,
               _errors("bmg160_emu.io.rates.RateFileError")),
    FuzzFormat("recording-npz", "recording.npz", load_recording,
               _errors("bmg160_emu.io.rates.RateFileError"), text=False),
    FuzzFormat("rates-counts-npz", "counts.npz", load_rate_file,
               _errors("bmg160_emu.io.rates.RateFileError"), text=False),
    FuzzFormat("rates-resd", "noise.resd", load_rate_file,
               _errors("bmg160_emu.io.rates.RateFileError"), text=False),
    FuzzFormat("recording-resd", "recording.resd", load_rate_file,
               _errors("bmg160_emu.io.rates.RateFileError"), text=False),
    FuzzFormat("uart-stream", "stream.txt", load_rate_file,
               _errors("bmg160_emu.io.rates.RateFileError")),
    FuzzFormat("scenario", "scenario.toml", load_scenario_file,
               _errors("bmg160_emu.adcs.scenarios.ScenarioError")),
    FuzzFormat("profile", "profile.toml", load_profile_file,
               _errors("bmg160_emu.noise.profile.ProfileError")),
)
BY_NAME = {f.name: f for f in FORMATS}

# --------------------------------------------------------------------------- mutations

_NUMBER = re.compile(rb"-?\d+(?:\.\d+)?(?:[eE][+-]?\d+)?")
_VALUE = re.compile(rb"(?<=[=:])\s*[^,\n\]}]+")
REPLACEMENTS = (
    b"1e308", b"-1e308", b"1e309", b"inf", b"-inf", b"nan", b"NaN", b"Infinity", b"-1", b"0",
    b"9" * 5000, b"9223372036854775808", b"1.5", b"true", b"null", b'"abc"', b"[]", b"{}",
    b"[1, 2]", b"-0", b"0x7FFFFFFF", b"1e-320",
)


def _flip(data: bytes, rng: random.Random) -> bytes:
    if not data:
        return b"\x00"
    i = rng.randrange(len(data))
    return data[:i] + bytes([data[i] ^ (1 << rng.randrange(8))]) + data[i + 1 :]


def _truncate(data: bytes, rng: random.Random) -> bytes:
    return data[: rng.randrange(len(data) + 1)]


def _delete_span(data: bytes, rng: random.Random) -> bytes:
    if not data:
        return data
    i = rng.randrange(len(data))
    return data[:i] + data[i + rng.randrange(1, 64) :]


def _duplicate_span(data: bytes, rng: random.Random) -> bytes:
    if not data:
        return data
    i = rng.randrange(len(data))
    j = min(len(data), i + rng.randrange(1, 200))
    return data[:j] + data[i:j] + data[j:]


def _lines(data: bytes, rng: random.Random) -> bytes:
    lines = data.split(b"\n")
    i = rng.randrange(len(lines))
    choice = rng.randrange(3)
    if choice == 0:
        del lines[i]
    elif choice == 1:
        lines.insert(i, lines[rng.randrange(len(lines))])
    else:
        rng.shuffle(lines)
    return b"\n".join(lines)


def _number(data: bytes, rng: random.Random) -> bytes:
    matches = list(_NUMBER.finditer(data))
    if not matches:
        return _flip(data, rng)
    m = rng.choice(matches)
    return data[: m.start()] + rng.choice(REPLACEMENTS) + data[m.end() :]


def _value(data: bytes, rng: random.Random) -> bytes:
    matches = list(_VALUE.finditer(data))
    if not matches:
        return _number(data, rng)
    m = rng.choice(matches)
    return data[: m.start()] + b" " + rng.choice(REPLACEMENTS) + data[m.end() :]


def _nest(data: bytes, rng: random.Random) -> bytes:
    depth = rng.choice((100, 10_000, 100_000))
    i = rng.randrange(len(data) + 1)
    return data[:i] + b"[" * depth + b"1" + b"]" * depth + data[i:]


def _long_line(data: bytes, rng: random.Random) -> bytes:
    i = rng.randrange(len(data) + 1)
    filler = rng.choice((b"x", b"9", b"1,", b" "))
    return data[:i] + filler * (200_000 // len(filler)) + data[i:]


def _junk(data: bytes, rng: random.Random) -> bytes:
    i = rng.randrange(len(data) + 1)
    junk = bytes(rng.randrange(256) for _ in range(rng.randrange(1, 32)))
    return data[:i] + junk + data[i:]


def _empty(data: bytes, rng: random.Random) -> bytes:
    return rng.choice((b"", b"\n", b" ", b"#\n", b"\xff\xfe"))


def line_endings(data: bytes, rng: random.Random) -> bytes:
    """The same text with CR-only line endings, or a mix of LF, CRLF and CR (issue 24)."""
    lines = data.split(b"\n")
    if rng.random() < 0.5:
        return b"\r".join(lines)
    return b"".join(line + rng.choice((b"\n", b"\r\n", b"\r")) for line in lines)


def _declared(data: bytes, rng: random.Random) -> bytes:
    """An .npy header (a file's, or an NPZ member's, found by its magic) whose shape claims
    far more rows than follow (issue 24: 1e11 rows in a 4 kB file asked for 2.2 TiB)."""
    at = data.find(b"'shape': (")
    if at < 0:
        return _flip(data, rng)
    start = at + len(b"'shape': (")
    end = data.find(b",", start)
    rows = rng.choice((b"100000000000", b"9223372036854775807", b"0", b"1"))
    newline = data.find(b"\n", end)
    if end < 0 or newline < 0:
        return _flip(data, rng)
    header = data[end:newline]
    grow = len(rows) - (end - start)  # the header keeps its length: padding gives or takes
    padding = len(header) - len(header.rstrip(b" "))
    if grow > padding:
        return _flip(data, rng)
    header = header[: len(header) - grow] if grow > 0 else header + b" " * -grow
    return data[:start] + rows + header + data[newline:]


MUTATIONS: dict[str, Callable[[bytes, random.Random], bytes]] = {
    "flip": _flip, "truncate": _truncate, "delete": _delete_span, "duplicate": _duplicate_span,
    "lines": _lines, "number": _number, "value": _value, "nest": _nest, "long_line": _long_line,
    "junk": _junk, "empty": _empty, "line_endings": line_endings, "declared": _declared,
}
BINARY_MUTATIONS = ("flip", "truncate", "delete", "duplicate", "junk", "empty", "declared")


def mutate(fmt: FuzzFormat, seed: int, rounds: int | None = None) -> tuple[bytes, list[str]]:
    """A mutated copy of the format's seed file (reproducible from ``seed``) and the names of
    the mutations applied."""
    rng = random.Random(seed)
    data = (seed_folder() / fmt.seed).read_bytes()
    names = list(MUTATIONS) if fmt.text else list(BINARY_MUTATIONS)
    applied = []
    for _ in range(rounds or rng.randint(1, 3)):
        name = rng.choice(names)
        data = MUTATIONS[name](data, rng)
        applied.append(name)
    return data, applied


@dataclass
class Outcome:
    kind: str  # "loaded", "format error", "other exception", "hang"
    detail: str = ""


def try_load(fmt: FuzzFormat, data: bytes, folder: Path) -> Outcome:
    """Load ``data`` as ``fmt`` from a file with the seed's suffix and classify what happens."""
    path = folder / f"fuzz{Path(fmt.seed).suffix}"
    path.write_bytes(data)
    expected = fmt.errors()
    try:
        with time_limit(TIME_LIMIT_S):
            fmt.load(path)
    except Hang as exc:
        return Outcome("hang", str(exc))
    except expected as exc:
        lines = str(exc).strip().splitlines() or [""]
        # one line; a script lists each of its errors on a line of its own, each naming
        # the file, line and column
        if len(lines) > 1 and not all(line.startswith(str(path)) for line in lines[1:]):
            return Outcome("other exception", f"multi-line message: {str(exc)[:200]!r}")
        if not lines[0].strip():
            return Outcome("other exception", f"empty {type(exc).__name__} message")
        return Outcome("format error", lines[0][:200])
    except Exception as exc:  # noqa: BLE001 - this is what the fuzz suite is looking for
        return Outcome("other exception", f"{type(exc).__name__}: {exc}"[:200])
    return Outcome("loaded")
