"""File names with any byte Linux allows (but / and NUL): what the commands write with them
reads back, what they print does not fail, and an error naming one stays on one line.

Found by the odd-name paths campaign (tools/fuzz.py --edges --only names): identify wrote a
profile whose name or header held a control character, which its own reader refused; a name
that is not UTF-8 was a UnicodeEncodeError traceback in identify and thermal; a firmware
build folder with a space failed in make.
"""

from __future__ import annotations

import contextlib
import dataclasses
import io
import os
import subprocess
import sys
from pathlib import Path

import pytest

from bmg160_emu import cli
from bmg160_emu.noise.profile import load_profile
from bmg160_emu.noise.profile_writer import format_profile, toml_comment, write_profile

REPO = Path(__file__).resolve().parents[1]
# characters TOML forbids in strings and comments (U+0000-U+001F but tab, U+007F), those
# a shell or make reads, a C1 control, and a name that is not UTF-8 (byte 0xff, which Python
# holds as the lone surrogate U+DCFF, PEP 383)
ODD = ["\x01", "\r", "\n", "\x1b[2J", "\x7f", "\t", '"', "\\", "'", "$x", "#", " ", "\x85",
       "é😀", "\udcff"]


def _run(argv: list[str]) -> tuple[int, str, str]:
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        status = cli.main(argv)
    return status, out.getvalue(), err.getvalue()


@pytest.mark.parametrize("odd", ODD, ids=[repr(c) for c in ODD])
def test_a_profile_named_with_any_character_reads_back(odd, tmp_path):
    name = f"my{odd}gyro"
    profile = dataclasses.replace(load_profile("paper"), name=name, description=f"from {name}")
    path = tmp_path / "p.toml"
    write_profile(profile, path, header=f"identified from {name}.csv\nsecond line {odd}")
    back = load_profile(path)
    if odd == "\udcff":  # no UTF-8 file holds it: written as the bytes' escape, ls -b's way
        assert back.name == "my\\xffgyro"
    else:
        assert back.name == name and back.description == f"from {name}"
    assert back.axes == profile.axes


def test_a_comment_shows_what_toml_forbids_as_escapes():
    assert toml_comment("a\x01b\x7fc\tok") == ["# a\\x01b\\x7fc\tok"]
    assert toml_comment("one\rtwo\n\nthree") == ["# one", "# two", "#", "# three"]


def _record(folder: Path, name: str) -> Path:
    path = folder / name
    status, _, err = _run(["generate", "--duration", "60s", "--seed", "3", "-o", str(path)])
    assert status == 0, err
    return path


@pytest.mark.parametrize("odd", ["\x01", "\r", "\x7f", "\udcff"], ids=repr)
def test_identify_writes_a_profile_its_reader_takes_whatever_the_names(odd, tmp_path):
    record = _record(tmp_path, f"in{odd}put.csv")
    out = tmp_path / f"p{odd}.toml"
    status, printed, err = _run(["identify", str(record), "--poles", "1", "--no-verdict",
                                 "--profile-out", str(out)])
    assert status == 0, err
    profile = load_profile(out)
    assert profile.name == ("p\\xff" if odd == "\udcff" else f"p{odd}")
    assert f"wrote {out}" in printed
    status, _, err = _run(["generate", "--profile", str(out), "--duration", "1s", "-o",
                           str(tmp_path / "g.npy")])
    assert status == 0, err


@pytest.mark.parametrize("odd", ["\x01", "\n", "\udcff"], ids=repr)
def test_thermal_errors_table_from_an_odd_name_goes_into_a_profile(odd, tmp_path):
    import numpy as np

    rng = np.random.default_rng(5)
    t = np.arange(0, 600.0, 0.1)
    temp = 20.0 + 20.0 * t / t[-1]
    rates = 0.01 * (temp - 25.0)[:, None] * [1.0, -0.5, 0.2] + rng.normal(0, 0.01, (t.size, 3))
    log = tmp_path / f"ther{odd}mal.csv"
    with open(log, "w", encoding="utf-8", errors="surrogateescape") as f:
        f.write("t_s,x_dps,y_dps,z_dps,temp_c\n")
        f.writelines(",".join(repr(float(v)) for v in row) + "\n" for row in zip(t, *rates.T, temp))
    table = tmp_path / f"e{odd}.toml"
    status, _, err = _run(["thermal", str(log), "--block", "10s", "--errors-out", str(table)])
    assert status == 0, err
    both = tmp_path / "with-errors.toml"
    both.write_text(format_profile(load_profile("paper")) + table.read_text(encoding="utf-8"),
                    encoding="utf-8")
    errors = load_profile(both).errors
    assert errors is not None and abs(errors["bias_tc_dps_per_k"][0][0] - 0.01) < 2e-3


def test_an_error_naming_a_file_with_a_newline_stays_on_one_line(tmp_path):
    status, _, err = _run(["identify", str(tmp_path / "no\nsuch\r.csv")])
    assert status == 2
    assert err.count("\n") == 1 and "no\\x0asuch\\x0d.csv" in err, err


def test_a_scripts_list_of_mistakes_stays_one_per_line(tmp_path):
    """The one-line rule escapes a name's newline, not the lines a list of mistakes is
    printed on (CI caught docs/script-format.md's example run together with \\x0a)."""
    script = tmp_path / "b\nroken.script"
    script.write_text("write RANGEE 1\nsleep 10\n")
    for argv in (["script", str(script), "-q"], ["dump", "--seed", "1", "--after", str(script)]):
        status, _, err = _run(argv)
        lines = err.splitlines()
        assert status == 2 and len(lines) == (3 if argv[0] == "script" else 2), err
        assert all("b\\x0aroken.script" in line for line in lines[-2:]), err


def test_a_name_that_is_not_utf8_is_printed_as_its_bytes_under_a_strict_utf8_locale(tmp_path):
    """A UTF-8 locale's stdout is strict (the C locale's is not): the summary and "wrote"
    lines named the file and raised UnicodeEncodeError after the outputs were written."""
    record = _record(tmp_path, "in\udcffput.csv")
    out = os.fsencode(tmp_path / "k\udcff.yaml")
    env = dict(os.environ, PYTHONIOENCODING="utf-8:strict", PYTHONPATH=str(REPO))
    proc = subprocess.run([sys.executable, "-m", "bmg160_emu", "identify", os.fsencode(record),
                           "--poles", "1", "--kalibr-out", out], capture_output=True, env=env,
                          check=False, stdin=subprocess.DEVNULL)
    assert proc.returncode == 0, proc.stderr.decode(errors="replace")[-400:]
    assert b"wrote " + out + b"\n" in proc.stdout
    assert Path(os.fsdecode(out)).is_file()


@pytest.mark.firmware
@pytest.mark.parametrize("folder", ["a b", "tab\there", "q'uote\"s", "d$ol#lar:%"])
def test_firmware_builds_into_a_folder_make_cannot_name(folder, tmp_path):
    from _firmware_backends import firmware_skip_reason

    from bmg160_emu.firmware.build import build_firmware

    if firmware_skip_reason() is not None:
        pytest.skip(str(firmware_skip_reason()))
    build = build_firmware(out_dir=tmp_path / folder / "fw")
    assert build.hex.is_file() and build.elf.is_file() and build.flash_bytes > 0
    assert build.hex.parent == tmp_path / folder / "fw"
    assert (build.directory / "bmg160_params.h").is_file()
