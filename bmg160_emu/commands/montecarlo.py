"""``bmg160-emu montecarlo``: run a scenario over many noise seeds, print error percentiles."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from bmg160_emu import limits
from bmg160_emu.commands._common import (
    Subparsers,
    add_command_parser,
    add_progress_options,
    bounded_option,
)

EPILOG = """\
examples:
  bmg160-emu montecarlo examples/scenarios/orbit_pointing.toml --runs 1000
  bmg160-emu montecarlo examples/scenarios/orbit_pointing.toml --runs 200 --seeds 5000 --workers 2 --output mc.csv
  bmg160-emu montecarlo examples/scenarios/orbit_pointing.toml --seeds 0:64 --scheduler tcp://10.0.0.5:8786

Each run is one noise realisation (seed) of every gyro in the scenario; the attitude
propagated from the gyro output is compared with the true attitude, and the percentiles of
the angle error across runs are printed over time. The same seeds give the same numbers
whatever the scheduler.
"""


def register(subparsers: Subparsers) -> None:
    parser = add_command_parser(
        subparsers,
        "montecarlo",
        "run an ADCS scenario over many noise seeds: angle-error percentiles, to CSV or JSON",
        "Run a scenario file (TOML, docs/scenarios.md) once per noise seed and summarise the "
        "angle error of the propagated attitude against truth as percentiles over time.",
        EPILOG,
    )
    parser.add_argument("scenario", metavar="SCENARIO", help="scenario file (TOML)")
    parser.add_argument("--runs", type=bounded_option(limits.RUNS), default=None, metavar="N",
                        help="number of runs (default 100)")
    parser.add_argument("--seeds", default=None, metavar="START|A:B|LIST",
                        help="START (seeds START..START+runs-1, default 0), A:B (B excluded) "
                        "or 1,5,9")
    parser.add_argument(
        "--scheduler", default=None, metavar="local|sync|ADDRESS",
        help="'local' (Dask local cluster; the default with the [montecarlo] extra), 'sync' "
        "(this process; the default without Dask) or a Dask scheduler address such as "
        "tcp://host:8786",
    )
    parser.add_argument("--workers", type=bounded_option(limits.WORKERS), default=None,
                        metavar="N", help="local worker processes (default: all cores)")
    parser.add_argument("--percentiles", default="50,90,95,99", metavar="P,P,...",
                        help="comma-separated percentiles of the angle error (default "
                        "50,90,95,99)")
    parser.add_argument("-o", "--output", default=None, metavar="FILE",
                        help="write the curves to FILE (.json or .csv)")
    parser.add_argument("--rows", type=bounded_option(limits.ROWS), default=10, metavar="N",
                        help="rows of the printed table (default 10)")
    add_progress_options(parser)
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from bmg160_emu.adcs.montecarlo import MonteCarloResult, parse_seeds, run_montecarlo
    from bmg160_emu.adcs.scenarios import ScenarioError, load_scenario
    from bmg160_emu.commands._common import CommandError
    from bmg160_emu.faults import FaultError

    if args.runs is not None and args.runs < 1:
        raise CommandError("--runs must be at least 1")
    if args.workers is not None and args.workers < 1:
        raise CommandError("--workers must be at least 1")
    runs = args.runs
    if runs is None and (args.seeds is None or not any(c in args.seeds for c in ":,")):
        runs = 100  # the default run count, also for a START seed (A:B and lists count themselves)
    try:
        seeds = parse_seeds(args.seeds, runs)
        percentiles = [float(p) for p in args.percentiles.split(",") if p.strip()]
    except ValueError as exc:
        raise CommandError(str(exc)) from None
    if not percentiles or not all(0 <= p <= 100 for p in percentiles):
        raise CommandError("--percentiles must be numbers within 0..100")
    if args.output and not args.output.endswith((".json", ".csv")):
        raise CommandError("--output must end in .json or .csv")
    if args.output:
        from bmg160_emu.commands._common import check_writable

        check_writable(Path(args.output))  # before the runs: else all of them would be lost
    scheduler = _scheduler(args.scheduler)
    try:
        scenario = load_scenario(args.scenario)
    except ScenarioError as exc:
        raise CommandError(_named(str(exc), args.scenario)) from None
    _check_memory(scenario, len(seeds), args.scenario)
    from bmg160_emu.progress import Progress

    progress = Progress("bmg160-emu montecarlo", enabled=args.progress)
    result: MonteCarloResult | None = None
    reported = False

    def report() -> None:  # the summary and the file, with a signal held until both are out
        nonlocal reported
        from bmg160_emu.io.atomic import held_signals

        assert result is not None
        with held_signals():
            print(result.summary(rows=max(2, args.rows)))
            if args.output:
                try:
                    result.write(args.output)
                except OSError as exc:
                    raise CommandError(f"cannot write {args.output}: {exc.strerror or exc} "
                                       "(the table above holds the results)") from None
                print(f"curves written to {args.output}")
            reported = True

    stopped = None
    try:
        try:
            result = run_montecarlo(scenario, seeds, scheduler=scheduler, workers=args.workers,
                                    progress=progress, percentiles=percentiles)
        except (ScenarioError, FaultError) as exc:  # a table of the file: named by it
            raise CommandError(_named(str(exc), args.scenario)) from None
        except (RuntimeError, ValueError) as exc:
            raise CommandError(str(exc)) from None
        report()
    except KeyboardInterrupt as exc:  # held while writing, or between the runs and the report
        if result is None:
            raise  # no run had finished (its own message says so)
        stopped = getattr(exc, "signal_name", "SIGINT")
        while not reported:  # a signal came before the report began: the runs are kept
            try:
                report()
            except KeyboardInterrupt:
                pass
    stopped = result.stopped_by or stopped
    if stopped is not None and not result.interrupted:
        print(f"bmg160-emu montecarlo: interrupted by {stopped} after all {result.runs} runs; "
              "the summary above" + (f" and {args.output} are complete" if args.output
                                     else " is complete"), file=sys.stderr)
        return 143 if stopped == "SIGTERM" else 130
    if result.interrupted:
        print(f"bmg160-emu montecarlo: interrupted by {stopped} after {result.runs} of "
              f"{result.planned_runs} runs; the finished runs are summarised above"
              + (f" and in {args.output}" if args.output else ""), file=sys.stderr)
        return 143 if stopped == "SIGTERM" else 130
    return 0


# Bytes held per run and grid time until the summary: the run's error and time arrays, their
# stack across runs, and np.percentile's sorted copy of it (4 arrays of float64)
BYTES_PER_RUN_AND_TIME = 32


def _check_memory(scenario, runs: int, path: str) -> None:
    """Every run's curve is kept until the percentiles are taken: refuse, before the runs, what
    this process cannot hold (a million runs of a 1-day scenario on a 1 s grid are 2.8 TB)."""
    from bmg160_emu.adcs.evaluation import readout_options
    from bmg160_emu.adcs.scenarios import ScenarioError
    from bmg160_emu.commands._common import CommandError, check_memory

    try:
        times = int(scenario.duration_s / readout_options(scenario)["grid_s"]) + 1
    except ScenarioError as exc:
        raise CommandError(_named(str(exc), path)) from None
    check_memory(runs * times * BYTES_PER_RUN_AND_TIME,
                 f"keeping {runs:,} runs of {times:,} grid times each",
                 "fewer --runs, or a coarser [readout] grid_s in the scenario")


def _named(message: str, scenario: str) -> str:
    """A scenario error found after loading names the file too."""
    return message if message.startswith(str(scenario)) else f"{scenario}: {message}"


def _scheduler(scheduler: str | None) -> str:
    """The scheduler this install can use (Dask's local cluster, or this process without
    Dask, said on stderr), its address checked before any work (issue 35)."""
    from bmg160_emu.adcs.montecarlo import scheduler_address
    from bmg160_emu.commands._common import CommandError
    from bmg160_emu.commands._extras import available, install_line

    has_dask = available("dask") and available("distributed")
    if scheduler is None:
        scheduler = "local" if has_dask else "sync"
        if not has_dask:
            print("bmg160-emu montecarlo: Dask is not installed: the runs go in this process "
                  f"(--scheduler sync); {install_line('montecarlo')} runs them on all cores",
                  file=sys.stderr)
    try:
        scheduler = scheduler_address(scheduler)
    except ValueError as exc:
        raise CommandError(str(exc)) from None
    if scheduler != "sync" and not has_dask:
        raise CommandError(f"--scheduler {scheduler} needs the [montecarlo] extra (Dask): "
                           f"{install_line('montecarlo')}, or --scheduler sync")
    return scheduler
