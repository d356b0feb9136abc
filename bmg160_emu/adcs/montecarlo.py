"""Monte Carlo: one scenario over many noise seeds, summarised as angle-error percentiles.

Each run depends on its seed only (noise realisations and random faults are all drawn from
it), so the runs can go anywhere: in this process (``scheduler="sync"``), on local cores
through Dask's local cluster (the default), or on an existing Dask cluster given by its
address. Results are gathered in seed order and reduced here, so the same seeds give the
same numbers, bit for bit, whatever the scheduler.
"""

from __future__ import annotations

import contextlib
import json
import os
import signal
import sys
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from types import SimpleNamespace
from typing import Any

import numpy as np

from bmg160_emu.adcs.results import RunResult
from bmg160_emu.adcs.scenarios import Scenario, load_scenario

DEFAULT_PERCENTILES = (50.0, 90.0, 95.0, 99.0)

RunFunction = Callable[[int], RunResult]


@dataclass
class MonteCarloResult:
    """Runs in seed order and their percentiles over time."""

    scenario: str
    seeds: list[int]
    times_s: np.ndarray
    angle_error_deg: np.ndarray  # (runs, times)
    percentiles: dict[float, np.ndarray]
    extras: dict[str, np.ndarray] = field(default_factory=dict)
    planned_runs: int | None = None  # set when interrupted: the runs that were asked for
    stopped_by: str | None = None  # "SIGINT" or "SIGTERM" when interrupted

    @property
    def interrupted(self) -> bool:
        return self.planned_runs is not None and self.planned_runs > len(self.seeds)

    @property
    def runs(self) -> int:
        return len(self.seeds)

    def final_percentiles(self) -> dict[float, float]:
        return {p: float(v[-1]) for p, v in self.percentiles.items()}

    def summary(self, rows: int = 10) -> str:
        """A table of the percentiles at ``rows`` evenly spaced times, for a terminal."""
        header = "  time_s" + "".join(f"{f'p{p:g}_deg':>12}" for p in self.percentiles)
        picks = np.unique(np.linspace(0, self.times_s.size - 1, rows).round().astype(int))
        runs = f"{self.runs} runs"
        if self.interrupted:
            runs = f"{self.runs} of {self.planned_runs} runs (interrupted)"
        lines = [(f"scenario {self.scenario}: {runs}, angle error of the propagated "
                 "attitude against truth"), header]
        for i in picks:
            cells = "".join(f" {v[i]:11.5f}" for v in self.percentiles.values())
            lines.append(f"{self.times_s[i]:8.2f}{cells}")
        return "\n".join(lines)

    def to_dict(self) -> dict[str, Any]:
        return {
            "scenario": self.scenario,
            "seeds": self.seeds,
            "runs_planned": self.planned_runs or len(self.seeds),
            "interrupted": self.interrupted,
            "times_s": self.times_s.tolist(),
            "percentiles_deg": {f"p{p:g}": v.tolist() for p, v in self.percentiles.items()},
            "extras": {k: v.tolist() for k, v in self.extras.items()},
        }

    def write(self, path: str | Path) -> None:
        """JSON with the percentile curves, or CSV (time and one column per percentile); the
        file appears whole or not at all (bmg160_emu.io.atomic). The curves of an interrupted
        run say so in the file: JSON ``"interrupted": true``, CSV a last line ``# partial: ...``
        (docs/outputs.md)."""
        from bmg160_emu.io.atomic import atomic_path

        path = Path(path)
        with atomic_path(path) as partial:
            if path.suffix == ".csv":
                names = [f"p{p:g}_deg" for p in self.percentiles]
                table = np.column_stack([self.times_s, *self.percentiles.values()])
                np.savetxt(partial, table, delimiter=",", header=",".join(["time_s", *names]),
                           comments="", fmt="%.9g")
                if self.interrupted:  # in the file: the curves of fewer runs than asked for
                    with partial.open("a", encoding="utf-8") as handle:
                        handle.write(f"# partial: {self.runs} of {self.planned_runs} runs "
                                     f"(interrupted by {self.stopped_by or 'a signal'})\n")
            else:
                partial.write_text(json.dumps(self.to_dict(), indent=1) + "\n")


def reduce_runs(
    scenario_name: str,
    results: Sequence[RunResult],
    percentiles: Iterable[float] = DEFAULT_PERCENTILES,
) -> MonteCarloResult:
    """Stack runs (already in seed order) and take percentiles across runs at each time."""
    if not results:
        raise ValueError("no runs to summarise")
    times = results[0].times_s
    for r in results:
        if r.times_s.shape != times.shape or not np.array_equal(r.times_s, times):
            raise ValueError(f"run with seed {r.seed} has another time grid than the first run")
    errors = np.stack([r.angle_error_deg for r in results])
    levels = {float(p): np.percentile(errors, p, axis=0) for p in percentiles}
    extras = {k: np.array([r.extras.get(k, np.nan) for r in results]) for k in results[0].extras}
    return MonteCarloResult(scenario_name, [r.seed for r in results], times, errors, levels, extras)


def parse_seeds(text: str | None, runs: int | None) -> list[int]:
    """Seeds from the command line: ``START`` (with runs), ``A:B`` (B excluded) or ``1,5,9``."""
    if text is None:
        if runs is None:
            raise ValueError("give --runs, --seeds or both")
        text = "0"
    from bmg160_emu.limits import RUNS, SEED_START, LimitError

    text = text.strip()
    try:  # each seed, and the count, bounded before any list is made (0:10**12 was one)
        if ":" in text:
            first, _, last = text.partition(":")
            a, b = SEED_START.parse(first, "--seeds"), SEED_START.parse(last, "--seeds")
            RUNS.check(max(b - a, 1), f"--seeds {text}")
            seeds = list(range(a, b))
        elif "," in text:
            seeds = [SEED_START.parse(s, "--seeds") for s in text.split(",")[: int(RUNS.high) + 1]
                     if s.strip()]
            RUNS.check(len(seeds), f"--seeds {text[:40]}")
        else:
            start = SEED_START.parse(text, "--seeds")
            seeds = list(range(start, start + (runs if runs is not None else 1)))
    except LimitError as exc:
        raise ValueError(str(exc)) from None
    if runs is not None and len(seeds) != runs and (":" in text or "," in text):
        raise ValueError(f"--runs {runs} but --seeds {text!r} gives {len(seeds)} seeds")
    if not seeds:
        raise ValueError(f"no seeds in {text!r}")
    if len(set(seeds)) != len(seeds) or min(seeds) < 0:
        raise ValueError("seeds must be distinct non-negative integers")
    return seeds


def _progress(total: int, enabled: bool | None):
    # enabled None: a bar only on a terminal, so logs and CI output stay clean
    disable = (not sys.stderr.isatty()) if enabled is None else not enabled
    if disable:  # no bar: tqdm (an extra) is not needed
        return contextlib.nullcontext(SimpleNamespace(update=lambda n: None))
    from tqdm import tqdm

    from bmg160_emu.io.atomic import held_signals

    # held: a signal inside tqdm's constructor left a half-built bar whose __del__ printed
    # an AttributeError traceback (found by tests/_fuzz_signals.py)
    with held_signals():
        return tqdm(total=total, unit="run", desc="monte carlo")


class Interrupted(KeyboardInterrupt):
    """^C or SIGTERM during the runs; ``results`` holds the runs finished before it."""

    def __init__(self, results: list[RunResult], cause: BaseException) -> None:
        super().__init__()
        self.results = results
        self.signal_name = getattr(cause, "signal_name", "SIGINT")
        self.kept: str | None = None  # what cli's one line says was kept


def _run_sync(run: RunFunction, seeds: Sequence[int], progress: bool | None) -> list[RunResult]:
    results: list[RunResult] = []
    with _progress(len(seeds), progress) as bar:
        try:
            for seed in seeds:
                results.append(run(seed))
                bar.update(1)
        except KeyboardInterrupt as exc:
            raise Interrupted(results, exc) from None
    return results


def _run_dask(run: RunFunction, seeds: Sequence[int], progress: bool | None,
              address: str | None, workers: int | None) -> list[RunResult]:
    try:
        from distributed import Client, LocalCluster, as_completed
    except ImportError:  # pragma: no cover - depends on the installation
        raise RuntimeError(
            "Dask is not installed: pip install 'bmg160-emu[montecarlo]', or use scheduler='sync'"
        ) from None
    from bmg160_emu.io.atomic import held_signals

    cluster = None
    if address is None:
        with held_signals() as arrived:  # a ^C while the workers start is acted on once they
            cluster = LocalCluster(      # have (Dask's start-up printed a traceback, issue 24)
                n_workers=workers or os.cpu_count() or 1,
                threads_per_worker=1,  # the runs are CPU-bound Python: one process per core
                processes=True,
                # None still binds :8787 (distributed 2026.8): a busy port gave a warning
                dashboard_address=":0",
            )
            client = Client(cluster)
            if arrived:  # stopped before any run: the cluster goes down before the signal acts
                client.close()
                cluster.close()
        if arrived:  # held_signals delivered it; should a handler have let it pass (seen once
            cause = KeyboardInterrupt()  # in campaign 3: client.map on the closed client)
            cause.signal_name = signal.Signals(arrived[0]).name  # type: ignore[attr-defined]
            raise Interrupted([], cause)
    else:
        try:
            client = Client(address, timeout="10s")
        except (OSError, ValueError, TimeoutError) as exc:
            raise RuntimeError(f"cannot reach the Dask scheduler at {address!r}: {exc} "
                               "(expected 'local', 'sync' or an address like "
                               "tcp://host:8786)") from None
    try:
        futures = client.map(run, list(seeds), pure=False)
        by_seed: dict[int, RunResult] = {}
        with _progress(len(seeds), progress) as bar:
            try:
                for future in as_completed(futures):
                    result = future.result()
                    by_seed[result.seed] = result
                    bar.update(1)
            except KeyboardInterrupt as exc:
                raise Interrupted([by_seed[s] for s in seeds if s in by_seed], exc) from None
        return [by_seed[s] for s in seeds]
    finally:
        with held_signals():  # a second ^C must not cut the cluster's shut-down
            client.close()
            if cluster is not None:
                cluster.close()


def run_montecarlo(
    scenario: Scenario | str | Path,
    seeds: Sequence[int],
    *,
    scheduler: str = "local",
    workers: int | None = None,
    progress: bool | None = None,
    percentiles: Iterable[float] = DEFAULT_PERCENTILES,
    run: RunFunction | None = None,
) -> MonteCarloResult:
    """Run ``scenario`` once per seed and summarise the angle error over time.

    ``scheduler``: ``"local"`` (Dask local cluster, ``workers`` processes, default all cores),
    ``"sync"`` (this process, no Dask), or a Dask scheduler address such as
    ``"tcp://10.0.0.5:8786"``. ``run`` replaces the default per-seed run
    (:func:`bmg160_emu.adcs.evaluation.propagation_run`) by any picklable ``f(seed) ->
    RunResult``.
    """
    if not isinstance(scenario, Scenario):
        scenario = load_scenario(scenario)
    seeds = [int(s) for s in seeds]
    if not seeds:
        raise ValueError("no seeds to run")
    if run is None:
        from bmg160_emu.adcs.evaluation import PropagationRun

        run = PropagationRun(scenario)
    try:
        results = map_runs(run, seeds, scheduler=scheduler, workers=workers, progress=progress)
    except Interrupted as stop:
        if not stop.results:
            stop.kept = "no run had finished: nothing to summarise or write"
            raise
        # the finished runs are kept: summarised (in seed order) and marked as interrupted
        partial = reduce_runs(scenario.name, stop.results, percentiles)
        partial.planned_runs = len(seeds)
        partial.stopped_by = stop.signal_name
        return partial
    return reduce_runs(scenario.name, results, percentiles)


def map_runs(run: RunFunction, seeds: Iterable[int], *, scheduler: str = "local",
             workers: int | None = None, progress: bool | None = None) -> list[RunResult]:
    """``run(seed)`` for every seed on ``scheduler`` (as :func:`run_montecarlo`), in seed
    order: for any picklable run (the Basilisk example's closed loop, ...)."""
    seeds = [int(s) for s in seeds]
    if not seeds:
        raise ValueError("no seeds to run")
    if scheduler == "sync":
        return _run_sync(run, seeds, progress)
    return _run_dask(run, seeds, progress, None if scheduler == "local" else scheduler, workers)
