"""Run the worked example: ``python examples/basilisk_detumble/run_example.py``.

Writes ``report.md``, ``summary.json``, ``closed_loop.png`` and ``knowledge_error.png``
into ``--out`` (default ``basilisk_detumble_out``). ``--montecarlo RUNS`` then runs the
dispersed Monte Carlo (montecarlo_detumble.py) and writes its archive there too.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

import report
import scenario


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--duration", type=float, default=400.0, help="simulated seconds")
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--out", default="basilisk_detumble_out")
    parser.add_argument("--montecarlo", type=int, default=0, metavar="RUNS")
    parser.add_argument("--mc-duration", type=float, default=150.0)
    parser.add_argument("--scheduler", default="local", help="sync, local or a Dask address")
    parser.add_argument("--workers", type=int, default=None)
    args = parser.parse_args(argv)
    if args.duration <= 0 or args.montecarlo < 0:
        parser.error("--duration must be positive and --montecarlo >= 0")
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    result = scenario.run(scenario.Setup(duration_s=args.duration, seed=args.seed))
    (out / "report.md").write_text(report.text(result))
    (out / "summary.json").write_text(json.dumps(result.summary, indent=1) + "\n")
    for path in report.figures(result, out):
        print(f"figure: {path}")
    print(report.text(result))
    if args.montecarlo:
        import montecarlo_detumble

        mc = montecarlo_detumble.run(range(args.montecarlo), out / "montecarlo",
                                     duration_s=args.mc_duration, scheduler=args.scheduler,
                                     workers=args.workers)
        print(mc.describe())
    return 0


if __name__ == "__main__":
    sys.exit(main())
