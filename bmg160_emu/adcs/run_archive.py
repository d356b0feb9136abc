"""A folder that keeps every Monte Carlo run: what a GNC team archives and reruns.

One ``run-<seed>.json`` per run: the seed, the dispersed parameters, the run's summary
numbers, its failure reason (None when it passed) and the setup needed to rerun it, plus
an optional ``run-<seed>.npz`` with its time series. ``index.json`` lists the runs and the
failures. A run depends on its seed only, so :meth:`RunArchive.rerun` with the same run
function gives the archived record back, bit for bit (JSON keeps floats exactly: ``repr``
round-trips).
"""

from __future__ import annotations

import json
import math
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np


class ArchiveError(ValueError):
    """An archive folder or record that cannot be used, with the file."""


@dataclass
class RunRecord:
    """One run as archived."""

    seed: int
    parameters: dict[str, float]
    summary: dict[str, Any]
    failure: str | None = None
    setup: dict[str, Any] = field(default_factory=dict)
    series: dict[str, np.ndarray] | None = None  # optional time series (npz)

    def to_dict(self) -> dict[str, Any]:
        return {"seed": self.seed, "parameters": self.parameters, "summary": self.summary,
                "failure": self.failure, "setup": self.setup}

    def same_as(self, other: RunRecord) -> bool:
        """Equal seed, parameters, summary, failure and series (NaN equal to NaN)."""
        if json.dumps(self.to_dict(), sort_keys=True) != json.dumps(other.to_dict(), sort_keys=True):
            return False
        if (self.series is None) != (other.series is None):
            return False
        if self.series is None or other.series is None:
            return True
        return self.series.keys() == other.series.keys() and all(
            np.array_equal(self.series[k], other.series[k], equal_nan=True) for k in self.series)


def _clean(value: Any) -> Any:
    """JSON-safe: numpy scalars to Python, NaN/inf to None."""
    if isinstance(value, Mapping):
        return {str(k): _clean(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_clean(v) for v in value]
    if isinstance(value, np.ndarray):
        return _clean(value.tolist())
    if isinstance(value, (np.floating, float)):
        value = float(value)
        return value if math.isfinite(value) else None
    if isinstance(value, np.integer):
        return int(value)
    return value


class RunArchive:
    """The archive folder (created when missing)."""

    def __init__(self, folder: str | Path) -> None:
        self.folder = Path(folder)
        self.folder.mkdir(parents=True, exist_ok=True)

    def _json(self, seed: int) -> Path:
        return self.folder / f"run-{int(seed)}.json"

    def write(self, record: RunRecord) -> Path:
        """Store one run (replacing an earlier record of that seed)."""
        record.parameters = _clean(record.parameters)
        record.summary = _clean(record.summary)
        record.setup = _clean(record.setup)
        path = self._json(record.seed)
        path.write_text(json.dumps(record.to_dict(), indent=1) + "\n")
        npz = self.folder / f"run-{int(record.seed)}.npz"
        if record.series is not None:
            arrays: dict[str, Any] = dict(record.series)
            np.savez_compressed(npz, **arrays)
        elif npz.exists():
            npz.unlink()
        return path

    def write_all(self, records: Iterable[RunRecord]) -> None:
        records = list(records)
        for record in records:
            self.write(record)
        index = {"runs": sorted(r.seed for r in records),
                 "failures": [{"seed": r.seed, "reason": r.failure} for r in records if r.failure]}
        (self.folder / "index.json").write_text(json.dumps(index, indent=1) + "\n")

    def read(self, seed: int) -> RunRecord:
        path = self._json(seed)
        try:
            data = json.loads(path.read_text())
        except OSError:
            raise ArchiveError(f"{path}: no archived run with seed {seed}") from None
        except json.JSONDecodeError as exc:
            raise ArchiveError(f"{path}: not JSON (line {exc.lineno}: {exc.msg})") from None
        try:
            record = RunRecord(int(data["seed"]), data["parameters"], data["summary"],
                               data.get("failure"), data.get("setup", {}))
        except (KeyError, TypeError, ValueError):
            raise ArchiveError(f"{path}: needs seed, parameters and summary") from None
        npz = self.folder / f"run-{int(seed)}.npz"
        if npz.exists():
            with np.load(npz) as data_npz:
                record.series = {k: data_npz[k] for k in data_npz.files}
        return record

    def seeds(self) -> list[int]:
        return sorted(int(p.stem[4:]) for p in self.folder.glob("run-*.json"))

    def records(self) -> list[RunRecord]:
        return [self.read(s) for s in self.seeds()]

    def failures(self) -> list[RunRecord]:
        return [r for r in self.records() if r.failure]

    def rerun(self, seed: int, run: Callable[[int], RunRecord]) -> tuple[RunRecord, bool]:
        """Run ``seed`` again and say whether it reproduces the archived record exactly."""
        archived = self.read(seed)
        again = run(int(seed))
        again.parameters = _clean(again.parameters)
        again.summary = _clean(again.summary)
        again.setup = _clean(again.setup)
        return again, archived.same_as(again)
