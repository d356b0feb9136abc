"""identify's outputs appear together or not at all (issue 35): a full disk part way through
--figures left a half-full folder, and a late signal left 4 of 5 outputs written while the
command said "unfinished outputs removed"."""

from __future__ import annotations

import errno
import os
import signal

import pytest

from bmg160_emu.cli import main

pytest.importorskip("matplotlib")


@pytest.fixture(scope="module")
def static_csv(tmp_path_factory):
    path = tmp_path_factory.mktemp("rec") / "static.csv"
    assert main(["generate", "--profile", "paper", "--rate", "200", "--duration", "60s",
                 "--seed", "1", "-o", str(path)]) == 0
    return path


def _outputs(tmp_path):
    return {"--profile-out": tmp_path / "mine.toml", "--adev-out": tmp_path / "adev.csv",
            "--kalibr-out": tmp_path / "imu.yaml", "--matlab-out": tmp_path / "g.m",
            "--plot": tmp_path / "adev.png"}


def test_a_full_disk_part_way_through_the_figures_leaves_no_folder_and_no_output(
        static_csv, tmp_path, monkeypatch, capsys):
    from bmg160_emu.noise import plots

    real_save, saved = plots.save, []

    def save_until_full(fig, path):
        if len(saved) == 3:
            raise OSError(errno.ENOSPC, "No space left on device", str(path))
        saved.append(path)
        real_save(fig, path)

    monkeypatch.setattr(plots, "save", save_until_full)
    outputs = _outputs(tmp_path)
    argv = ["identify", str(static_csv), "--poles", "1", "--figures", str(tmp_path / "figs")]
    for option, path in outputs.items():
        argv += [option, str(path)]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert "No space left on device; no output written" in err and err.count("\n") == 1
    assert not (tmp_path / "figs").exists()
    assert sorted(p.name for p in tmp_path.iterdir()) == []  # no output, no temporary file


def test_an_output_that_fails_as_it_is_put_in_place_takes_the_others_with_it(
        static_csv, tmp_path, capsys):
    outputs = _outputs(tmp_path)
    argv = ["identify", str(static_csv), "--poles", "1", "--kalibr-out", "/dev/full"]
    for option, path in outputs.items():
        if option != "--kalibr-out":
            argv += [option, str(path)]
    assert main(argv) == 2
    assert "No space left on device" in capsys.readouterr().err
    assert sorted(p.name for p in tmp_path.iterdir()) == []


def test_a_signal_while_the_outputs_are_written_leaves_none_and_says_so(
        static_csv, tmp_path, monkeypatch, capsys):
    # the signal comes while the third output is being written: none of the five appears
    # (they are renamed into place together, after the last is written), and the line says
    # that they were removed, not that some were kept
    from bmg160_emu.noise import interop

    real = interop.matlab_gyroparams

    def matlab_then_signal(result):
        signal.raise_signal(signal.SIGINT)
        return real(result)

    monkeypatch.setattr(interop, "matlab_gyroparams", matlab_then_signal)
    outputs = _outputs(tmp_path)
    argv = ["identify", str(static_csv), "--poles", "1"]
    for option, path in outputs.items():
        argv += [option, str(path)]
    assert main(argv) == 130
    err = capsys.readouterr().err
    assert "interrupted by SIGINT; unfinished" in err and "removed" in err
    assert "written whole" not in err
    assert sorted(p.name for p in tmp_path.iterdir()) == []


def test_a_signal_while_the_outputs_are_put_in_place_waits_for_the_last(tmp_path):
    # the renames of the set run with the signals held: a signal then acts after the last
    from bmg160_emu.io.atomic import atomic_paths

    targets = [tmp_path / f"out{k}.txt" for k in range(5)]
    with pytest.raises(KeyboardInterrupt), atomic_paths(targets) as temps:
        for k, temp in enumerate(temps):
            temp.write_text(str(k))
        signal.raise_signal(signal.SIGINT)  # during the block: the set is discarded
    assert [p.name for p in tmp_path.iterdir()] == []
    real_replace, seen = os.replace, []

    def replace_and_signal(source, target):
        real_replace(source, target)
        seen.append(target)
        if len(seen) == 2:
            signal.raise_signal(signal.SIGINT)  # among the renames: held until the last

    os.replace = replace_and_signal
    try:
        with pytest.raises(KeyboardInterrupt), atomic_paths(targets) as temps:
            for k, temp in enumerate(temps):
                temp.write_text(str(k))
    finally:
        os.replace = real_replace
    assert sorted(p.name for p in tmp_path.iterdir()) == [p.name for p in targets]
