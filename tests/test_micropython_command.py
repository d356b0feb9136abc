"""``bmg160-emu micropython main.py``: a MicroPython program run as on the board."""

from __future__ import annotations

import textwrap

from bmg160_emu.cli import main

READ_LOOP = """\
from machine import I2C, Pin
import time
import ustruct

i2c = I2C(1, scl=Pin(22), sda=Pin(21))
print("chip", hex(i2c.readfrom_mem(0x68, 0x00, 1)[0]))
i2c.writeto_mem(0x68, 0x10, b"\\x07")  # BW: ODR 100 Hz
start = time.ticks_ms()
while True:
    time.sleep_ms(100)
    x, y, z = ustruct.unpack("<hhh", i2c.readfrom_mem(0x68, 0x02, 6))
    print(time.ticks_diff(time.ticks_ms(), start), x, y, z)
"""


def _program(tmp_path, text: str, name: str = "main.py"):
    path = tmp_path / name
    path.write_text(textwrap.dedent(text))
    return path


def _lines(capsys) -> tuple[list[str], str]:
    out, err = capsys.readouterr()
    return out.splitlines(), err


def test_main_py_reads_moving_counts_on_a_clock_that_follows_its_sleeps(tmp_path, capsys):
    path = _program(tmp_path, READ_LOOP)
    status = main(["micropython", "--seed", "7", "--true-rate", "10", "0", "-5",
                   "--duration", "1s", str(path)])
    lines, err = _lines(capsys)
    assert status == 0 and lines[0] == "chip 0xf"
    samples = [[int(v) for v in line.split()] for line in lines[1:]]
    assert [s[0] for s in samples] == list(range(100, 1000, 100))  # each sleep_ms(100)
    x = [s[1] for s in samples]
    # 10 deg/s at 16.384 LSB per deg/s is 164 counts; the noise moves each sample
    assert all(abs(v - 164) < 20 for v in x) and len(set(x)) > 3
    assert "stopped after 1 s of program time" in err and "warning" not in err


def test_the_same_seed_gives_the_same_run(tmp_path, capsys):
    path = _program(tmp_path, READ_LOOP)
    runs = []
    for _ in range(2):
        main(["micropython", "--seed", "3", "--duration", "0.3s", str(path)])
        runs.append(_lines(capsys)[0])
    assert runs[0] == runs[1] and len(runs[0]) == 3


def test_a_loop_without_sleeps_is_warned_about_once(tmp_path, capsys):
    path = _program(tmp_path, """\
        from machine import I2C
        i2c = I2C(1)
        seen = set()
        for _ in range(200):
            seen.add(i2c.readfrom_mem(0x68, 0x02, 6))
        print(len(seen), "distinct samples")
    """)
    assert main(["micropython", "--seed", "1", str(path)]) == 0
    lines, err = _lines(capsys)
    assert lines == ["1 distinct samples"]
    assert err.count("warning") == 1
    assert "read the rate registers of 0x68 50 times at t=" in err
    assert "sleep between reads (time.sleep_ms)" in err


def test_a_bus_that_is_not_wired_says_where_the_chip_is(tmp_path, capsys):
    path = _program(tmp_path, "from machine import I2C\nI2C(0)\n")
    assert main(["micropython", str(path)]) == 1
    _, err = _lines(capsys)
    assert ("ValueError: I2C(0) doesn't exist: the chips are on I2C(1); --bus N puts them on "
            "I2C(N)") in err
    assert main(["micropython", "--bus", "0", str(path)]) == 0


def test_the_program_imports_its_own_modules_and_lib_and_sees_its_argv(tmp_path, capsys):
    (tmp_path / "lib").mkdir()
    (tmp_path / "lib" / "gyro.py").write_text("from micropython import const\nCHIP_ID = const(0)\n")
    (tmp_path / "config.py").write_text("ADDRESS = 0x68\n")
    path = _program(tmp_path, """\
        import sys
        from machine import I2C
        from gyro import CHIP_ID
        from config import ADDRESS
        print(I2C(1).readfrom_mem(ADDRESS, CHIP_ID, 1), sys.argv[1:])
        sys.exit(3)
    """)
    assert main(["micropython", str(path), "fast"]) == 3
    assert _lines(capsys)[0] == ["b'\\x0f' ['fast']"]


def test_real_time_runs_the_program_with_real_sleeps(tmp_path, capsys):
    path = _program(tmp_path, """\
        import time
        from machine import I2C
        time.sleep_ms(20)
        print(len(I2C(1).readfrom_mem(0x68, 0x02, 6)))
    """)
    assert main(["micropython", "--realtime", str(path)]) == 0
    assert _lines(capsys)[0] == ["6"]


def test_a_missing_program_is_one_line(tmp_path, capsys):
    assert main(["micropython", str(tmp_path / "nope.py")]) == 2
    assert "nope.py: no such program" in capsys.readouterr().err
