"""The uml engine boots a real guest: one user-mode Linux boot for this module, the chip
served in this process (virtio-i2c, its INT1 on virtio-gpio), the kernel's bmg160 driver
bound with its interrupt, and a triggered-buffer capture paced by that interrupt."""

from __future__ import annotations

import itertools
import shutil
import struct
from collections.abc import Iterator
from pathlib import Path

import pytest

import bmg160_emu
from bmg160_emu.device.chip import BMG160
from bmg160_emu.linux.guest import uml
from bmg160_emu.linux.guest.drivers import bind_command
from bmg160_emu.linux.guest.harness import Backend, Guest, temporary_work
from bmg160_emu.linux.guest_pace import GuestPacedClock

pytestmark = pytest.mark.kernel

CAPTURE = Path(bmg160_emu.__file__).resolve().parents[1] / "tests" / "kernel_guest" / (
    "guest_iio_capture.py")
ADDRESS = 0x68
RECORD_BYTES = 16  # x, y, z (3 x 16 bit), padding to 8, the 64-bit timestamp


@pytest.fixture(scope="module")
def guest() -> Iterator[tuple[Guest, Backend]]:
    engine = uml.engine()
    missing = engine.missing()
    if missing:
        pytest.skip("the uml engine is not ready: " + "; ".join(missing))
    clock = GuestPacedClock()
    work = temporary_work()
    backend = Backend({ADDRESS: BMG160(seed=5, clock=clock, address=ADDRESS)}, work / "s",
                      gpio=True, clock=clock)
    booted = Guest(engine, work, backend, modules=["bmg160_i2c"])
    try:
        booted.start(timeout_s=120)
        yield booted, backend
    finally:
        booted.close()
        backend.close()
        shutil.rmtree(work, ignore_errors=True)


def test_it_boots_with_the_contracts_environment(guest: tuple[Guest, Backend]) -> None:
    result = guest[0].run("echo $GUEST_ENGINE $GUEST_I2C_BUS $GUEST_GPIO_BASE; uname -m",
                          check=True)
    engine, bus, gpio_base, machine = result.stdout.split()
    assert (engine, machine) == ("uml", "x86_64")
    assert bus.isdigit() and gpio_base.isdigit()


def test_chip_id_through_virtio_i2c(guest: tuple[Guest, Backend]) -> None:
    result = guest[0].run(f"i2cget -y $GUEST_I2C_BUS 0x{ADDRESS:02x} 0x00", check=True)
    assert result.stdout.strip() == "0x0f"  # BMG160 datasheet, CHIP_ID (0x00) = 0x0F


def test_the_driver_binds_with_its_interrupt_and_captures_a_triggered_buffer(
        guest: tuple[Guest, Backend]) -> None:
    booted, backend = guest
    board = uml.engine().board_module()
    bound = booted.run(bind_command("bmg160", [ADDRESS], [backend.line_of(ADDRESS)], board))
    assert bound.returncode == 0, bound.stdout + bound.stderr
    seconds, hz = 2, 100
    script = f"""
D=$(ls -d /sys/bus/i2c/devices/$GUEST_I2C_BUS-00{ADDRESS:02x}/iio:device*)
cat "$D/name"
kw() {{ sh -c 'echo "$1" > "$2"' kw "$1" "$2"; }}
kw {hz} "$D/in_anglvel_sampling_frequency"
for e in "$D"/scan_elements/*_en; do echo 1 > "$e"; done
for t in /sys/bus/iio/devices/trigger*; do
    case "$(cat "$t/name")" in bmg160-dev${{D##*iio:device}}) cat "$t/name" > "$D/trigger/current_trigger" ;; esac
done
echo 4096 > "$D/buffer/length"; echo 32 > "$D/buffer/watermark"
before=$(awk '/virtio|gpio/ {{s += $2}} END {{print s + 0}}' /proc/interrupts)
kw 1 "$D/buffer/enable"
"$BMG160_PY" {CAPTURE} {seconds} "/dev/${{D##*/}}" "$BMG160_RESULTS/capture.bin"
kw 0 "$D/buffer/enable"
after=$(awk '/virtio|gpio/ {{s += $2}} END {{print s + 0}}' /proc/interrupts)
cat "$D/trigger/current_trigger"
echo $((after - before))
"""
    result = booted.run(script, timeout_s=60)
    assert result.returncode == 0, result.stdout + result.stderr
    name, trigger, interrupts = result.stdout.split()
    assert name == "bmg160" and trigger.startswith("bmg160-dev")
    data = (booted.results / "capture.bin").read_bytes()
    stamps_ns = [struct.unpack_from("<q", data, offset + 8)[0]
                 for offset in range(0, len(data) - RECORD_BYTES + 1, RECORD_BYTES)]
    records = len(stamps_ns)
    # The buffer fills from its enable to its disable, around the reader's 2 s: at least
    # 2 s of frames, in order. (Their count against the chip's own time axis, within 1 %,
    # is test_kernel_virtio_i2c's check, which runs on this engine too; on the guest's clock
    # the back end's pacing lets frames bunch up when it catches up with wall time.)
    assert records >= seconds * hz, records
    assert all(b > a for a, b in itertools.pairwise(stamps_ns)), "timestamps not increasing"
    # every frame is one data-ready interrupt through virtio-gpio (plus the i2c replies)
    assert int(interrupts) >= records
