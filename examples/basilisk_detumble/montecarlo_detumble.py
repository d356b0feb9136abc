"""Monte Carlo of the closed loop: N, B, K dispersed within the identification's intervals.

Each run (one seed) draws the gyro's N, B, K per axis from ``identification.json``
(:class:`bmg160_emu.adcs.dispersion.NoiseDispersion`), runs the Basilisk closed loop with
that profile, the seed's noise and star-tracker realisations and the same faults, and
returns the pointing error on the 0.1 s log grid plus an archive record. The runs go through
``bmg160_emu.adcs.montecarlo.map_runs`` (in this process or on Dask) and land in a
:class:`bmg160_emu.adcs.run_archive.RunArchive`; a run fails when it does not detumble
within the stated limit, misses an injected fault, or raises.

Rerun one archived run: ``python montecarlo_detumble.py ARCHIVE --rerun SEED``.
"""

from __future__ import annotations

import argparse
import sys
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

import scenario

from bmg160_emu.adcs.dispersion import NoiseDispersion
from bmg160_emu.adcs.montecarlo import default_scheduler, map_runs, reduce_runs
from bmg160_emu.adcs.results import RunResult
from bmg160_emu.adcs.run_archive import RunArchive, RunRecord

DISPERSION_STREAM = 2  # SeedSequence([seed, 2]): the parameter draws, apart from the noise
EXPECTED_DETECTIONS = {"bias step", "stuck axis", "nack"}
TIMING_KEYS = ("wall_s", "realtime_factor")  # machine-dependent: not part of a run's result


@dataclass
class DetumbleRunResult(RunResult):
    record: RunRecord | None = None


@dataclass
class DetumbleRun:
    """``run(seed)``: picklable, so Dask workers can run it."""

    duration_s: float = 150.0
    # identify --json of the gyro's record: N, B, K dispersed within its intervals and the
    # ground calibration; None: the profile as it is, every run (nothing to disperse within)
    identification: str | None = str(scenario.IDENTIFICATION)
    keep_series: bool = True
    setup_overrides: dict = field(default_factory=dict)
    profile: str = "paper"  # the gyro's profile (identify --profile-out): T, bias, the rest

    def setup(self, seed: int) -> tuple[scenario.Setup, dict[str, float]]:
        profile: object = self.profile
        drawn: dict[str, float] = {}
        if self.identification is not None:
            rng = np.random.default_rng(np.random.SeedSequence([int(seed), DISPERSION_STREAM]))
            profile, drawn = NoiseDispersion.from_identification(
                self.identification, base=self.profile).draw(rng)
        setup = scenario.Setup(duration_s=self.duration_s, seed=int(seed), profile=profile,
                               identification=self.identification, **self.setup_overrides)
        return setup, drawn

    def __call__(self, seed: int) -> DetumbleRunResult:
        setup, drawn = self.setup(seed)
        grid = np.round(np.arange(round(self.duration_s / setup.log_period_s) + 1)
                        * setup.log_period_s, 9)
        failure = None
        try:
            result = scenario.run(setup)
        except Exception as exc:  # noqa: BLE001 - a run that breaks is a failure to archive, not a crash
            failure = f"raised {type(exc).__name__}: {exc}"
            summary: dict = {}
            error = np.full(grid.size, np.nan)
            times = grid
            series = None
        else:
            summary = {k: v for k, v in result.summary.items() if k not in TIMING_KEYS}
            times, error = result.time_s, result.pointing_error_deg
            failure = judge(summary, setup)
            series = {"time_s": result.time_s, "rate_true_dps": result.rate_true_dps,
                      "pointing_error_deg": result.pointing_error_deg,
                      "wheel_rpm": result.wheel_rpm} if self.keep_series else None
        record = RunRecord(int(seed), drawn, summary, failure,
                           setup={"duration_s": self.duration_s, **self.setup_overrides,
                                  **({"profile": self.profile} if self.profile != "paper"
                                     else {}),
                                  **({"identification": self.identification}
                                     if self.identification != str(scenario.IDENTIFICATION)
                                     else {})},
                           series=series)
        extras = {k: float(v) for k, v in summary.items()
                  if isinstance(v, (int, float)) and not isinstance(v, bool)}
        extras["failed"] = float(failure is not None)
        return DetumbleRunResult(int(seed), np.asarray(times), np.asarray(error), extras, record)

    def record(self, seed: int) -> RunRecord:
        out = self(seed).record
        assert out is not None
        return out


def judge(summary: dict, setup: scenario.Setup) -> str | None:
    """The failure reason of a finished run (None when it passed)."""
    reasons = []
    det, limit = summary.get("detumble_time_s"), summary["detumble_limit_s"]
    if det is None or det > limit:
        reasons.append(f"detumble time {det} s over the {limit:.1f} s limit")
    if setup.faults == scenario.FAULTS:
        missed = EXPECTED_DETECTIONS - set(summary.get("faults_detected", []))
        if missed:
            reasons.append(f"faults not detected: {sorted(missed)}")
    return "; ".join(reasons) or None


@dataclass
class Campaign:
    results: list
    archive: RunArchive

    def describe(self) -> str:
        mc = reduce_runs("basilisk detumble", self.results, percentiles=(50, 95))
        det = np.array([r.extras.get("detumble_time_s", np.nan) for r in self.results])
        failures = [(r.seed, r.record.failure) for r in self.results if r.record.failure]
        done = det[np.isfinite(det)]
        limit = self.results[0].extras.get("detumble_limit_s", np.nan)
        timing = (f"detumble time: median {np.median(done):.1f} s, max {done.max():.1f} s "
                  f"({done.size} of {det.size} runs detumbled; limit {limit:.1f} s)"
                  if done.size else f"no run detumbled (limit {limit:.1f} s)")
        final = mc.final_percentiles()
        lines = [f"{mc.runs} runs, archive {self.archive.folder}", timing,
                 f"final pointing error: median {final[50.0]:.4f} deg, p95 {final[95.0]:.4f} deg",
                 f"failures: {len(failures)}"]
        lines += [f"  seed {s}: {why}" for s, why in failures]
        return "\n".join(lines)


def run(seeds, folder, *, duration_s: float = 150.0, scheduler: str = "local",
        workers: int | None = None, progress: bool | None = None, profile: str = "paper",
        identification: str | None = str(scenario.IDENTIFICATION), **overrides) -> Campaign:
    """The campaign over ``seeds``, archived in ``folder``: the gyro of ``profile``, its N,
    B, K dispersed within ``identification`` (None: not dispersed)."""
    runner = DetumbleRun(duration_s=duration_s, setup_overrides=overrides, profile=profile,
                         identification=identification)
    results = map_runs(runner, seeds, scheduler=scheduler, workers=workers, progress=progress)
    archive = RunArchive(folder)
    archive.write_all(r.record for r in results)
    return Campaign(results, archive)


def add_gyro_options(parser: argparse.ArgumentParser) -> None:
    """--profile and --identification: the user's own gyro, as identify writes it."""
    parser.add_argument("--profile", default="paper", metavar="FILE.toml",
                        help="the gyro's noise profile (bmg160-emu identify --profile-out; "
                        "default: the paper's gyro)")
    parser.add_argument("--identification", default=None, metavar="FILE.json",
                        help="bmg160-emu identify --json of the same record: the ground "
                        "calibration and the Monte Carlo's N, B, K intervals (default: the "
                        "example's identification.json with the paper profile; none with "
                        "--profile: the profile's bias, and N, B, K as they are)")


def identification_for(args: argparse.Namespace) -> str | None:
    """The identification the options name; the example's own only for the paper's gyro."""
    if args.identification is not None:
        return args.identification
    return str(scenario.IDENTIFICATION) if args.profile == "paper" else None


def scheduler_or_default(scheduler: str | None) -> str:
    """The scheduler asked for, or the CLI's default (local with Dask, else this process,
    said on stderr)."""
    if scheduler is not None:
        return scheduler
    chosen, note = default_scheduler()
    if note:
        print(f"note: {note}", file=sys.stderr)
    return chosen


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description="Monte Carlo of the Basilisk detumble example")
    parser.add_argument("archive", help="archive folder")
    parser.add_argument("--runs", type=int, default=20)
    parser.add_argument("--duration", type=float, default=150.0)
    add_gyro_options(parser)
    parser.add_argument("--scheduler", default=None,
                        help="sync, local or a Dask address (default: local with Dask, else sync)")
    parser.add_argument("--workers", type=int, default=None)
    parser.add_argument("--rerun", type=int, default=None, metavar="SEED",
                        help="rerun one archived seed and compare it with its record")
    args = parser.parse_args(argv)
    args.scheduler = scheduler_or_default(args.scheduler)
    if args.rerun is not None:
        archive = RunArchive(args.archive)
        setup = archive.read(args.rerun).setup
        runner = DetumbleRun(duration_s=setup.pop("duration_s"),
                             profile=setup.pop("profile", "paper"),
                             identification=setup.pop("identification",
                                                      str(scenario.IDENTIFICATION)),
                             setup_overrides=setup)
        again, same = archive.rerun(args.rerun, runner.record)
        print(f"seed {args.rerun}: {'identical to' if same else 'DIFFERS from'} the archive; "
              f"failure: {again.failure}")
        return 0 if same else 1
    campaign = run(range(args.runs), args.archive, duration_s=args.duration,
                   scheduler=args.scheduler, workers=args.workers, profile=args.profile,
                   identification=identification_for(args))
    print(campaign.describe())
    return 0


if __name__ == "__main__":
    sys.exit(main())
