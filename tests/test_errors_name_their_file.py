"""Errors name the file they come from (issue 35): a profile by its path, not by the name it
holds; paper mode's missing fields by the profile; a scenario's fault by the scenario file;
a scenario's gyro profile found beside the scenario, from any folder."""

from __future__ import annotations

from pathlib import Path

import pytest

from bmg160_emu.cli import main

REPO = Path(__file__).resolve().parents[1]
MY_GYRO = (REPO / "examples/profiles/my-gyro.toml").read_text()


@pytest.fixture
def profile_named_paper(tmp_path):
    # a user's profile that calls itself "paper": the message must name the file
    path = tmp_path / "adis.toml"
    path.write_text(MY_GYRO.replace('name = "my-gyro"', 'name = "paper"')
                    + "\n[errors]\nbogus = 1\n")
    return path


@pytest.mark.parametrize("command", [["record", "--duration", "0.1s", "-o", "{tmp}/r.csv"],
                                     ["dump"]])
def test_a_bad_errors_table_is_named_by_its_file(command, profile_named_paper, tmp_path,
                                                 capsys):
    argv = [a.replace("{tmp}", str(tmp_path)) for a in command]
    assert main([*argv, "--seed", "1", "--profile", str(profile_named_paper)]) == 2
    err = capsys.readouterr().err
    assert f"{profile_named_paper} [errors]: unknown keys ['bogus']" in err
    assert "profile paper" not in err


@pytest.mark.parametrize("command", [
    ["generate", "--duration", "1s", "-o", "{tmp}/g.npy"],
    ["record", "--duration", "0.1s", "-o", "{tmp}/r.csv", "--seed", "1"],
    ["demo", "--seed", "1", "--samples", "2"]])
def test_paper_mode_without_its_fields_names_the_profile(command, tmp_path, capsys):
    path = tmp_path / "mine.toml"
    path.write_text(MY_GYRO)
    argv = [a.replace("{tmp}", str(tmp_path)) for a in command]
    assert main([*argv, "--profile", str(path), "--noise-mode", "paper"]) == 2
    assert f"{path}: paper mode needs sigma_gyro" in capsys.readouterr().err


def test_a_bad_fault_is_named_by_its_scenario_file(tmp_path, capsys):
    scenario = tmp_path / "f.toml"
    scenario.write_text('duration_s = 5.0\n[[fault]]\nkind = "bogus"\n')
    assert main(["montecarlo", str(scenario), "--runs", "1", "--scheduler", "sync"]) == 2
    assert f"{scenario}: fault 1: fault kind must be one of" in capsys.readouterr().err


def test_a_scenario_finds_its_gyro_profile_beside_it_from_another_folder(
        tmp_path, monkeypatch, capsys):
    orbit = tmp_path / "orbit"
    orbit.mkdir()
    (orbit / "adis.toml").write_text(MY_GYRO)
    (orbit / "my_orbit.toml").write_text(
        'duration_s = 3.0\n[readout]\ngrid_s = 1.0\n[[gyro]]\nprofile = "adis.toml"\n')
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    monkeypatch.chdir(elsewhere)
    assert main(["montecarlo", "../orbit/my_orbit.toml", "--runs", "1", "--scheduler",
                 "sync"]) == 0, capsys.readouterr().err
    (elsewhere / "adis.toml").write_text("not a profile")  # the folder's own file is not it
    assert main(["montecarlo", "../orbit/my_orbit.toml", "--runs", "1", "--scheduler",
                 "sync"]) == 0
