"""Run a benchmark against another checkout of the package and this one, interleaved.

    python tools/bench_pair.py --base ../parent [--runs 3] -- tools/bench_chip.py [its options]

Runs the benchmark script (this checkout's copy) ``--runs`` times with the other checkout
first on PYTHONPATH (A, the base) and as many times with this one (B), alternately: A, B, A,
B ..., so that the load of a shared machine falls on both alike. Every output line is read as
a template with numbers in it; for each template that every run printed, the line is printed
once more with each number that varies replaced by ``A median -> B median [B/A]`` (for a
time, below 1: B is faster); a number the same in every run (a count, a setting) is printed
as it is. The load average (1 min) is taken before each run and printed with its range.
"""

from __future__ import annotations

import argparse
import os
import re
import statistics
import subprocess
import sys
from pathlib import Path

# a number, with a unit or an x right after it allowed (131.7x, 5.4us), not inside a word (0x02)
NUMBER = re.compile(r"(?<![\w.])-?\d[\d,]*(?:\.\d+)?(?:e[-+]?\d+)?(?![\d.])")
HERE = Path(__file__).resolve().parent.parent


def _numbers(line: str) -> tuple[str, list[float]]:
    """(the line with its numbers as {}, the numbers)."""
    values = [float(m.replace(",", "")) for m in NUMBER.findall(line)]
    return NUMBER.sub("{}", line), values


def _key(template: str) -> str:
    """A template without its padding (a number's width moves the spaces around it)."""
    return " ".join(template.split())


def _run(script: list[str], pythonpath: str | None) -> tuple[list[str], float]:
    env = dict(os.environ)
    if pythonpath:
        env["PYTHONPATH"] = pythonpath
    else:
        env.pop("PYTHONPATH", None)
    load = os.getloadavg()[0]
    done = subprocess.run([sys.executable, *script], env=env, cwd=HERE, capture_output=True,
                          text=True, check=True)
    return done.stdout.splitlines(), load


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--base", required=True, type=Path,
                        help="the other checkout (its folder holding bmg160_emu)")
    parser.add_argument("--runs", type=int, default=3, help="runs of each, alternated")
    parser.add_argument("script", nargs=argparse.REMAINDER,
                        help="-- then the benchmark script and its options")
    args = parser.parse_args()
    script = args.script[1:] if args.script[:1] == ["--"] else args.script
    if not script:
        parser.error("give the benchmark after --")
    if not (args.base / "bmg160_emu").is_dir():
        parser.error(f"{args.base}: no bmg160_emu package there")
    outputs: dict[str, list[list[str]]] = {"A": [], "B": []}
    loads: list[float] = []
    for _ in range(args.runs):
        for side, path in (("A", str(args.base.resolve())), ("B", None)):
            lines, load = _run(script, path)
            outputs[side].append(lines)
            loads.append(load)
    print(f"{' '.join(script)}: A = {args.base} (PYTHONPATH), B = this checkout; "
          f"{args.runs} runs each, alternated; load average {min(loads):.1f}-{max(loads):.1f}")
    parsed = {side: [{_key(t): v for t, v in reversed([_numbers(line) for line in lines])}
                     for lines in runs]
              for side, runs in outputs.items()}  # per run: template -> its first numbers
    for line in outputs["A"][0]:
        template, _ = _numbers(line)
        if "{}" not in template:
            print(line)
            continue
        values = {side: [run.get(_key(template)) for run in runs]
                  for side, runs in parsed.items()}
        if any(v is None for vs in values.values() for v in vs):
            print(line + "   (not printed by every run: not paired)")
            continue
        pieces = []
        for j in range(len(values["A"][0])):
            a_runs = [v[j] for v in values["A"]]
            b_runs = [v[j] for v in values["B"]]
            if len(set(a_runs + b_runs)) == 1:  # a count or a setting, the same everywhere
                pieces.append(f"{a_runs[0]:g}")
                continue
            a, b = statistics.median(a_runs), statistics.median(b_runs)
            ratio = f" [{b / a:.3f}]" if a > 0 and b > 0 else ""
            pieces.append(f"{a:g} -> {b:g}{ratio}")
        print(template.format(*pieces))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
