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

    from bmg160_emu.io.formats import block_writer_for
    from bmg160_emu.io.partial import npy_trailer, partial_note, write_sidecar

    for suffix in (".npy", ".csv"):
        for cut in (False, True):
            path = tmp_path / f"r{int(cut)}{suffix}"
            with open(path, "w+b") as handle:
                writer = block_writer_for("rate stream", path)(handle, 10, 100.0, ["made here"])
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


@pytest.fixture
def full_disk(monkeypatch):
    """Every write to a temporary output file (io.atomic's ``.NAME.*.part*``) fails with
    ENOSPC after its first 10 bytes, as a file system that fills up mid-file."""
    import pathlib

    real_open = pathlib.Path.open

    class Filling:
        def __init__(self, handle):
            self.handle, self.written = handle, 0

        def write(self, data):
            self.written += len(data)
            if self.written > 10:
                raise OSError(errno.ENOSPC, "No space left on device")
            return self.handle.write(data)

        def __getattr__(self, name):
            return getattr(self.handle, name)

        def __enter__(self):
            return self

        def __exit__(self, *exc):
            self.handle.close()

    def open_filling(self, mode="r", *args, **kwargs):
        handle = real_open(self, mode, *args, **kwargs)
        return Filling(handle) if ".part" in self.name and "w" in mode else handle

    import builtins

    real_builtin_open = builtins.open

    def builtin_open_filling(file, mode="r", *args, **kwargs):
        handle = real_builtin_open(file, mode, *args, **kwargs)
        named = isinstance(file, (str, os.PathLike)) and ".part" in os.path.basename(file)
        return Filling(handle) if named and "w" in mode else handle

    monkeypatch.setattr(pathlib.Path, "open", open_filling)
    monkeypatch.setattr(builtins, "open", builtin_open_filling)


def test_dump_to_a_full_disk_is_one_line_and_keeps_the_old_file(tmp_path, full_disk, capsys):
    from bmg160_emu.cli import main

    out = tmp_path / "regs.txt"
    out.write_text("old dump\n")
    assert main(["dump", "--seed", "1", "-o", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and f"cannot write {out}: No space left on device" in err
    assert out.read_text() == "old dump\n"  # it used to be cut to what fitted
    assert leftovers(tmp_path) == []


def test_replay_to_a_full_disk_is_one_line_and_keeps_the_old_file(tmp_path, full_disk, capsys):
    from bmg160_emu.cli import main

    data = tmp_path / "real.csv"
    data.write_text("t_s,x,y,z\n" + "".join(f"{k / 100:.2f},0.1,0.2,0.3\n" for k in range(50)))
    out = tmp_path / "out.csv"
    out.write_text("old recording\n")
    assert main(["replay", str(data), "--seed", "1", "-o", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and f"cannot write {out}: No space left on device" in err
    assert out.read_text() == "old recording\n"
    assert leftovers(tmp_path) == []


def test_vhost_user_i2c_keeps_its_old_stats_and_log_on_a_start_up_error(tmp_path, capsys):
    # they were opened (truncated to 0 bytes) before the socket was tried
    from bmg160_emu.cli import main

    stats, log = tmp_path / "stats.json", tmp_path / "bus.log"
    stats.write_text('{"old": 1}\n')
    log.write_text("old log\n")
    socket = tmp_path / "i2c.sock"
    socket.write_text("a file, not a socket\n")
    assert main(["vhost-user-i2c", "--socket", str(socket), "--stats", str(stats),
                 "--log", str(log), "--seed", "1", "--duration", "2s"]) == 2
    assert "exists and is not a socket" in capsys.readouterr().err
    assert stats.read_text() == '{"old": 1}\n' and log.read_text() == "old log\n"
    assert leftovers(tmp_path) == []


@pytest.mark.parametrize("command", ["script", "run"])
def test_a_trace_and_log_on_a_full_disk_are_one_line_and_leave_no_hidden_file(
        tmp_path, full_disk, capsys, command):
    # run --trace --log on a full disk was a traceback and left a hidden .part file
    import shutil

    from bmg160_emu.cli import main

    trace, log = tmp_path / "s.jsonl", tmp_path / "bus.log"
    if command == "script":
        script = tmp_path / "one.script"
        script.write_text("read CHIP_ID == 0x0F\n")
        argv = ["script", str(script), "--seed", "1", "--quiet", "--trace", str(trace)]
    else:
        if shutil.which("true") is None:
            pytest.skip("no 'true' program to run")
        argv = ["run", "--seed", "1", "--trace", str(trace), "--log", str(log), "--", "true"]
    status = main(argv)
    err = capsys.readouterr().err
    if command == "run" and "umockdev" in err.lower() and status == 2 and "cannot write" not in err:
        pytest.skip(f"run needs umockdev here: {err.strip()}")
    assert status == 2
    assert err.count("\n") == 1 and "No space left on device" in err and "Traceback" not in err
    assert not trace.exists() and not log.exists()
    assert leftovers(tmp_path) == []


def test_vhost_user_i2c_on_a_full_disk_is_one_line_and_leaves_no_hidden_file(
        tmp_path, full_disk, capsys):
    # it was a traceback at io/atomic.py
    from bmg160_emu.cli import main

    folder = tmp_path / "s"
    folder.mkdir(mode=0o700)
    stats = tmp_path / "stats.json"
    stats.write_text('{"old": 1}\n')
    status = main(["vhost-user-i2c", "--socket", str(folder / "i2c.sock"), "--seed", "1",
                   "--duration", "0.3s", "--stats", str(stats)])
    err = capsys.readouterr().err
    assert status == 2 and "Traceback" not in err
    assert f"cannot write {stats}: No space left on device" in err
    assert stats.read_text() == '{"old": 1}\n'
    assert leftovers(tmp_path) == []
