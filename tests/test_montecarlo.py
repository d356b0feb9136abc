"""Monte Carlo over noise seeds: same seeds, same numbers, whatever the scheduler."""

from __future__ import annotations

import math

import numpy as np
import pytest

from bmg160_emu.adcs.montecarlo import (
    MonteCarloResult,
    RunResult,
    parse_seeds,
    reduce_runs,
    run_montecarlo,
)
from bmg160_emu.adcs.scenarios import scenario_from_dict
from bmg160_emu.cli import main
from bmg160_emu.commands._extras import available

# the [montecarlo] extra; the default test install ([test]) leaves Dask out
needs_dask = pytest.mark.skipif(not available("distributed"),
                                reason="Dask is not installed: pip install 'bmg160-emu[montecarlo]'")

WHITE = {ax: {"N": 1.779073e-2, "B": 0.0, "T": 1.0, "K": 0.0, "bias": 0.0} for ax in "xyz"}

SCENARIO_TOML = """
name = "short slew"
duration_s = 3.0

[[motion]]
kind = "slew"
axis = [0, 0, 1]
angle_deg = 2.0
max_rate_dps = 2.0
max_accel_dps2 = 4.0
start_s = 1.0

[readout]
range_dps = 250
bias = "profile"
grid_s = 0.5
"""


def _short():
    return scenario_from_dict({"duration_s": 3.0, "motion": [
        {"kind": "constant", "rate_dps": [0.0, -0.06, 0.0]}],
        "readout": {"grid_s": 0.5, "bias": "profile"}})


@needs_dask
def test_same_seeds_give_identical_results_in_process_and_on_a_dask_local_cluster():
    seeds = [3, 4, 5, 6]
    in_process = run_montecarlo(_short(), seeds, scheduler="sync", progress=False)
    on_dask = run_montecarlo(_short(), seeds, scheduler="local", workers=2, progress=False)
    assert on_dask.seeds == seeds
    assert np.array_equal(in_process.angle_error_deg, on_dask.angle_error_deg)
    for p in in_process.percentiles:
        assert np.array_equal(in_process.percentiles[p], on_dask.percentiles[p])
    other = run_montecarlo(_short(), [7, 8, 9, 10], scheduler="sync", progress=False)
    assert not np.array_equal(other.angle_error_deg, in_process.angle_error_deg)


def test_angle_error_of_white_noise_grows_like_n_sqrt_t():
    # Per axis the angle error is N sqrt(t) (angle random walk); its 3-D magnitude is
    # Maxwell-distributed with median 1.5382 N sqrt(t). With 30 runs the sample median has a
    # relative standard error of about 1.2533 * 0.44 / sqrt(30) = 10 %: accept 35 %.
    scenario = scenario_from_dict({"duration_s": 6.5, "gyro": [{"profile": WHITE}],
                                   "readout": {"grid_s": 1.0, "bias": "profile"}})
    result = run_montecarlo(scenario, range(30), scheduler="sync", progress=False)
    elapsed = result.times_s - 0.5  # the estimator starts after the 0.5 s settling time
    expected = 1.5382 * 1.779073e-2 * np.sqrt(elapsed)
    assert np.allclose(result.percentiles[50.0], expected, rtol=0.35)
    # and it grows: the last median is about sqrt(6) times the first
    assert result.percentiles[50.0][-1] / result.percentiles[50.0][0] > 0.6 * math.sqrt(6)


def test_percentiles_are_taken_across_runs_at_each_time():
    times = np.array([1.0, 2.0])
    runs = [RunResult(s, times, np.array([s, 10.0 * s])) for s in range(1, 102)]
    result = reduce_runs("x", runs, percentiles=[50, 90])
    assert np.allclose(result.percentiles[50.0], [51.0, 510.0])
    assert np.allclose(result.percentiles[90.0], [91.0, 910.0])
    with pytest.raises(ValueError, match="another time grid"):
        reduce_runs("x", [runs[0], RunResult(9, np.array([1.0]), np.array([0.0]))])


def test_results_are_written_as_csv_or_json(tmp_path):
    times = np.array([1.0, 2.0])
    result = reduce_runs("x", [RunResult(s, times, np.array([s, s + 1.0])) for s in range(5)])
    assert isinstance(result, MonteCarloResult)
    result.write(tmp_path / "mc.csv")
    table = np.loadtxt(tmp_path / "mc.csv", delimiter=",", skiprows=1)
    assert np.allclose(table[:, 0], times)
    assert np.allclose(table[:, 1], [2.0, 3.0])  # median of 0..4 and 1..5
    result.write(tmp_path / "mc.json")
    assert '"p50"' in (tmp_path / "mc.json").read_text()


@pytest.mark.parametrize(
    "text, runs, seeds",
    [(None, 3, [0, 1, 2]), ("10", 2, [10, 11]), ("4:7", None, [4, 5, 6]), ("1,5,9", None, [1, 5, 9])],
)
def test_seeds_from_the_command_line(text, runs, seeds):
    assert parse_seeds(text, runs) == seeds


@pytest.mark.parametrize("text, runs", [("a:b", None), ("4:7", 5), ("3,3", None), ("5:5", None)])
def test_bad_seeds_are_refused(text, runs):
    with pytest.raises(ValueError):
        parse_seeds(text, runs)


def test_command_prints_percentiles_and_writes_curves(tmp_path, capsys):
    scenario = tmp_path / "slew.toml"
    scenario.write_text(SCENARIO_TOML)
    out = tmp_path / "curves.csv"
    status = main(["montecarlo", str(scenario), "--runs", "3", "--seeds", "20",
                   "--scheduler", "sync", "--output", str(out), "--no-progress"])
    assert status == 0
    printed = capsys.readouterr().out
    assert "short slew: 3 runs" in printed and "p95_deg" in printed
    table = np.loadtxt(out, delimiter=",", skiprows=1)
    assert table.shape[1] == 5 and np.all(table[:, 1:] >= 0)


@pytest.mark.parametrize(
    "args, message",
    [
        (["missing.toml", "--runs", "2", "--scheduler", "sync"], "cannot read scenario"),
        (["{scenario}", "--runs", "0"], "runs must be an integer from 1 to 1,000,000"),
        (["{scenario}", "--seeds", "x"], "seeds must be"),
        (["{scenario}", "--runs", "2", "--percentiles", "150"], "within 0..100"),
        (["{scenario}", "--runs", "1", "--output", "a.txt"], ".json or .csv"),
    ],
)
def test_command_errors_are_one_line_and_exit_2(tmp_path, capsys, args, message):
    scenario = tmp_path / "s.toml"
    scenario.write_text(SCENARIO_TOML)
    try:  # a bad --runs is a usage error (limits.RUNS): argparse exits with 2
        status = main(["montecarlo", *[a.format(scenario=scenario) for a in args]])
    except SystemExit as exc:
        status = exc.code
    err = capsys.readouterr().err
    assert status == 2
    assert message in err and "Traceback" not in err


@needs_dask  # without Dask: the [montecarlo] extra is named (test_extras.py)
def test_a_scheduler_address_that_is_not_one_is_a_clear_error(tmp_path, capsys):
    scenario = tmp_path / "s.toml"
    scenario.write_text(SCENARIO_TOML)
    status = main(["montecarlo", str(scenario), "--runs", "1", "--scheduler", "bogus"])
    err = capsys.readouterr().err
    assert status == 2
    assert "cannot reach the Dask scheduler at 'bogus'" in err and "Traceback" not in err


@needs_dask
def test_an_existing_dask_cluster_given_by_address_gives_the_same_results():
    # In a fresh interpreter: after the in-process cluster and command tests above, a new
    # LocalCluster's IO loop in this process did not start within distributed's 10 s (seen in
    # this session's CI run; the cause is in distributed's loop bookkeeping, not looked into).
    import subprocess
    import sys
    import textwrap

    code = textwrap.dedent("""
        import numpy as np
        from distributed import LocalCluster
        from bmg160_emu.adcs.montecarlo import run_montecarlo
        from bmg160_emu.adcs.scenarios import scenario_from_dict

        scenario = scenario_from_dict({"duration_s": 3.0, "motion": [
            {"kind": "constant", "rate_dps": [0.0, -0.06, 0.0]}],
            "readout": {"grid_s": 0.5, "bias": "profile"}})
        seeds = [3, 4]
        with LocalCluster(n_workers=1, threads_per_worker=1, processes=True,
                          dashboard_address=None) as cluster:
            remote = run_montecarlo(scenario, seeds, scheduler=cluster.scheduler_address,
                                    progress=False)
        in_process = run_montecarlo(scenario, seeds, scheduler="sync", progress=False)
        print(np.array_equal(remote.angle_error_deg, in_process.angle_error_deg))
    """)
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                            timeout=300, check=False)
    assert result.returncode == 0, result.stderr[-2000:]
    assert result.stdout.strip().splitlines()[-1] == "True"


def test_progress_bar_counts_runs_when_asked(capsys):
    run_montecarlo(_short(), [1, 2], scheduler="sync", progress=True)
    err = capsys.readouterr().err
    assert "monte carlo" in err and "2/2" in err


@pytest.mark.parametrize(
    "args, seeds",
    [
        ([], list(range(100))),  # --runs defaults to 100, seeds from 0
        (["--seeds", "5000"], list(range(5000, 5100))),  # START with the default 100 runs
        (["--seeds", "5000", "--runs", "3"], [5000, 5001, 5002]),
        (["--seeds", "4:7"], [4, 5, 6]),
        (["--seeds", "1,5,9"], [1, 5, 9]),
    ],
)
def test_command_runs_the_seeds_its_help_promises(tmp_path, monkeypatch, args, seeds):
    from bmg160_emu.adcs import montecarlo

    asked = []

    def fake_run_montecarlo(scenario, seed_list, **options):
        asked.append(list(seed_list))
        return reduce_runs("s", [montecarlo.RunResult(s, np.array([1.0]), np.array([0.0]))
                                 for s in seed_list])

    monkeypatch.setattr(montecarlo, "run_montecarlo", fake_run_montecarlo)
    scenario = tmp_path / "s.toml"
    scenario.write_text(SCENARIO_TOML)
    assert main(["montecarlo", str(scenario), "--scheduler", "sync", *args]) == 0
    assert asked == [seeds]


class _StopAtThirdSeed:
    """A run function that is interrupted (^C) when it reaches the third seed."""

    def __init__(self) -> None:
        self.calls = 0

    def __call__(self, seed: int) -> RunResult:
        self.calls += 1
        if self.calls == 3:
            raise KeyboardInterrupt
        return RunResult(seed, np.arange(3.0), np.full(3, float(seed)))


def test_an_interrupted_monte_carlo_keeps_the_runs_already_finished(tmp_path):
    result = run_montecarlo(_short(), [10, 11, 12, 13, 14], scheduler="sync",
                            run=_StopAtThirdSeed())
    assert result.seeds == [10, 11] and result.planned_runs == 5 and result.interrupted
    assert "2 of 5 runs (interrupted)" in result.summary()
    result.write(tmp_path / "partial.json")
    import json

    data = json.loads((tmp_path / "partial.json").read_text())
    assert data["interrupted"] is True and data["runs_planned"] == 5 and data["seeds"] == [10, 11]


def test_monte_carlo_output_to_a_missing_folder_is_refused_before_the_runs(tmp_path, capsys):
    scenario = tmp_path / "s.toml"
    scenario.write_text(SCENARIO_TOML)
    status = main(["montecarlo", str(scenario), "--runs", "2", "--scheduler", "sync",
                   "--output", str(tmp_path / "nope" / "curves.json")])
    err = capsys.readouterr()
    assert status == 2 and "does not exist" in err.err and "scenario" not in err.out


def test_monte_carlo_output_onto_a_full_disk_is_a_one_line_error_after_the_table(
        tmp_path, capsys):
    scenario = tmp_path / "s.toml"
    scenario.write_text(SCENARIO_TOML)
    full = tmp_path / "full.json"
    full.symlink_to("/dev/full")
    status = main(["montecarlo", str(scenario), "--runs", "2", "--scheduler", "sync",
                   "--output", str(full)])
    captured = capsys.readouterr()
    assert status == 2 and "p50_deg" in captured.out  # the results were printed ...
    assert captured.err.count("\n") == 1 and "No space left on device" in captured.err


@pytest.mark.parametrize(("scheduler", "message"), [
    ("5:2", "'5' is not an IPv4 address a.b.c.d"),  # once a 3.07 EiB allocation in Dask
    ("0:99999999999999999999", "'0' is not an IPv4 address"),  # once an OverflowError
    ("localhost:99999999999999999999", "the port must be 1 to 65535, not '999999999"),
    ("tcp://10.0.0.5:0", "the port must be 1 to 65535, not '0'"),
    ("tcp://:8786", "'' is not a host name"),
    ("udp://10.0.0.5:8786", "scheme one of tcp, tls, inproc, ucx, ws, wss"),
    ("tls://[::zz]:8786", "'::zz' is not an IPv6 address"),
    ("a" * 300 + ":8786", "is not a host name"),
])
def test_a_scheduler_that_cannot_be_an_address_is_refused_in_one_line(
        tmp_path, capsys, scheduler, message):
    scenario = tmp_path / "s.toml"
    scenario.write_text(SCENARIO_TOML)
    status = main(["montecarlo", str(scenario), "--runs", "1", "--scheduler", scheduler])
    err = capsys.readouterr().err
    assert status == 2 and message in err, err
    assert len(err.strip().splitlines()) == 1 and len(err) < 400 and "Traceback" not in err


@pytest.mark.parametrize("address", ["local", "sync", "tcp://10.0.0.5:8786", "localhost:8786",
                                     "tls://[::1]:8786", "bogus", "scheduler.example.org"])
def test_scheduler_addresses_a_dask_cluster_takes_pass_the_check(address):
    from bmg160_emu.adcs.montecarlo import scheduler_address

    assert scheduler_address(address) == address


class _FakeFuture:
    def __init__(self, value):
        self.value = value

    def result(self):
        return self.value


@needs_dask
@pytest.mark.parametrize("when", ["close", "last run"])
def test_a_signal_while_dask_shuts_down_keeps_every_finished_run(monkeypatch, tmp_path, capsys,
                                                                 when):
    # issue 35: a SIGTERM while the client closed, after every run had finished, left the
    # command saying "unfinished outputs removed" with no file. Here a stand-in Client runs
    # the runs in this process and raises SIGTERM as it closes (or as the last run ends);
    # the command's own handler (cli._terminate) turns it into the exception it raises.
    import signal

    import distributed

    from bmg160_emu.adcs.evaluation import PropagationRun

    class Client:
        def __init__(self, address, timeout=None):
            pass

        def map(self, run, seeds, pure=False):
            return [_FakeFuture(run(s)) for s in seeds]

        def close(self):
            if when == "close":
                signal.raise_signal(signal.SIGTERM)

    def as_completed(futures):
        for k, future in enumerate(futures):
            if when == "last run" and k == len(futures) - 1:
                yield future
                signal.raise_signal(signal.SIGTERM)
            else:
                yield future

    monkeypatch.setattr(distributed, "Client", Client)
    monkeypatch.setattr(distributed, "as_completed", as_completed)
    scenario = tmp_path / "s.toml"
    scenario.write_text(SCENARIO_TOML)
    out = tmp_path / "curves.json"
    status = main(["montecarlo", str(scenario), "--runs", "3", "--scheduler",
                   "tcp://127.0.0.1:8786", "--output", str(out)])
    err = capsys.readouterr().err
    assert status == 143, err
    assert "interrupted by SIGTERM after all 3 runs" in err and "complete" in err
    import json

    document = json.loads(out.read_text())
    assert document["seeds"] == [0, 1, 2] and document["interrupted"] is False
    whole = run_montecarlo(scenario, [0, 1, 2], scheduler="sync", progress=False)
    assert document["percentiles_deg"]["p50"] == whole.percentiles[50.0].tolist()
    del PropagationRun
