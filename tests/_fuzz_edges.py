"""The command line at its edges (issue 35): path lengths, scheduler addresses, thermal
blocks below the sample period, memory caps, and (in tests/_fuzz_signals.py) Dask under
SIGTERM.

Shared by tests/test_fuzz_edges.py (a fixed budget in CI) and ``tools/fuzz.py --edges``
(campaigns with new seeds). The invariant is the CLI fuzz's (tests/_fuzz_cli.py): exit 0, or
1 or 2 with one error line on stderr; never a traceback, never a hang. Under a memory cap a
command may also still be running, without error, when the harness stops it: a stream that
never holds the whole job in memory.
"""

from __future__ import annotations

import argparse
import os
import random
import re
import string
import subprocess
import sys
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path

from _fuzz_cli import Outcome, classify, cli_seed_folder, run_in_process

REPO = Path(__file__).resolve().parents[1]

# ---------------------------------------------------------------------------- paths

# Every option and argument that names a file or a folder, each in a command line that is
# valid otherwise and cheap ("{p}" is the path under test, "{seeds}" the fuzz seed folder,
# "{tmp}" a scratch folder). tests/test_fuzz_edges.py checks the list against the parsers:
# a path option added later without an entry here fails CI.
PATH_OPTIONS: dict[str, tuple[str, ...]] = {
    "diff A": ("diff", "{p}", "{seeds}/dump.json"),
    "diff B": ("diff", "{seeds}/dump.json", "{p}"),
    "dump --after": ("dump", "--seed", "1", "--after", "{p}"),
    "dump -o": ("dump", "--seed", "1", "-o", "{p}"),
    "dump --profile": ("dump", "--seed", "1", "--profile", "{p}"),
    "dump --device": ("dump", "--seed", "1", "--device", "{p}@0x10"),
    "firmware build --profile": ("firmware", "build", "--profile", "{p}", "--out", "{tmp}/fw"),
    "firmware build --out": ("firmware", "build", "--out", "{p}"),
    "firmware capture --profile": ("firmware", "capture", "--profile", "{p}", "--duration", "1",
                                   "--output", "{tmp}/s.txt"),
    "firmware capture --out": ("firmware", "capture", "--out", "{p}", "--duration", "1",
                               "--output", "{tmp}/s.txt"),
    "firmware capture -o": ("firmware", "capture", "--duration", "1", "-o", "{p}"),
    "generate --profile": ("generate", "--profile", "{p}", "--duration", "0.2s", "--seed", "1",
                           "-o", "{tmp}/o.npy"),
    "generate -o": ("generate", "--duration", "0.2s", "--seed", "1", "-o", "{p}"),
    "compare RECORDING": ("compare", "{p}", "paper", "--seeds", "2"),
    "compare PROFILE": ("compare", "{seeds}/stream.txt", "{p}", "--seeds", "2"),
    "compare --figure": ("compare", "{seeds}/stream.txt", "paper", "--seeds", "2", "--figure",
                         "{p}"),
    "identify FILE": ("identify", "{p}", "--poles", "1"),
    "identify --plot": ("identify", "{seeds}/long/noise.csv", "--poles", "1", "--plot", "{p}"),
    "identify --figures": ("identify", "{seeds}/long/noise.csv", "--poles", "1", "--figures",
                           "{p}"),
    "identify --profile-out": ("identify", "{seeds}/long/noise.csv", "--poles", "1",
                               "--profile-out", "{p}"),
    "identify --adev-out": ("identify", "{seeds}/long/noise.csv", "--poles", "1", "--adev-out",
                            "{p}"),
    "identify --kalibr-out": ("identify", "{seeds}/long/noise.csv", "--poles", "1",
                              "--kalibr-out", "{p}"),
    "identify --matlab-out": ("identify", "{seeds}/long/noise.csv", "--poles", "1",
                              "--matlab-out", "{p}"),
    "kernel run --module": ("kernel", "run", "--engine", "none", "--module", "{p}", "--",
                            "true"),
    "kernel run --results": ("kernel", "run", "--engine", "none", "--results", "{p}", "--",
                             "true"),
    "kernel run --console": ("kernel", "run", "--engine", "none", "--console", "{p}", "--",
                             "true"),
    "kernel run --profile": ("kernel", "run", "--engine", "none", "--profile", "{p}", "--",
                             "true"),
    "micropython PROGRAM": ("micropython", "--seed", "1", "--duration", "1s", "{p}"),
    "micropython --profile": ("micropython", "--seed", "1", "--profile", "{p}", "--duration",
                              "1s", "{tmp}/main.py"),
    "micropython --device": ("micropython", "--seed", "1", "--device", "{p}@0x10",
                             "--duration", "1s", "{tmp}/main.py"),
    "montecarlo SCENARIO": ("montecarlo", "{p}", "--runs", "1", "--scheduler", "sync",
                            "--no-progress"),
    "montecarlo -o": ("montecarlo", "{seeds}/mc-short.toml", "--runs", "1", "--scheduler",
                      "sync", "--no-progress", "-o", "{p}"),
    "record --truth": ("record", "--truth", "{p}", "--duration", "0.05s", "-o", "{tmp}/r.csv"),
    "record -o": ("record", "--duration", "0.05s", "--seed", "1", "-o", "{p}"),
    "record --profile": ("record", "--duration", "0.05s", "--seed", "1", "--profile", "{p}",
                         "-o", "{tmp}/r.csv"),
    "replay DATA": ("replay", "{p}", "--script", "{seeds}/short.script", "--seed", "1"),
    "replay -o": ("replay", "{seeds}/recording.csv", "--seed", "1", "-o", "{p}"),
    "replay --script": ("replay", "{seeds}/recording.csv", "--seed", "1", "--script", "{p}"),
    "replay --profile": ("replay", "{seeds}/recording.csv", "--seed", "1", "--profile", "{p}",
                         "--script", "{seeds}/short.script"),
    "run --log": ("run", "--log", "{p}", "--", "true"),
    "run --trace": ("run", "--trace", "{p}", "--", "true"),
    "run --profile": ("run", "--profile", "{p}", "--", "true"),
    "run --device": ("run", "--device", "{p}@0x10", "--", "true"),
    "script FILE": ("script", "{p}", "-q", "--seed", "1"),
    "script --trace": ("script", "{seeds}/short.script", "-q", "--seed", "1", "--trace", "{p}"),
    "script --device": ("script", "{seeds}/short.script", "-q", "--seed", "1", "--device",
                        "{p}@0x10"),
    "script --profile": ("script", "{seeds}/short.script", "-q", "--seed", "1", "--profile",
                         "{p}"),
    "serve --socket": ("serve", "--socket", "{p}", "--duration", "0.2s"),
    "serve --trace": ("serve", "--socket", "{tmp}/nodir/s", "--trace", "{p}", "--duration",
                      "0.2s"),
    "serve --log": ("serve", "--socket", "{tmp}/nodir/s", "--log", "{p}", "--duration", "0.2s"),
    "serve --stats": ("serve", "--socket", "{tmp}/nodir/s", "--stats", "{p}", "--duration",
                      "0.2s"),
    "serve --ready-file": ("serve", "--socket", "{tmp}/nodir/s", "--ready-file", "{p}",
                           "--duration", "0.2s"),
    "serve --profile": ("serve", "--socket", "{tmp}/nodir/s", "--profile", "{p}",
                        "--duration", "0.2s"),
    "serve --device": ("serve", "--socket", "{tmp}/nodir/s", "--device", "{p}@0x10",
                       "--duration", "0.2s"),
    "stub --stats": ("stub", "--bus", "99", "--duration", "1s", "--stats", "{p}"),
    "stub --ready-file": ("stub", "--bus", "99", "--duration", "1s", "--ready-file", "{p}"),
    "stub --profile": ("stub", "--bus", "99", "--duration", "1s", "--profile", "{p}"),
    "stub --device": ("stub", "--bus", "99", "--duration", "1s", "--device", "{p}@0x10"),
    "thermal FILE": ("thermal", "{p}", "--block", "10s"),
    "thermal --noise-profile": ("thermal", "{seeds}/thermal.csv", "--block", "10s",
                                "--noise-profile", "{p}"),
    "thermal --px4-params": ("thermal", "{seeds}/thermal.csv", "--block", "10s",
                             "--px4-params", "{p}"),
    "thermal --errors-out": ("thermal", "{seeds}/thermal.csv", "--block", "10s",
                             "--errors-out", "{p}"),
    "trace FILE": ("trace", "{p}"),
    "demo --profile": ("demo", "--seed", "1", "--samples", "2", "--profile", "{p}"),
    "vhost-user-i2c --socket": ("vhost-user-i2c", "--socket", "{p}", "--duration", "0.2s"),
    "vhost-user-i2c --gpio-socket": ("vhost-user-i2c", "--socket", "{tmp}/nodir/s",
                                     "--gpio-socket", "{p}", "--duration", "0.2s"),
    "vhost-user-i2c --trace": ("vhost-user-i2c", "--socket", "{tmp}/nodir/s", "--trace", "{p}",
                               "--duration", "0.2s"),
    "vhost-user-i2c --log": ("vhost-user-i2c", "--socket", "{tmp}/nodir/s", "--log", "{p}",
                             "--duration", "0.2s"),
    "vhost-user-i2c --stats": ("vhost-user-i2c", "--socket", "{tmp}/nodir/s", "--stats", "{p}",
                               "--duration", "0.2s"),
    "vhost-user-i2c --ready-file": ("vhost-user-i2c", "--socket", "{tmp}/nodir/s",
                                    "--ready-file", "{p}", "--duration", "0.2s"),
    "vhost-user-i2c --true-rate-file": ("vhost-user-i2c", "--socket", "{tmp}/nodir/s",
                                        "--true-rate-file", "{p}", "--duration", "0.2s"),
    "vhost-user-i2c --profile": ("vhost-user-i2c", "--socket", "{tmp}/nodir/s", "--profile",
                                 "{p}", "--duration", "0.2s"),
    "watch --socket": ("watch", "--socket", "{p}"),
}

# Options that take a path but are not typed Path in their parser (a built-in name or a file)
PATH_DESTS = {"profile", "noise_profile", "scenario", "output", "out", "devices"}


def path_actions() -> Iterator[tuple[str, argparse.Action]]:
    """(label, action) of every parser argument that names a file or folder: typed Path, or
    one of PATH_DESTS. Labels are ``COMMAND OPTION`` or ``COMMAND METAVAR`` for positionals."""
    from bmg160_emu.cli import build_parser

    parser = build_parser()
    for name, command in parser.command_parsers.items():
        parsers = [(name, command)]
        for action in command._actions:
            if isinstance(action, argparse._SubParsersAction):
                parsers += [(f"{name} {n}", p) for n, p in action.choices.items()]
        for label, p in parsers:
            for action in p._actions:
                if action.help == argparse.SUPPRESS:
                    continue  # an old spelling, kept hidden for a release
                if action.type is Path or action.dest in PATH_DESTS:
                    shown = (min(action.option_strings, key=len) if action.option_strings
                             else str(action.metavar or action.dest.upper()))
                    yield f"{label} {shown}", action


def path_values(tmp: Path, rng: random.Random) -> list[tuple[str, str]]:
    """(kind, path) of the hostile paths tried on every path option: names past NAME_MAX
    (255 bytes), a path past PATH_MAX (4096), multibyte names whose characters fit but whose
    bytes do not, a folder where a file is meant, a file where a folder is meant, a name of
    exactly 255 bytes that does not exist (legal: the command's usual error)."""
    letters = string.ascii_letters + string.digits + "._-"
    word = "".join(rng.choice(letters) for _ in range(rng.randint(256, 400)))
    return [
        ("long name", word),
        ("long name in a folder", str(tmp / ("n" * rng.randint(256, 300) + ".csv"))),
        ("long path", "/".join(["d" * 200] * rng.randint(21, 40))),
        ("multibyte name", "é" * rng.randint(128, 200)),  # 2 bytes a character
        ("a folder", str(tmp)),
        ("through a file", str(cli_seed_folder() / "short.script" / "x.csv")),
        ("255-byte name", str(tmp / ("m" * 251 + ".csv"))),
    ]


MAIN_PY = "import time\ntime.sleep_ms(5)\n"  # a MicroPython program for micropython's options
PATH_LIMIT_S = 120.0  # a hang, not a speed: a valid identify --figures run is ~5 s here


def fuzz_path(label: str, kind: str, path: str, tmp: Path,
              run: Callable[[list[str]], Outcome] | None = None) -> tuple[str, Outcome]:
    """One path option with one hostile path, run from a folder of its own (a relative path
    lands there); also fails on a temporary file left in tmp, and on anything a refused
    run leaves in that folder (a socket path past PATH_MAX once left 20 nested folders of
    200 d's beside the checkout, made before the path was refused)."""
    if run is None:
        def run(argv: list[str]) -> Outcome:
            return run_in_process(argv, PATH_LIMIT_S)
    seeds = str(cli_seed_folder())
    (tmp / "main.py").write_text(MAIN_PY)
    argv = [a.replace("{p}", path).replace("{seeds}", seeds).replace("{tmp}", str(tmp))
            for a in PATH_OPTIONS[label]]
    here = tmp / "cwd"
    here.mkdir(exist_ok=True)
    before = set(os.listdir(here))
    previous = os.getcwd()
    os.chdir(here)
    try:
        outcome = run(argv)
    finally:
        os.chdir(previous)
    left = [p.name for p in tmp.iterdir() if ".part" in p.name]
    if left and not outcome.broken:
        outcome = Outcome("left a temporary file", outcome.status, ", ".join(left))
    behind = sorted(set(os.listdir(here)) - before)
    if behind and outcome.status != 0 and not outcome.broken:
        names = ", ".join(n if len(n) < 40 else n[:20] + "..." for n in behind)
        outcome = Outcome("a refused run left files behind", outcome.status, names)
    shown = path if len(path) < 60 else f"{path[:25]}...({len(path)} characters)"
    return f"bmg160-emu {label} {kind} {shown}", outcome


# ---------------------------------------------------------------------------- names

# For each path option, the seed file it reads (copied to the odd name) or None for one it
# writes, and the suffix it expects: so that a name with odd characters reaches the code that
# opens, prints and writes it, not a suffix check.
ODD_NAME_FILES: dict[str, tuple[str | None, str]] = {
    "diff A": ("dump.json", ".json"), "diff B": ("dump.json", ".json"),
    "dump --after": ("short.script", ".script"), "dump -o": (None, ".json"),
    "dump --profile": ("profile.toml", ".toml"), "dump --device": ("standin.toml", ".toml"),
    "firmware build --profile": ("profile.toml", ".toml"), "firmware build --out": (None, ""),
    "firmware capture --profile": ("profile.toml", ".toml"),
    "firmware capture --out": (None, ""), "firmware capture -o": (None, ".txt"),
    "generate --profile": ("profile.toml", ".toml"), "generate -o": (None, ".csv"),
    "compare RECORDING": ("stream.txt", ".txt"), "compare PROFILE": ("profile.toml", ".toml"),
    "compare --figure": (None, ".png"), "identify FILE": ("long/noise.csv", ".csv"),
    "identify --plot": (None, ".png"), "identify --figures": (None, ""),
    "identify --profile-out": (None, ".toml"), "identify --adev-out": (None, ".csv"),
    "identify --kalibr-out": (None, ".yaml"), "identify --matlab-out": (None, ".m"),
    "kernel run --module": (None, ".ko"), "kernel run --results": (None, ".json"),
    "kernel run --console": (None, ".log"), "kernel run --profile": ("profile.toml", ".toml"),
    "micropython PROGRAM": ("main.py", ".py"), "micropython --profile": ("profile.toml", ".toml"),
    "micropython --device": ("standin.toml", ".toml"),
    "montecarlo SCENARIO": ("mc-short.toml", ".toml"), "montecarlo -o": (None, ".csv"),
    "record --truth": ("scenario.toml", ".toml"), "record -o": (None, ".csv"),
    "record --profile": ("profile.toml", ".toml"), "replay DATA": ("recording.csv", ".csv"),
    "replay -o": (None, ".npz"), "replay --script": ("short.script", ".script"),
    "replay --profile": ("profile.toml", ".toml"), "run --log": (None, ".log"),
    "run --trace": (None, ".jsonl"), "run --profile": ("profile.toml", ".toml"),
    "run --device": ("standin.toml", ".toml"), "script FILE": ("short.script", ".script"),
    "script --trace": (None, ".jsonl"), "script --device": ("standin.toml", ".toml"),
    "script --profile": ("profile.toml", ".toml"), "serve --socket": (None, ".sock"),
    "serve --trace": (None, ".jsonl"), "serve --log": (None, ".log"),
    "serve --stats": (None, ".json"), "serve --ready-file": (None, ".ready"),
    "serve --profile": ("profile.toml", ".toml"), "serve --device": ("standin.toml", ".toml"),
    "stub --stats": (None, ".json"), "stub --ready-file": (None, ".ready"),
    "stub --profile": ("profile.toml", ".toml"), "stub --device": ("standin.toml", ".toml"),
    "thermal FILE": ("thermal.csv", ".csv"), "thermal --noise-profile": ("profile.toml", ".toml"),
    "thermal --px4-params": (None, ".params"), "thermal --errors-out": (None, ".toml"),
    "trace FILE": ("session.jsonl", ".jsonl"), "demo --profile": ("profile.toml", ".toml"),
    "vhost-user-i2c --socket": (None, ".sock"), "vhost-user-i2c --gpio-socket": (None, ".sock"),
    "vhost-user-i2c --trace": (None, ".jsonl"), "vhost-user-i2c --log": (None, ".log"),
    "vhost-user-i2c --stats": (None, ".json"), "vhost-user-i2c --ready-file": (None, ".ready"),
    "vhost-user-i2c --true-rate-file": ("rate.txt", ".txt"),
    "vhost-user-i2c --profile": ("profile.toml", ".toml"), "watch --socket": (None, ".sock"),
}

# Bytes a Linux file name may hold that a program may mishandle: C0 controls (TOML forbids
# them in strings and comments; a newline splits a one-line error), DEL, a C1 control in
# UTF-8, what a shell or make reads itself, and bytes that are not UTF-8 (Python holds them
# as lone surrogates, PEP 383; a strict UTF-8 stdout cannot print them).
ODD_BYTES = ([bytes([c]) for c in range(1, 32)] + [b"\x7f", b"\xc2\x85", b"\xff", b"\xc3",
             b"\x80", b"\xed\xa0\x80"] + [c.encode() for c in " \"'$#:%;=\\`*?[](){}|&<>~!"]
             + ["é".encode(), "😀".encode()])
# The profile and [errors] table outputs, read back after a run (label -> the output, and
# whether it is an [errors] table): an odd output name reaches the profile's name, an odd
# input name its header comment (for which the input options also write one).
READ_BACK = {"identify --profile-out": ("{p}", False), "thermal --errors-out": ("{p}", True),
             "identify FILE": ("{tmp}/out.toml", False), "thermal FILE": ("{tmp}/e.toml", True)}
ODD_NAME_EXTRA = {"identify FILE": ("--no-verdict", "--profile-out", "{tmp}/out.toml"),
                  "thermal FILE": ("--errors-out", "{tmp}/e.toml")}
NAME_LIMIT_S = 120.0  # a hang, not a speed (identify --figures with its figures: ~10 s)


def odd_stem(rng: random.Random) -> bytes:
    """A file name stem of plain letters with one to four odd bytes among them."""
    parts = [rng.choice(string.ascii_letters).encode() for _ in range(rng.randint(1, 4))]
    for _ in range(rng.randint(1, 4)):
        parts.insert(rng.randint(0, len(parts)), rng.choice(ODD_BYTES))
    return b"".join(parts)


def fuzz_odd_name(label: str, stem: bytes, tmp: Path) -> tuple[str, Outcome]:
    """One path option given the name ``stem`` + its suffix (the seed it reads copied there),
    run as a person runs it (a child process under a strict UTF-8 locale's stdout). Beside
    the CLI invariant: an error line holds no raw control character, and a profile or
    ``[errors]`` table that was written reads back."""
    import shutil

    seed, suffix = ODD_NAME_FILES[label]
    seeds = cli_seed_folder()
    root = os.fsencode(tmp)
    for folder in (root, root + b"/nodir", root + b"/cwd"):
        os.makedirs(folder, exist_ok=True)
        os.chmod(folder, 0o700)  # serve and watch want a private folder for their sockets
    (tmp / "main.py").write_text(MAIN_PY)
    path = root + b"/" + stem + suffix.encode()
    if seed is not None:
        shutil.copy(seeds / seed if seed != "main.py" else tmp / "main.py", path)
    argv = [a.encode().replace(b"{p}", path).replace(b"{seeds}", os.fsencode(seeds))
            .replace(b"{tmp}", root) for a in PATH_OPTIONS[label] + ODD_NAME_EXTRA.get(label, ())]
    env = dict(os.environ, PYTHONIOENCODING="utf-8:strict", PYTHONPATH=str(REPO))
    shown = f"bmg160-emu {label} {stem!r}"
    try:
        proc = subprocess.run([sys.executable, "-m", "bmg160_emu", *argv], capture_output=True,
                              timeout=NAME_LIMIT_S, env=env, cwd=root + b"/cwd",
                              stdin=subprocess.DEVNULL, check=False)
    except subprocess.TimeoutExpired:
        return shown, Outcome("hang", None, f"no exit after {NAME_LIMIT_S:g} s")
    finally:
        for folder in (root + b"/nodir", root + b"/cwd"):
            shutil.rmtree(folder, ignore_errors=True)
    stderr = proc.stderr.decode("utf-8", "backslashreplace")
    outcome = classify(proc.returncode, stderr)
    if outcome.broken:
        return shown, outcome
    raw = [line for line in stderr.splitlines() if ": error:" in line
           and re.search("[\x00-\x08\x0b-\x1f\x7f]", line)]
    if raw:
        return shown, Outcome("bad message", proc.returncode, f"raw control character: {raw[0]!r}"[:300])
    written = READ_BACK.get(label)
    if proc.returncode == 0 and written is not None:
        from bmg160_emu.noise.profile import load_profile
        from bmg160_emu.noise.profile_writer import format_profile

        out, table = written
        out_path = os.fsdecode(path if out == "{p}" else out.replace("{tmp}", str(tmp)).encode())
        text = Path(out_path).read_text(encoding="utf-8")
        if table:  # an [errors] table, which a user adds to a profile
            text = format_profile(load_profile("paper")) + text
        check = tmp / "read-back.toml"
        check.write_text(text, encoding="utf-8")
        try:
            load_profile(check)
        except ValueError as exc:
            return shown, Outcome("unreadable output", 0, str(exc)[:300])
    return shown, outcome


# ---------------------------------------------------------------------------- schedulers


def scheduler_strings(rng: random.Random, count: int) -> list[str]:
    """Strings a person (or a script with a bug) might give --scheduler: addresses with
    hosts and ports of every size and form, schemes, separators, numbers past 64 bits."""
    schemes = ["", "tcp://", "tls://", "udp://", "ucx://", "ws://", "inproc://", "://", "tcp:/"]
    hosts = ["", "localhost", "10.0.0.5", "5", "0", "256.1.1.1", "1.2.3", "[::1]", "[::zz]",
             "::1", "a" * 300, "host_name", "-bad", "scheduler.example.org", "ex ample", "é"]
    ports = ["", ":", ":0", ":2", ":8786", ":65535", ":65536", ":-1", ":99999999999999999999",
             ":8786:1", ":0x10", ":8786 ", ":٣"]
    out = []
    for _ in range(count):
        kind = rng.random()
        if kind < 0.8:
            out.append(rng.choice(schemes) + rng.choice(hosts) + rng.choice(ports))
        else:
            out.append("".join(rng.choice(string.printable) for _ in range(rng.randint(0, 40))))
    return out


def judge_scheduler(text: str) -> str | None:
    """What is wrong with ``scheduler_address(text)``, or None. It either refuses the text in
    one line (ValueError, under 300 characters) or accepts it as the text itself, and what it
    accepts Dask can parse: a scheme distributed knows, and for TCP-like schemes a host and a
    port from 1 to 65535 by distributed's own parser (an accepted 0:99999999999999999999 was
    an OverflowError in the resolver)."""
    from bmg160_emu.adcs.montecarlo import scheduler_address

    try:
        got = scheduler_address(text)
    except ValueError as exc:
        message = str(exc)
        if "\n" in message or len(message) > 300:
            return f"refused in {len(message)} characters over {message.count(chr(10)) + 1} lines"
        return None
    except Exception as exc:  # noqa: BLE001 - what the harness looks for
        return f"{type(exc).__name__}: {exc}"[:200]
    if got != text:
        return f"accepted as {got!r}"
    if text in ("local", "sync"):
        return None
    from distributed.comm.addressing import parse_address, parse_host_port

    scheme, location = parse_address(text if "://" in text else f"tcp://{text}")
    if scheme == "inproc":
        return None
    try:
        host, port = parse_host_port(location, default_port=8786)
    except Exception as exc:  # noqa: BLE001
        return f"accepted, but Dask cannot parse it: {type(exc).__name__}: {exc}"[:200]
    if not 1 <= int(port) <= 65535 or not host:
        return f"accepted with host {host!r} and port {port!r}"
    return None


# ---------------------------------------------------------------------------- thermal blocks


def thermal_log(folder: Path, rate_hz: float, seconds: float) -> Path:
    """A thermal log at ``rate_hz``: bias 0.01 deg/s/K, the die warming by 20 K."""
    import numpy as np

    path = folder / f"thermal-{rate_hz:g}Hz.csv"
    if not path.exists():
        rng = np.random.default_rng(3)
        t = np.arange(int(seconds * rate_hz)) / rate_hz
        temp = 20.0 + 20.0 * t / t[-1]
        rates = 0.01 * (temp[:, None] - 30.0) + 0.02 * rng.standard_normal((t.size, 3))
        rows = "".join(f"{a:.6f},{b:.5f},{c:.5f},{d:.5f},{e:.3f}\n"
                       for a, (b, c, d), e in zip(t, rates, temp))
        path.write_text("time_s,x_dps,y_dps,z_dps,temperature_c\n" + rows)
    return path


def block_text(seconds: float, rng: random.Random) -> str:
    """``seconds`` as one of the duration spellings (us, ms, s, bare seconds)."""
    unit = rng.choice(["us", "ms", "s", ""])
    value = seconds / {"us": 1e-6, "ms": 1e-3, "s": 1.0, "": 1.0}[unit]
    return f"{value:.6g}{unit}"


def fuzz_block(rng: random.Random, folder: Path,
               run: Callable[[list[str]], Outcome] = run_in_process) -> tuple[str, Outcome]:
    """A thermal log at a random rate and a block from 1 us to just below its sample period,
    or one that cuts the log into more blocks than the fit takes: refused in one line."""
    rate = rng.choice([1.0, 10.0, 50.0, 100.0, 400.0])
    log = thermal_log(folder, rate, 2500.0 / rate + 60.0)  # 2,500 samples and a minute
    period = 1.0 / rate
    if rng.random() < 0.7:
        block = period * 10 ** rng.uniform(-6, -0.0005)  # below the period
        expected = "shorter than the log's sample period"
    else:
        block = period * rng.uniform(1.0, 1.2)  # a block a sample: 2,500+ blocks
        expected = "the fit takes at most"
    argv = ["thermal", str(log), "--block", block_text(block, rng)]
    outcome = run(argv)
    if outcome.kind == "ok" or (outcome.kind == "error" and expected not in outcome.detail):
        outcome = Outcome("not refused", outcome.status, outcome.detail or "exit 0")
    return f"bmg160-emu {' '.join(argv)}", outcome


# ---------------------------------------------------------------------------- memory caps


@dataclass(frozen=True)
class Capped:
    """A command with legal values that need more memory than the cap, or that must stream."""

    name: str
    argv: tuple[str, ...]
    may_stream: bool = False  # still running at the deadline, without error, is fine
    needs: tuple[str, ...] = ()  # programs it needs on PATH (skipped without them)


CAPPED = (
    Capped("record 1e8 samples to NPZ", ("record", "--rate", "2000", "--duration", "50000s",
                                         "--seed", "1", "-o", "{tmp}/big.npz")),
    Capped("record 1e8 samples to CSV", ("record", "--rate", "2000", "--duration", "50000s",
                                         "--seed", "1", "-o", "{tmp}/big.csv")),
    Capped("record 1e8 samples to RESD", ("record", "--rate", "1000", "--duration", "1d",
                                          "--seed", "1", "-o", "{tmp}/big.resd")),
    Capped("montecarlo, a million runs of a long grid",
           ("montecarlo", "{tmp}/long-grid.toml", "--runs", "1000000", "--scheduler", "sync",
            "--no-progress")),
    Capped("generate 30 days", ("generate", "--rate", "100", "--duration", "30d", "--seed",
                                "1", "-o", "{tmp}/month.npy"), may_stream=True),
    Capped("demo, a million samples", ("demo", "--seed", "1", "--samples", "1000000"),
           may_stream=True),
    Capped("script, advance 720h", ("script", "{tmp}/month.script", "-q", "--seed", "1"),
           may_stream=True),
    Capped("firmware capture, 30 days", ("firmware", "capture", "--duration", "30d", "-o",
                                         "{tmp}/month.txt"), may_stream=True,
           needs=("avr-gcc", "simavr")),
)
LONG_GRID = 'duration_s = 86400.0\n[[motion]]\nkind = "rest"\n[readout]\ngrid_s = 0.01\n'
MONTH_SCRIPT = "write BW 0x01\nadvance 720h\nread CHIP_ID == 0x0F\n"


def run_capped(capped: Capped, tmp: Path, cap_bytes: int, seconds: float) -> Outcome:
    """``capped`` as a subprocess with its address space capped at ``cap_bytes`` (ulimit -v),
    stopped after ``seconds``: exit 0, or one line; still running without error where it may
    stream. A MemoryError, numpy's "Unable to allocate" or an OOM kill breaks the invariant."""
    (tmp / "long-grid.toml").write_text(LONG_GRID)
    (tmp / "month.script").write_text(MONTH_SCRIPT)
    argv = [a.replace("{tmp}", str(tmp)) for a in capped.argv]
    command = (f"ulimit -v {cap_bytes // 1024} && exec {sys.executable} -m bmg160_emu "
               + " ".join(_quote(a) for a in argv))
    env = dict(os.environ, PYTHONPATH=str(REPO))
    process = subprocess.Popen(["sh", "-c", command], stdout=subprocess.DEVNULL,
                               stderr=subprocess.PIPE, text=True, env=env, cwd=tmp,
                               start_new_session=True)
    deadline = time.monotonic() + seconds
    while process.poll() is None and time.monotonic() < deadline:
        time.sleep(0.05)
    running = process.poll() is None
    if running:
        os.killpg(process.pid, 9)
    _, err = process.communicate()
    if running:
        if "Traceback" in err or "rror" in err:
            return Outcome("traceback", None, err.strip().splitlines()[-1][:300])
        if capped.may_stream:
            return Outcome("ok", None, f"still streaming after {seconds:g} s")
        return Outcome("hang", None, f"neither refused nor done after {seconds:g} s")
    if "Unable to allocate" in err or "MemoryError" in err:
        return Outcome("traceback", process.returncode, "an allocation failed: "
                       + err.strip().splitlines()[-1][:250])
    return classify(process.returncode, err)


def _quote(text: str) -> str:
    return "'" + text.replace("'", "'\"'\"'") + "'"


MEMORY_WORDS = re.compile(r"needs about [\d.]+ [kMGT]?B of memory")
