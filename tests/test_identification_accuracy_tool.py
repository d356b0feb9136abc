"""tools/identification_accuracy.py: a record scored with bootstrap intervals, and its table."""

from __future__ import annotations

import json
import math

from _tools import load_tool


def _tool():
    return load_tool("identification_accuracy")


def test_bootstrap_intervals_are_scored_beside_the_asymptotic_ones(tmp_path):
    tool = _tool()
    # 0.3 h of the paper truth (216,000 samples): long enough for every term to be fitted
    record = tool.one_record("paper", 0.3, seed=1, bootstrap=8)
    assert record["bootstrap_replicates"] == 8
    assert set(record["gmwm_boot"]) == set(record["gmwm"]) == {"N", "B", "T", "K"}
    for name, (value, low, high) in record["gmwm_boot"].items():
        assert value == record["gmwm"][name][0]  # the same estimate, other intervals
        assert math.isfinite(low) and math.isfinite(high) and 0 < low <= high
        assert [low, high] != record["gmwm"][name][1:]  # percentiles, not the asymptotic ones
    path = tmp_path / "records.jsonl"
    path.write_text(json.dumps(record) + "\n")
    rows = tool.table(path, 2, [0.3], ["paper"]).splitlines()  # seeds 0 and 1
    boot = [r for r in rows if "| gmwm_boot |" in r]
    assert len(boot) == 4 and all(r.endswith("| 1 |") for r in boot)
