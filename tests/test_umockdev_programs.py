"""Unmodified programs against the emulated chip on a umockdev /dev/i2c-N (`bmg160-emu run`).

Each program kind runs once under `bmg160-emu run` (real time, seeded chip with a known true
rate) and its output is asserted on: i2c-tools (i2cdetect, i2cget, i2cset, i2cdump in byte
and I2C-block modes, i2ctransfer), smbus2 in a subprocess, and a C program using ioctl on
/dev/i2c-N, compiled here with the system C compiler.
"""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

pytestmark = pytest.mark.umockdev

TRUE_RATE_DPS = (20.0, -10.0, 5.0)
CHIP_OPTIONS = ["--seed", "3", "--true-rate", "20", "-10", "5"]


def _umockdev_missing() -> str | None:
    try:
        from bmg160_emu.linux.umockdev import (
            UMockdevUnavailable,
            load_umockdev,
            preload_available,
        )

        load_umockdev()
    except UMockdevUnavailable as exc:
        return str(exc)
    if not preload_available():
        return "umockdev's preload library is missing (apt-get install libumockdev0)"
    return None


_MISSING = _umockdev_missing()
if _MISSING:
    pytest.skip(f"umockdev route unavailable: {_MISSING}", allow_module_level=True)


def run_emulated(args: list[str], timeout: float = 120, **kwargs) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-m", "bmg160_emu", "run", *args],
        capture_output=True, text=True, timeout=timeout, check=False, **kwargs,
    )


def signed_words(data: list[int]) -> list[int]:
    return [int.from_bytes(bytes(data[i : i + 2]), "little", signed=True) for i in range(0, 6, 2)]


# The model's noise is ~0.8 deg/s rms at the reset bandwidth (BW 0: 523 Hz) and ~0.2 deg/s
# rms at BW 7 (32 Hz), its bias ~0.1 deg/s: tolerances of > 5 sigma for one sample.
TOLERANCE_RESET_BW_DPS = 4.5
TOLERANCE_BW7_DPS = 1.5


def assert_rate_counts(
    counts: list[int], full_scale_dps: float = 2000.0, tol_dps: float = TOLERANCE_RESET_BW_DPS
) -> None:
    """Counts of X, Y, Z (or the first axes) match the true rate at this range."""
    for value, true in zip(counts, TRUE_RATE_DPS):
        assert abs(value * full_scale_dps / 32768 - true) < tol_dps, counts


# --------------------------------------------------------------------------- i2c-tools

I2C_TOOLS_SCRIPT = """\
set -u
cd "$1"
i2cdetect -y -r 1 > detect.txt 2>&1
i2cget -y 1 0x68 0x00 > chip_id.txt 2>&1
i2cget -y 1 0x50 0x00 > missing.txt 2>&1; echo "status $?" >> missing.txt
i2cset -y 1 0x68 0x0f 0x03 > /dev/null 2>&1
i2cset -y 1 0x68 0x10 0x07
i2cget -y 1 0x68 0x0f > range.txt
i2cget -y 1 0x68 0x10 > bw.txt
i2cdump -y 1 0x68 b > dump_b.txt 2>&1
i2cdump -y 1 0x68 i > dump_i.txt 2>&1
for n in 1 2 3 4 5; do i2ctransfer -y 1 w1@0x68 0x02 r6; sleep 0.02; done > transfer.txt 2>&1
i2cset -y 1 0x68 0x3e 0x40
sleep 0.5
i2cget -y 1 0x68 0x0e > fifo_before.txt
i2ctransfer -y 1 w1@0x68 0x3f r120 > fifo_frames.txt
i2cget -y 1 0x68 0x0e > fifo_after.txt
"""


@pytest.fixture(scope="module")
def i2c_tools(tmp_path_factory):
    if shutil.which("i2cget") is None:
        pytest.skip("i2c-tools is not installed (apt-get install i2c-tools)")
    out = tmp_path_factory.mktemp("i2c_tools")
    script = out / "tools.sh"
    script.write_text(I2C_TOOLS_SCRIPT)
    result = run_emulated([*CHIP_OPTIONS, "--", "sh", str(script), str(out)])
    assert result.returncode == 0, result.stderr
    return out


def test_i2cdetect_r_finds_only_the_chip(i2c_tools):
    rows = (i2c_tools / "detect.txt").read_text().splitlines()[1:]
    cells = {}
    for row in rows:
        base = int(row[:2], 16)
        for i, cell in enumerate(row[4:].split()):
            cells[base + i + (3 if base == 0 else 0)] = cell
    assert cells[0x68] == "68"
    assert all(v == "--" for k, v in cells.items() if k != 0x68)


def test_i2cget_reads_chip_id(i2c_tools):
    assert (i2c_tools / "chip_id.txt").read_text().strip() == "0x0f"


def test_missing_address_fails_like_a_real_adapter(i2c_tools):
    text = (i2c_tools / "missing.txt").read_text()
    assert "Read failed" in text
    assert "status 2" in text


def test_i2cset_writes_reach_the_model(i2c_tools):
    assert (i2c_tools / "range.txt").read_text().strip() == "0x03"
    assert (i2c_tools / "bw.txt").read_text().strip() == "0x87"  # bit 7 is read-only 1


def test_i2cdump_byte_and_block_modes_agree_on_configuration(i2c_tools):
    def rows(name):
        lines = (i2c_tools / name).read_text().splitlines()[1:]
        return {line[:2]: line[4:51].split() for line in lines}

    byte_mode, block_mode = rows("dump_b.txt"), rows("dump_i.txt")
    for mode in (byte_mode, block_mode):
        assert mode["00"][0] == "0f"
        assert mode["00"][15] == "03"  # RANGE as written
        assert mode["10"][0] == "87"  # BW
    # configuration registers 0x10..0x3e are the same in both modes (no side effects)
    assert byte_mode["10"] == block_mode["10"]
    assert byte_mode["20"] == block_mode["20"]


def test_i2ctransfer_sees_changing_rate_data(i2c_tools):
    lines = (i2c_tools / "transfer.txt").read_text().splitlines()
    samples = [[int(v, 16) for v in line.split()] for line in lines]
    assert len(samples) == 5
    assert len({tuple(s) for s in samples}) >= 3
    for s in samples:
        assert_rate_counts(signed_words(s), 250.0, TOLERANCE_BW7_DPS)  # RANGE 3, BW 7


def test_fifo_drains_through_i2c_tools(i2c_tools):
    before = int((i2c_tools / "fifo_before.txt").read_text(), 16) & 0x7F
    after = int((i2c_tools / "fifo_after.txt").read_text(), 16) & 0x7F
    frames = [int(v, 16) for v in (i2c_tools / "fifo_frames.txt").read_text().split()]
    # 0.5 s at ODR 100 Hz (BW 7) stores ~50 frames; 20 frames are read out, and at most a
    # few new ones arrive in the ~10-50 ms between the two status reads.
    assert before >= 30
    assert after <= before - 15
    assert len(frames) == 120
    assert_rate_counts(signed_words(frames[:6]), 250.0, TOLERANCE_BW7_DPS)


# --------------------------------------------------------------------------- smbus2

SMBUS2_CLIENT = """\
import errno, json, time
from smbus2 import SMBus, i2c_msg
out = {}
with SMBus(1) as bus:
    out["chip_id"] = bus.read_byte_data(0x68, 0x00)
    out["blocks"] = []
    for _ in range(5):
        out["blocks"].append(bus.read_i2c_block_data(0x68, 0x02, 6))
        time.sleep(0.002)
    out["word_x"] = bus.read_word_data(0x68, 0x02)
    bus.write_byte_data(0x68, 0x10, 0x07)          # ODR 100 Hz
    bus.write_byte_data(0x68, 0x3E, 0x40)          # FIFO mode, X Y Z
    time.sleep(0.3)
    before = bus.read_byte_data(0x68, 0x0E) & 0x7F
    write, read = i2c_msg.write(0x68, [0x3F]), i2c_msg.read(0x68, 6 * before)
    drain_start = time.monotonic()
    bus.i2c_rdwr(write, read)
    after = bus.read_byte_data(0x68, 0x0E) & 0x7F
    out["fifo_drain_to_status_s"] = time.monotonic() - drain_start
    out["fifo"] = [before, after, list(read)[:6]]
    try:
        bus.read_byte_data(0x50, 0x00)
        out["missing"] = None
    except OSError as exc:
        out["missing"] = exc.errno
print(json.dumps(out))
"""


@pytest.fixture(scope="module")
def smbus2_client(tmp_path_factory):
    script = tmp_path_factory.mktemp("smbus2") / "client.py"
    script.write_text(SMBUS2_CLIENT)
    result = run_emulated([*CHIP_OPTIONS, "--", sys.executable, str(script)])
    assert result.returncode == 0, result.stderr
    return json.loads(result.stdout)


def test_smbus2_reads_chip_id_and_changing_rates(smbus2_client):
    assert smbus2_client["chip_id"] == 0x0F
    blocks = smbus2_client["blocks"]
    assert len({tuple(b) for b in blocks}) >= 3
    for block in blocks:
        assert_rate_counts(signed_words(block))
    word = smbus2_client["word_x"]
    assert_rate_counts([word - 65536 if word >= 32768 else word])  # X alone


def test_smbus2_fifo_drains_completely(smbus2_client):
    before, after, first = smbus2_client["fifo"]
    assert before >= 15  # 0.3 s at 100 Hz
    # Everything read: what the status shows arrived after the drain, at most one frame per
    # 10 ms (ODR 100 Hz) of the time from the drain to the status read (usually < 1 ms,
    # longer when the machine is loaded), plus one.
    assert after <= 1 + int(smbus2_client["fifo_drain_to_status_s"] * 100)
    assert_rate_counts(signed_words(first), tol_dps=TOLERANCE_BW7_DPS)


def test_smbus2_missing_address_raises_the_bus_errno(smbus2_client):
    from bmg160_emu.bus.i2c import I2CBus

    bus = I2CBus(1, {})
    with pytest.raises(OSError) as expected:
        bus.read_byte_data(0x50, 0)
    assert smbus2_client["missing"] == expected.value.errno


# ------------------------------------------------------------- every SMBus size, as FakeSMBus

EVERY_KIND = """\
def every_kind(bus):
    \"\"\"Each SMBus transaction kind on configuration registers (deterministic from reset);
    each result is its value or the errno it failed with.\"\"\"
    def attempt(call, *args):
        try:
            result = call(*args)
            return list(result) if isinstance(result, (list, bytes)) else result
        except OSError as exc:
            return f"errno {exc.errno}"
    a = 0x68
    out = [
        attempt(bus.write_quick, a),
        attempt(bus.read_byte_data, a, 0x1B),
        attempt(bus.write_word_data, a, 0x22, 0x0304),
        attempt(bus.read_word_data, a, 0x22),
        attempt(bus.write_i2c_block_data, a, 0x24, [5, 6, 7]),
        attempt(bus.read_i2c_block_data, a, 0x22, 8),
        attempt(bus.process_call, a, 0x26, 0x0102),
        attempt(bus.read_block_data, a, 0x1B),
        attempt(bus.write_block_data, a, 0x23, [9, 10]),
        attempt(bus.block_process_call, a, 0x22, [2, 3]),
        attempt(bus.read_i2c_block_data, a, 0x1B, 16),
        attempt(bus.write_byte, a, 0x1B),
        attempt(bus.read_byte, a),
        attempt(bus.read_byte_data, 0x50, 0x00),
    ]
    bus.pec = 1
    out.append(attempt(bus.read_byte_data, a, 0x1B))
    out.append(attempt(bus.write_byte_data, a, 0x1C, 0xA1))
    bus.pec = 0
    out.append(attempt(bus.read_i2c_block_data, a, 0x1B, 4))
    return out
"""


def test_every_smbus_kind_answers_as_fake_smbus(tmp_path: Path):
    """The same calls through the umockdev node (smbus2, ioctls) and on the in-process
    FakeSMBus give the same values and the same errnos: one I2CBus behind both."""
    from bmg160_emu.bus.smbus import FakeSMBus
    from bmg160_emu.device.chip import BMG160

    namespace: dict = {}
    exec(EVERY_KIND, namespace)  # noqa: S102 - the test's own source, shared with the child
    with FakeSMBus(1, devices={0x68: BMG160(seed=3)}) as bus:
        expected = namespace["every_kind"](bus)
    script = tmp_path / "every_kind.py"
    script.write_text(
        "import json\nfrom smbus2 import SMBus\n" + EVERY_KIND
        + "with SMBus(1) as bus:\n    print(json.dumps(every_kind(bus)))\n"
    )
    result = run_emulated([*CHIP_OPTIONS, "--", sys.executable, str(script)])
    assert result.returncode == 0, result.stderr
    assert json.loads(result.stdout) == json.loads(json.dumps(expected))
    assert any(isinstance(v, str) for v in expected)  # some kinds fail: errnos compared too


# --------------------------------------------------------------------------- C, ioctl

C_CLIENT = textwrap.dedent(
    r"""
    #include <errno.h>
    #include <fcntl.h>
    #include <linux/i2c.h>
    #include <linux/i2c-dev.h>
    #include <stdio.h>
    #include <sys/ioctl.h>
    #include <time.h>
    #include <unistd.h>

    static long microseconds(void)
    {
        struct timespec now;
        clock_gettime(CLOCK_MONOTONIC, &now);
        return now.tv_sec * 1000000L + now.tv_nsec / 1000;
    }

    static int smbus(int fd, char rw, unsigned char cmd, int size, union i2c_smbus_data *d)
    {
        struct i2c_smbus_ioctl_data a = { .read_write = rw, .command = cmd, .size = size, .data = d };
        return ioctl(fd, I2C_SMBUS, &a);
    }

    static int rdwr(int fd, unsigned char reg, unsigned char *buf, unsigned short len)
    {
        struct i2c_msg m[2] = { { 0x68, 0, 1, &reg }, { 0x68, I2C_M_RD, len, buf } };
        struct i2c_rdwr_ioctl_data a = { m, 2 };
        return ioctl(fd, I2C_RDWR, &a);
    }

    int main(int argc, char **argv)
    {
        union i2c_smbus_data d;
        unsigned long funcs = 0;
        unsigned char buf[600], reg;
        int fd = open(argv[1], O_RDWR), i, before, after;
        long drain_start;
        if (fd < 0) { perror("open"); return 1; }
        if (ioctl(fd, I2C_FUNCS, &funcs) < 0) { perror("I2C_FUNCS"); return 1; }
        printf("funcs %lu\n", funcs);
        if (ioctl(fd, I2C_SLAVE, 0x68) < 0) { perror("I2C_SLAVE"); return 1; }
        if (smbus(fd, I2C_SMBUS_READ, 0x00, I2C_SMBUS_BYTE_DATA, &d) < 0) { perror("smbus"); return 1; }
        printf("chip_id %d\n", d.byte);
        for (i = 0; i < 5; i++) {
            if (rdwr(fd, 0x02, buf, 6) != 2) { perror("I2C_RDWR"); return 1; }
            printf("rate %d %d %d\n", (short)(buf[0] | buf[1] << 8),
                   (short)(buf[2] | buf[3] << 8), (short)(buf[4] | buf[5] << 8));
            usleep(2000);
        }
        d.byte = 0x07;  /* BW: ODR 100 Hz */
        if (smbus(fd, I2C_SMBUS_WRITE, 0x10, I2C_SMBUS_BYTE_DATA, &d) < 0) { perror("w"); return 1; }
        buf[0] = 0x3E; buf[1] = 0x40;  /* FIFO mode, plain write() */
        if (write(fd, buf, 2) != 2) { perror("write"); return 1; }
        usleep(300000);
        reg = 0x0E;  /* FIFO_STATUS, split form: write the pointer, then read() */
        if (write(fd, &reg, 1) != 1 || read(fd, buf, 1) != 1) { perror("split"); return 1; }
        before = buf[0] & 0x7F;
        drain_start = microseconds();
        if (rdwr(fd, 0x3F, buf, 6 * before) != 2) { perror("fifo"); return 1; }
        printf("fifo_first %d %d %d\n", (short)(buf[0] | buf[1] << 8),
               (short)(buf[2] | buf[3] << 8), (short)(buf[4] | buf[5] << 8));
        if (smbus(fd, I2C_SMBUS_READ, 0x0E, I2C_SMBUS_BYTE_DATA, &d) < 0) { perror("st"); return 1; }
        after = d.byte & 0x7F;
        printf("fifo %d %d\n", before, after);
        printf("fifo_drain_to_status_us %ld\n", microseconds() - drain_start);
        d.block[0] = 6;
        if (smbus(fd, I2C_SMBUS_READ, 0x02, I2C_SMBUS_I2C_BLOCK_DATA, &d) < 0) { perror("blk"); return 1; }
        printf("block %d %d\n", d.block[0], (short)(d.block[1] | d.block[2] << 8));
        ioctl(fd, I2C_SLAVE, 0x50);
        errno = 0;
        i = smbus(fd, I2C_SMBUS_READ, 0x00, I2C_SMBUS_BYTE_DATA, &d);
        printf("missing %d %d\n", i, errno);
        close(fd);
        return 0;
    }
    """
)


@pytest.fixture(scope="module")
def c_client(tmp_path_factory):
    cc = shutil.which("cc") or shutil.which("gcc")
    if cc is None:
        pytest.skip("no C compiler (apt-get install gcc)")
    work = tmp_path_factory.mktemp("c_client")
    source = work / "client.c"
    source.write_text(C_CLIENT)
    binary = work / "client"
    subprocess.run([cc, "-O2", "-Wall", "-o", str(binary), str(source)], check=True)
    result = run_emulated([*CHIP_OPTIONS, "--", str(binary), "/dev/i2c-1"])
    assert result.returncode == 0, result.stdout + result.stderr
    lines = [line.split() for line in result.stdout.splitlines()]
    parsed: dict[str, list] = {}
    for key, *values in lines:
        parsed.setdefault(key, []).append([int(v) for v in values])
    return parsed


def test_c_ioctl_client_sees_the_adapter_and_chip_id(c_client):
    from bmg160_emu.bus.i2c import DEFAULT_FUNCS

    assert c_client["funcs"] == [[DEFAULT_FUNCS]]
    assert c_client["chip_id"] == [[0x0F]]


def test_c_ioctl_client_sees_changing_rate_data(c_client):
    rates = c_client["rate"]
    assert len(rates) == 5 and len({tuple(r) for r in rates}) >= 3
    for rate in rates:
        assert_rate_counts(rate)
    (count, x), = c_client["block"]
    assert count == 6
    assert_rate_counts([x])  # X alone


def test_c_ioctl_client_drains_the_fifo(c_client):
    (before, after), = c_client["fifo"]
    (drain_to_status_us,), = c_client["fifo_drain_to_status_us"]
    # Everything read: at most one new frame per 10 ms (ODR 100 Hz) between the drain and
    # the status read (usually < 1 ms, longer on a loaded machine), plus one.
    assert before >= 15 and after <= 1 + drain_to_status_us // 10_000
    assert_rate_counts(c_client["fifo_first"][0], tol_dps=TOLERANCE_BW7_DPS)


def test_c_ioctl_client_missing_address(c_client):
    from bmg160_emu.bus.i2c import I2CBus

    with pytest.raises(OSError) as expected:
        I2CBus(1, {}).read_byte_data(0x50, 0)
    assert c_client["missing"] == [[-1, expected.value.errno]]


C_EDGE_CASES = textwrap.dedent(
    r"""
    #include <errno.h>
    #include <fcntl.h>
    #include <linux/i2c.h>
    #include <linux/i2c-dev.h>
    #include <stdio.h>
    #include <sys/ioctl.h>

    #define REPORT(name, call) do { errno = 0; int r_ = (call); \
        printf("%s %d %d\n", name, r_, r_ < 0 ? errno : 0); } while (0)

    int main(int argc, char **argv)
    {
        int fd = open(argv[1], O_RDWR);
        union i2c_smbus_data d;
        unsigned char buf[8];
        struct i2c_msg m[43];
        struct i2c_rdwr_ioctl_data rdwr = { m, 43 };
        struct i2c_smbus_ioctl_data a = { I2C_SMBUS_READ, 0x00, 9, &d };
        int i;
        for (i = 0; i < 43; i++) { m[i].addr = 0x68; m[i].flags = I2C_M_RD; m[i].len = 1; m[i].buf = buf; }
        REPORT("slave_0x80", ioctl(fd, I2C_SLAVE, 0x80));
        REPORT("slave_force", ioctl(fd, I2C_SLAVE_FORCE, 0x68));
        REPORT("size_9", ioctl(fd, I2C_SMBUS, &a));
        a.size = I2C_SMBUS_BYTE_DATA; a.read_write = 2;
        REPORT("read_write_2", ioctl(fd, I2C_SMBUS, &a));
        a.read_write = I2C_SMBUS_READ; a.data = 0;
        REPORT("null_data", ioctl(fd, I2C_SMBUS, &a));
        a.data = &d; a.size = I2C_SMBUS_I2C_BLOCK_DATA; d.block[0] = 33;
        REPORT("i2c_block_33", ioctl(fd, I2C_SMBUS, &a));
        a.size = I2C_SMBUS_I2C_BLOCK_BROKEN; d.block[0] = 0;
        REPORT("block_broken", ioctl(fd, I2C_SMBUS, &a));
        printf("broken_block %d %d\n", d.block[0], d.block[1]);
        REPORT("rdwr_43", ioctl(fd, I2C_RDWR, &rdwr));
        rdwr.nmsgs = 0;
        REPORT("rdwr_0", ioctl(fd, I2C_RDWR, &rdwr));
        rdwr.nmsgs = 1; m[0].len = 8193;
        REPORT("rdwr_8193", ioctl(fd, I2C_RDWR, &rdwr));
        REPORT("unknown", ioctl(fd, 0x0799, 0));
        return 0;
    }
    """
)


def test_c_ioctl_argument_checks_match_i2c_dev(tmp_path: Path):
    """Malformed requests fail as drivers/i2c/i2c-dev.c makes them fail."""
    import errno

    cc = shutil.which("cc") or shutil.which("gcc")
    if cc is None:
        pytest.skip("no C compiler (apt-get install gcc)")
    source, binary = tmp_path / "edge.c", tmp_path / "edge"
    source.write_text(C_EDGE_CASES)
    subprocess.run([cc, "-O2", "-o", str(binary), str(source)], check=True)
    result = run_emulated(["--", str(binary), "/dev/i2c-1"])
    assert result.returncode == 0, result.stderr
    seen = {line.split()[0]: [int(v) for v in line.split()[1:]] for line in result.stdout.splitlines()}
    einval = [-1, errno.EINVAL]
    assert seen["slave_0x80"] == einval  # above 0x7f without I2C_TENBIT
    assert seen["slave_force"] == [0, 0]
    assert seen["size_9"] == einval  # no such SMBus size
    assert seen["read_write_2"] == einval
    assert seen["null_data"] == einval  # a read needs the data union
    assert seen["i2c_block_33"] == einval  # I2C block transfers carry at most 32 bytes
    assert seen["block_broken"] == [0, 0]
    assert seen["broken_block"] == [32, 0x0F]  # size 6 reads 32 bytes from the command on
    assert seen["rdwr_43"] == einval  # I2C_RDWR_IOCTL_MAX_MSGS is 42
    assert seen["rdwr_0"] == einval
    assert seen["rdwr_8193"] == einval  # messages are capped at 8192 bytes
    assert seen["unknown"] == [-1, errno.ENOTTY]


# --------------------------------------------------------------------------- the command


def test_run_exits_with_the_program_status():
    assert run_emulated(["--", "sh", "-c", "exit 3"]).returncode == 3


def test_run_without_program_is_a_clear_error():
    result = run_emulated([])
    assert result.returncode == 2
    assert "no program given" in result.stderr and "Traceback" not in result.stderr


def test_run_with_unknown_program_is_a_clear_error():
    result = run_emulated(["--", "no-such-program-bmg160"])
    assert result.returncode == 2
    assert "command not found" in result.stderr


def test_run_serves_two_chips_and_the_bus_number(tmp_path: Path):
    if shutil.which("i2cget") is None:
        pytest.skip("i2c-tools is not installed (apt-get install i2c-tools)")
    result = run_emulated(
        ["--bus", "4", "--address", "0x68", "--address", "0x69", "--",
         "sh", "-c", "i2cget -y 4 0x68 0 && i2cget -y 4 0x69 0"]
    )
    assert result.returncode == 0, result.stderr
    assert result.stdout.split() == ["0x0f", "0x0f"]


def test_run_passes_sigterm_on_to_the_program():
    process = subprocess.Popen(
        [sys.executable, "-m", "bmg160_emu", "run", "--", "sh", "-c", "echo started; exec sleep 60"],
        stdout=subprocess.PIPE, text=True,
    )
    try:
        assert process.stdout.readline().strip() == "started"
        process.terminate()
        assert process.wait(timeout=30) == 128 + 15  # the program died of SIGTERM
    finally:
        if process.poll() is None:
            process.kill()


def test_run_trace_records_the_session_for_bmg160_emu_trace(tmp_path: Path):
    """--trace writes every transaction of the program as JSON Lines with a header naming
    the chips; `bmg160-emu trace` decodes it register by register."""
    trace = tmp_path / "session.jsonl"
    client = tmp_path / "client.py"
    client.write_text(
        "from smbus2 import SMBus\n"
        "with SMBus(1) as bus:\n"
        "    bus.read_byte_data(0x68, 0x00)\n"
        "    bus.write_byte_data(0x68, 0x0F, 0x02)\n"
        "    bus.read_i2c_block_data(0x68, 0x02, 6)\n"
        "    try:\n"
        "        bus.read_byte_data(0x50, 0x00)\n"
        "    except OSError:\n"
        "        pass\n"
    )
    result = run_emulated([*CHIP_OPTIONS, "--trace", str(trace), "--", sys.executable, str(client)])
    assert result.returncode == 0, result.stderr
    header, *lines, end = [json.loads(line) for line in trace.read_text().splitlines()]
    assert header["format"] == "bmg160-emu trace" and header["seed"] == 3
    # a complete session ends with its end line (docs/trace-format.md)
    assert end == {"end": "bmg160-emu trace", "transactions": 4}
    assert header["chips"][0]["true_rate_dps"] == list(TRUE_RATE_DPS)
    assert [(r["kind"], r["address"], r["error"]) for r in lines] == [
        ("read_byte_data", 0x68, None),
        ("write_byte_data", 0x68, None),
        ("read_i2c_block_data", 0x68, None),
        ("read_byte_data", 0x50, "EREMOTEIO"),
    ]
    assert lines[0]["read"] == [0x0F]
    times = [r["time"] for r in lines]
    assert times == sorted(times)

    decoded = subprocess.run(
        [sys.executable, "-m", "bmg160_emu", "trace", str(trace)],
        capture_output=True, text=True, timeout=60, check=False,
    )
    assert decoded.returncode == 0, decoded.stderr
    text = decoded.stdout.splitlines()
    assert len(text) == 4
    assert "CHIP_ID -> 0x0f" in text[0]
    assert "RANGE <- 0x02" in text[1]
    assert "x=" in text[2] and "z=" in text[2]  # the rate burst decoded as words


def test_run_trace_without_seed_records_the_seed_it_chose(tmp_path: Path):
    trace = tmp_path / "session.jsonl"
    result = run_emulated(["--trace", str(trace), "--", "sh", "-c", "exit 0"])
    assert result.returncode == 0, result.stderr
    header, end = [json.loads(line) for line in trace.read_text().splitlines()]
    assert isinstance(header["seed"], int)  # a replay can rebuild the same chips
    assert end == {"end": "bmg160-emu trace", "transactions": 0}  # complete, with none


def test_run_trace_to_an_unwritable_path_is_a_clear_error(tmp_path: Path):
    result = run_emulated(["--trace", str(tmp_path / "no" / "such" / "dir.jsonl"), "--", "true"])
    assert result.returncode == 2
    assert "cannot write" in result.stderr and "Traceback" not in result.stderr


def test_run_trace_of_a_real_time_session_replays_without_divergence(tmp_path: Path):
    """The program polls in real time (ODR 2000 Hz: a sample every 0.5 ms, so a sample
    falls between two of its reads) and drains the FIFO; the trace still replays exactly:
    the chips start sampling at t = 0 as the replay's do, and each request happens at the
    one instant its trace line carries."""
    trace = tmp_path / "session.jsonl"
    client = tmp_path / "client.py"
    client.write_text(
        "from smbus2 import SMBus, i2c_msg\n"
        "with SMBus(1) as bus:\n"
        "    for _ in range(200):\n"
        "        bus.read_i2c_block_data(0x68, 0x02, 6)\n"
        "    bus.write_byte_data(0x68, 0x3E, 0x40)\n"
        "    for _ in range(30):\n"
        "        n = bus.read_byte_data(0x68, 0x0E) & 0x7F\n"
        "        if n:\n"
        "            bus.i2c_rdwr(i2c_msg.write(0x68, [0x3F]), i2c_msg.read(0x68, 6 * n))\n"
    )
    result = run_emulated([*CHIP_OPTIONS, "--trace", str(trace), "--", sys.executable, str(client)])
    assert result.returncode == 0, result.stderr
    replayed = subprocess.run(
        [sys.executable, "-m", "bmg160_emu", "trace", "--replay", str(trace)],
        capture_output=True, text=True, timeout=120, check=False,
    )
    assert replayed.returncode == 0, replayed.stdout + replayed.stderr
    assert "no divergence" in replayed.stdout


def test_run_log_to_an_unwritable_path_is_refused_before_the_program_runs(tmp_path: Path):
    marker = tmp_path / "ran"
    log = tmp_path / "no" / "such" / "dir.log"
    result = run_emulated(["--log", str(log), "--", "touch", str(marker)])
    assert result.returncode == 2
    assert f"cannot write {log}" in result.stderr and "Traceback" not in result.stderr
    assert not marker.exists()


def _children_of(pid: int) -> list[int]:
    try:
        text = Path(f"/proc/{pid}/task/{pid}/children").read_text()
    except OSError:
        return []
    return [int(p) for p in text.split()]


def _alive(pid: int) -> bool:
    """Running (not gone, not a zombie waiting for a reaper)."""
    try:
        return Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0] != "Z"
    except OSError:
        return False


def test_run_killed_with_sigkill_takes_its_program_and_folder_with_it(tmp_path: Path):
    import os
    import signal
    import time

    from bmg160_emu.linux.umockdev import OWNER_FILE, remove_stale_testbeds

    env = dict(os.environ, TMPDIR=str(tmp_path))
    session = subprocess.Popen(
        [sys.executable, "-m", "bmg160_emu", "run", "--", "sleep", "60"],
        env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
    )
    try:
        deadline = time.monotonic() + 60
        while not _children_of(session.pid) and time.monotonic() < deadline:
            time.sleep(0.05)
        (program,) = _children_of(session.pid)
        folders = list(tmp_path.glob("umockdev.*"))
        assert len(folders) == 1 and (folders[0] / OWNER_FILE).exists()
        session.send_signal(signal.SIGKILL)
        session.wait(timeout=10)
        deadline = time.monotonic() + 5
        while _alive(program) and time.monotonic() < deadline:
            time.sleep(0.05)
        # the program died with its emulator (PR_SET_PDEATHSIG), it did not linger
        assert not _alive(program)
    finally:
        if session.poll() is None:
            session.kill()
    assert folders[0].exists()  # SIGKILL left the folder behind ...
    assert remove_stale_testbeds(str(tmp_path)) == [str(folders[0])]  # ... the next run takes it
    assert not folders[0].exists()
    other = tmp_path / "umockdev.other"  # not ours (no owner file): left alone
    other.mkdir()
    assert remove_stale_testbeds(str(tmp_path)) == []
    assert other.exists()
