"""The command line's fuzz harness (issue 24): every input format the CLI reads and every
numeric option, run through ``bmg160_emu.cli.main`` as a person would run them.

Shared by tests/test_fuzz_cli.py (a fixed-seed budget in CI) and ``tools/fuzz.py --cli``
(long campaigns). The invariant for every run: exit 0, or exit 1 or 2 with one error line on
stderr; never a traceback, never a numpy RuntimeWarning on stderr, never a hang beyond
``TIME_LIMIT_S`` (in-process: SIGALRM; ``run_subprocess`` checks a hang the hard way).

Files: the valid files of tests/_fuzz_formats.py (written by the project's own CLI) and a few
more (Kalibr and MATLAB profiles, a thermal CSV, an Allan deviation curve, a stand-in TOML, a
dynamics table, a true-rate file), each mutated by the format mutations, by line-ending
rewrites (CR only, mixed) and, for the array formats, by declared-size attacks (an .npy
header claiming 1e11 rows, NPZ columns that are empty, one row, 0-D or 3-D, a replay span of
2e8 s).
"""

from __future__ import annotations

import contextlib
import functools
import io
import os
import random
import subprocess
import sys
import warnings
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from _fuzz_formats import Hang, _cli, line_endings, mutate, seed_folder, time_limit

TIME_LIMIT_S = 20.0  # one CLI run; the slowest valid run here (identify) takes ~2 s

# Values for every numeric option (issue 24): not finite, zero, negative, far too large,
# integers past 64 bits, and text that float() or int() half-accepts.
BAD_NUMBERS = ("nan", "NaN", "inf", "-inf", "+inf", "0", "-0", "-1", "-200", "1e308",
               "-1e308", "1e309", "1e23", "1e-320", str(2**63), str(2**64), "9" * 400, "1e9d",
               "0x10", "1_000", "", " ", "1.5", "abc")


@dataclass(frozen=True)
class CliFormat:
    """One input format as the CLI reads it: its seed file and the command lines that read
    it (``{}`` stands for the file; ``{tmp}`` for a scratch folder)."""

    name: str
    seed: str
    commands: tuple[tuple[str, ...], ...]
    text: bool = True


SCRIPT = "-q", "--seed", "1"
CLI_FORMATS: tuple[CliFormat, ...] = (
    CliFormat("script", "bringup.script", (("script", "{}", *SCRIPT),
                                           ("dump", "--after", "{}", "--seed", "1"))),
    CliFormat("trace", "session.jsonl", (("trace", "{}"), ("trace", "--replay", "{}"))),
    CliFormat("dump-i2cdump", "dump.i2cdump", (("diff", "{}", "{seeds}/dump.json"),
                                               ("dump", "--device", "{}@0x10", "--seed", "1"))),
    CliFormat("dump-table", "dump.table", (("diff", "{seeds}/dump.json", "{}"),)),
    CliFormat("dump-json", "dump.json", (("diff", "{}", "{}"),)),
    CliFormat("standin-toml", "standin.toml", (("dump", "--device", "{}@0x10", "--seed", "1"),)),
    CliFormat("rates-csv", "long/noise.csv", (("identify", "{}", "--poles", "1"),)),
    CliFormat("rates-npy", "long/noise.npy", (("identify", "{}", "--rate", "200", "--poles", "1"),),
              text=False),
    CliFormat("rates-resd", "long/noise.resd", (("identify", "{}", "--poles", "1"),), text=False),
    CliFormat("uart-stream", "stream.txt", (("identify", "{}", "--poles", "1"),)),
    CliFormat("recording-csv", "long/recording.csv",
              (("replay", "{}", "--script", "{seeds}/short.script", "--seed", "1"),
               ("replay", "{}", "--seed", "1", "-o", "{tmp}/out.npz"),
               ("identify", "{}", "--poles", "1"))),
    CliFormat("recording-npz", "long/recording.npz",
              (("replay", "{}", "--script", "{seeds}/short.script", "--seed", "1"),
               ("identify", "{}", "--poles", "1")), text=False),
    CliFormat("recording-resd", "long/recording.resd", (("identify", "{}", "--poles", "1"),),
              text=False),
    CliFormat("scenario-mc", "mc.toml", (("montecarlo", "{}", "--runs", "1", "--scheduler",
                                          "sync", "--no-progress"),)),
    CliFormat("scenario", "scenario.toml",
              (("record", "--truth", "{}", "--duration", "0.05s", "--seed", "1", "-o",
                "{tmp}/out.csv"),
               ("record", "--truth", "{}", "--seed", "1", "--rate", "100", "-o", "{tmp}/out.npz"))),
    CliFormat("dynamics-table", "table/dynamics_table.csv",
              (("record", "--truth", "{seeds}/table/table.toml", "--duration", "0.05s",
                "--seed", "1", "-o", "{tmp}/out.csv"),)),
    CliFormat("profile-toml", "profile.toml", (("generate", "--profile", "{}", "--duration",
                                                "0.5s", "--rate", "200", "--seed", "1", "-o",
                                                "{tmp}/out.npy"),
                                               ("dump", "--profile", "{}", "--seed", "1"))),
    CliFormat("profile-kalibr", "imu.yaml", (("generate", "--profile", "{}", "--duration",
                                              "0.5s", "--rate", "200", "--seed", "1", "-o",
                                              "{tmp}/out.npy"),)),
    CliFormat("profile-matlab", "gyro.m", (("generate", "--profile", "{}", "--duration",
                                            "0.5s", "--rate", "200", "--seed", "1", "-o",
                                            "{tmp}/out.npy"),)),
    CliFormat("thermal-csv", "thermal.csv", (("thermal", "{}", "--block", "10s"),)),
    CliFormat("adev-curve", "adev.csv", (("identify", "--curve", "{}", "--rate", "200",
                                          "--duration", "1h"),)),
)

SHORT_SCRIPT = "advance 2ms\nread CHIP_ID == 0x0F\nburst RATE_X_LSB 6\n"
TABLE_TOML = ('duration_s = 2.0\n[[motion]]\nkind = "table"\nfile = "dynamics_table.csv"\n'
              'units = "rad/s"\ninterpolation = "linear"\n')
MATLAB_TEXT = ("params = gyroparams('NoiseDensity', [3.1e-4 3.2e-4 3.0e-4], "
               "'RandomWalk', 1.9e-6, 'BiasInstability', [1e-5 2e-5 3e-5], "
               "'ConstantBias', [0 0 0]);\n")


@functools.lru_cache(maxsize=1)
def cli_seed_folder() -> Path:
    """The seeds of tests/_fuzz_formats.py and the files only the CLI reads."""
    folder = seed_folder()
    repo = Path(__file__).resolve().parents[1]
    (folder / "short.script").write_text(SHORT_SCRIPT)
    (folder / "imu.yaml").write_bytes((repo / "examples/profiles/imu.yaml").read_bytes())
    (folder / "gyro.m").write_text(MATLAB_TEXT)
    (folder / "standin.toml").write_bytes(
        (repo / "bmg160_emu/device/standins/bmm150.toml").read_bytes())
    (folder / "table").mkdir(exist_ok=True)
    (folder / "table/dynamics_table.csv").write_bytes(
        (repo / "examples/scenarios/dynamics_table.csv").read_bytes())
    (folder / "table/table.toml").write_text(TABLE_TOML)
    # a thermal run: 10 min at 10 Hz, bias 0.01 deg/s/K, the die warming by 20 K
    rng = np.random.default_rng(7)
    t = np.arange(6000) / 10.0
    temp = 20.0 + 20.0 * t / t[-1]
    rates = 0.01 * (temp[:, None] - 30.0) + 0.02 * rng.standard_normal((t.size, 3))
    lines = ["time_s,x_dps,y_dps,z_dps,temperature_c"]
    lines += [f"{a:.1f},{b:.5f},{c:.5f},{d:.5f},{e:.3f}" for a, (b, c, d), e in zip(t, rates, temp)]
    (folder / "thermal.csv").write_text("\n".join(lines) + "\n")
    # an Allan deviation curve: white noise N = 0.01 deg/s/sqrt(Hz) at octave intervals
    tau = 0.005 * 2.0 ** np.arange(14)
    adev = 0.01 / np.sqrt(tau)
    (folder / "adev.csv").write_text(
        "tau_s,x_dps,y_dps,z_dps\n" + "".join(f"{a:g},{b:g},{b:g},{b:g}\n" for a, b in
                                              zip(tau, adev)))
    (folder / "rate.txt").write_text("1 2 3\n")
    # identify needs 5 s of samples: 6 s at 200 Hz, as generate and record write them
    long = folder / "long"
    long.mkdir(exist_ok=True)
    for suffix in (".csv", ".npy", ".resd"):
        _cli("generate", "--profile", "paper", "--rate", "200", "--duration", "6s", "--seed",
             "1", "-o", str(long / f"noise{suffix}"))
    for suffix in (".csv", ".npz", ".resd"):
        _cli("record", "--duration", "6s", "--rate", "200", "--seed", "2", "--true-rate", "1",
             "2", "3", "-o", str(long / f"recording{suffix}"))
    (folder / "mc.toml").write_bytes((repo / "examples/scenarios/rest.toml").read_bytes())
    # the numeric options' scenario: 3 s, so that a valid --runs 16 (0x10) takes seconds
    (folder / "mc-short.toml").write_text('duration_s = 3.0\n[[motion]]\nkind = "rest"\n')
    return folder


# ---------------------------------------------------------------------------- mutations


def _npy_bytes(array: np.ndarray) -> bytes:
    out = io.BytesIO()
    np.save(out, array)
    return out.getvalue()


def declared_size(name: str, data: bytes, rng: random.Random) -> bytes:
    """A file of an array format whose declared sizes lie, or whose columns have the wrong
    shape (issue 24's first class)."""
    if name == "rates-npy":
        choice = rng.randrange(4)
        if choice == 0:  # the header claims 1e11 rows of 3 float64 (2.2 TiB)
            return _huge_npy()
        return _npy_bytes([np.empty((0, 3)), np.zeros(()), np.zeros((2, 3, 4)),
                           np.zeros((1, 3))][choice])
    if name == "recording-npz":
        with np.load(io.BytesIO(data)) as npz:
            columns = {key: npz[key] for key in npz.files}
        key = rng.choice(sorted(columns))
        column = np.atleast_1d(columns[key])
        columns[key] = rng.choice([np.empty(0), np.zeros(()), np.zeros((2, 3, 4)), column[:1],
                                   np.full(column.shape, np.nan) if column.dtype.kind == "f"
                                   else column[:0]])
        if key == "t_s" and rng.random() < 0.5:  # a replay span of 2e8 s in two samples
            columns = {k: v[:2] for k, v in columns.items() if np.ndim(v)}
            columns["t_s"] = np.array([0.0, 2e8])
        out = io.BytesIO()
        np.savez(out, **columns)
        return out.getvalue()
    if name == "recording-csv":  # a replay span of 2e8 s; or evenly spaced, days long
        lines = data.split(b"\n")
        rows = [i for i, line in enumerate(lines) if line[:1].isdigit()]
        if rows and rng.random() < 0.5:
            step = rng.choice((100, 5000))
            for k, i in enumerate(rows):
                cells = lines[i].split(b",")
                lines[i] = b",".join([str(k * step).encode(), *cells[1:]])
        elif rows:
            last = lines[rows[-1]].split(b",")
            last[0] = b"200000000"
            lines[rows[-1]] = b",".join(last)
        return b"\n".join(lines)
    return data


def _temperatures(data: bytes, rng: random.Random) -> bytes:
    """The thermal CSV with its temperature column as plateaus (fewer distinct values than a
    cubic needs), a constant, or one absurd value."""
    lines = data.split(b"\n")
    rows = [i for i, line in enumerate(lines) if line[:1].isdigit()]
    choice = rng.randrange(3)
    for k, i in enumerate(rows):
        cells = lines[i].split(b",")
        if choice == 0:
            cells[-1] = b"20" if k < len(rows) // 2 else b"40"
        elif choice == 1:
            cells[-1] = b"25"
        elif k == len(rows) // 3:
            cells[-1] = rng.choice((b"1e12", b"-300", b"1e308"))
        lines[i] = b",".join(cells)
    return b"\n".join(lines)


def _huge_npy() -> bytes:
    header = "{'descr': '<f8', 'fortran_order': False, 'shape': (100000000000, 3), }"
    header += " " * (63 - (len(header) + 10) % 64) + "\n"
    return b"\x93NUMPY\x01\x00" + len(header).to_bytes(2, "little") + header.encode() + \
        b"\x00" * 4096


def mutated(fmt: CliFormat, seed: int) -> tuple[bytes, str]:
    """A mutated copy of the format's seed (reproducible from ``seed``) and what was done."""
    rng = random.Random(seed)
    data = (cli_seed_folder() / fmt.seed).read_bytes()
    kind = rng.random()
    if fmt.text and kind < 0.15:
        return line_endings(data, rng), "line endings"
    if not fmt.text and kind < 0.3 and fmt.name in ("rates-npy", "recording-npz"):
        return declared_size(fmt.name, data, rng), "declared size"
    if fmt.name == "recording-csv" and kind < 0.2:
        return declared_size(fmt.name, data, rng), "replay span"
    if fmt.name == "thermal-csv" and kind < 0.2:  # temperatures a fit cannot use
        return _temperatures(data, rng), "temperatures"
    from _fuzz_formats import FuzzFormat

    proxy = FuzzFormat(fmt.name, fmt.seed, lambda path: None, lambda: (), fmt.text)
    out, applied = mutate(proxy, seed)
    return out, "+".join(applied)


# ---------------------------------------------------------------------------- running


@dataclass
class Outcome:
    kind: str  # "ok", "error", "traceback", "hang", "bad exit", "bad message", "warning"
    status: int | None = None
    detail: str = ""

    @property
    def broken(self) -> bool:
        return self.kind not in ("ok", "error")


def classify(status: int | None, stderr: str) -> Outcome:
    """Exit 0, or 1/2 with exactly one error line; anything else breaks the invariant."""
    if "Traceback" in stderr:
        return Outcome("traceback", status, stderr.strip().splitlines()[-1][:300])
    if "Warning" in stderr:
        line = next(x for x in stderr.splitlines() if "Warning" in x)
        return Outcome("warning", status, line[:300])
    if status == 0:
        return Outcome("ok", 0)
    if status == 1 and (stderr.startswith("divergence at ") or not stderr.strip()):
        return Outcome("ok", 1)  # a finding, not an error: trace --replay's report, diff's
    if status not in (1, 2):
        return Outcome("bad exit", status, stderr.strip()[-300:])
    lines = [x for x in stderr.strip().splitlines() if x.strip()]
    if not lines:
        return Outcome("bad message", status, "no message on stderr")
    if lines[0].startswith("usage:"):  # argparse: the usage, then one error line
        lines = [x for x in lines if x.startswith("bmg160-emu")]
    errors = [x for x in lines if ": error:" in x or "failed" in x.lower()]
    if len(errors) != 1:
        return Outcome("bad message", status, " | ".join(lines)[:300])
    return Outcome("error", status, errors[0][:300])


def run_in_process(argv: list[str], limit_s: float = TIME_LIMIT_S) -> Outcome:
    """``bmg160-emu ARGV`` through ``cli.main`` in this process, classified."""
    from bmg160_emu.cli import main

    out, err = io.StringIO(), io.StringIO()
    status: int | None = None
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err), \
                    time_limit(limit_s):
                status = main(argv)
        except SystemExit as exc:
            status = exc.code if isinstance(exc.code, int) else (0 if exc.code is None else 1)
            if isinstance(exc.code, str):
                err.write(exc.code + "\n")
        except Hang as exc:
            return Outcome("hang", None, str(exc))
        except BaseException as exc:  # noqa: BLE001 - what the harness looks for
            return Outcome("traceback", None, f"{type(exc).__name__}: {exc}"[:300])
    for w in caught:
        if issubclass(w.category, RuntimeWarning):
            return Outcome("warning", status, f"{w.category.__name__}: {w.message} "
                                              f"({Path(w.filename).name}:{w.lineno})"[:300])
    return classify(status, err.getvalue())


def run_subprocess(argv: list[str], limit_s: float = TIME_LIMIT_S) -> Outcome:
    """The same in a child process, killed after ``limit_s``: a hang no signal handler in the
    process can hide."""
    env = dict(os.environ, PYTHONPATH=str(Path(__file__).resolve().parents[1]))
    try:
        proc = subprocess.run([sys.executable, "-m", "bmg160_emu", *argv], capture_output=True, check=False,
                              text=True, timeout=limit_s, env=env, stdin=subprocess.DEVNULL)
    except subprocess.TimeoutExpired:
        return Outcome("hang", None, f"no exit after {limit_s:g} s")
    return classify(proc.returncode, proc.stderr)


def expand(command: tuple[str, ...], path: Path, tmp: Path) -> list[str]:
    seeds = str(cli_seed_folder())
    return [a.replace("{}", str(path)).replace("{seeds}", seeds).replace("{tmp}", str(tmp))
            for a in command]


def fuzz_format(fmt: CliFormat, seed: int, tmp: Path,
                run: Callable[[list[str]], Outcome] = run_in_process) -> tuple[str, Outcome]:
    """One mutated file of ``fmt`` read by one of its commands (chosen by ``seed``)."""
    data, applied = mutated(fmt, seed)
    seed_name = Path(fmt.seed).name
    path = tmp / seed_name
    if fmt.name == "dynamics-table":
        path = tmp / "table" / seed_name
        path.parent.mkdir(exist_ok=True)
        (path.parent / "table.toml").write_text(TABLE_TOML)
    path.write_bytes(data)
    command = fmt.commands[seed % len(fmt.commands)]
    if fmt.name == "dynamics-table":
        command = tuple(a.replace("{seeds}/table", str(path.parent)) for a in command)
    argv = expand(command, path, tmp)
    return f"{applied}: bmg160-emu {' '.join(argv)}", run(argv)


# ---------------------------------------------------------------------------- numeric options

# Every numeric option, each with a command line around it that is valid otherwise and cheap
# (``{v}`` is the value under test). The list is checked against the parsers in
# tests/test_fuzz_cli.py, so an option added later without an entry here fails CI.
NUMERIC_OPTIONS: dict[str, tuple[str, ...]] = {
    "generate --rate": ("generate", "--duration", "0.2s", "--seed", "1", "--rate", "{v}", "-o",
                        "{tmp}/o.npy"),
    "generate --duration": ("generate", "--rate", "200", "--seed", "1", "--duration", "{v}",
                            "-o", "{tmp}/o.npy"),
    "generate --seed": ("generate", "--duration", "0.2s", "--rate", "200", "--seed", "{v}", "-o",
                        "{tmp}/o.npy"),
    "generate --bandwidth": ("generate", "--duration", "0.2s", "--rate", "200", "--seed", "1",
                             "--bandwidth", "{v}", "-o", "{tmp}/o.npy"),
    "record --duration": ("record", "--seed", "1", "--rate", "100", "--duration", "{v}", "-o",
                          "{tmp}/o.csv"),
    "record --rate": ("record", "--seed", "1", "--duration", "0.05s", "--rate", "{v}", "-o",
                      "{tmp}/o.csv"),
    "record --true-rate": ("record", "--seed", "1", "--duration", "0.05s", "--true-rate", "1",
                           "{v}", "3", "-o", "{tmp}/o.csv"),
    "record --temperature": ("record", "--seed", "1", "--duration", "0.05s", "--temperature",
                             "{v}", "-o", "{tmp}/o.csv"),
    "dump --temperature": ("dump", "--seed", "1", "--temperature", "{v}"),
    "micropython --heap": ("micropython", "--heap", "{v}", "{tmp}/main.py"),
    "dump --seed": ("dump", "--seed", "{v}"),
    "dump --bandwidth": ("dump", "--seed", "1", "--bandwidth", "{v}"),
    "dump --range": ("dump", "--seed", "1", "--range", "{v}"),
    "dump --address": ("dump", "--seed", "1", "--address", "{v}"),
    "demo --samples": ("demo", "--seed", "1", "--samples", "{v}"),
    "demo --fifo-frames": ("demo", "--seed", "1", "--samples", "2", "--fifo-frames", "{v}"),
    "identify --rate": ("identify", "{seeds}/long/noise.npy", "--poles", "1", "--rate", "{v}"),
    "identify --verdict-seeds": ("identify", "{seeds}/long/noise.csv", "--poles", "1",
                                 "--verdict-seeds", "{v}"),
    "compare --rate": ("compare", "{seeds}/long/noise.npy", "paper", "--seeds", "2", "--rate",
                       "{v}"),
    "compare --seeds": ("compare", "{seeds}/stream.txt", "paper", "--seeds", "{v}"),
    "identify --seed": ("identify", "{seeds}/long/noise.csv", "--poles", "1", "--seed", "{v}"),
    "identify --skip": ("identify", "{seeds}/long/noise.csv", "--poles", "1", "--skip", "{v}"),
    "identify --tau-min": ("identify", "{seeds}/long/noise.csv", "--poles", "1", "--tau-min", "{v}"),
    "identify --tau-max": ("identify", "{seeds}/long/noise.csv", "--poles", "1", "--tau-max", "{v}"),
    "identify --poles": ("identify", "{seeds}/long/noise.csv", "--poles", "{v}"),
    "identify --bootstrap": ("identify", "{seeds}/long/noise.csv", "--poles", "1", "--bootstrap",
                             "{v}"),
    "identify --samples": ("identify", "--curve", "{seeds}/adev.csv", "--samples", "{v}"),
    "identify --curve --rate": ("identify", "--curve", "{seeds}/adev.csv", "--duration", "1h",
                                "--rate", "{v}"),
    "identify --curve --duration": ("identify", "--curve", "{seeds}/adev.csv", "--rate", "200",
                                    "--duration", "{v}"),
    "thermal --reference": ("thermal", "{seeds}/thermal.csv", "--block", "10s", "--reference",
                            "{v}"),
    "thermal --block": ("thermal", "{seeds}/thermal.csv", "--block", "{v}"),
    "thermal --order": ("thermal", "{seeds}/thermal.csv", "--block", "10s", "--order", "{v}"),
    "thermal --px4-instance": ("thermal", "{seeds}/thermal.csv", "--block", "10s",
                               "--px4-instance", "{v}", "--px4-params", "{tmp}/p.params"),
    "montecarlo --runs": ("montecarlo", "{seeds}/mc-short.toml", "--scheduler", "sync",
                          "--no-progress", "--runs", "{v}"),
    "montecarlo --seeds": ("montecarlo", "{seeds}/mc-short.toml", "--scheduler", "sync",
                           "--no-progress", "--runs", "1", "--seeds", "{v}"),
    "montecarlo --workers": ("montecarlo", "{seeds}/mc-short.toml", "--no-progress", "--runs",
                             "1", "--scheduler", "sync", "--workers", "{v}"),
    "montecarlo --rows": ("montecarlo", "{seeds}/mc-short.toml", "--scheduler", "sync",
                          "--no-progress", "--runs", "1", "--rows", "{v}"),
    "montecarlo --percentiles": ("montecarlo", "{seeds}/mc-short.toml", "--scheduler", "sync",
                                 "--no-progress", "--runs", "1", "--percentiles", "{v}"),
    "replay --max-gap-factor": ("replay", "{seeds}/recording.csv", "--script",
                                "{seeds}/short.script", "--seed", "1", "--max-gap-factor",
                                "{v}"),
    "replay --data-range": ("replay", "{seeds}/recording.csv", "--unit", "counts", "--script",
                            "{seeds}/short.script", "--seed", "1", "--data-range", "{v}"),
    "script --seed": ("script", "{seeds}/short.script", "-q", "--seed", "{v}"),
    "firmware capture --duration": ("firmware", "capture", "--duration", "{v}", "--output",
                                   "{tmp}/s.txt"),
    "firmware capture --rate": ("firmware", "capture", "--duration", "1", "--rate", "{v}",
                               "--output", "{tmp}/s.txt"),
    "firmware build --seed": ("firmware", "build", "--seed", "{v}", "--out", "{tmp}/fw"),
    # an unknown engine after the value: a valid timeout (1.5) ends there, no guest boots
    "kernel run --timeout": ("kernel", "run", "--timeout", "{v}", "--engine", "none", "--", "true"),
    "stub --duration": ("stub", "--bus", "99", "--duration", "{v}"),
    "stub --max-refresh-hz": ("stub", "--bus", "99", "--max-refresh-hz", "{v}"),
    "stub --bus": ("stub", "--bus", "{v}", "--duration", "1s"),
    "vhost-user-i2c --duration": ("vhost-user-i2c", "--socket", "{tmp}/nodir/s", "--duration",
                                  "{v}"),
    "run --bus": ("run", "--bus", "{v}", "--", "true"),
}

# Options whose value reaches the hardware or the network before any check could matter
# (stub needs root and the i2c-stub module; firmware needs avr-gcc): the value is still
# checked at parse time, so these run fine without the hardware and end in a usage error or
# the missing tool's one-line error.


def fuzz_option(name: str, value: str, tmp: Path,
                run: Callable[[list[str]], Outcome] = run_in_process) -> tuple[str, Outcome]:
    command = NUMERIC_OPTIONS[name]
    seeds = str(cli_seed_folder())
    argv = [a.replace("{v}", value).replace("{seeds}", seeds).replace("{tmp}", str(tmp))
            for a in command]
    return f"bmg160-emu {' '.join(argv)}", run(argv)


# ---------------------------------------------------------------------------- campaign


def campaign(examples: int, first_seed: int = 0, save: Path | None = None,
             formats: list[str] | None = None, out: Callable[[str], None] = print) -> int:
    """``examples`` mutated files per format, then every numeric option with every value of
    BAD_NUMBERS; prints counts and each broken run. Returns the number of broken runs."""
    import tempfile
    import time
    from collections import Counter

    broken = 0
    started = time.monotonic()
    chosen = [f for f in CLI_FORMATS if not formats or f.name in formats]
    out(f"{'format':<18}{'ok':>6}{'error':>7}{'broken':>8}")
    with tempfile.TemporaryDirectory() as folder:
        tmp = Path(folder)
        for fmt in chosen:
            counts: Counter[str] = Counter()
            for seed in range(first_seed, first_seed + examples):
                what, outcome = fuzz_format(fmt, seed, tmp)
                counts["broken" if outcome.broken else outcome.kind] += 1
                if outcome.broken:
                    broken += 1
                    out(f"  {fmt.name} seed {seed} {outcome.kind}: {outcome.detail} <- {what}")
                    if save is not None:
                        save.mkdir(parents=True, exist_ok=True)
                        data, _ = mutated(fmt, seed)
                        (save / f"{fmt.name}-{seed}{Path(fmt.seed).suffix}").write_bytes(data)
            out(f"{fmt.name:<18}{counts['ok']:>6}{counts['error']:>7}{counts['broken']:>8}")
        if not formats:
            counts = Counter()
            for name in NUMERIC_OPTIONS:
                for value in BAD_NUMBERS:
                    what, outcome = fuzz_option(name, value, tmp)
                    counts["broken" if outcome.broken else outcome.kind] += 1
                    if outcome.broken:
                        broken += 1
                        out(f"  {name} {value!r} {outcome.kind}: {outcome.detail} <- {what}")
            out(f"{'numeric options':<18}{counts['ok']:>6}{counts['error']:>7}{counts['broken']:>8}")
    out(f"{broken} broken runs; {time.monotonic() - started:.0f} s")
    return broken
