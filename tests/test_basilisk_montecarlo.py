"""Monte Carlo of the Basilisk closed loop: dispersions from an identification, per-run
archive, rerun by seed, failures list, identical results in-process and on Dask."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np
import pytest

from bmg160_emu.adcs.dispersion import DispersionError, Interval, NoiseDispersion
from bmg160_emu.adcs.run_archive import ArchiveError, RunArchive, RunRecord

EXAMPLE = Path(__file__).resolve().parent.parent / "examples" / "basilisk_detumble"
IDENTIFICATION = EXAMPLE / "identification.json"


def test_draws_have_the_interval_ends_as_their_2_5_and_97_5_percent_quantiles():
    interval = Interval(value=0.004, low=0.001, high=0.0052)  # asymmetric, as B's often is
    rng = np.random.default_rng(11)
    draws = np.array([interval.draw(rng) for _ in range(20000)])
    # with 20000 draws the 2.5 % quantile's standard error is sqrt(p(1-p)/n) = 0.11 % in
    # probability; the 1.5 .. 3.5 % band is 9 standard errors wide
    assert 0.015 < np.mean(draws < interval.low) < 0.035
    assert 0.015 < np.mean(draws > interval.high) < 0.035
    assert 0.48 < np.mean(draws < interval.value) < 0.52  # the estimate is the median
    assert draws.min() >= 0.0


def test_dispersion_from_the_identify_json_draws_n_b_k_per_axis():
    dispersion = NoiseDispersion.from_identification(IDENTIFICATION)
    ident = json.loads(IDENTIFICATION.read_text())["axes"]
    profile, drawn = dispersion.draw(np.random.default_rng(0))
    assert sorted(drawn) == sorted(f"{k}_{a}" for k in "NBK" for a in "xyz")
    for axis in "xyz":
        for key in "NBK":
            low, high = ident[axis][key]["ci95"]
            # one draw: inside a widened interval (a draw falls outside the CI 5 % of the time)
            assert max(0.0, low - (high - low)) <= profile[axis][key] <= high + (high - low)
        assert profile[axis]["T"] == 33.9 and profile[axis]["bias"] == 0.116359  # base profile
    again, _ = dispersion.draw(np.random.default_rng(0))
    assert again == profile


def test_dispersion_errors_name_the_file(tmp_path):
    bad = tmp_path / "ident.json"
    bad.write_text('{"axes": {"x": {"N": {"value": 1.0}}}}')
    with pytest.raises(DispersionError, match=r"ident\.json: axes\.x\.N: needs 'value' and 'ci95'"):
        NoiseDispersion.from_identification(bad)
    bad.write_text("{not json")
    with pytest.raises(DispersionError, match=r"ident\.json: not JSON \(line 1"):
        NoiseDispersion.from_identification(bad)


def test_archive_round_trips_a_record_exactly(tmp_path):
    archive = RunArchive(tmp_path / "mc")
    series = {"t": np.arange(5) * 0.1, "err": np.array([1.0, np.nan, 1 / 3, 2e-17, 5.0])}
    record = RunRecord(7, {"N_x": 0.1 + 0.2}, {"detumble_time_s": 81.23456789012345, "ok": None},
                       "detumble time None s over the 9.0 s limit", {"duration_s": 6.0}, series)
    archive.write_all([record, RunRecord(8, {}, {"a": 1.0})])
    back = archive.read(7)
    assert back.same_as(record) and back.parameters["N_x"] == 0.1 + 0.2
    assert archive.seeds() == [7, 8]
    assert [r.seed for r in archive.failures()] == [7]
    index = json.loads((tmp_path / "mc" / "index.json").read_text())
    assert index["failures"] == [{"seed": 7, "reason": record.failure}]
    with pytest.raises(ArchiveError, match="no archived run with seed 9"):
        archive.read(9)


# ---------------------------------------------------------------------- the closed loop


@pytest.fixture(scope="module")
def campaign_module():
    try:
        import Basilisk  # noqa: F401
    except ImportError as exc:  # absent, or a wheel that does not load here
        pytest.skip(f"Basilisk (bsk) is not importable ({exc}): "
                    "pip install 'bmg160-emu[basilisk]'")
    sys.path.insert(0, str(EXAMPLE))
    import montecarlo_detumble

    return montecarlo_detumble


SHORT = {"kd": 0.5, "faults": []}  # 6 s runs: too short to detumble, so every run fails


def test_campaign_is_identical_in_process_and_on_dask_and_reruns_by_seed(campaign_module,
                                                                         tmp_path):
    seeds = [4, 9]
    sync = campaign_module.run(seeds, tmp_path / "sync", duration_s=6.0, scheduler="sync",
                               progress=False, **SHORT)
    dask = campaign_module.run(seeds, tmp_path / "dask", duration_s=6.0, scheduler="local",
                               workers=2, progress=False, **SHORT)
    for a, b in zip(sync.results, dask.results):
        assert a.seed == b.seed
        assert np.array_equal(a.angle_error_deg, b.angle_error_deg)
        assert a.record.same_as(b.record)
    assert not np.array_equal(sync.results[0].angle_error_deg, sync.results[1].angle_error_deg)
    # each run's archive: seed, dispersed N, B, K, summary, series
    record = sync.archive.read(9)
    assert record.seed == 9 and set(record.parameters) >= {"N_x", "B_y", "K_z"}
    assert record.summary["duration_s"] == 6.0 and "wall_s" not in record.summary
    assert record.series is not None and record.series["pointing_error_deg"].size == 61
    # the dispersed parameters differ between seeds and come from the seed alone
    assert sync.archive.read(4).parameters != record.parameters
    # the failures list: 6 s cannot detumble (stated limit 9.0 s at Kd = 0.5/s)
    failures = sync.archive.failures()
    assert [f.seed for f in failures] == seeds
    assert all("detumble time" in f.failure for f in failures)
    assert "failures: 2" in sync.describe()
    # rerun one run by its seed: the archived record comes back exactly
    setup = dict(record.setup)
    runner = campaign_module.DetumbleRun(duration_s=setup.pop("duration_s"),
                                         setup_overrides=setup)
    again, same = sync.archive.rerun(9, runner.record)
    assert same and again.summary == record.summary
    # and from the command line, as the docs say
    assert campaign_module.main([str(tmp_path / "sync"), "--rerun", "9"]) == 0
