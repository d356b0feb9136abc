"""Output files are complete or absent (bmg160_emu.io.atomic): written beside the target and
renamed into place; an exception, ^C or a full disk leaves the target as it was."""

from __future__ import annotations

import errno
import os
import stat

import pytest

from bmg160_emu.io.atomic import (
    OutputError,
    atomic_open,
    atomic_path,
    check_free_space,
    check_writable,
)


def leftovers(folder):
    return sorted(p.name for p in folder.iterdir() if ".part" in p.name)


def test_the_target_appears_whole_when_the_block_completes(tmp_path):
    target = tmp_path / "out.csv"
    with atomic_open(target, "w", encoding="utf-8") as f:
        f.write("a,b\n")
        assert not target.exists()  # nothing under the target's name until complete
    assert target.read_text() == "a,b\n"
    assert leftovers(tmp_path) == []
    umask = os.umask(0)
    os.umask(umask)
    assert stat.S_IMODE(target.stat().st_mode) == 0o666 & ~umask  # as open() would make it


@pytest.mark.parametrize("error", [RuntimeError("boom"), KeyboardInterrupt()])
def test_an_interrupted_write_leaves_the_old_target_and_no_temporary_file(tmp_path, error):
    target = tmp_path / "out.npy"
    target.write_bytes(b"old")
    with pytest.raises(type(error)), atomic_path(target) as temp:
        temp.write_bytes(b"half of the new")
        raise error
    assert target.read_bytes() == b"old"
    assert leftovers(tmp_path) == []


def test_the_temporary_path_keeps_the_suffix_writers_choose_formats_by(tmp_path):
    import numpy as np

    target = tmp_path / "x.npy"
    with atomic_path(target) as temp:
        assert temp.suffix == ".npy" and temp.parent == tmp_path
        np.save(temp, np.arange(3))  # np.save would append .npy to another suffix
    assert np.load(target).tolist() == [0, 1, 2]


def test_a_symbolic_link_is_kept_and_the_file_it_names_replaced(tmp_path):
    real = tmp_path / "data" / "real.csv"
    real.parent.mkdir()
    real.write_text("old")
    link = tmp_path / "link.csv"
    link.symlink_to(real)
    with atomic_open(link) as f:
        f.write("new")
    assert link.is_symlink() and real.read_text() == "new"


def test_a_full_disk_is_an_error_not_a_success(tmp_path):
    full = tmp_path / "full.csv"
    full.symlink_to("/dev/full")
    with pytest.raises(OSError) as exc, atomic_open(full) as f:
        f.write("x" * 100_000)
    assert exc.value.errno == errno.ENOSPC
    assert full.is_symlink()  # the link to the device is not replaced by a regular file


def test_check_writable_names_the_path_and_the_reason(tmp_path):
    with pytest.raises(OutputError, match="folder .* does not exist"):
        check_writable(tmp_path / "missing" / "x.csv")
    with pytest.raises(OutputError, match="it is a folder"):
        check_writable(tmp_path)
    check_writable(tmp_path / "fine.csv")


def test_check_free_space_names_what_is_needed_and_what_is_free(tmp_path):
    check_free_space(tmp_path / "small.npy", 1000)
    with pytest.raises(OutputError, match=r"needs 1000000000\.0 TB and .* free"):
        check_free_space(tmp_path / "huge.npy", 10**21)


@pytest.mark.parametrize("number", [2, 15])  # SIGINT, SIGTERM
def test_a_signal_while_an_output_is_finished_is_held_until_it_is_whole(tmp_path, number):
    # a ^C while the file is written used to remove it, and every sample with it (issue 24)
    import signal

    from bmg160_emu.io.atomic import held_signals

    stops = []
    previous = signal.signal(number, lambda n, frame: stops.append(n))
    try:
        target = tmp_path / "out.csv"
        with held_signals() as arrived, atomic_open(target, "w") as f:
            f.write("a\n")
            signal.raise_signal(number)
            f.write("b\n")
            assert stops == [] and arrived == [number]
        assert stops == [number]  # delivered again, to the handler it was meant for
        assert target.read_text() == "a\nb\n"
        assert signal.getsignal(number) is not None and stops == [number]
    finally:
        signal.signal(number, previous)


def test_every_cut_output_says_it_is_partial_and_a_complete_one_does_not(tmp_path):
    # io.partial reads the mark of each format (docs/outputs.md); numpy still loads a cut .npy
    import json

    import numpy as np

    from bmg160_emu.io.partial import npy_trailer, partial_note, write_sidecar
    from bmg160_emu.io.rate_stream import RateStreamWriter

    for suffix in (".npy", ".csv"):
        for cut in (False, True):
            path = tmp_path / f"r{int(cut)}{suffix}"
            with open(path, "w+b") as handle:
                writer = RateStreamWriter(handle, suffix, 10, 100.0, ["made here"])
                writer.write(0, np.ones((4, 3)))
                if cut:
                    writer.end_short("interrupted after 4 of 10 samples")
                else:
                    writer.write(4, np.ones((6, 3)))
            note = partial_note(path)
            assert (note is not None and "4 of 10" in note) if cut else note is None, (path, note)
            if suffix == ".npy":
                assert np.load(path).shape == ((4, 3) if cut else (10, 3))
    plain = tmp_path / "plain.npy"
    np.save(plain, np.zeros((3, 3)))
    assert partial_note(plain) is None
    plain.write_bytes(plain.read_bytes() + npy_trailer("by hand"))
    assert partial_note(plain) == "partial: by hand"
    runs = tmp_path / "curves.json"
    runs.write_text(json.dumps({"seeds": [0, 1], "runs_planned": 9, "interrupted": True}))
    assert partial_note(runs) == "interrupted: 2 of 9 runs"
    resd = tmp_path / "x.resd"
    resd.write_bytes(b"RESD")
    assert partial_note(resd) is None
    write_sidecar(resd, "interrupted after 1 of 2 samples")
    assert partial_note(resd) == "partial: interrupted after 1 of 2 samples"
