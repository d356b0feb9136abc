"""`bmg160-emu identify --method gmwm`: the same outputs as the Allan fit, GMWM's numbers."""

from __future__ import annotations

import json

import numpy as np
import pytest

from bmg160_emu.cli import main
from bmg160_emu.noise import NoiseGenerator, load_profile

PAPER = load_profile("paper").x


@pytest.fixture(scope="module")
def record(tmp_path_factory):
    path = tmp_path_factory.mktemp("rec") / "noise.npy"
    np.save(path, NoiseGenerator("paper", rate_hz=200.0, seed=7).generate(15 * 60 * 200)[:, :1])
    return path


def test_json_carries_gmwm_estimates_and_fit(record, capsys):
    assert main(["identify", str(record), "--rate", "200", "--json", "--method", "gmwm"]) == 0
    ax = json.loads(capsys.readouterr().out)["axes"]["x"]
    # 15 min at 200 Hz: N's scatter is ~0.1 %, 3 % is far outside it
    assert ax["N"]["value"] == pytest.approx(PAPER.N, rel=0.03)
    assert ax["fit"]["method"].startswith("GMWM") and ax["fit"]["model"] == "WN+GM+RW"
    assert ax["fit"]["parameters"]["N"]["value"] == ax["N"]["value"]
    low, high = ax["N"]["ci95"]
    assert low < ax["N"]["value"] < high
    assert {"ieee_readoffs", "psd", "mean", "std"} <= set(ax)


def test_summary_profile_and_bootstrap(record, tmp_path, capsys):
    profile = tmp_path / "g.toml"
    args = ["identify", str(record), "--rate", "200", "--method", "gmwm", "--bootstrap", "5"]
    assert main(args + ["--seed", "1", "--profile-out", str(profile)]) == 0
    out = capsys.readouterr().out
    assert "fit: GMWM" in out and "axis x GMWM: model WN+GM+RW" in out
    assert "N bootstrap 95 %" in out
    assert load_profile(profile).x.N == pytest.approx(PAPER.N, rel=0.03)


def test_default_method_is_unchanged_and_bootstrap_needs_gmwm(record, capsys):
    assert main(["identify", str(record), "--rate", "200", "--json"]) == 0
    ax = json.loads(capsys.readouterr().out)["axes"]["x"]
    assert "GMWM" not in ax["fit"]["method"]
    assert main(["identify", str(record), "--rate", "200", "--bootstrap", "3"]) != 0
    assert "--bootstrap needs --method gmwm" in capsys.readouterr().err
