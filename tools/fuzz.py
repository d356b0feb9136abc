"""A long fuzz campaign over every file format the project reads (issue 12).

    python tools/fuzz.py --examples 2000            # 2000 mutated files per format
    python tools/fuzz.py --examples 500 --format trace --save failures/
    python tools/fuzz.py --cli --examples 200      # the command line (tests/_fuzz_cli.py)
    python tools/fuzz.py --signals --trials 50      # signals at random moments (issue 24)
    python tools/fuzz.py --edges --examples 20      # paths, names, schedulers, blocks, memory (35)
    python tools/fuzz.py --full-disk /mnt/small --trials 5   # every writer on a full disk

Each example is a valid file (made by the project's own CLI) with 1-3 random mutations (bit
flips, truncation, deleted/duplicated spans and lines, numbers replaced by huge, non-finite or
wrongly typed values, deep nesting, 200k-character lines, binary junk, empty files), loaded
by the format's loader. The invariant: a valid load or the format's own one-line error; never
another exception, never a hang (tests/_fuzz_formats.py says the limit). Prints counts per
format and exits 1 if any example broke it; --save writes each breaking file for a rerun.
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time
from collections import Counter
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO / "tests"))

from _fuzz_cli import CLI_FORMATS, campaign
from _fuzz_formats import FORMATS, mutate, try_load


def main() -> int:
    if "--signals" in sys.argv[1:]:
        return signals_main(sys.argv[1:])
    if "--edges" in sys.argv[1:]:
        return edges_main(sys.argv[1:])
    if "--full-disk" in sys.argv[1:]:
        return full_disk_main(sys.argv[1:])
    parser = argparse.ArgumentParser(
        description=__doc__.split("\n\n")[0],
        epilog="other campaigns, each with its own options (--help after it): --signals "
               "(SIGINT/SIGTERM at random moments), --edges (paths, schedulers, blocks, "
               "memory), --full-disk DIR (every writer on a full disk)")
    parser.add_argument("--examples", type=int, default=1000, help="mutated files per format")
    parser.add_argument("--cli", action="store_true",
                        help="run the command line instead of the loaders: --examples mutated "
                        "files per CLI format, then every numeric option with every bad value")
    parser.add_argument("--format", action="append",
                        choices=sorted({f.name for f in FORMATS} | {f.name for f in CLI_FORMATS}),
                        help="only this format (repeatable; default all)")
    parser.add_argument("--first-seed", type=int, default=0, help="seed of the first example")
    parser.add_argument("--save", type=Path, default=None, help="folder for breaking files")
    args = parser.parse_args()
    if args.cli:
        return 1 if campaign(args.examples, args.first_seed, args.save, args.format) else 0
    formats = [f for f in FORMATS if not args.format or f.name in args.format]
    failures = 0
    started = time.monotonic()
    print(f"{'format':<16}{'loaded':>8}{'format error':>14}{'other':>8}{'hang':>6}")
    with tempfile.TemporaryDirectory() as tmp:
        for fmt in formats:
            counts: Counter[str] = Counter()
            for seed in range(args.first_seed, args.first_seed + args.examples):
                data, applied = mutate(fmt, seed)
                outcome = try_load(fmt, data, Path(tmp))
                counts[outcome.kind] += 1
                if outcome.kind in ("other exception", "hang"):
                    failures += 1
                    print(f"  {fmt.name} seed {seed} ({'+'.join(applied)}): {outcome.detail}")
                    if args.save is not None:
                        args.save.mkdir(parents=True, exist_ok=True)
                        (args.save / f"{fmt.name}-{seed}{Path(fmt.seed).suffix}").write_bytes(data)
            print(f"{fmt.name:<16}{counts['loaded']:>8}{counts['format error']:>14}"
                  f"{counts['other exception']:>8}{counts['hang']:>6}")
    total = args.examples * len(formats)
    print(f"{total} examples in {time.monotonic() - started:.0f} s; {failures} broke the invariant")
    return 1 if failures else 0


def signals_main(argv: list[str]) -> int:
    """``--signals``: SIGINT/SIGTERM at seeded random moments for every command that writes
    (tests/_fuzz_signals.py); counts per command, each failure with its seed."""
    from _fuzz_signals import COMMANDS, campaign

    parser = argparse.ArgumentParser(prog="fuzz.py --signals")
    parser.add_argument("--signals", action="store_true", required=True)
    parser.add_argument("--trials", type=int, default=50, help="signalled runs per command")
    parser.add_argument("--command", action="append", choices=[c.name for c in COMMANDS],
                        help="only this command line (repeatable; default all)")
    parser.add_argument("--first-seed", type=int, default=0, help="seed of the first trial")
    args = parser.parse_args(argv)
    failed: list[str] = []

    def report(line: str) -> None:
        print(line, flush=True)
        if line.startswith("  "):
            failed.append(line)

    started = time.monotonic()
    with tempfile.TemporaryDirectory() as tmp:
        counts = campaign(args.command or [c.name for c in COMMANDS], args.trials,
                          args.first_seed, Path(tmp), report)
    total = sum(c.get("ok", 0) + c.get("failed", 0) + c.get("start-up", 0)
                for c in counts.values())
    print(f"{total} signalled runs in {time.monotonic() - started:.0f} s; {len(failed)} failed")
    return 1 if failed else 0


def edges_main(argv: list[str]) -> int:
    """``--edges``: the command line at its edges (tests/_fuzz_edges.py), ``--examples``
    seeds each: hostile paths on every path option, an odd name on each (a child process),
    scheduler strings (1,000 a seed), thermal blocks, and the memory-cap commands
    (``--cap-gib``, 20 s each) once."""
    import random
    import shutil

    from _fuzz_edges import (
        CAPPED,
        ODD_NAME_FILES,
        PATH_OPTIONS,
        fuzz_block,
        fuzz_odd_name,
        fuzz_path,
        judge_scheduler,
        odd_stem,
        path_values,
        run_capped,
        scheduler_strings,
    )

    parser = argparse.ArgumentParser(prog="fuzz.py --edges")
    parser.add_argument("--edges", action="store_true", required=True)
    parser.add_argument("--examples", type=int, default=10, help="seeds per kind")
    parser.add_argument("--first-seed", type=int, default=0, help="the first seed")
    parser.add_argument("--cap-gib", type=float, default=1.0, help="address-space cap")
    parser.add_argument("--only", choices=("paths", "names", "schedulers", "blocks", "memory"),
                        action="append", help="only these kinds (default all)")
    args = parser.parse_args(argv)
    kinds = args.only or ["paths", "names", "schedulers", "blocks", "memory"]
    seeds = range(args.first_seed, args.first_seed + args.examples)
    broken: list[str] = []
    counts: Counter[str] = Counter()
    started = time.monotonic()

    def tally(kind: str, what: str, bad: str | None) -> None:
        counts[kind] += 1
        if bad is not None:
            broken.append(f"  {kind}: {bad} <- {what}")
            print(broken[-1], flush=True)

    with tempfile.TemporaryDirectory() as folder:
        tmp = Path(folder)
        for seed in seeds:
            if "paths" in kinds:
                for label in PATH_OPTIONS:
                    work = tmp / f"p{seed}"
                    work.mkdir(exist_ok=True)
                    for kind, path in path_values(work, random.Random(f"{label}{seed}")):
                        what, outcome = fuzz_path(label, kind, path, work)
                        tally("paths", what, f"{outcome.kind}: {outcome.detail}"
                              if outcome.broken else None)
            if "names" in kinds:  # every path option with an odd name, in a child process
                for label in ODD_NAME_FILES:
                    stem = odd_stem(random.Random(f"{label}{seed}"))
                    what, outcome = fuzz_odd_name(label, stem, tmp / f"n{seed}")
                    tally("names", what, f"{outcome.kind}: {outcome.detail}"
                          if outcome.broken else None)
            if "schedulers" in kinds:
                for text in scheduler_strings(random.Random(seed), 1000):
                    tally("schedulers", repr(text), judge_scheduler(text))
            if "blocks" in kinds:
                rng = random.Random(seed)
                for _ in range(10):
                    what, outcome = fuzz_block(rng, tmp)
                    tally("blocks", what, f"{outcome.kind}: {outcome.detail}"
                          if outcome.broken else None)
        if "memory" in kinds:
            for capped in CAPPED:
                if any(shutil.which(program) is None for program in capped.needs):
                    print(f"memory: {capped.name}: skipped (needs {', '.join(capped.needs)})")
                    continue
                work = tmp / "memory"
                work.mkdir(exist_ok=True)
                outcome = run_capped(capped, work, int(args.cap_gib * 2**30), 20.0)
                tally("memory", capped.name, f"{outcome.kind}: {outcome.detail}"
                      if outcome.broken else None)
    for kind, n in counts.items():
        print(f"{kind:<12}{n:>8} runs")
    print(f"{sum(counts.values())} runs in {time.monotonic() - started:.0f} s; "
          f"{len(broken)} broke the invariant")
    return 1 if broken else 0


def full_disk_main(argv: list[str]) -> int:
    """``--full-disk DIR``: every command line of the signal suite that writes a file
    (tests/_fuzz_signals.py), its outputs on DIR, a small file system (a tmpfs of a few MB:
    ``mount -t tmpfs -o size=4m tmpfs DIR``) filled to leave a seeded number of bytes free
    (0 to 2 MB). Each run must end with exit 0 and every output complete (equal to a run on
    a roomy disk), or with one error line and every output as it was before (an earlier
    version is left in place, to catch one truncated or replaced by a cut file); never a
    traceback, and no temporary file left."""
    import random
    import shutil
    import subprocess

    from _fuzz_cli import classify
    from _fuzz_signals import BY_NAME, COMMANDS, prepare, read_output, reference

    parser = argparse.ArgumentParser(prog="fuzz.py --full-disk")
    parser.add_argument("--full-disk", type=Path, required=True, metavar="DIR",
                        help="a small file system's mount point (it is filled; its files "
                        "are removed)")
    parser.add_argument("--trials", type=int, default=5, help="fill levels per command")
    parser.add_argument("--first-seed", type=int, default=0)
    parser.add_argument("--command", action="append", choices=[c.name for c in COMMANDS])
    args = parser.parse_args(argv)
    disk: Path = args.full_disk
    names = args.command or [c.name for c in COMMANDS if not c.server and not c.optional]
    failures: list[str] = []
    runs = 0
    started = time.monotonic()
    with tempfile.TemporaryDirectory() as tmp:
        for name in names:
            command = BY_NAME[name]
            roomy = Path(tmp) / name
            ref = reference(command, roomy)
            for seed in range(args.first_seed, args.first_seed + args.trials):
                rng = random.Random(f"{name}{seed}")
                for child in disk.iterdir():
                    if child.is_dir():
                        shutil.rmtree(child)
                    else:
                        child.unlink()
                work = disk / "work"
                prepare(work)  # the inputs (small) on the disk too
                previous = {}
                for output in command.outputs:  # an earlier version, to be left as it was
                    (work / output).write_bytes(b"earlier version\n")
                    previous[output] = b"earlier version\n"
                free = shutil.disk_usage(disk).free
                leave = rng.choice([0, 0, 512, 4096, rng.randint(0, 2 << 20)])
                filler = max(free - leave, 0)
                with (disk / "filler").open("wb") as handle:
                    while filler > 0:
                        chunk = min(filler, 1 << 20)
                        try:
                            handle.write(b"\0" * chunk)
                            handle.flush()
                        except OSError:
                            break
                        filler -= chunk
                runs += 1
                argv_ = command.line(work)
                proc = subprocess.run([sys.executable, "-m", "bmg160_emu", *argv_],
                                      check=False, capture_output=True, text=True, cwd=work,
                                      timeout=600, env={**os.environ, "PYTHONPATH": str(REPO)})
                outcome = classify(proc.returncode, proc.stderr)
                problems = []
                if outcome.broken:
                    problems.append(f"{outcome.kind}: {outcome.detail}")
                for output in command.outputs:
                    path = work / output
                    if proc.returncode == 0:
                        try:
                            same = _same(_unplaced(read_output(path), work),
                                         _unplaced(ref.contents[output], roomy))
                        except Exception as exc:  # noqa: BLE001 - what is looked for
                            same, problems = False, [*problems, f"{output}: {exc}"]
                        if not same:
                            problems.append(f"{output}: exit 0 but not the whole output")
                    elif (not path.exists() or path.read_bytes() != previous[output]) \
                            and not (path.exists() and _marked(path)):
                        problems.append(f"{output}: changed by a run that failed")
                left = [p.name for p in work.iterdir() if ".part" in p.name]
                if left:
                    problems.append(f"temporary files left: {left}")
                state = "ok" if proc.returncode == 0 else "refused"
                if problems:
                    failures.append(f"  {name} seed {seed} (left {leave} bytes): "
                                    + "; ".join(problems))
                    print(failures[-1], flush=True)
                else:
                    print(f"{name} seed {seed} (left {leave} bytes): {state}", flush=True)
    print(f"{runs} full-disk runs in {time.monotonic() - started:.0f} s; "
          f"{len(failures)} failed")
    return 1 if failures else 0


def _unplaced(content: object, folder: Path) -> object:
    """Text output with its work folder's path (identify names its input) made neutral."""
    return content.replace(str(folder), "{work}") if isinstance(content, str) else content


def _same(kept: object, whole: object) -> bool:
    import numpy as np

    if isinstance(kept, np.ndarray):
        return isinstance(whole, np.ndarray) and kept.shape == whole.shape and bool(
            np.array_equal(kept, whole))
    return kept == whole


def _marked(path: Path) -> bool:
    """An honest shorter output (io.partial's mark), which a run that stops may leave."""
    from bmg160_emu.io.partial import partial_note

    try:
        return partial_note(path) is not None
    except Exception:  # noqa: BLE001 - an unreadable file is not marked
        return False


if __name__ == "__main__":
    raise SystemExit(main())
