"""The kernel talks to the model itself: virtio-i2c and virtio-gpio through vhost-user.

Through the ``bmg160_kernel`` fixture (bmg160_emu/pytest_kernel.py): one guest per session
with the back ends in this process serving two chips (0x68 and 0x69); i2c-tools, an i2c-dev
program draining the FIFO and clearing a latched status, a C read loop, the kernel's bmg160
driver bound with its interrupt on a virtio-gpio line, triggered-buffer captures with the
driver's own data-ready triggers (100 Hz on 0x68, 200 Hz on 0x69), and an any-motion event.
The transaction log the tests read is the bus the guest's kernel talks to.

On the uml engine the guest runs in virtual time (its clock is the chips'), so the tests
assert what the driver and the chip did at each instant of that clock: every sample, its
interrupt and its read, whatever the host's speed. Under QEMU (real time) they allow for
what a loaded host drops.
"""

from __future__ import annotations

import itertools
import json
import math
import os
import statistics
import struct
import subprocess
import time
from pathlib import Path

import pytest

pytestmark = pytest.mark.kernel

GUEST_FILES = Path(__file__).resolve().parent / "kernel_guest"
TRUE_RATE_DPS = (20.0, -10.0, 5.0)
SAMPLES = int(os.environ.get("BMG160_VIRTIO_CAPTURE_SAMPLES", "3000"))
BOTH = [0x68, 0x69]


@pytest.fixture
def rates(bmg160_kernel):
    for chip in bmg160_kernel.chips.values():
        chip.set_true_rate(TRUE_RATE_DPS)
    return bmg160_kernel


@pytest.mark.bmg160_kernel(driver=None)
def test_i2c_tools_see_both_chips_and_a_nack_elsewhere(bmg160_kernel):
    assert "i2c_virtio" in bmg160_kernel.run("i2cdetect -l").stdout
    grid = bmg160_kernel.run("i2cdetect -y $GUEST_I2C_BUS").stdout
    row60 = next(line for line in grid.splitlines() if line.startswith("60:"))
    assert row60.split()[9:11] == ["68", "69"]
    for address in ("0x68", "0x69"):
        assert bmg160_kernel.run(f"i2cget -y $GUEST_I2C_BUS {address} 0x00").stdout.strip() \
            == "0x0f"
    nack = bmg160_kernel.run("i2cget -y $GUEST_I2C_BUS 0x50 0x00", check=False)
    assert nack.returncode != 0 and "Read failed" in nack.stderr
    assert bmg160_kernel.bus.log.filter(address=0x50, failed=True)


@pytest.mark.bmg160_kernel(driver=None)
def test_i2cdump_shows_the_reset_map(bmg160_kernel):
    dump = bmg160_kernel.run("i2cdump -y $GUEST_I2C_BUS 0x68 i").stdout
    rows = {line[:2]: line[4:51].split() for line in dump.splitlines()[1:]}
    block = [int(v, 16) for v in rows["00"] + rows["10"]]
    assert block[0x00] == 0x0F and block[0x10] == 0x80


@pytest.mark.bmg160_kernel(driver=None)
def test_guest_program_drains_the_fifo_and_reads_leave_a_latched_status(bmg160_kernel):
    line = bmg160_kernel.session.backend.line_of(0x69)  # INT1 of 0x69
    result = bmg160_kernel.run(
        f"n=$((GUEST_GPIO_BASE + {line})); echo $n > /sys/class/gpio/export\n"
        "v=$(ls -d /sys/class/gpio/bmg160-0x69-INT1 /sys/class/gpio/gpio$n 2>/dev/null "
        "| head -n 1)/value\n"
        f'"$BMG160_PY" {GUEST_FILES / "guest_i2c_checks.py"} $GUEST_I2C_BUS 0x69 "$v"\n'
        "s=$?; echo $n > /sys/class/gpio/unexport; exit $s")
    checks = json.loads(result.stdout)
    assert checks["count_full"] == 100
    # 60 frames popped; new ones arrive at 100 Hz while the program runs between the reads:
    # in virtual time only the guest's own clock reads pass (256 ns each), so at most one
    # sample instant falls between; up to 5 under a loaded TCG guest in real time
    if bmg160_kernel.virtual:
        assert 40 <= checks["count_after_60"] <= 41, checks
    else:
        assert 40 <= checks["count_after_60"] <= 45, checks
    # Real samples, not one repeated frame: at rest, the reset range (2000 deg/s) and the
    # 32 Hz filter the model's noise is 2-2.7 LSB rms per axis, and 60 consecutive frames
    # of it held 51-60 distinct ones over seeds 0-19 (the old bound of 55 failed one run in
    # five); 30 is far below that and far above the 1 of a frozen FIFO.
    assert checks["distinct_frames"] >= 30, checks
    fifo_int = 0x10  # INT_STATUS_1 bit 4
    assert checks["status_full"] & fifo_int and checks["line_full"] == 1
    assert checks["line_before"] == 0
    # latched: reading the status does not clear it (spec 6.3) ...
    assert checks["status_after_drain"] & fifo_int and checks["status_read_again"] & fifo_int
    assert checks["status_bypass"] & fifo_int and checks["line_after_drain"] == 1
    # ... reset_int written from the guest does, and the GPIO line follows
    assert not checks["status_after_reset_int"] & fifo_int
    assert checks["line_after_reset_int"] == 0


@pytest.mark.bmg160_kernel(driver=None)
def test_guest_read_loop_speed(bmg160_kernel, tmp_path):
    loop = tmp_path / "i2c_read_loop"
    subprocess.run(["gcc", "-O2", "-o", str(loop), str(GUEST_FILES / "i2c_read_loop.c")],
                   check=True)
    out = bmg160_kernel.run(f"{loop} $GUEST_I2C_BUS 0x68 0x02 6 5000", timeout_s=600).stdout
    fields = dict(item.split("=") for item in out.split())
    assert int(fields["reads"]) == 5000
    # the speed figure is tools/bench_uml.py's (timed on the host: in virtual time the
    # guest's own clock says how much guest time the reads took, not how fast they went)
    assert float(fields["per_s"]) > 0
    assert bmg160_kernel.bus.log.total - bmg160_kernel.mark >= 5000  # each one reached the bus
    print(f"guest read loop: {fields}")


@pytest.mark.bmg160_kernel(addresses=BOTH)
def test_the_driver_binds_both_chips_with_their_interrupts(bmg160_kernel):
    for address in BOTH:
        device = bmg160_kernel.iio(address)
        assert bmg160_kernel.run(f"cat {device}/name").stdout.strip() == "bmg160"
        assert bmg160_kernel.run(f"ls {device}/events").stdout.split()  # only with an IRQ
    triggers = bmg160_kernel.run("cat /sys/bus/iio/devices/trigger*/name").stdout.split()
    assert sum(t.startswith("bmg160-dev") for t in triggers) >= 2
    assert "virtio-gpio" in bmg160_kernel.run("grep -i gpio /proc/interrupts").stdout
    # the probe soft-reset each chip: 0x14 = 0xB6 in the log, then 6-byte rate reads later
    for address in BOTH:
        assert (0x14, 0xB6) in bmg160_kernel.writes(address)


def _rate_reads(kernel, address: int) -> list[tuple[float, tuple[int, int, int]]]:
    """(chip time, counts) of every 6-byte rate read of ``address`` in the test's log."""
    return [(t.time, struct.unpack("<3h", t.read)) for t in kernel.bus.log.filter(
        address=address, register=0x02) if len(t.read) == 6 and t.error is None]


def _reference_std(odr_hz: int, bw_code: int, range_code: int, n: int) -> list[float]:
    """The model's own noise std (counts) at these settings: a virtual-clock chip."""
    from bmg160_emu.device.chip import BMG160

    chip = BMG160(seed=11, true_rate=TRUE_RATE_DPS)
    chip.write(0x0F, bytes([range_code]))
    chip.write(0x10, bytes([bw_code]))
    chip.advance(0.5)
    values = []
    for _ in range(n):
        chip.advance(1.0 / odr_hz)
        values.append(struct.unpack("<3h", chip.read(0x02, 6)))
    return [statistics.stdev(v[axis] for v in values) for axis in range(3)]


@pytest.mark.parametrize(("odr_hz", "address"), [
    pytest.param(100, 0x68, marks=pytest.mark.bmg160_kernel(addresses=[0x68])),
    pytest.param(200, 0x69, marks=pytest.mark.bmg160_kernel(addresses=[0x69]))])
def test_triggered_buffer_with_the_drivers_data_ready_trigger(rates, odr_hz, address):
    kernel = rates
    kernel.set_attr("in_anglvel_sampling_frequency", odr_hz)
    # the reader wakes every 32 frames, not every frame (under TCG a wake-up of the guest's
    # reader costs about a millisecond); in virtual time N samples cost N samples of work
    frames = kernel.capture(samples=SAMPLES, seconds=SAMPLES / odr_hz + 5, watermark=32)
    assert len(frames) > 10, len(frames)
    stamps = [f[3] for f in frames]
    assert all(b > a for a, b in itertools.pairwise(stamps)), "timestamps not monotonic"
    span_s = (stamps[-1] - stamps[0]) * 1e-9
    # The frames are the driver's capture reads, in order, in the bus's log: their chip
    # times give the span of the chip's own time the capture covered.
    reads = _rate_reads(kernel, address)
    values = [v for _, v in reads]
    triples = [f[:3] for f in frames]
    starts = [i for i in range(len(values) - len(triples) + 1)
              if values[i] == triples[0] and values[i:i + len(triples)] == triples]
    assert len(starts) == 1, "the capture is not one run of the driver's reads in the log"
    chip_span_s = reads[starts[0] + len(frames) - 1][0] - reads[starts[0]][0]
    samples = odr_hz * chip_span_s + 1
    period_ns = 1e9 / odr_hz
    if kernel.virtual:
        # Every sample of the chip reached the buffer, one data-ready interrupt each, read
        # at its own instant: consecutive reads one output period apart on the chip's
        # clock, and the driver's time stamps (the guest's clock, which is the chip's, at
        # the interrupt) one period apart too, to the guest's own few clock reads (256 ns
        # each, arch/um/kernel/time.c) in the handler
        assert len(frames) == SAMPLES and round(samples) == SAMPLES, (len(frames), samples)
        gaps = [b - a for a, b in itertools.pairwise(stamps)]
        assert max(abs(g - period_ns) for g in gaps) < 20_000, (min(gaps), max(gaps))
    else:
        # Issue 14: the frame count within 1 % of ODR x time on the chip's time axis (the
        # back end paces the chips so that a guest stalled by its host misses no data-ready
        # sample; IIO still drops an edge whose previous handler has not finished).
        assert samples * 0.99 <= len(frames) <= samples + 1, (len(frames), samples)
        # On the guest's clock the chips lag when the guest cannot keep up (a paced clock
        # never runs ahead of wall time); 0.5 % bounds the guest's TSC-calibrated clock.
        expected = odr_hz * span_s + 1
        assert len(frames) <= expected * 1.005 + 1, (len(frames), expected, span_s)
        assert len(frames) >= 0.5 * expected, (len(frames), expected, span_s)
    gpio = kernel.session.backend.gpio
    print(f"{odr_hz} Hz: {len(frames)} frames, {len(frames) / samples:.2%} of the chip's "
          f"samples over {span_s:.3f} s of the guest's clock; held {gpio.held_samples}, "
          f"given up {gpio.given_up}")
    # No sample repeated beyond chance: the expected number of equal consecutive triples
    # is (N - 1) * prod_axis P(consecutive values equal); allow what a Poisson count of
    # that mean exceeds with probability 1e-6.
    from scipy.stats import poisson

    pairs = list(itertools.pairwise(frames))
    repeats = sum(a[:3] == b[:3] for a, b in pairs)
    chance = len(pairs) * math.prod(
        sum(a[axis] == b[axis] for a, b in pairs) / len(pairs) for axis in range(3))
    assert repeats <= poisson.isf(1e-6, chance), (repeats, chance)
    chip = kernel.chip
    assert chip.odr_hz == odr_hz
    registers = chip.dump()
    range_code, bw_code = registers[0x0F] & 7, registers[0x10] & 7
    full_scale = 2000 / 2 ** range_code
    for axis in range(3):
        mean_dps = statistics.fmean(f[axis] for f in frames) * full_scale / 32768
        # N >= 2700 samples: the mean's noise is < 0.02 deg/s; 0.5 deg/s bounds the model's
        # turn-on bias (noise-model.md), a wrong scale would be off by >= 5 deg/s
        assert math.isclose(mean_dps, TRUE_RATE_DPS[axis], abs_tol=0.5), (axis, mean_dps)
    seen = [statistics.stdev(f[axis] for f in frames) for axis in range(3)]
    reference = _reference_std(odr_hz, bw_code, range_code, len(frames))
    for s, r in zip(seen, reference):
        # N >= 2700 samples correlated over a few samples (low-pass at ~1/3 of ODR):
        # N_eff >= 500, each std within 3.2 % (1 sigma, sqrt(1/(2 N_eff))), their ratio
        # within 4.5 %; 20 % is > 4.4 sigma.
        assert math.isclose(s, r, rel_tol=0.20), (seen, reference)


def test_any_motion_event_reaches_user_space(rates):
    """A step of the true rate 0.5 s into the event reader's 3 s raises the driver's
    any-motion (rate of change) event. In virtual time the step is a host event at that
    instant of the guest's clock; against wall time the host steps it once the reader is
    ready (its start under TCG takes seconds)."""
    kernel = rates
    device = kernel.iio()
    kernel.set_attr("events/in_anglvel_roc_either_value", 2)
    kernel.set_attr("events/in_anglvel_roc_either_en", 1)
    reader = f'"$BMG160_PY" {GUEST_FILES / "guest_iio_events.py"} /dev/{device.rsplit("/")[-1]} 3'
    if kernel.virtual:
        kernel.at(0.5, lambda: kernel.chip.set_true_rate((200.0, 0.0, 0.0)))
        kernel.at(1.5, lambda: kernel.chip.set_true_rate(TRUE_RATE_DPS))
        # the reader's start on the guest's wall clock (CLOCK_REALTIME, the events' clock)
        out = kernel.run(f"date +start=%s%N; {reader}").stdout
    else:
        ready, log = kernel.guest.results / "events.ready", kernel.guest.results / "events.txt"
        kernel.run(f"{reader} {ready} > {log} 2>&1 &")
        deadline = time.monotonic() + 60
        while not ready.exists() and time.monotonic() < deadline:
            time.sleep(0.05)
        assert ready.exists(), "the event reader did not start"
        time.sleep(0.5)
        kernel.chip.set_true_rate((200.0, 0.0, 0.0))
        time.sleep(1.0)
        kernel.chip.set_true_rate(TRUE_RATE_DPS)
        kernel.run("sleep 3")
        out = log.read_text()
    kernel.set_attr("events/in_anglvel_roc_either_en", 0)
    events = [line for line in out.splitlines() if line.startswith("id=")]
    assert events, out
    # IIO_EV_TYPE_ROC = 2 on IIO_ANGL_VEL = 4 (uapi/linux/iio/types.h)
    assert all("type=2" in e and "chan_type=4" in e for e in events), events
    if kernel.virtual:
        # In the guest's time the step comes 0.5 s (and at most the 1 ms of one horizon)
        # after the reader's start, whose Python start-up costs no guest time beyond its
        # clock reads: no event before it, and one within 10 samples at the driver's 100 Hz
        # after it (the step through the 32 Hz low-pass, then the any-motion engine's 4
        # samples, spec 4.17: 50-70 ms seen)
        start_ns = int(out.split("start=")[1].split()[0])
        first_s = (int(events[0].split("timestamp_ns=")[1].split()[0]) - start_ns) / 1e9
        assert 0.5 - 0.001 <= first_s <= 0.5 + 0.1, first_s
