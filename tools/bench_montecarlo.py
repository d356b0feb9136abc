"""Monte Carlo throughput on this machine: runs per minute, and the speed-up from 1 to 2 workers.

    python tools/bench_montecarlo.py [--runs 16] [--scenario examples/scenarios/orbit_pointing.toml]

Three measurements of the same seeds in the same process, so they compare like with like:
in-process (no Dask), a Dask local cluster with 1 worker, and one with 2 workers. Cluster
start-up is timed separately and left out of the run rates. The machine may be shared:
repeat and read the ratios, not the absolute figures. The results of the three are also
checked to be identical (same seeds, same numbers).
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

from bmg160_emu.adcs.evaluation import PropagationRun
from bmg160_emu.adcs.scenarios import load_scenario

DEFAULT_SCENARIO = Path(__file__).resolve().parent.parent / "examples/scenarios/orbit_pointing.toml"


def _dask_rate(run, seeds, workers):
    from distributed import Client, LocalCluster

    started = time.perf_counter()
    cluster = LocalCluster(n_workers=workers, threads_per_worker=1, processes=True,
                           dashboard_address=None)
    client = Client(cluster)
    client.submit(run, seeds[0], pure=False).result()  # warm-up: imports in every worker
    client.run(lambda: None)
    startup = time.perf_counter() - started
    begin = time.perf_counter()
    results = client.gather(client.map(run, seeds, pure=False))
    elapsed = time.perf_counter() - begin
    client.close()
    cluster.close()
    return elapsed, startup, results


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=16)
    parser.add_argument("--scenario", default=str(DEFAULT_SCENARIO))
    args = parser.parse_args()
    scenario = load_scenario(args.scenario)
    run = PropagationRun(scenario)
    seeds = list(range(1000, 1000 + args.runs))
    run(seeds[0])  # warm-up: imports and caches in this process

    begin = time.perf_counter()
    reference = [run(s) for s in seeds]
    in_process = time.perf_counter() - begin
    one, start_one, res_one = _dask_rate(run, seeds, 1)
    two, start_two, res_two = _dask_rate(run, seeds, 2)

    same = all(np.array_equal(a.angle_error_deg, b.angle_error_deg) and
               np.array_equal(a.angle_error_deg, c.angle_error_deg)
               for a, b, c in zip(reference, res_one, res_two))
    per_min = lambda seconds: 60.0 * args.runs / seconds
    print(f"scenario {scenario.name!r}, {scenario.duration_s:g} s simulated per run, "
          f"{args.runs} runs")
    print(f"in process (no Dask)   : {per_min(in_process):8.1f} runs/min")
    print(f"Dask local, 1 worker   : {per_min(one):8.1f} runs/min  (cluster start {start_one:.1f} s)")
    print(f"Dask local, 2 workers  : {per_min(two):8.1f} runs/min  (cluster start {start_two:.1f} s)")
    print(f"speed-up 1 -> 2 workers: {one / two:8.2f} x")
    print(f"Dask overhead, 1 worker against in process: {one / in_process:.2f} x the time")
    print(f"identical results across schedulers: {same}")
    return 0 if same else 1


if __name__ == "__main__":
    raise SystemExit(main())
