"""The Zephyr module's host half without Zephyr: a small C client built from
zephyr/src/bmg160_emu_link.c (the code native_sim links) against the server. Zephyr's own
message flags and buffer sets go through the module's translation, and the answers must be
the ones the Python client gets for the same wire traffic (issue 33)."""

from __future__ import annotations

import itertools
import shutil
import subprocess
from pathlib import Path

import pytest

from bmg160_emu.device.registers import address_of
from bmg160_emu.serve import protocol as p
from tests._serve_harness import gyro, serving

ROOT = Path(__file__).resolve().parents[1]
SOURCES = [ROOT / "zephyr" / "host" / "bmg160_emu_client.c",
           ROOT / "zephyr" / "src" / "bmg160_emu_link.c"]
CHIP_ID, RATE_X_LSB, RANGE, BW = (address_of(n) for n in ("CHIP_ID", "RATE_X_LSB", "RANGE", "BW"))
INT_EN_0, INT_MAP_1 = address_of("INT_EN_0"), address_of("INT_MAP_1")
# Zephyr's i2c_msg flags (include/zephyr/drivers/i2c.h)
WRITE, READ, STOP, RESTART = 0x0, 0x1, 0x2, 0x4
SPI_WORD_8 = 8 << 5  # SPI_WORD_SET(8): Zephyr's operation word for 8-bit words


@pytest.fixture(scope="module")
def c_client(tmp_path_factory) -> Path:
    compiler = shutil.which("cc") or shutil.which("gcc")
    if compiler is None:
        pytest.skip("no C compiler (cc or gcc): .ci/setup.d/serve.sh installs gcc")
    out = tmp_path_factory.mktemp("c") / "bmg160_emu_client"
    subprocess.run([compiler, "-std=c11", "-D_DEFAULT_SOURCE", "-Wall", "-Wextra", "-Werror",
                    "-o", str(out), *map(str, SOURCES), f"-I{ROOT / 'zephyr' / 'src'}"],
                   check=True, capture_output=True, text=True, timeout=120)
    return out


def run_c(binary: Path, path: str, lines: list[str]) -> tuple[list[str], str, int]:
    done = subprocess.run([str(binary), path], check=False, input="\n".join(lines) + "\n",
                          capture_output=True, text=True, timeout=60)
    return done.stdout.splitlines(), done.stderr, done.returncode


def fields(answer: str) -> dict[str, str]:
    return dict(item.split("=", 1) for item in answer.split())


def test_zephyr_i2c_api_shapes_through_the_module_translation(tmp_path, c_client):
    with serving(tmp_path, [gyro(setup_writes=[(BW, bytes([0x05]))])]) as (path, server):
        lines, err, code = run_c(c_client, path, [
            f"zi2c 1000 68 {WRITE}:{CHIP_ID:02x} {READ | RESTART | STOP}:1",  # write_read
            f"zi2c 2000 68 {WRITE}:{RANGE:02x} {WRITE | STOP}:0305",  # i2c_burst_write
            f"zi2c 3000 68 {WRITE}:{RANGE:02x} {READ | RESTART | STOP}:2",
            f"zi2c 4000 68 {WRITE | STOP}:{RANGE:02x}04",  # i2c_write of [reg, value]
            f"zi2c 5000 68 {WRITE | STOP}:{RANGE:02x}",  # i2c_write then i2c_read
            f"zi2c 6000 68 {READ | STOP}:1",
            f"zi2c 7000 68 {WRITE}:{RATE_X_LSB:02x} {READ | RESTART | STOP}:6",
            f"zi2c 8000 33 {WRITE | STOP}:00",  # nobody there
            "bye 9000",
        ])
        log = list(server.sessions[0].log)
    assert code == 0, err
    answers = [fields(a) for a in lines if a.startswith("rc=")]
    assert lines[0].startswith("hello chips=1") and "bmg160 id=0f i2c=68 cs=00 pins=2" in lines[1]
    assert [a["rc"] for a in answers] == ["0"] * 7 + ["-121", "0"]
    assert answers[0]["data"] == "0f"
    assert answers[2]["data"] == "0385"  # the burst write was one write of both bytes
    assert answers[5]["data"] == "04"  # the read after a stop reads from the pointer
    burst = next(t for t in log if t.kind == "i2c_write" and t.register == RANGE)
    assert burst.written == bytes([0x03, 0x05])
    # what the C link read is what the chip gave: the same bytes a Python client reads at
    # the same simulated time on a fresh board of the same seed
    (tmp_path / "again").mkdir()
    with serving(tmp_path / "again", [gyro(setup_writes=[(BW, bytes([0x05]))])]) as (path, _):
        from bmg160_emu.serve.client import ServeClient

        py = ServeClient(path)
        py.greet()
        py.burst_write(0x68, RANGE, bytes([0x03, 0x05]), 2000)
        py.burst_write(0x68, RANGE, bytes([0x04]), 4000)
        rates = py.write_read(0x68, RATE_X_LSB, 6, 7000).data
    assert answers[6]["data"] == rates.hex()


def test_zephyr_spi_buffer_sets_are_one_frame(tmp_path, c_client):
    with serving(tmp_path, [gyro(part="bmi088_gyro")]) as (path, _):
        lines, err, code = run_c(c_client, path, [
            # bmi08x_gyro_transceive_spi, read: tx {reg | 0x80}, rx {dummy 1, data 6}
            f"zspi 1000 0 {SPI_WORD_8:x} {0x80 | RATE_X_LSB:02x} 1,6",
            f"spi 1000 0 0 {0x80 | RATE_X_LSB:02x}000000000000",  # the same frame, flat
            # write: tx {reg, data}, no rx set
            f"zspi 2000 0 {SPI_WORD_8:x} {RANGE:02x},03 -",
            f"zspi 3000 0 {SPI_WORD_8:x} {0x80 | RANGE:02x} .1,1",  # a NULL rx buffer
            # chip select held over two transfers (SPI_HOLD_ON_CS), then released
            f"zspi 4000 0 {SPI_WORD_8 | 1 << 12:x} {0x80 | CHIP_ID:02x} 1",
            f"zspi 4000 0 {SPI_WORD_8:x} - 1",
            f"zspi 5000 0 {16 << 5:x} 80 2",  # 16-bit words: not for this chip
            "bye 6000",
        ])
    assert code == 0, err
    answers = [fields(a) if a.startswith("rc=") else {"rc": a} for a in lines[2:]]
    assert answers[0]["data"] == answers[1]["data"] and len(answers[0]["data"]) == 14
    assert answers[2]["rc"] == "0" and answers[3]["data"] == "03"
    assert answers[4]["data"] == "00" and answers[5]["data"] == "0f"
    assert answers[6]["rc"] == "notsup"


def test_the_c_link_follows_the_lines_and_the_time_stamps(tmp_path, c_client):
    with serving(tmp_path, [gyro(setup_writes=[(BW, bytes([0x05]))])]) as (path, _):
        lines, err, code = run_c(c_client, path, [
            f"zi2c 1000000 68 {WRITE}:{INT_MAP_1:02x} {WRITE | STOP}:01",
            f"zi2c 2000000 68 {WRITE}:{INT_EN_0:02x} {WRITE | STOP}:80",
            "sync 1000",  # back in time: refused
            "rate 3000000 0 90 0 0",
            "bye 4000000",
        ])
    assert code == 0, err
    first, armed, back, rate, _ = (fields(a) for a in lines[2:])
    assert first["rc"] == "0"
    assert armed["next"] != "never" and int(armed["next"]) > 2_000_000
    assert back["rc"] == "-22" and rate["rc"] == "0"


def test_a_server_that_goes_away_is_one_line(tmp_path, c_client):
    with serving(tmp_path) as (path, server):
        proc = subprocess.Popen([str(c_client), path], stdin=subprocess.PIPE,
                                stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        assert proc.stdout is not None and proc.stdin is not None
        proc.stdin.write(f"i2c 1000 68 0:{CHIP_ID:02x} {p.I2C_M_RD}:1\n")
        proc.stdin.flush()
        while not (line := proc.stdout.readline()).startswith("rc="):
            pass
        assert fields(line)["data"] == "0f"
        server.stop()
    proc.stdin.write(f"i2c 2000 68 0:{CHIP_ID:02x} {p.I2C_M_RD}:1\n")
    proc.stdin.close()
    assert proc.wait(30) == 1
    err = proc.stderr.read() if proc.stderr else ""
    assert err.count("\n") == 1 and ("the server closed the connection" in err
                                     or "lost the server" in err)


def test_no_server_is_one_line_naming_the_socket(tmp_path, c_client):
    _, err, code = run_c(c_client, str(tmp_path / "none.sock"), [])
    assert code == 1 and err.count("\n") == 1
    assert f"cannot connect to {tmp_path / 'none.sock'}" in err and "bmg160-emu serve" in err


def test_same_seed_same_counts_with_a_cpu_hog_beside_it(tmp_path, c_client):
    # a polling driver's session: the line's times as the server names them, reads at
    # each output period; stamps, not the host's speed, set what the chips produce
    import sys

    script = [f"zi2c 1000000 68 {WRITE}:{INT_MAP_1:02x} {WRITE | STOP}:01",
              f"zi2c 2000000 68 {WRITE}:{INT_EN_0:02x} {WRITE | STOP}:80"]
    script += [f"zi2c {(30 + 10 * k) * 1_000_000} 68 {WRITE}:{RATE_X_LSB:02x} "
               f"{READ | RESTART | STOP}:6" for k in range(400)]
    script.append("bye 5000000000")

    def session(folder: Path) -> list[str]:
        folder.mkdir()
        with serving(folder, [gyro(setup_writes=[(BW, bytes([0x05]))])], seed=21) as (path, _):
            lines, err, code = run_c(c_client, path, script)
        assert code == 0, err
        return lines

    quiet = session(tmp_path / "quiet")
    hogs = [subprocess.Popen([sys.executable, "-c", "while True: pass"]) for _ in range(2)]
    try:
        loaded = session(tmp_path / "loaded")
    finally:
        for hog in hogs:
            hog.kill()
            hog.wait()
    reads = [fields(a)["data"] for a in quiet[4:-1]]
    # a new sample at each read (noise of about 1.5 LSB per axis at BW code 5): the
    # session is not trivial
    assert len(reads) == 400 and sum(a != b for a, b in itertools.pairwise(reads)) > 300
    assert loaded == quiet
