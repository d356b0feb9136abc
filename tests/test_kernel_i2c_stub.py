"""The i2c-stub adapter on a real Linux kernel: i2c-tools and the kernel's own bmg160 driver.

The session's guest of the bmg160_kernel fixture (bmg160_emu/pytest_kernel.py) runs
tests/kernel_guest/kernel_checks.sh as one command, which loads i2c-stub and i2c-dev, starts `bmg160-emu stub`,
reads the chip with i2c-tools, binds the kernel's bmg160 driver and drives it through sysfs,
writing what it saw to files. The tests below assert on those files; the guest console is
attached to every test's report.
"""

from __future__ import annotations

import itertools
import json
import math
import shlex
import shutil
import statistics
import struct
import sys
from dataclasses import dataclass
from pathlib import Path

import pytest

import bmg160_emu

pytestmark = pytest.mark.kernel

REPO = Path(bmg160_emu.__file__).resolve().parents[1]
GUEST_FILES = Path(__file__).resolve().parent / "kernel_guest"
TRUE_RATE_DPS = (20.0, -10.0, 5.0)
TEMPERATURE_C = 30.0
STUB_ARGS = "--seed 7 --true-rate 20 -10 5 --temperature 30"
SAMPLES = 12  # per axis and configuration (kernel_checks.sh)


def _hrtimer_modules(engine):
    """The folder of the IIO software-trigger modules for the QEMU engine's kernel (None
    when they cannot be built here), or "builtin" where the kernel has them (uml.config)."""
    from bmg160_emu.linux.guest.debian_modules import bundled_dir

    return bundled_dir() if engine.name == "qemu" else "builtin"


@dataclass(frozen=True)
class Checks:
    """What the checks script left: its exit status and output; the guest's console."""

    returncode: int
    output: str
    console: str
    timed_out: bool = False


@pytest.fixture(scope="module")
def guest(bmg160_kernel_session, tmp_path_factory):
    """Run every check once, as one command on the session's guest: (output folder, Checks)."""
    from bmg160_emu.linux.guest.harness import GuestDied

    for tool, package in (("i2cget", "i2c-tools"), ("setpriv", "util-linux")):
        if shutil.which(tool) is None:
            pytest.skip(f"{tool} is missing (Debian package {package}; the guest runs the host's)")
    session_guest = bmg160_kernel_session.ensure()
    out = session_guest.results / "i2c_stub"
    out.mkdir(exist_ok=True)
    kmod = _hrtimer_modules(session_guest.engine)
    command = (
        (f"export KMOD={shlex.quote(str(kmod))} TOOLS={shlex.quote(str(GUEST_FILES))}\n"
         if kmod else "")
        + f"export PY={shlex.quote(sys.executable)} GUEST_OUT={shlex.quote(str(out))}\n"
        f"export PYTHONPATH={shlex.quote(str(REPO))}\n"
        f"export STUB_ARGS={shlex.quote(STUB_ARGS)}\n"
        f". {shlex.quote(str(GUEST_FILES / 'kernel_checks.sh'))}\n")
    # 400 s: about 70 s on a quiet machine; on a loaded one the guest's Python imports under
    # QEMU's software emulation took minutes (this session's own runs).
    try:
        result = session_guest.run(command, timeout_s=400, check=False)
    except GuestDied as exc:
        return out, Checks(-1, "", str(exc), timed_out="took over" in str(exc))
    return out, Checks(result.returncode, result.stdout + result.stderr,
                       session_guest.console())


@pytest.fixture(autouse=True)
def _console_in_report(request, guest):
    """Attach the guest console to the test's report (shown with any failure)."""
    _, result = guest
    request.node.add_report_section("setup", "checks output", result.output)
    request.node.add_report_section("setup", "guest console", result.console)


def text(guest, name: str) -> str:
    out, result = guest
    path = out / name
    assert path.exists(), f"the guest did not write {name} (timed out: {result.timed_out})"
    return path.read_text()


def numbers(guest, name: str) -> list[float]:
    return [float(v) for v in text(guest, name).split()]


def stub_report(guest) -> dict:
    return json.loads(text(guest, "stub_stats.json"))


def test_the_checks_ran_every_step(guest):
    _, result = guest
    assert not result.timed_out, "the guest did not finish in time"
    assert text(guest, "done.txt").strip() == "done"
    assert text(guest, "stub_ready.txt").strip() == "ready"


def test_stub_command_errors_are_one_line_and_exit_2(guest):
    expected = {
        "err_missing.txt": "does not exist",
        "err_address.txt": "not one of i2c-stub's chip addresses",
        "err_not_stub.txt": "not an i2c-stub adapter",
        "err_permission.txt": "permission denied",
    }
    for name, phrase in expected.items():
        lines = text(guest, name).strip().splitlines()
        assert lines[-1] == "2", (name, lines)
        assert len(lines) == 2 and phrase in lines[0], (name, lines)
        assert "Traceback" not in lines[0]


def test_i2cget_reads_chip_id(guest):
    assert text(guest, "i2cget_chip_id.txt").strip() == "0x0f"


def test_i2cdump_shows_reset_map(guest):
    rows = {line[:2]: line[4:51].split() for line in text(guest, "i2cdump_i.txt").splitlines()[1:]}
    block = [int(v, 16) for v in rows["00"] + rows["10"]]
    assert block[0x00] == 0x0F  # CHIP_ID
    assert block[0x10] == 0x80  # BW reset value, bit 7 reads 1 (spec 4.9)
    byte_rows = text(guest, "i2cdump_b.txt").splitlines()[1:]
    assert byte_rows[0].split()[1] == "0f"


def test_rate_registers_change_and_word_and_block_reads_agree(guest):
    words = [int(v, 16) for v in text(guest, "i2cget_rate_x_words.txt").split()]
    assert len(set(words)) >= 3, words
    blocks = [
        [int(v, 16) for v in line.split()[:6]]
        for line in text(guest, "i2cdump_rate_blocks.txt").splitlines()
    ]
    assert len({tuple(b) for b in blocks}) >= 3
    # Same true rate, so word reads (slot = reg[r] | reg[r+1] << 8) and block reads give
    # counts of the same size: 20 deg/s at the reset range 2000 deg/s is 327.7 counts.
    expected = TRUE_RATE_DPS[0] * 32768 / 2000
    for counts in [w - 65536 if w >= 32768 else w for w in words] + [
        b[0] | b[1] << 8 for b in blocks
    ]:
        # the model's noise at the reset bandwidth (523 Hz) is ~13 counts rms: 70 is > 5 sigma
        assert abs(counts - expected) < 70, counts


def test_kernel_driver_binds_and_reports_the_emulated_chip(guest):
    assert text(guest, "iio_name.txt").strip() == "bmg160"
    attributes = dict(line.split(" ", 1) for line in text(guest, "iio_attributes.txt").splitlines())
    assert attributes["in_anglvel_scale"].strip() == "0.000266"  # driver default 500 deg/s
    assert attributes["in_anglvel_sampling_frequency"].strip() == "100"
    # in_temp_raw = (T - 23) / 0.5 K per LSB (spec 4.3; driver offset 23, scale 500 mK)
    assert int(attributes["in_temp_raw"]) == round((TEMPERATURE_C - 23.0) / 0.5)
    assert numbers(guest, "temp_raw.txt") == [14.0] * 3


def test_bound_address_is_busy_without_force(guest):
    busy = text(guest, "i2cget_busy.txt")
    assert "Device or resource busy" in busy and "status 1" in busy
    # ... while the adapter, opening with I2C_SLAVE_FORCE, kept serving the driver
    assert any(e["register"] == 0x0F and e["range"] == 0 for e in stub_report(guest)["events"])


def test_probe_writes_reached_the_model_and_were_normalised(guest):
    rows = text(guest, "i2cdump_after_probe.txt").splitlines()
    row10 = rows[2].split()[1:]
    assert rows[1].split()[-2] == "02"  # RANGE 500 deg/s as the driver wrote it
    assert row10[0] == "87"  # BW 0x07 written, read back with the read-only bit 7 set
    assert row10[4] == "00"  # the soft-reset command 0xB6 was taken and cleared
    # INT_EN_1 and INT_RST_LATCH as the driver wrote them (0x0D; 0x8F read back as 0x0F, its
    # bit 7 self-clears), also when runtime suspend (LPM1 = 0x80) lands in the same refresh
    assert row10[6] == "0d"
    assert rows[3].split()[2] == "0f"
    events = stub_report(guest)["events"]
    assert any(e["register"] == 0x14 and e["value"] == 0xB6 for e in events)


def _mean_dps(guest, prefix: str, full_scale_dps: float) -> list[float]:
    return [
        statistics.fmean(numbers(guest, f"{prefix}_{axis}.txt")) * full_scale_dps / 32768
        for axis in "xyz"
    ]


@pytest.mark.parametrize(
    ("prefix", "full_scale_dps"),
    [("raw_default", 500), ("raw_2000", 2000), ("raw_resumed_2000", 2000), ("raw_250", 250)],
)
def test_sysfs_raw_values_follow_the_true_rate_at_each_scale(guest, prefix, full_scale_dps):
    for axis in "xyz":
        values = numbers(guest, f"{prefix}_{axis}.txt")
        assert len(values) == SAMPLES
        # New samples, not one frozen value. At +-2000 deg/s the noise is ~2.9 counts rms, and
        # 12 rounded normal draws give fewer than 3 distinct values with p < 1e-5 (fewer than 6,
        # the old bound, with p ~ 0.04 per axis: 12 such checks made the test flaky).
        assert len(set(values)) >= 3, values
    # Mean of 12 samples: the model's noise at the driver's 32 Hz bandwidth is ~0.2 deg/s
    # rms (0.06 deg/s for the mean) and its bias ~0.1 deg/s, far inside 1.5 deg/s; a wrong
    # range would be off by a factor of 2 or more (10 deg/s and up).
    for mean, true in zip(_mean_dps(guest, prefix, full_scale_dps), TRUE_RATE_DPS):
        assert math.isclose(mean, true, abs_tol=1.5), (prefix, mean, true)


def test_noise_level_matches_the_model(guest):
    """The spread of the kernel's readings is the model's noise at the driver's settings
    (RANGE 500 deg/s, BW code 7: ODR 100 Hz), sampled 50 ms apart as the guest did."""
    from bmg160_emu.device.chip import BMG160

    chip = BMG160(seed=11, true_rate=TRUE_RATE_DPS)
    chip.write(0x0F, b"\x02")
    chip.write(0x10, b"\x07")
    reference = {axis: [] for axis in range(3)}
    for _ in range(600):
        chip.advance(0.05)
        raw = chip.read(0x02, 6)
        for axis in range(3):
            reference[axis].append(int.from_bytes(raw[2 * axis : 2 * axis + 2], "little", signed=True))
    expected = statistics.fmean(statistics.stdev(v) for v in reference.values())
    seen = statistics.fmean(
        statistics.stdev(numbers(guest, f"raw_default_{axis}.txt")) for axis in "xyz"
    )
    # 3 axes x 11 degrees of freedom: the sample s/sigma lies in [0.6, 1.45] with 99.9 %
    # probability (chi-square, 33 dof); wider bounds allow for counts quantisation.
    assert expected > 1.0
    assert 0.5 * expected < seen < 1.8 * expected, (seen, expected)


def test_sysfs_scale_and_frequency_writes_change_the_emulator(guest):
    assert text(guest, "scale_2000.txt").strip() == "0.001065"
    assert text(guest, "freq_400.txt").strip() == "400"
    assert text(guest, "scale_250.txt").strip() == "0.000133"
    events = stub_report(guest)["events"]
    ranges = [e["range"] for e in events if e["register"] == 0x0F]
    odrs = [e["odr_hz"] for e in events if e["register"] == 0x10]
    assert ranges[-2:] == [0, 3]  # 2000 then (after resume) 250 deg/s
    assert 400 in odrs and odrs[-1] == 200


def test_runtime_suspend_and_resume_reach_the_model(guest):
    assert text(guest, "lpm1_idle.txt").strip() == "0x80"
    events = stub_report(guest)["events"]
    power = [(e["time_s"], e["power_mode"]) for e in events if e["register"] == 0x11]
    suspended = next(t for t, mode in power if mode == "suspend")
    resumed = next(t for t, mode in power if mode == "normal" and t > suspended)
    # the scale written after the resume reached the model, which was running again
    range_250 = next(e for e in events if e["register"] == 0x0F and e["range"] == 3)
    assert range_250["time_s"] > resumed
    assert range_250["power_mode"] == "normal"


def test_adapter_refresh_follows_the_output_data_rate(guest):
    by_odr = stub_report(guest)["summary"]["by_odr_hz"]
    for odr in ("100", "400", "200"):
        assert odr in by_odr, by_odr
    # The median period is the output data period unless the guest CPU cannot keep up;
    # the ordering holds either way, and 100 Hz is slow enough to be met.
    med = {odr: by_odr[odr]["period_median_s"] for odr in by_odr}
    assert med["400"] < med["200"] < med["100"]
    assert math.isclose(med["100"], 0.010, rel_tol=0.2)


def test_adapter_stops_cleanly_on_sigterm(guest):
    assert text(guest, "stub_exit.txt").strip() == "0"


def test_buffered_capture_with_the_hrtimer_trigger(guest):
    """The driver's triggered buffer, paced by the hrtimer software trigger at 100 Hz while
    the adapter refreshes at the 200 Hz output data rate left by step 3e."""
    out, _ = guest
    path = out / "hrtimer_capture.bin"
    if not path.exists():
        pytest.skip("the IIO software-trigger modules could not be built")
    data = path.read_bytes()
    frames = [struct.unpack_from("<hhhxxq", data, i) for i in range(0, len(data) - 15, 16)]
    assert len(frames) > 10, f"{len(frames)} frames captured"
    stamps = [f[3] for f in frames]
    assert all(b > a for a, b in itertools.pairwise(stamps))
    span_s = (stamps[-1] - stamps[0]) * 1e-9
    # The hrtimer fires at 100 Hz; IIO drops a trigger that fires while the driver's read
    # of the previous one is still in flight, which a loaded TCG guest does often (74 % of
    # the periods kept at a host load average of 9): half is the floor asserted here.
    assert len(frames) >= 0.5 * (100 * span_s + 1), (len(frames), span_s)
    # 250 deg/s range (step 3e's scale 0.000133): 131.072 LSB per deg/s
    assert (out / "hrtimer_scale.txt").read_text().strip() == "0.000133"
    for axis in range(3):
        mean = statistics.fmean(f[axis] for f in frames) / 131.072
        assert math.isclose(mean, TRUE_RATE_DPS[axis], abs_tol=1.0), (axis, mean)
    fresh = sum(a[:3] != b[:3] for a, b in itertools.pairwise(frames)) / (len(frames) - 1)
    print(f"hrtimer capture: {len(frames)} frames in {span_s:.2f} s, {fresh:.1%} fresh")
    # reads at 100 Hz of samples made at 200 Hz: each read sees a new sample unless the
    # adapter's refresh (its own schedule, late under load) did not run between two reads
    assert fresh > 0.3
