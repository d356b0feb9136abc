"""The uml engine boots a real guest in real time (``--real-time``; the bmg160_kernel
fixture's tests run in virtual time): one user-mode Linux boot for this module, the chip
served in this process (virtio-i2c, its INT1 on virtio-gpio), the agent as init, the
kernel's bmg160 driver bound with its interrupt, and a triggered-buffer capture paced by
that interrupt against wall time."""

from __future__ import annotations

import itertools
import shutil
from collections.abc import Iterator

import pytest

from bmg160_emu.device.chip import BMG160
from bmg160_emu.linux.guest import agent, uml
from bmg160_emu.linux.guest.drivers import bind_failure, bind_ops
from bmg160_emu.linux.guest.harness import Backend, Guest, temporary_work
from bmg160_emu.linux.guest_pace import GuestPacedClock

pytestmark = pytest.mark.kernel

ADDRESS = 0x68


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
    assert int(bus) == guest[0].i2c_bus and int(gpio_base) == int(guest[0].facts["gpio_base"])
    # the agent is the guest's PID 1 and reads sysfs itself
    assert guest[0].facts["pid"] == "1"
    assert guest[0].read(f"/sys/bus/i2c/devices/i2c-{bus}/name").startswith("i2c_virtio")


def test_chip_id_through_virtio_i2c(guest: tuple[Guest, Backend]) -> None:
    result = guest[0].run(f"i2cget -y $GUEST_I2C_BUS 0x{ADDRESS:02x} 0x00", check=True)
    assert result.stdout.strip() == "0x0f"  # BMG160 datasheet, CHIP_ID (0x00) = 0x0F


def test_module_loads_with_timer_signals_about_do_not_hang_the_guest(
        guest: tuple[Guest, Backend]) -> None:
    """The i2c-stub route's hang (issue 32): loading a module frees its init section, which
    flushed a vmalloc range on the host page by page (munmap, mmap); with kernel stacks in
    vmalloc space (CONFIG_VMAP_STACK) a timer signal between the two found the running
    task's thread_info unmapped, and UML looped in SIGSEGV at 100 % CPU for ever. Against
    wall time with a guest process asking for a timer every millisecond, this hung the
    guest within 50 loads in 3 runs of 3 before uml.config unset VMAP_STACK."""
    booted, _ = guest
    booted.run("(while :; do sleep 0.001; done) > /dev/null 2>&1 & "
               "echo $! > $BMG160_RESULTS/timers.pid", check=True)
    try:
        cycle = [agent.modprobe("bmg160_i2c"), agent.rmmod("bmg160_i2c", check=True),
                 agent.rmmod("bmg160_core", check=True)]
        replies = booted.call(cycle * 150, timeout_s=120)
        assert [r.error() for r in replies if r.status] == []
    finally:
        booted.run("kill $(cat $BMG160_RESULTS/timers.pid)")
        booted.call([agent.modprobe("bmg160_i2c")])  # as the guest booted, for the next test


def test_the_driver_binds_with_its_interrupt_and_captures_a_triggered_buffer(
        guest: tuple[Guest, Backend]) -> None:
    booted, backend = guest
    board = uml.engine().board_module()
    ops = bind_ops("bmg160", [ADDRESS], booted.i2c_bus, [backend.line_of(ADDRESS)], board,
                   int(booted.facts["gpio_base"]))
    assert bind_failure(booted.call(ops), ops) is None
    seconds, hz = 2, 100
    device = booted.call([agent.glob(f"/sys/bus/i2c/devices/{booted.i2c_bus}-"
                                     f"{ADDRESS:04x}/iio:device*")])[0].text.split()[0]
    assert booted.read(f"{device}/name") == "bmg160\n"
    booted.write(f"{device}/in_anglvel_sampling_frequency", hz)
    records = booted.capture(device, seconds=seconds, watermark=32)
    stamps_ns = [r[3] for r in records]
    # The reader runs for 2 s of the guest's clock: the frames of about that span, in order,
    # each one data-ready interrupt through virtio-gpio. (Their count against the chip's own
    # time axis, within 1 %, is test_kernel_virtio_i2c's check in virtual time; against wall
    # time the back end's pacing lets frames bunch up when it catches up.)
    assert len(records) >= (seconds - 0.5) * hz, len(records)
    assert all(b > a for a, b in itertools.pairwise(stamps_ns)), "timestamps not increasing"
    assert backend.gpio is not None
    assert backend.gpio.lines[backend.line_of(ADDRESS)].interrupts >= len(records)
