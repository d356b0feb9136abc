"""The kernel's bmg160 driver binds to the BMI055 and BMI088 gyroscope parts through i2c-stub.

The bmg160_kernel fixture's session guest loads i2c-stub with two chip addresses and runs one
Python process that builds a ``bmi055_gyro`` at 0x68 and a ``bmi088_gyro`` at 0x69 with
``make_chip`` and keeps both in i2c-stub's memory (``I2CStubAdapter``, one thread each).
The guest then reads both with i2c-tools, binds the driver by the names its I2C ID table
gives them (``bmi055_gyro``, ``bmi088_gyro``) and reads the rate and temperature through
sysfs. The tests assert on what it wrote; the guest console is attached to every report.
"""

from __future__ import annotations

import json
import math
import shlex
import shutil
import statistics
import sys
from dataclasses import dataclass
from pathlib import Path

import pytest

import bmg160_emu

pytestmark = pytest.mark.kernel

REPO = Path(bmg160_emu.__file__).resolve().parents[1]
TRUE_RATE_DPS = (20.0, -10.0, 5.0)
TEMPERATURE_C = 30.0
PARTS = {"bmi055_gyro": 0x68, "bmi088_gyro": 0x69}
SAMPLES = 12

# Runs in the guest: both parts on the i2c-stub bus ($STUB_BUS), until SIGTERM; then a JSON report per part.
ADAPTERS = """
import json, os, signal, sys, threading
from dataclasses import dataclass
from pathlib import Path
from bmg160_emu.linux.i2c_stub import I2CStubAdapter
from bmg160_emu.clock import RealTimeClock
from bmg160_emu.device.parts import make_chip

out, parts = Path(sys.argv[1]), sys.argv[2:]
clock = RealTimeClock()
stop = threading.Event()
signal.signal(signal.SIGTERM, lambda *_: stop.set())
adapters = {}
for spec in parts:
    name, address = spec.split("@")
    chip = make_chip(name, seed=7, clock=clock, address=int(address, 0),
                     true_rate=(20.0, -10.0, 5.0), temperature_c=30.0)
    adapters[name] = I2CStubAdapter(chip, int(os.environ["STUB_BUS"]), int(address, 0))
    adapters[name].preload()
threads = [threading.Thread(target=a.run, kwargs={"should_stop": stop.is_set, "preload": False})
           for a in adapters.values()]
for t in threads:
    t.start()
Path("/run/parts.ready").write_text("ready\\n")
for t in threads:
    t.join()
for name, a in adapters.items():
    a.close()
    report = {"events": a.events, "part": a.chip.part.name, "final": a.chip.dump().hex()}
    (out / f"stub_{name}.json").write_text(json.dumps(report))
"""

GUEST_SCRIPT = r"""
set -u
OUT=${GUEST_OUT:?}
cd /run || exit 1
modprobe ${GUEST_ROOT:+-d "$GUEST_ROOT"} i2c-stub chip_addr=0x68,0x69,0x18 || echo "modprobe i2c-stub failed"
modprobe ${GUEST_ROOT:+-d "$GUEST_ROOT"} i2c-dev || echo "modprobe i2c-dev failed"
rm -f /run/parts.ready /run/accel.ready
S=$(for d in /sys/bus/i2c/devices/i2c-*; do grep -q "SMBus stub" "$d/name" && echo "${d##*/i2c-}"; done | head -n 1)
export STUB_BUS=$S
"$PY" "$ADAPTERS" "$OUT" bmi055_gyro@0x68 bmi088_gyro@0x69 > "$OUT/adapters.log" 2>&1 &
STUB=$!
i=0
while [ ! -e /run/parts.ready ] && [ $i -lt 3000 ] && kill -0 $STUB 2>/dev/null; do
    sleep 0.1; i=$((i + 1))
done
[ -e /run/parts.ready ] && echo ready > "$OUT/ready.txt"
for a in 0x68 0x69; do
    i2cdump -y -r 0x00-0x3f "$S" $a b > "$OUT/i2cdump_$a.txt" 2>&1
done
modprobe ${GUEST_ROOT:+-d "$GUEST_ROOT"} bmg160_i2c || echo "modprobe bmg160_i2c failed"
n=0
for spec in bmi055_gyro:0x68 bmi088_gyro:0x69; do
    name=${spec%:*}; a=${spec#*:}
    echo "$name $a" > /sys/bus/i2c/devices/i2c-$S/new_device
    i=0; IIO=/nowhere
    while [ ! -e "$IIO/in_anglvel_x_raw" ] && [ $i -lt 100 ]; do
        sleep 0.1; i=$((i + 1))
        IIO=$(ls -d /sys/bus/i2c/devices/$S-00${a#0x}/iio:device* 2>/dev/null | head -n 1)
    done
    cat "$IIO/name" > "$OUT/iio_name_$name.txt" 2>&1
    cat "$IIO/in_anglvel_scale" > "$OUT/scale_$name.txt" 2>&1
    for axis in x y z; do
        j=0
        while [ $j -lt 12 ]; do read -r v < "$IIO/in_anglvel_${axis}_raw"; echo "$v"; sleep 0.05; j=$((j + 1)); done \
            > "$OUT/raw_${name}_$axis.txt" 2>&1
    done
    cat "$IIO/in_temp_raw" > "$OUT/temp_$name.txt" 2>&1
    n=$((n + 1))
done
if [ "${WITH_ACCEL:-1}" = 1 ]; then
# the BMI055's accelerometer as a stand-in behind i2c-stub, bound by the kernel's bmc150-accel
"$PY" -m bmg160_emu stub --bus "$S" --device bma2x2_accel@0x18 --ready-file /run/accel.ready \
    --stats "$OUT/stub_accel.json" > "$OUT/stub_accel.log" 2>&1 &
ACCEL=$!
i=0
while [ ! -e /run/accel.ready ] && [ $i -lt 3000 ] && kill -0 $ACCEL 2>/dev/null; do
    sleep 0.1; i=$((i + 1))
done
i2cget -y "$S" 0x18 0x00 > "$OUT/accel_chip_id.txt" 2>&1
modprobe ${GUEST_ROOT:+-d "$GUEST_ROOT"} bmc150-accel-i2c || echo "modprobe bmc150-accel-i2c failed"
echo bmi055_accel 0x18 > /sys/bus/i2c/devices/i2c-$S/new_device
i=0
ACC=""
while [ -z "$ACC" ] && [ $i -lt 100 ]; do
    for d in /sys/bus/i2c/devices/$S-0018/iio:device*; do
        [ -e "$d/in_accel_x_raw" ] && ACC=$d
    done
    [ -z "$ACC" ] && sleep 0.1
    i=$((i + 1))
done
if [ -n "$ACC" ]; then
    cat "$ACC/name" > "$OUT/accel_name.txt" 2>&1
    cat "$ACC/in_accel_x_raw" > "$OUT/accel_x_raw.txt" 2>&1
    cat "$ACC/in_accel_scale" > "$OUT/accel_scale.txt" 2>&1
    sleep 0.5
fi
echo "bmi055_accel 0x18" > "$OUT/accel_bound.txt"
kill -TERM $ACCEL 2>/dev/null
wait $ACCEL
fi
kill -TERM $STUB 2>/dev/null
wait $STUB
dmesg > "$OUT/dmesg.txt"
# leave the shared guest as it was: no clients, no i2c-stub
for a in 0x68 0x69 0x18; do echo $a > /sys/bus/i2c/devices/i2c-$S/delete_device; done
rmmod i2c-stub
echo done > "$OUT/done.txt"
"""


@dataclass(frozen=True)
class Checks:
    returncode: int
    output: str
    console: str
    timed_out: bool = False


@pytest.fixture(scope="module")
def guest(bmg160_kernel_session, tmp_path_factory):
    """The script as one command on the bmg160_kernel session's guest: (out folder, Checks)."""
    from bmg160_emu.linux.guest.harness import GuestDied

    if shutil.which("i2cdump") is None:
        pytest.skip("i2cdump is missing (Debian package i2c-tools; the guest runs the host's)")
    session_guest = bmg160_kernel_session.ensure()
    work = tmp_path_factory.mktemp("kernel_parts")
    adapters = work / "adapters.py"
    adapters.write_text(ADAPTERS)
    out = session_guest.results / "parts"
    out.mkdir(exist_ok=True)
    command = ("export WITH_ACCEL=1\n"
               f"export PY={shlex.quote(sys.executable)} ADAPTERS={shlex.quote(str(adapters))}\n"
               f"export PYTHONPATH={shlex.quote(str(REPO))} GUEST_OUT={shlex.quote(str(out))}\n"
               + GUEST_SCRIPT)
    # 400 s as tests/test_kernel_i2c_stub.py: the guest's Python imports are slow under TCG
    try:
        result = session_guest.run(command, timeout_s=400, check=False)
    except GuestDied as exc:
        return out, Checks(-1, "", str(exc), timed_out="took over" in str(exc))
    return out, Checks(result.returncode, result.stdout + result.stderr,
                       session_guest.console())


@pytest.fixture(autouse=True)
def _console_in_report(request, guest):
    request.node.add_report_section("setup", "guest console", guest[1].console)


def text(guest, name: str) -> str:
    out, result = guest
    path = out / name
    assert path.exists(), f"the guest did not write {name} (timed out: {result.timed_out})"
    return path.read_text()


def test_guest_ran_to_the_end(guest):
    assert not guest[1].timed_out
    assert text(guest, "ready.txt").strip() == "ready"
    assert text(guest, "done.txt").strip() == "done"


@pytest.mark.parametrize("name, address", sorted(PARTS.items()))
def test_i2cdump_shows_each_parts_reset_map(guest, name, address):
    rows = text(guest, f"i2cdump_0x{address:02x}.txt").splitlines()[1:]
    dump = [int(v, 16) for row in rows for v in row.split()[1:17]]
    assert dump[0x00] == 0x0F and dump[0x10] == 0x80 and dump[0x16] == 0x0F
    if name == "bmi088_gyro":  # reserved on the BMI088 (DS 5.4), reset 0x04 / 0xA0 / 0xF4 on a BMG160
        assert dump[0x1B] == dump[0x1C] == dump[0x33] == 0x00
    else:
        assert (dump[0x1B], dump[0x1C]) == (0x04, 0xA0)


@pytest.mark.parametrize("name", sorted(PARTS))
def test_kernel_driver_binds_by_the_parts_name_and_reads_the_rate(guest, name):
    assert text(guest, f"iio_name_{name}.txt").strip() == name
    assert text(guest, f"scale_{name}.txt").strip() == "0.000266"  # driver default 500 deg/s
    for axis, true in zip("xyz", TRUE_RATE_DPS):
        values = [float(v) for v in text(guest, f"raw_{name}_{axis}.txt").split()]
        assert len(values) == SAMPLES
        # new samples, not one frozen value (noise ~2 counts rms at 500 deg/s, 32 Hz filter)
        assert len(set(values)) >= 3, values
        # The median of 12 samples (noise ~0.08 deg/s, bias instability ~0.01; a wrong range
        # would be off by a factor of 2 or more), not the mean: the first read after the
        # driver's runtime resume can still see i2c-stub's memory from before the chip's
        # first sample (0) when the in-guest adapter takes longer than the driver's 80 ms
        # start-up wait (one CI run at load: x read 0, then 1319, 1308, ...)
        median = statistics.median(values) * 500.0 / 32768
        assert math.isclose(median, true, abs_tol=1.5), (name, axis, median, values)


def test_temperature_is_absent_on_the_bmi088_die(guest):
    # BMI055: (30 - 23) / 0.5 K per LSB = 14; BMI088: register 0x08 reserved, reads 0
    assert int(text(guest, "temp_bmi055_gyro.txt")) == round((TEMPERATURE_C - 23.0) / 0.5)
    assert int(text(guest, "temp_bmi088_gyro.txt")) == 0


def test_driver_writes_to_registers_the_bmi088_lacks_are_dropped(guest):
    report = json.loads(text(guest, "stub_bmi088_gyro.json"))
    assert report["part"] == "bmi088_gyro"
    final = bytes.fromhex(report["final"])
    written = {e["register"] for e in report["events"]}
    assert {0x0F, 0x10, 0x21} <= written  # range, bandwidth and INT_RST_LATCH were written
    assert final[0x0F] == 0x02 and final[0x10] == 0x87  # 500 deg/s, code 7 (bit 7 reads 1)
    assert final[0x21] == 0x00  # INT_RST_LATCH is absent on the BMI088: it still reads 0


def test_the_kernels_bmc150_accel_driver_binds_to_the_bma2x2_stand_in(guest):
    # the stand-in behind i2c-stub (linux/i2c_stub_standin.py): chip ID 0xFA, found by the
    # driver's probe; it holds registers and produces no motion data, so the raw value is 0
    assert text(guest, "accel_chip_id.txt").strip() == "0xfa"
    assert text(guest, "accel_name.txt").strip() == "bmi055_accel", text(guest, "dmesg.txt")[-3000:]
    assert int(text(guest, "accel_x_raw.txt")) == 0
    report = json.loads(text(guest, "stub_accel.json"))
    final = bytes.fromhex(report["final"]["registers"])
    # the probe's writes reached the stand-in through the adapter: its soft reset, then its
    # default +-4 g range (PMU_RANGE 0x05, bmc150-accel-core.c BMC150_ACCEL_DEF_RANGE_4G),
    # which the reset must not undo when one poll sees both
    assert any("0x14" in e["writes"] for e in report["events"])
    assert final[0x0F] == 0x05, report["events"]
