"""Run the worked example: ``python examples/basilisk_detumble/run_example.py``.

Writes ``report.md``, ``summary.json``, ``closed_loop.png`` and ``knowledge_error.png``
into ``--out`` (default ``basilisk_detumble_out``). ``--profile`` flies your own gyro (a
profile from ``bmg160-emu identify --profile-out``; with ``--identification``, that record's
``identify --json`` for the ground calibration and the Monte Carlo's intervals), and the
report predicts the knowledge error from its N, B, T and K. ``--montecarlo RUNS`` then runs
the dispersed Monte Carlo (montecarlo_detumble.py) and writes its archive there too.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

import montecarlo_detumble
import report
import scenario


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--duration", type=float, default=400.0, help="simulated seconds")
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--out", default="basilisk_detumble_out")
    montecarlo_detumble.add_gyro_options(parser)
    parser.add_argument("--montecarlo", type=int, default=0, metavar="RUNS")
    parser.add_argument("--mc-duration", type=float, default=150.0)
    parser.add_argument("--scheduler", default=None,
                        help="sync, local or a Dask address (default: local with Dask, else "
                        "sync, as bmg160-emu montecarlo)")
    parser.add_argument("--workers", type=int, default=None)
    args = parser.parse_args(argv)
    if not 0 < args.duration <= 30 * 86400 or args.montecarlo < 0 \
            or not 0 < args.mc_duration <= 30 * 86400:
        parser.error("--duration and --mc-duration must be positive (at most 30 days) and "
                     "--montecarlo >= 0")
    for option, path in (("--profile", args.profile), ("--identification",
                                                        args.identification)):
        if path not in (None, "paper") and not Path(path).is_file():
            parser.error(f"{option} {path}: no such file")
    setup = scenario.Setup(duration_s=args.duration, seed=args.seed, profile=args.profile,
                           identification=montecarlo_detumble.identification_for(args))
    try:
        setup_noise = scenario.profile_axes(setup)  # a bad profile: one line, before the run
        calibration = scenario.bias_calibration_dps(setup)
    except (ValueError, KeyError, OSError) as exc:
        parser.error(f"{exc}")
    del setup_noise, calibration
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    result = scenario.run(setup)
    (out / "report.md").write_text(report.text(result))
    (out / "summary.json").write_text(json.dumps(result.summary, indent=1) + "\n")
    for path in report.figures(result, out):
        print(f"figure: {path}")
    print(report.text(result))
    if args.montecarlo:
        mc = montecarlo_detumble.run(
            range(args.montecarlo), out / "montecarlo", duration_s=args.mc_duration,
            scheduler=montecarlo_detumble.scheduler_or_default(args.scheduler),
            workers=args.workers, profile=args.profile,
            identification=montecarlo_detumble.identification_for(args))
        print(mc.describe())
    return 0


if __name__ == "__main__":
    sys.exit(main())
