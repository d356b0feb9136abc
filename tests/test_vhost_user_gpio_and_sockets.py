"""The virtio-gpio device (INT1/INT2 lines following the model) and the back end's sockets.

The GPIO device is driven by the in-process fake front end (tests/_vhost_front_end.py) on a
virtual clock: requests on queue 0, interrupt buffers on queue 1, as the Linux gpio-virtio
driver queues them. The socket tests run the real command and server.
"""

from __future__ import annotations

import os
import socket
import struct
import subprocess
import sys
import threading
from pathlib import Path

import pytest
from _vhost_front_end import FakeFrontEnd

from bmg160_emu.device.chip import BMG160
from bmg160_emu.linux import vhost_user as vu
from bmg160_emu.linux import virtio_gpio as vg
from bmg160_emu.linux import virtio_gpio_spec as gpio_spec
from bmg160_emu.linux.vhost_user_server import (
    Connection,
    Server,
    SocketPathError,
    check_socket_path,
)

REPO = Path(__file__).resolve().parents[1]


@pytest.fixture
def gpio():
    chips = {0x68: BMG160(seed=5), 0x69: BMG160(seed=6)}
    device = vg.VirtioGPIODevice(chips)
    front, back = socket.socketpair()
    connection = Connection(back, device)
    fe = FakeFrontEnd(front, connection.receive)
    fe.handshake(num_queues=2)
    yield fe, device, chips
    connection.close()
    fe.close()


def request(fe, device, kind: int, line: int = 0, value: int = 0, size: int = 2) -> bytes:
    head = fe.add(0, [struct.pack("<HHI", kind, line, value)], [size])
    device.kick(0)
    assert dict(fe.used(0))[head] == size
    return fe.read_back(0, head, [size])[0]


def queue_event(fe, device, line: int) -> int:
    head = fe.add(1, [struct.pack("<H", line)], [1])
    device.kick(1)
    return head


def test_config_names_and_directions(gpio):
    fe, device, _ = gpio
    body = fe.call(vu.GET_CONFIG, struct.pack("<III", 0, 8, 0) + bytes(8))
    ngpio, names_size = struct.unpack_from("<HxxI", body, 12)
    assert ngpio == 4
    names = request(fe, device, gpio_spec.MSG_GET_NAMES, size=names_size + 1)
    assert names[0] == gpio_spec.STATUS_OK
    assert names[1:].split(b"\0")[:4] == [b"bmg160-0x68-INT1", b"bmg160-0x68-INT2",
                                          b"bmg160-0x69-INT1", b"bmg160-0x69-INT2"]
    assert request(fe, device, gpio_spec.MSG_GET_DIRECTION, 1) == bytes([0, gpio_spec.DIRECTION_IN])
    assert request(fe, device, gpio_spec.MSG_SET_DIRECTION, 1, gpio_spec.DIRECTION_OUT)[0] == gpio_spec.STATUS_ERR
    assert request(fe, device, gpio_spec.MSG_SET_VALUE, 1, 1)[0] == gpio_spec.STATUS_ERR
    assert request(fe, device, gpio_spec.MSG_GET_VALUE, 9)[0] == gpio_spec.STATUS_ERR


def test_line_level_follows_a_latched_interrupt_and_reset_int(gpio):
    fe, device, chips = gpio
    chip = chips[0x69]
    chip.write(0x21, b"\x0f")  # latched
    chip.write(0x18, b"\x04")  # int1_fifo
    chip.write(0x15, b"\x40")  # fifo_en
    chip.write(0x3E, b"\x40")  # FIFO mode
    assert request(fe, device, gpio_spec.MSG_GET_VALUE, 2) == b"\x00\x00"
    chip.advance(0.06)  # 100 frames at 2000 Hz: full
    assert request(fe, device, gpio_spec.MSG_GET_VALUE, 2) == b"\x00\x01"
    chip.write(0x3E, b"\x00")  # bypass: no longer full, but the status is latched
    chip.read(0x0A)  # reads do not clear it (spec 6.3)
    assert request(fe, device, gpio_spec.MSG_GET_VALUE, 2) == b"\x00\x01"
    chip.write(0x21, b"\x8f")  # reset_int
    assert request(fe, device, gpio_spec.MSG_GET_VALUE, 2) == b"\x00\x00"
    chip.write(0x16, b"\x0e")  # INT1 active low (int1_lvl = 0): the idle level is high
    assert request(fe, device, gpio_spec.MSG_GET_VALUE, 2) == b"\x00\x01"


def test_data_ready_edges_raise_one_interrupt_per_queued_buffer(gpio):
    fe, device, chips = gpio
    chip = chips[0x68]
    chip.write(0x10, b"\x07")  # ODR 100 Hz
    chip.write(0x18, b"\x01")  # int1_data
    chip.write(0x15, b"\x80")  # data_en
    assert request(fe, device, gpio_spec.MSG_IRQ_TYPE, 0, gpio_spec.IRQ_TYPE_EDGE_RISING) == b"\x00\x00"
    head = queue_event(fe, device, 0)
    assert fe.used(1) == []
    chip.advance(0.0005)
    device.poll(0.0)
    assert fe.used(1) == []  # no sample since the type was set: no edge
    fired = 0
    for _ in range(50):
        chip.advance(0.010)  # one sample; polled long after its 300 us pulse ended
        device.poll(0.0)
        used = fe.used(1)
        if used:
            assert used == [(head, 1)] and fe.read_back(1, head, [1])[0] == b"\x01"
            fired += 1
            head = queue_event(fe, device, 0)  # the guest re-queues after handling
    assert fired == 50
    # edges while no buffer is queued are held (coalesced) until the next buffer
    fe.used(1)
    chip.advance(0.030)
    device.poll(0.0)
    assert fe.used(1) == [(head, 1)]
    chip.advance(0.030)
    device.poll(0.0)
    head = queue_event(fe, device, 0)
    assert fe.used(1) == [(head, 1)]


def test_an_i2c_transfer_looks_at_the_lines_while_a_trigger_is_set(gpio):
    """The I2C device's after-transfer hook follows the lines (a read can clear a latched
    status) once the driver has set a trigger type: here it sees the data-ready edge of
    a sample the transfer produced, without the server's poll."""
    fe, device, chips = gpio
    chip = chips[0x68]
    chip.write(0x10, b"\x07")  # ODR 100 Hz
    chip.write(0x18, b"\x01")  # int1_data
    chip.write(0x15, b"\x80")  # data_en
    device.after_transfer()  # no trigger yet: nothing to follow
    request(fe, device, gpio_spec.MSG_IRQ_TYPE, 0, gpio_spec.IRQ_TYPE_EDGE_RISING)
    head = queue_event(fe, device, 0)
    chip.advance(0.0005)
    device.after_transfer()
    assert fe.used(1) == []  # no sample since the type was set: no edge
    chip.advance(0.010)  # a transfer that found a new sample
    assert fe.used(1) == []
    device.after_transfer()
    assert fe.used(1) == [(head, 1)] and fe.read_back(1, head, [1])[0] == b"\x01"


def test_disabling_the_interrupt_returns_the_buffer_invalid(gpio):
    fe, device, chips = gpio
    request(fe, device, gpio_spec.MSG_IRQ_TYPE, 0, gpio_spec.IRQ_TYPE_EDGE_RISING)
    head = queue_event(fe, device, 0)
    assert chips[0x68].truth_hooks  # watched while a trigger is set ...
    request(fe, device, gpio_spec.MSG_IRQ_TYPE, 0, gpio_spec.IRQ_TYPE_NONE)
    assert fe.used(1) == [(head, 1)] and fe.read_back(1, head, [1])[0] == b"\x00"
    assert not chips[0x68].truth_hooks  # ... and not after


def test_level_high_fires_while_the_latched_line_is_active(gpio):
    fe, device, chips = gpio
    chip = chips[0x68]
    for reg, value in ((0x21, 0x0F), (0x18, 0x04), (0x15, 0x40), (0x3E, 0x40)):
        chip.write(reg, bytes([value]))
    request(fe, device, gpio_spec.MSG_IRQ_TYPE, 0, gpio_spec.IRQ_TYPE_LEVEL_HIGH)
    head = queue_event(fe, device, 0)
    assert fe.used(1) == []
    chip.advance(0.06)
    device.poll(0.0)
    assert fe.used(1) == [(head, 1)]
    head = queue_event(fe, device, 0)  # still active: fires again at once
    assert fe.used(1) == [(head, 1)]
    chip.write(0x3E, b"\x00")
    chip.write(0x21, b"\x8f")
    head = queue_event(fe, device, 0)
    assert fe.used(1) == []


# --------------------------------------------------------------------------- sockets


def test_socket_directory_is_created_private(tmp_path):
    path = tmp_path / "new" / "i2c.sock"
    check_socket_path(str(path))
    assert (path.parent.stat().st_mode & 0o777) == 0o700


def test_a_path_past_the_socket_address_is_refused_before_any_folder_is_made(tmp_path):
    # sun_path holds 107 bytes and a NUL (unix(7)): bind() would refuse it after the
    # folders were made; refused first, nothing is left behind
    deep = tmp_path / "a" / "b"
    path = str(deep / ("s" * (108 - len(str(deep)) - 1)))
    assert len(path) == 108
    with pytest.raises(SocketPathError, match="at most 107 bytes"):
        check_socket_path(path)
    assert list(tmp_path.iterdir()) == []
    check_socket_path(path[:-1])  # 107 bytes: served
    assert deep.is_dir()


def test_refuses_a_directory_open_to_others(tmp_path):
    folder = tmp_path / "shared"
    folder.mkdir(mode=0o755)
    folder.chmod(0o755)
    with pytest.raises(SocketPathError, match="open to other users"):
        check_socket_path(str(folder / "i2c.sock"))


def test_refuses_a_path_another_user_owns(tmp_path):
    if os.getuid() == 0:
        folder = tmp_path / "theirs"
        folder.mkdir(mode=0o700)
        os.chown(folder, 65534, 65534)  # nobody
        target = folder / "i2c.sock"
    else:
        target = Path("/i2c.sock")  # / belongs to root
    with pytest.raises(SocketPathError, match="belongs to user"):
        check_socket_path(str(target))


def test_refuses_a_socket_another_back_end_serves(tmp_path):
    folder = tmp_path / "s"
    folder.mkdir(mode=0o700)
    live = socket.socket(socket.AF_UNIX)
    live.bind(str(folder / "i2c.sock"))
    live.listen(1)
    try:
        with pytest.raises(SocketPathError, match="already serving"):
            check_socket_path(str(folder / "i2c.sock"))
    finally:
        live.close()
    check_socket_path(str(folder / "i2c.sock"))  # now stale: removed and accepted
    assert not (folder / "i2c.sock").exists()


def test_command_error_is_one_line_and_exit_2(tmp_path):
    folder = tmp_path / "open"
    folder.mkdir()
    folder.chmod(0o777)
    result = subprocess.run(
        [sys.executable, "-m", "bmg160_emu", "vhost-user-i2c", "--socket",
         str(folder / "i2c.sock"), "--duration", "1", "--seed", "1"],  # no chosen-seed line
        capture_output=True, text=True, env={**os.environ, "PYTHONPATH": str(REPO)}, check=False)
    assert result.returncode == 2
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and "open to other users" in lines[0], result.stderr


def test_server_serves_a_front_end_over_its_socket(tmp_path):
    from bmg160_emu.bus.i2c import I2CBus
    from bmg160_emu.linux.virtio_i2c import FLAG_FAIL_NEXT, FLAG_M_RD, VirtioI2CDevice

    device = VirtioI2CDevice(I2CBus(0, {0x68: BMG160(seed=1)}))
    server = Server()
    path = tmp_path / "vu" / "i2c.sock"
    server.add(str(path), device)
    assert (path.stat().st_mode & 0o777) == 0o600
    thread = threading.Thread(target=server.run, daemon=True)
    thread.start()
    client = socket.socket(socket.AF_UNIX)
    client.connect(str(path))
    fe = FakeFrontEnd(client, lambda: None)  # the server thread reads the messages
    try:
        fe.handshake()
        fe.add(0, [struct.pack("<HHI", 0x68 << 1, 0, FLAG_FAIL_NEXT), b"\x00"], [1])
        head = fe.add(0, [struct.pack("<HHI", 0x68 << 1, 0, FLAG_M_RD)], [1, 1])
        os.eventfd_write(fe.queues[0]["kick"], 1)  # the guest kicks
        import select

        assert select.select([fe.queues[0]["call"]], [], [], 10)[0], "no call"
        assert fe.read_back(0, head, [1, 1]) == [b"\x0f", b"\x00"]
    finally:
        server.stop()
        thread.join(10)
        fe.close()
        server.close()
    assert not path.exists()


def _open_fds() -> set[str]:
    return set(os.listdir("/proc/self/fd"))


def test_server_keeps_serving_when_its_pollers_stop_asking_and_leaves_no_fd(tmp_path):
    """A poller that wants no further call (returns None) leaves the loop waiting on its
    sockets alone, not on a deadline at infinity; the kick fds it watches (its own
    duplicates) and every socket are closed when the server closes."""
    from bmg160_emu.bus.i2c import I2CBus
    from bmg160_emu.linux.virtio_i2c import FLAG_FAIL_NEXT, FLAG_M_RD, VirtioI2CDevice

    before = _open_fds()
    calls = []
    server = Server()
    server.pollers.append(lambda now_s: calls.append(now_s))  # returns None
    device = VirtioI2CDevice(I2CBus(0, {0x68: BMG160(seed=1)}))
    server.add(str(tmp_path / "vu" / "i2c.sock"), device)
    failures = []

    def run():
        try:
            server.run()
        except BaseException as exc:  # noqa: BLE001 - reported by the test below
            failures.append(exc)

    thread = threading.Thread(target=run, daemon=True)
    thread.start()
    client = socket.socket(socket.AF_UNIX)
    client.settimeout(10)  # a server that died fails the test rather than hang it
    client.connect(str(tmp_path / "vu" / "i2c.sock"))
    fe = FakeFrontEnd(client, lambda: None)
    try:
        fe.handshake(backend_channel=True)
        for _ in range(3):
            fe.add(0, [struct.pack("<HHI", 0x68 << 1, 0, FLAG_FAIL_NEXT), b"\x00"], [1])
            head = fe.add(0, [struct.pack("<HHI", 0x68 << 1, 0, FLAG_M_RD)], [1, 1])
            os.eventfd_write(fe.queues[0]["kick"], 1)
            import select

            assert select.select([fe.queues[0]["call"]], [], [], 10)[0], failures or "no call"
            fe.called(0)
            assert len(fe.used(0)) == 2
            fe.set_used_event(0, fe.queues[0]["used_seen"])  # interrupt me for the next
            assert fe.read_back(0, head, [1, 1]) == [b"\x0f", b"\x00"]
    finally:
        fe.close()  # the front end goes first: the server drops the connection
        server.stop()
        thread.join(10)
        server.close()
    assert not failures and not thread.is_alive()
    assert len(calls) == 1  # called at the start, never again: it asked for nothing more
    assert _open_fds() == before, {f: os.readlink(f"/proc/self/fd/{f}") for f in _open_fds() - before}


def test_an_edge_whose_sample_the_driver_already_read_is_dropped(gpio):
    fe, device, chips = gpio
    chip = chips[0x68]
    chip.write(0x10, b"\x07")  # ODR 100 Hz
    chip.write(0x18, b"\x01")
    chip.write(0x15, b"\x80")
    request(fe, device, gpio_spec.MSG_IRQ_TYPE, 0, gpio_spec.IRQ_TYPE_EDGE_RISING)
    head = queue_event(fe, device, 0)
    chip.advance(0.010)
    # the driver read the rates (the I2C device records when) before this look saw the
    # sample: on the chip its pulse came while the handler ran, and IIO dropped it
    chip.read(0x02, 6)
    device.rate_reads[0x68] = chip.time
    device.poll(0.0)
    assert fe.used(1) == [] and device.stale_edges == 1
    chip.advance(0.010)  # the next sample, not read yet: its edge fires
    device.poll(0.0)
    assert fe.used(1) == [(head, 1)]


def test_true_rate_file_applies_each_change_once(tmp_path):
    """`echo X Y Z > FILE` truncates then writes: an empty file is looked at again, and the
    same rate seen under a second time stamp is not a second change."""
    from bmg160_emu.commands.vhost_user_i2c import _RateFile

    applied: list[tuple[int, tuple[float, ...]]] = []

    class Chip(BMG160):
        def set_true_rate(self, rate, **kw):
            applied.append((id(self), tuple(rate)))
            super().set_true_rate(rate, **kw)

    chips = {0x68: Chip(seed=5), 0x69: Chip(seed=6)}
    path = tmp_path / "true_rate.txt"
    poller = _RateFile(path, chips)
    assert poller(0.0) == pytest.approx(0.05)          # no file yet: nothing applied
    path.write_text("")
    poller(0.05)                                        # caught between truncate and write
    assert poller.changes == []
    path.write_text("200 0 0\n")
    poller(0.10)
    os.utime(path, ns=(path.stat().st_atime_ns, path.stat().st_mtime_ns + 1))
    poller(0.15)                                        # same text, new time stamp
    path.write_text("20 -10 5\n")
    poller(0.20)
    assert [c["true_rate_dps"] for c in poller.changes] == [[200.0, 0.0, 0.0], [20.0, -10.0, 5.0]]
    # each chip got each rate once, in order
    assert [rate for _, rate in applied] == [(200.0, 0.0, 0.0)] * 2 + [(20.0, -10.0, 5.0)] * 2
