"""The kernel talks to the model itself: virtio-i2c and virtio-gpio through vhost-user.

One QEMU guest boots once per test session with `bmg160-emu vhost-user-i2c` serving two
chips (0x68 and 0x69) on the host, and runs tests/kernel_guest/virtio_checks.sh: i2c-tools, an
i2c-dev program draining the FIFO and clearing a latched status, a C read loop (speed),
the kernel's bmg160 driver bound with its interrupt on a virtio-gpio line, 60 s of
triggered-buffer capture from both chips at once (100 Hz and 200 Hz) with the driver's own
data-ready triggers, and an any-motion event. The tests assert on what it wrote.
"""

from __future__ import annotations

import itertools
import json
import math
import os
import shlex
import shutil
import signal
import statistics
import struct
import subprocess
import sys
import time
from pathlib import Path

import pytest
from _kernel_boot import GUEST_FILES, boot_script, qemu_engine

import bmg160_emu

pytestmark = pytest.mark.kernel

REPO = Path(bmg160_emu.__file__).resolve().parents[1]
TRUE_RATE_DPS = (20.0, -10.0, 5.0)
SEED = 7
CAPTURE_S = float(os.environ.get("BMG160_VIRTIO_CAPTURE_S", "60"))
# One vCPU: under TCG on a busy host two vCPU threads plus QEMU and the back end compete
# for the cores; one kept 87 % of the 100 Hz frames where two kept 37 % (same load).
CPUS = int(os.environ.get("BMG160_VIRTIO_CPUS", "1"))


@pytest.fixture(scope="module")
def session(tmp_path_factory):
    """Start the back end, boot the guest once, stop the back end: (out folder, result)."""
    if shutil.which("i2cget") is None:
        pytest.skip("i2cget is missing (Debian package i2c-tools; the guest runs the host's)")
    engine = qemu_engine()  # prepared: its modules are built
    from bmg160_emu.linux.guest.kmod import bundled_dir

    kmod = bundled_dir()
    work = tmp_path_factory.mktemp("virtio")
    out = work / "out"
    out.mkdir()
    sockets = work / "sockets"  # the back end creates it 0700
    read_loop = work / "i2c_read_loop"
    subprocess.run(["gcc", "-O2", "-o", str(read_loop), str(GUEST_FILES / "i2c_read_loop.c")],
                   check=True)
    backend = subprocess.Popen(
        [sys.executable, "-m", "bmg160_emu", "vhost-user-i2c",
         "--socket", str(sockets / "i2c.sock"), "--gpio-socket", str(sockets / "gpio.sock"),
         "--address", "0x68", "--address", "0x69", "--seed", str(SEED),
         "--true-rate", *map(str, TRUE_RATE_DPS), "--trace", str(work / "trace.jsonl"),
         "--stats", str(work / "stats.json"), "--ready-file", str(work / "ready"),
         "--true-rate-file", str(out / "true_rate.txt")],
        stdout=subprocess.PIPE, stderr=subprocess.STDOUT, env={**os.environ, "PYTHONPATH": str(REPO)},
    )
    deadline = time.monotonic() + 60
    while not (work / "ready").exists() and backend.poll() is None and time.monotonic() < deadline:
        time.sleep(0.05)
    if not (work / "ready").exists():
        backend.kill()
        pytest.fail(f"the back end did not start: {backend.communicate()[0].decode()}")
    script = work / "run.sh"
    script.write_text(
        f"export PY={shlex.quote(sys.executable)}\n"
        f"export PYTHONPATH={shlex.quote(str(REPO))}\n"
        f"export KMOD={shlex.quote(str(kmod))} TOOLS={shlex.quote(str(GUEST_FILES))}\n"
        f"export READ_LOOP={shlex.quote(str(read_loop))} CAPTURE_S={CAPTURE_S:g}\n"
        f". {shlex.quote(str(GUEST_FILES / 'virtio_checks.sh'))}\n"
    )
    started = time.monotonic()
    result = boot_script(engine, script, out, timeout_s=CAPTURE_S + 150,
                         console_log=work / "console.txt", cpus=CPUS,
                         i2c_socket=sockets / "i2c.sock", gpio_socket=sockets / "gpio.sock")
    wall = time.monotonic() - started
    backend.send_signal(signal.SIGTERM)
    try:
        backend_log = backend.communicate(timeout=30)[0].decode()
    except subprocess.TimeoutExpired:
        backend.kill()
        backend_log = backend.communicate()[0].decode()
    (work / "backend.log").write_text(backend_log)
    print(f"virtio guest session: {wall:.1f} s wall time")
    return {"out": out, "work": work, "result": result, "backend": backend_log,
            "returncode": backend.returncode, "wall_s": wall}


@pytest.fixture(autouse=True)
def _console_in_report(request, session):
    request.node.add_report_section("setup", "guest console", session["result"].console)
    request.node.add_report_section("setup", "back end", session["backend"])


def text(session, name: str) -> str:
    path = session["out"] / name
    assert path.exists(), f"the guest did not write {name} (timed out: {session['result'].timed_out})"
    return path.read_text()


def stats(session) -> dict:
    return json.loads((session["work"] / "stats.json").read_text())


def test_guest_ran_every_step_and_the_back_end_stopped_cleanly(session):
    assert not session["result"].timed_out
    assert text(session, "done.txt").strip() == "done"
    assert session["returncode"] == 0, session["backend"]
    assert "Traceback" not in session["backend"]


def test_i2c_tools_see_both_chips_and_a_nack_elsewhere(session):
    assert "i2c_virtio" in text(session, "i2cdetect_l.txt")
    grid = text(session, "i2cdetect.txt")
    row60 = next(line for line in grid.splitlines() if line.startswith("60:"))
    assert row60.split()[9:11] == ["68", "69"]
    assert text(session, "chip_id_68.txt").strip() == "0x0f"
    assert text(session, "chip_id_69.txt").strip() == "0x0f"
    nack = text(session, "nack.txt")
    assert "status 2" in nack or "Read failed" in nack or "status 1" in nack, nack


def test_i2cdump_shows_the_reset_map(session):
    rows = {line[:2]: line[4:51].split() for line in text(session, "i2cdump_i.txt").splitlines()[1:]}
    block = [int(v, 16) for v in rows["00"] + rows["10"]]
    assert block[0x00] == 0x0F and block[0x10] == 0x80


def test_guest_program_drains_the_fifo_and_reads_leave_a_latched_status(session):
    checks = json.loads(text(session, "i2c_checks.json"))
    assert checks["count_full"] == 100
    # 60 frames popped; new ones arrive at 100 Hz in the two transfers between the reads
    # (under TCG on a loaded host up to ~50 ms: 5 frames)
    assert 40 <= checks["count_after_60"] <= 45, checks
    assert checks["distinct_frames"] >= 55  # real samples, not one repeated frame
    fifo_int = 0x10  # INT_STATUS_1 bit 4
    assert checks["status_full"] & fifo_int and checks["line_full"] == 1
    assert checks["line_before"] == 0
    # latched: reading the status does not clear it (spec 6.3) ...
    assert checks["status_after_drain"] & fifo_int and checks["status_read_again"] & fifo_int
    assert checks["status_bypass"] & fifo_int and checks["line_after_drain"] == 1
    # ... reset_int written from the guest does, and the GPIO line follows
    assert not checks["status_after_reset_int"] & fifo_int
    assert checks["line_after_reset_int"] == 0


def test_the_trace_shows_the_guest_drivers_reads(session):
    from bmg160_emu.io.trace import read_trace

    _, records = read_trace(session["work"] / "trace.jsonl")
    # the driver's probe soft-resets each chip (0x14 = 0xB6), then reads the rates as
    # 6-byte bursts from 0x02 (register write + read in one transfer: an I2C block read)
    probes = {r["address"]: r["time"] for r in records
              if r["kind"] == "i2c_write" and r["register"] == 0x14 and r["written"] == [0xB6]}
    assert set(probes) >= {0x68, 0x69}
    for address, capture in ((0x68, "capture_100.bin"), (0x69, "capture_200.bin")):
        bursts = [r for r in records if r["address"] == address and r["time"] > probes[address]
                  and r["kind"] == "read_i2c_block_data" and r["register"] == 0x02
                  and len(r["read"]) == 6]
        frames = _frames(session, capture)
        # every frame in the guest's buffer came from one of these reads
        assert frames and len(bursts) >= len(frames), (address, len(bursts), len(frames))
        assert {f[:3] for f in frames} <= {struct.unpack("<3h", bytes(r["read"])) for r in bursts}


def _rate_reads(session, address: int) -> list[tuple[float, tuple[int, int, int]]]:
    """(chip time, counts) of every 6-byte rate read of ``address`` in the trace."""
    from bmg160_emu.io.trace import read_trace

    _, records = read_trace(session["work"] / "trace.jsonl")
    return [(r["time"], struct.unpack("<3h", bytes(r["read"]))) for r in records
            if r["address"] == address and r["kind"] == "read_i2c_block_data"
            and r["register"] == 0x02 and len(r["read"]) == 6]


def _frames(session, name: str) -> list[tuple[int, int, int, int]]:
    data = (session["out"] / name).read_bytes()
    return [struct.unpack_from("<hhhxxq", data, i) for i in range(0, len(data) - 15, 16)]


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


@pytest.mark.parametrize(("odr_hz", "name", "address"),
                         [(100, "capture_100.bin", "0x68"), (200, "capture_200.bin", "0x69")])
def test_triggered_buffer_with_the_drivers_data_ready_trigger(session, odr_hz, name, address):
    frames = _frames(session, name)
    stamps = [f[3] for f in frames]
    assert all(b > a for a, b in itertools.pairwise(stamps)), "timestamps not monotonic"
    span_s = (stamps[-1] - stamps[0]) * 1e-9
    # The frames are the driver's capture reads, in order, in the back end's trace: their
    # chip times give the span of the chip's own time the capture covered.
    reads = _rate_reads(session, int(address, 16))
    values = [v for _, v in reads]
    triples = [f[:3] for f in frames]
    starts = [i for i in range(len(values) - len(triples) + 1)
              if values[i] == triples[0] and values[i:i + len(triples)] == triples]
    assert len(starts) == 1, "the capture is not one run of the driver's reads in the trace"
    chip_span_s = reads[starts[0] + len(frames) - 1][0] - reads[starts[0]][0]
    samples = odr_hz * chip_span_s + 1
    # Issue 14: the frame count within 1 % of ODR x time. On the chip's time axis (the
    # samples the model produced while the capture ran) this holds: the back end paces the
    # chips (--pace guest) so that a guest stalled by its host misses no data-ready sample.
    # What is still lost are edges IIO drops because the handler of the previous one has not
    # finished (measured 0.5 % at 100 Hz and 1.1 % at 200 Hz with a 0.3 ms guard on a host
    # at load 10; the 1 ms guard is there for them) and edges given up after 50 ms.
    assert samples * 0.99 <= len(frames) <= samples + 1, (len(frames), samples, chip_span_s)
    # On the guest's clock the chips' time lags when the guest cannot take 300 interrupts
    # and reads a second: a paced clock never runs ahead of the host's wall time and makes
    # up its lag at twice wall speed when it can. The guest's clock is not the host's: under
    # TCG its TSC is calibrated at boot, and a quiet run (no lag) kept 100.07 % and 100.13 %
    # of ODR x guest time, the guest's clock 0.07-0.14 % slow; 0.5 % bounds that. How much
    # the chips lag is the host's doing: this project's 2-core host gave 93 %, 82 % and 71 %
    # at load 8-10, and 64 % with the in-process test suite running beside it. The lower
    # bound only says the pacing never stalls the chips (a hold that always ran to its 50 ms
    # timeout would give < 10 %).
    expected = odr_hz * span_s + 1
    assert len(frames) <= expected * 1.005 + 1, (len(frames), expected, span_s)
    assert len(frames) >= 0.5 * expected, (len(frames), expected, span_s)
    print(f"{odr_hz} Hz: {len(frames)} frames, {len(frames) / samples:.2%} of the chip's "
          f"samples, {len(frames) / expected:.2%} of ODR x guest time; back end "
          f"{stats(session).get('paced')}")
    # No sample repeated. Two consecutive samples can agree on all three axes by chance (the
    # filtered noise moves a few counts per sample): the expected number of such pairs is
    # (N - 1) * prod_axis P(consecutive values equal), P taken from the record itself. A
    # trigger reading one sample twice would add to that; allow only what a Poisson count
    # of that mean exceeds with probability 1e-6.
    from scipy.stats import poisson

    pairs = list(itertools.pairwise(frames))
    repeats = sum(a[:3] == b[:3] for a, b in pairs)
    chance = len(pairs) * math.prod(
        sum(a[axis] == b[axis] for a, b in pairs) / len(pairs) for axis in range(3))
    assert repeats <= poisson.isf(1e-6, chance), (repeats, chance)
    final = stats(session)["final"][address]
    registers = bytes.fromhex(final["registers"])
    assert final["odr_hz"] == odr_hz
    range_code, bw_code = registers[0x0F] & 7, registers[0x10] & 7
    full_scale = 2000 / 2 ** range_code
    for axis in range(3):
        mean_dps = statistics.fmean(f[axis] for f in frames) * full_scale / 32768
        # N >= 5400 samples: the mean's noise is < 0.01 deg/s; 0.5 deg/s bounds the model's
        # turn-on bias (noise-model.md), a wrong scale would be off by >= 5 deg/s
        assert math.isclose(mean_dps, TRUE_RATE_DPS[axis], abs_tol=0.5), (axis, mean_dps)
    seen = [statistics.stdev(f[axis] for f in frames) for axis in range(3)]
    reference = _reference_std(odr_hz, bw_code, range_code, len(frames))
    for s, r in zip(seen, reference):
        # Each std comes from N >= 5400 samples whose noise is correlated over a few samples
        # (low-pass at ~1/3 of ODR): N_eff >= 1000, so each estimate is within 2.2 % (1
        # sigma, sqrt(1/(2 N_eff))) and their ratio within 3.2 %; 15 % is > 4.5 sigma.
        assert math.isclose(s, r, rel_tol=0.15), (seen, reference)


def test_any_motion_event_reaches_user_space(session):
    events = [line for line in text(session, "events.txt").splitlines() if line.startswith("id=")]
    assert events, text(session, "events.txt")
    # IIO_EV_TYPE_ROC = 2 on IIO_ANGL_VEL = 4 (uapi/linux/iio/types.h)
    assert all("type=2" in e and "chan_type=4" in e for e in events), events
    changes = stats(session)["true_rate_changes"]
    assert [c["true_rate_dps"] for c in changes][:2] == [[200.0, 0.0, 0.0], list(TRUE_RATE_DPS)]


def test_guest_read_loop_speed(session):
    fields = dict(item.split("=") for item in text(session, "speed.txt").split())
    assert int(fields["reads"]) == 20000
    # the acceptance figure (issue 14); the benchmark reports it against the other routes
    assert float(fields["per_s"]) > 0
    print(f"guest read loop: {fields}")
