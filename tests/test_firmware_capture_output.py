"""`firmware capture --output`: the stream file is complete or absent, and a write error is an
error (onto a full disk it reported `wrote full.csv`, exit 0)."""

from __future__ import annotations

import pytest
from _firmware_backends import firmware_skip_reason

from bmg160_emu import cli

pytestmark = [
    pytest.mark.firmware,
    pytest.mark.skipif(firmware_skip_reason() is not None, reason=str(firmware_skip_reason())),
]


def test_capture_onto_a_full_disk_is_a_one_line_error(tmp_path, capsys):
    full = tmp_path / "full.csv"
    full.symlink_to("/dev/full")
    status = cli.main(["firmware", "capture", "--duration", "0.2", "--output", str(full),
                       "--out", str(tmp_path / "build")])
    err = capsys.readouterr().err.strip()
    assert status == 2
    assert err.count("\n") == 0 and "No space left on device" in err and "full.csv" in err


def test_capture_writes_the_whole_stream_under_its_name(tmp_path, capsys):
    out = tmp_path / "stream.txt"
    status = cli.main(["firmware", "capture", "--duration", "0.2", "--output", str(out),
                       "--out", str(tmp_path / "build")])
    assert status == 0 and f"wrote {out}" in capsys.readouterr().out
    assert out.read_text().strip()
    assert [p.name for p in tmp_path.iterdir() if ".part" in p.name] == []


def test_capture_to_a_missing_folder_is_refused_before_the_build(tmp_path, capsys):
    status = cli.main(["firmware", "capture", "--duration", "0.2",
                       "--output", str(tmp_path / "nope" / "s.txt")])
    assert status == 2 and "does not exist" in capsys.readouterr().err
