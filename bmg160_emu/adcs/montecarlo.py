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
import logging
import os
import signal
import threading
from collections.abc import Callable, Iterable, Iterator, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from bmg160_emu.adcs.results import RunResult
from bmg160_emu.adcs.scenarios import Scenario, load_scenario
from bmg160_emu.progress import Progress

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
    planned_runs: int | None = None  # the runs that were asked for (run_montecarlo sets it)
    stopped_by: str | None = None  # "SIGINT" or "SIGTERM": the signal that stopped the job,
    # also when it came after the last run (then the result is complete)

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


def _progress(progress: bool | None | Progress) -> Progress:
    """The progress report of the runs: a :class:`~bmg160_emu.progress.Progress` as given,
    or one on stderr (``None``: a line redrawn on a terminal, and a long estimate said
    everywhere; ``True``: drawn even off a terminal; ``False``: nothing at all)."""
    if isinstance(progress, Progress):
        return progress
    if progress is False:
        return Progress("monte carlo", stream=_Discard(), terminal=False)
    return Progress("monte carlo", enabled=progress)


class _Discard:
    def write(self, text: str) -> int:
        return len(text)

    def flush(self) -> None:
        pass


class Interrupted(KeyboardInterrupt):
    """^C or SIGTERM during the runs; ``results`` holds the runs finished before it."""

    def __init__(self, results: list[RunResult], cause: BaseException) -> None:
        super().__init__()
        self.results = results
        self.signal_name = getattr(cause, "signal_name", "SIGINT")
        self.kept: str | None = None  # what cli's one line says was kept


def _run_sync(run: RunFunction, seeds: Sequence[int], progress: Progress) -> list[RunResult]:
    results: list[RunResult] = []
    try:  # the whole stage: a signal as the last run ends still keeps every run
        with progress.stage(len(seeds), "runs") as bar:
            for seed in seeds:
                results.append(run(seed))
                bar(len(results))
    except KeyboardInterrupt as exc:
        raise Interrupted(results, exc) from None
    return results


def _run_dask(run: RunFunction, seeds: Sequence[int], progress: Progress,
              address: str | None, workers: int | None) -> list[RunResult]:
    """The runs on a Dask cluster. A signal at any moment (the cluster starting, the runs,
    its shut-down) stops it the same way: the cluster is shut down and :class:`Interrupted`
    carries every run finished by then, all of them when the signal came during the
    shut-down (issue 35: a SIGTERM there used to lose them all)."""
    try:
        from distributed import Client, LocalCluster, as_completed
    except ImportError:  # pragma: no cover - depends on the installation
        raise RuntimeError(
            "Dask is not installed: pip install 'bmg160-emu[montecarlo]', or use scheduler='sync'"
        ) from None
    from bmg160_emu.io.atomic import held_signals

    cluster = client = None
    by_seed: dict[int, RunResult] = {}
    stop: BaseException | None = None
    try:
        if address is None:
            with held_signals():  # a ^C while the workers start is acted on once they have
                # (Dask's start-up printed a traceback, issue 24)
                with _workers_immune_to_sigint():
                    cluster = LocalCluster(
                        n_workers=workers or os.cpu_count() or 1,
                        threads_per_worker=1,  # CPU-bound Python runs: a process per core
                        processes=True,
                        # None still binds :8787 (distributed 2026.8): a busy port warned
                        dashboard_address=":0",
                        # the workers' WARNINGs and ERRORs at shut-down (a task cancelled,
                        # a heartbeat to the closed scheduler) are Dask's housekeeping, not
                        # the user's; a run's error comes back through its future and is
                        # said once, here (issue 35)
                        silence_logs=logging.CRITICAL,
                    )
                client = Client(cluster)
        else:
            client = _connect(Client, address)
        futures = client.map(run, list(seeds), pure=False)
        with progress.stage(len(seeds), "runs") as bar:
            for future in as_completed(futures):
                result = future.result()
                by_seed[result.seed] = result
                bar(len(by_seed))
    except KeyboardInterrupt as exc:
        stop = exc
    finally:
        late = _shut_down(client, cluster)
    if stop is None:
        stop = late  # during the shut-down: every run had finished
    if stop is not None:
        raise Interrupted([by_seed[s] for s in seeds if s in by_seed], stop)
    return [by_seed[s] for s in seeds]


def _connect(client_type: Any, address: str) -> Any:
    """A client of the scheduler at ``address`` (already checked by
    :func:`scheduler_address`), or a RuntimeError saying why not in one line: whatever
    answers there (another service, a wrong port) must not surface as Dask's traceback (a
    reply read as a frame length once asked numpy for 3.07 EiB, issue 35)."""
    try:
        return client_type(address, timeout="10s")
    except KeyboardInterrupt:
        raise
    except Exception as exc:  # noqa: BLE001 - any failure to connect is the user's one line
        detail = str(exc).splitlines()[0][:200] if str(exc) else type(exc).__name__
        raise RuntimeError(f"cannot reach the Dask scheduler at {address!r}: {detail} "
                           "(expected 'local', 'sync' or an address like "
                           "tcp://host:8786)") from None


@contextlib.contextmanager
def _workers_immune_to_sigint() -> Iterator[None]:
    """The local cluster's workers forked from a fork server that was started with SIGINT
    ignored: an ignored signal stays ignored across exec, CPython keeps it so at start-up,
    and the fork server hands its children the disposition it started with, so a worker
    never takes a SIGINT, from its first instruction on. A ^C at the terminal reaches the
    whole process group, and workers that died of it printed their own tracebacks (while
    importing Dask, before any code of ours could run in them) as this process was keeping
    the finished runs (issue 35); now this process alone owns the shut-down. (A signal mask
    does not survive multiprocessing's fork and exec: tried, the fork server's was clear.)
    SIGINT is ignored here only while the fork server's process is made, a fork and an exec
    (the fork server then imports Dask on its own, in its own time). Where there is no fork
    server (not POSIX), or one runs already (started by a program before us), the workers
    start as Dask starts them."""
    import multiprocessing

    if threading.current_thread() is not threading.main_thread() \
            or "forkserver" not in multiprocessing.get_all_start_methods():
        yield
        return
    import dask
    from distributed.utils import get_mp_context

    with dask.config.set({"distributed.worker.multiprocessing-method": "forkserver"}):
        get_mp_context()  # Dask's preload for the fork server: its packages, once
        from multiprocessing import forkserver

        previous = signal.signal(signal.SIGINT, signal.SIG_IGN)
        try:
            forkserver.ensure_running()
        finally:
            signal.signal(signal.SIGINT, previous if previous is not None else signal.SIG_DFL)
        yield


def _shut_down(client: Any, cluster: Any) -> BaseException | None:
    """Close the client and the local cluster with the signals held (a second ^C must not
    cut the shut-down, and Dask's own logging of the closing comms is silenced); returns
    the signal that came meanwhile, as the exception its handler raised, or None."""
    from bmg160_emu.io.atomic import held_signals

    quiet = _quiet_dask_logs()
    try:
        with held_signals():
            if client is not None:
                client.close()
            if cluster is not None:
                cluster.close()
    except KeyboardInterrupt as exc:  # held, then delivered: the runs are all in
        return exc
    finally:
        quiet.close()
    return None


class _quiet_dask_logs:
    """Dask's loggers in this process at ERROR while the cluster closes (a heartbeat that
    finds its comm closed logs a WARNING); restored by ``close()``."""

    NAMES = ("distributed", "tornado", "asyncio")

    def __init__(self) -> None:
        self.levels = {}
        for name in self.NAMES:
            logger = logging.getLogger(name)
            self.levels[name] = logger.level
            logger.setLevel(max(logger.level, logging.CRITICAL))

    def close(self) -> None:
        for name, level in self.levels.items():
            logging.getLogger(name).setLevel(level)


def run_montecarlo(
    scenario: Scenario | str | Path,
    seeds: Sequence[int],
    *,
    scheduler: str = "local",
    workers: int | None = None,
    progress: bool | None | Progress = None,
    percentiles: Iterable[float] = DEFAULT_PERCENTILES,
    run: RunFunction | None = None,
) -> MonteCarloResult:
    """Run ``scenario`` once per seed and summarise the angle error over time.

    ``scheduler``: ``"local"`` (Dask local cluster, ``workers`` processes, default all cores),
    ``"sync"`` (this process, no Dask), or a Dask scheduler address such as
    ``"tcp://10.0.0.5:8786"``. ``run`` replaces the default per-seed run
    (:class:`bmg160_emu.adcs.evaluation.PropagationRun`) by any picklable ``f(seed) ->
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
    from bmg160_emu.io.atomic import held_signals

    stopped_by = None
    try:
        results = map_runs(run, seeds, scheduler=scheduler, workers=workers, progress=progress)
    except Interrupted as stop:
        if not stop.results:
            stop.kept = "no run had finished: nothing to summarise or write"
            raise
        # the finished runs are kept: summarised (in seed order) and marked as interrupted
        results, stopped_by = stop.results, stop.signal_name
    summary = None
    while summary is None:  # the runs are in: a signal now waits for their summary
        try:
            with held_signals():
                summary = reduce_runs(scenario.name, results, percentiles)
        except KeyboardInterrupt as exc:
            stopped_by = stopped_by or getattr(exc, "signal_name", "SIGINT")
    summary.planned_runs = len(seeds)
    summary.stopped_by = stopped_by
    return summary


def map_runs(run: RunFunction, seeds: Iterable[int], *, scheduler: str = "local",
             workers: int | None = None,
             progress: bool | None | Progress = None) -> list[RunResult]:
    """``run(seed)`` for every seed on ``scheduler`` (as :func:`run_montecarlo`), in seed
    order: for any picklable run (the Basilisk example's closed loop, ...). ``progress``:
    see :func:`_progress`."""
    seeds = [int(s) for s in seeds]
    if not seeds:
        raise ValueError("no seeds to run")
    address = scheduler_address(scheduler)
    if address == "sync":
        return _run_sync(run, seeds, _progress(progress))
    return _run_dask(run, seeds, _progress(progress), None if address == "local" else address,
                     workers)


def default_scheduler() -> tuple[str, str | None]:
    """The scheduler when none is asked for: Dask's local cluster where Dask is installed,
    else this process, with a note that says so and how to get Dask (the CLI and the
    Basilisk example fall back alike, issue 35)."""
    import importlib.util

    if all(importlib.util.find_spec(name) is not None for name in ("dask", "distributed")):
        return "local", None
    return "sync", ("Dask is not installed: the runs go in this process (scheduler sync); "
                    "pip install 'bmg160-emu[montecarlo]' runs them on all cores")


SCHEMES = ("tcp", "tls", "inproc", "ucx", "ws", "wss")  # distributed's comm back ends


def scheduler_address(text: str) -> str:
    """``local``, ``sync`` or a Dask scheduler address (``tcp://host:8786``, ``host:8786``),
    checked before anything connects: a scheme distributed knows, a host name or IP address,
    a port from 1 to 65535. ValueError says what is wrong in one line (``5:2`` once reached
    another service that answered with a 3.07 EiB frame; ``0:99999999999999999999``
    overflowed the resolver, issue 35)."""
    import ipaddress
    import re

    if text in ("local", "sync"):
        return text
    def cut(part: str, width: int = 40) -> str:
        return part if len(part) <= width else part[:width - 3] + "..."

    shown = cut(text, 60)
    expected = (f"--scheduler {shown!r}: expected 'local', 'sync' or a Dask scheduler address "
                "like tcp://host:8786")
    scheme, sep, rest = text.partition("://")
    if not sep:
        scheme, rest = "tcp", text
    if scheme not in SCHEMES:
        raise ValueError(f"{expected} (scheme one of {', '.join(SCHEMES)})")
    if scheme == "inproc":
        return text
    if rest.startswith("["):  # [IPv6]:port
        host, _, port_text = rest[1:].partition("]")
        has_port = port_text != ""  # "]:8786"; anything else after "]" fails the port check
        port_text = port_text.removeprefix(":")
        try:
            ipaddress.IPv6Address(host)
        except ValueError:
            raise ValueError(f"{expected} ({cut(host)!r} is not an IPv6 address)") from None
    else:
        has_port = ":" in rest  # "host:" too: an empty port is no port
        host, _, port_text = rest.rpartition(":") if has_port else (rest, "", "")
        if re.fullmatch(r"[0-9.]+", host):
            try:
                ipaddress.IPv4Address(host)
            except ValueError:
                raise ValueError(f"{expected} ({cut(host)!r} is not an IPv4 address a.b.c.d)") \
                    from None
        elif not re.fullmatch(r"(?=.{1,253}$)[A-Za-z0-9]([A-Za-z0-9-]*[A-Za-z0-9])?"
                              r"(\.[A-Za-z0-9]([A-Za-z0-9-]*[A-Za-z0-9])?)*", host):
            raise ValueError(f"{expected} ({cut(host)!r} is not a host name)")
    if has_port and (not re.fullmatch(r"[0-9]{1,5}", port_text)
                      or not 1 <= int(port_text) <= 65535):
        raise ValueError(f"{expected} (the port must be 1 to 65535, not "
                         f"{cut(port_text, 20)!r})")
    return text
