"""The vhost-user back end and virtio-i2c device, driven by an in-process fake front end.

The front end (tests/_vhost_front_end.py) plays QEMU and the guest's i2c-virtio driver: real
vhost-user messages over a socketpair, guest RAM in a memfd, split rings with indirect
descriptors and EVENT_IDX, so every byte the back end handles is laid out as under QEMU.
"""

from __future__ import annotations

import errno
import socket
import struct

import pytest
from _vhost_front_end import DESC_F_INDIRECT, USER_BASE, FakeFrontEnd

from bmg160_emu.bus.i2c import I2CBus
from bmg160_emu.device.chip import BMG160
from bmg160_emu.linux import vhost_user as vu
from bmg160_emu.linux.vhost_user_server import Connection
from bmg160_emu.linux.virtio_i2c import FLAG_FAIL_NEXT, FLAG_M_RD, VirtioI2CDevice


@pytest.fixture
def rig():
    chip = BMG160(seed=3, true_rate=(20.0, -10.0, 5.0))
    bus = I2CBus(0, {0x68: chip})
    device = VirtioI2CDevice(bus)
    front, back = socket.socketpair(socket.AF_UNIX, socket.SOCK_STREAM)
    connection = Connection(back, device)
    fe = FakeFrontEnd(front, connection.receive)
    fe.handshake()
    yield fe, device, chip, bus
    connection.close()
    fe.close()


def header(address: int, flags: int) -> bytes:
    return struct.pack("<HHI", address << 1, 0, flags)


def register_read(fe, device, address: int, register: int, length: int, indirect=True):
    """write [register] with FAIL_NEXT, then read ``length`` bytes, one kick: the driver's way."""
    w = fe.add(0, [header(address, FLAG_FAIL_NEXT), bytes([register])], [1], indirect)
    r = fe.add(0, [header(address, FLAG_M_RD)], [length, 1], indirect)
    device.kick(0)
    used = dict(fe.used(0))
    status_w = fe.read_back(0, w, [1])[0][0]
    data, status_r = fe.read_back(0, r, [length, 1])
    return used, (w, r), status_w, status_r[0], data


def test_offers_the_features_qemu_and_the_driver_need(rig):
    _, device, _, _ = rig
    offered = device.offered_features
    for bit in (0, vu.VIRTIO_RING_F_INDIRECT_DESC, vu.VIRTIO_RING_F_EVENT_IDX,
                vu.VHOST_USER_F_PROTOCOL_FEATURES, vu.VIRTIO_F_VERSION_1):
        assert offered >> bit & 1, bit
    assert device.offered_protocol_features >> vu.PROTOCOL_F_REPLY_ACK & 1
    # UML's virtio_uml allocates the device's IRQ only when it can set up this channel
    assert device.offered_protocol_features >> vu.PROTOCOL_F_SLAVE_REQ & 1
    assert device.memory.regions and device.rings[0].ready


def test_the_backend_request_channel_is_acked_kept_and_closed_with_the_connection():
    """UML's start-up: SET_SLAVE_REQ_FD (no payload, one fd, NEED_REPLY) is acked with 0;
    the back end keeps the socket open (the front end would take EOF on it as the back end
    gone) until a new one replaces it or the connection ends."""
    device = VirtioI2CDevice(I2CBus(0, {0x68: BMG160(seed=3)}))
    front, back = socket.socketpair()
    connection = Connection(back, device)
    fe = FakeFrontEnd(front, connection.receive)
    try:
        fe.handshake(backend_channel=True)
        first = fe.backend_channel
        assert device.slave_req_fd is not None and first is not None
        first.setblocking(False)
        with pytest.raises(BlockingIOError):  # open, nothing sent: the back end holds it
            first.recv(1)
        *_, status_w, status_r, data = register_read(fe, device, 0x68, 0x00, 1)
        assert (status_w, status_r, data) == (0, 0, b"\x0f")
        fe.backend_channel = None  # keep ``first`` to see it closed
        assert fe.set_backend_channel() == 0  # a second one replaces the first
        assert first.recv(1) == b""  # EOF: the back end closed its copy of the old one
        second = fe.backend_channel
        second.setblocking(False)  # a channel left open fails the test instead of hanging
        connection.close()
        assert device.slave_req_fd is None
        assert second.recv(1) == b""
        first.close()
    finally:
        fe.close()


def test_backend_request_channel_without_its_fd_ends_the_connection(rig):
    fe, _, _, _ = rig
    with pytest.raises(vu.VhostUserError, match="SET_SLAVE_REQ_FD with 0"):
        fe.send(vu.SET_SLAVE_REQ_FD, b"", need_reply=True)


@pytest.mark.parametrize("indirect", [True, False])
def test_register_read_returns_the_chip_id(rig, indirect):
    fe, device, _, _ = rig
    used, (w, r), status_w, status_r, data = register_read(fe, device, 0x68, 0x00, 1, indirect)
    assert (status_w, status_r, data) == (0, 0, b"\x0f")
    assert used == {w: 1, r: 2}  # used length: bytes written (status, or data + status)


def test_rate_burst_is_the_models_current_sample(rig):
    fe, device, chip, _ = rig
    chip.advance(0.05)
    expected = chip.dump()[0x02:0x08]
    assert 0x68 not in device.rate_reads
    *_, status, data = register_read(fe, device, 0x68, 0x02, 6)
    assert status == 0 and data == expected
    assert device.rate_reads[0x68] == chip.time  # when the driver last read the rates
    counts = struct.unpack("<3h", data)
    # 20 deg/s at the reset range 2000 deg/s is 327.7 counts; noise ~13 counts rms
    assert abs(counts[0] - 327.7) < 70


def test_write_reaches_the_model(rig):
    fe, device, chip, _ = rig
    fe.add(0, [header(0x68, 0), bytes([0x0F, 0x03])], [1])  # RANGE = 250 deg/s
    device.kick(0)
    assert fe.used(0) and chip.peek(0x0F) == 0x03


def test_absent_address_fails_the_whole_group_and_is_logged(rig):
    fe, device, _, bus = rig
    _, _, status_w, status_r, _ = register_read(fe, device, 0x50, 0x00, 1)
    assert (status_w, status_r) == (1, 1)
    assert device.stats.failed == 2
    last = bus.log[-1]
    assert last.address == 0x50 and last.error == "EREMOTEIO"


def test_zero_length_message_probes_the_address(rig):
    fe, device, _, _ = rig
    ok = fe.add(0, [header(0x68, 0)], [1])
    device.kick(0)
    nack = fe.add(0, [header(0x69, 0)], [1])
    device.kick(0)
    assert fe.read_back(0, ok, [1])[0] == b"\x00"
    assert fe.read_back(0, nack, [1])[0] == b"\x01"


def test_a_fault_hook_fails_the_request_through_the_same_bus(rig):
    fe, device, _, bus = rig

    def nack_second(_bus, index, _address, _kind):
        if index == 1:
            raise OSError(errno.EREMOTEIO, "injected")

    bus.transaction_hooks.append(nack_second)
    first = register_read(fe, device, 0x68, 0x00, 1)
    second = register_read(fe, device, 0x68, 0x00, 1)
    assert (first[2], first[3]) == (0, 0)
    assert (second[2], second[3]) == (1, 1)  # transaction 1 (a register read) fails whole


def test_fifo_read_pops_frames(rig):
    fe, device, chip, _ = rig
    fe.add(0, [header(0x68, 0), bytes([0x3E, 0x40])], [1])  # FIFO_CONFIG_1: FIFO mode, XYZ
    device.kick(0)
    fe.used(0)
    chip.advance(0.05)  # 0.05 s at the reset ODR 2000 Hz: the 100-frame FIFO is full
    count_before = register_read(fe, device, 0x68, 0x0E, 1)[4][0] & 0x7F
    register_read(fe, device, 0x68, 0x3F, 6 * 10)  # ten frames
    count_after = register_read(fe, device, 0x68, 0x0E, 1)[4][0] & 0x7F
    assert count_before == 100 and count_after == 90


def test_transaction_log_shows_the_guest_reads(rig):
    fe, device, _, bus = rig
    # a register read (write [reg], read n in one transfer) is the I2C block read on the wire
    *_, data = register_read(fe, device, 0x68, 0x02, 6)
    last = bus.log[-1]
    assert (last.kind, last.register, last.read) == ("read_i2c_block_data", 0x02, data)
    # anything else is logged message by message: a write, then a read from the pointer
    fe.add(0, [header(0x68, 0), b"\x0f\x02"], [1])
    fe.add(0, [header(0x68, FLAG_M_RD)], [1, 1])
    device.kick(0)
    kinds = [(e.kind, e.register, e.written, e.read) for e in list(bus.log)[-2:]]
    # the write left the pointer at 0x10 (auto-increment): the read gets BW's reset 0x80
    assert kinds == [("i2c_write", 0x0F, b"\x02", b""), ("i2c_read", None, b"", b"\x80")]


def test_a_register_read_split_over_two_kicks_is_one_transfer(rig):
    fe, device, _, bus = rig
    w = fe.add(0, [header(0x68, FLAG_FAIL_NEXT), bytes([0x00])], [1])
    device.kick(0)  # the driver kicked before it queued the read
    assert fe.used(0) == [] and len(bus.log) == 0
    r = fe.add(0, [header(0x68, FLAG_M_RD)], [1, 1])
    device.kick(0)
    assert dict(fe.used(0)) == {w: 1, r: 2}
    assert fe.read_back(0, r, [1, 1]) == [b"\x0f", b"\x00"]
    assert [(e.kind, e.register) for e in bus.log] == [("read_i2c_block_data", 0x00)]


def test_a_register_read_too_long_for_a_block_read_is_plain_i2c(rig):
    fe, device, chip, bus = rig
    _, _, status_w, status_r, data = register_read(fe, device, 0x68, 0x00, 40)
    assert (status_w, status_r) == (0, 0) and data == chip.dump()[:40]
    # one register read (I2CBus: a write then a read of one address is one transaction)
    assert [(e.kind, e.register) for e in bus.log] == [("i2c_read", 0x00)]


def test_a_fault_hook_sees_a_register_read_as_one_transaction(rig):
    # as from i2c-dev and every other stack: the write of the register and the read after
    # it are one transaction (an on_register fault selects it, on_transaction counts it once)
    fe, device, _, bus = rig
    seen = []
    bus.transaction_hooks.append(lambda _b, i, a, kind: seen.append(kind))
    register_read(fe, device, 0x68, 0x02, 6)
    assert seen == ["i2c_read"]
    assert [(e.kind, e.register, len(e.read)) for e in bus.log] == [("i2c_read", 0x02, 6)]


def test_event_idx_avail_event_and_call_suppression(rig):
    fe, device, _, _ = rig
    fe.called(0)
    fe.set_used_event(0, 0xFFFF)  # the driver wants no interrupt soon
    register_read(fe, device, 0x68, 0x00, 1)
    assert fe.avail_event(0) == 2  # kick me when you add entry 2 on
    assert fe.called(0) == 0
    fe.set_used_event(0, 2)  # interrupt once used passes index 2
    register_read(fe, device, 0x68, 0x00, 1)
    assert fe.avail_event(0) == 4 and fe.called(0) == 1


def test_without_event_idx_the_no_interrupt_flag_is_honoured():
    chip = BMG160(seed=1)
    device = VirtioI2CDevice(I2CBus(0, {0x68: chip}))
    front, back = socket.socketpair()
    connection = Connection(back, device)
    fe = FakeFrontEnd(front, connection.receive)
    fe.handshake(features=device.offered_features & ~(1 << vu.VIRTIO_RING_F_EVENT_IDX))
    try:
        register_read(fe, device, 0x68, 0x00, 1)
        assert fe.called(0) == 1
        fe.ram[fe.queues[0]["avail"]:fe.queues[0]["avail"] + 2] = b"\x01\x00"
        register_read(fe, device, 0x68, 0x00, 1)
        assert fe.called(0) == 0
    finally:
        connection.close()
        fe.close()


def test_get_vring_base_stops_the_ring_and_reports_its_index(rig):
    fe, device, _, _ = rig
    register_read(fe, device, 0x68, 0x00, 1)
    body = fe.call(vu.GET_VRING_BASE, struct.pack("<II", 0, 0))
    assert struct.unpack("<II", body) == (0, 2)
    assert not device.rings[0].ready


def test_unknown_message_with_need_reply_gets_a_failure_status(rig):
    fe, _, _, _ = rig
    fe.send(99, b"", need_reply=True)
    request, _, body = fe.reply()
    assert request == 99 and struct.unpack("<Q", body)[0] != 0


def test_request_outside_guest_memory_ends_the_connection(rig):
    fe, device, _, _ = rig
    q = fe.queues[0]
    fe._desc(q, 0, 0x10_0000_0000, 16, DESC_F_INDIRECT, 0)
    fe.ram[q["avail"] + 4:q["avail"] + 6] = b"\x00\x00"
    fe.ram[q["avail"] + 2:q["avail"] + 4] = b"\x01\x00"
    with pytest.raises(vu.VhostUserError, match="outside the memory table"):
        device.kick(0)


def test_a_register_read_pair_outside_guest_memory_ends_the_connection(rig):
    """The register-read shortcut never serves what the general path would refuse."""
    fe, device, _, bus = rig
    fe.add(0, [header(0x68, FLAG_FAIL_NEXT), b"\x00"], [1])
    fe.add(0, [header(0x68, FLAG_M_RD)], [1, 1])
    q = fe.queues[0]
    fe._desc(q, 0, 0x10_0000_0000, 48, DESC_F_INDIRECT, 0)  # the write's table: nowhere
    with pytest.raises(vu.VhostUserError, match="outside the memory table"):
        device.kick(0)
    assert len(bus.log) == 0


def test_reads_whose_entries_wrap_round_the_rings_end(rig):
    """After one lone request, every fourth register read's two entries straddle the end
    of the ring (size 8): the available heads taken and the used pair put across it keep
    their order and lengths."""
    fe, device, chip, bus = rig
    # used_event lies just past the last available entry: give it a value no head has
    fe.set_used_event(0, 0x1234)
    fe.add(0, [header(0x68, 0), bytes([0x0F, 0x01])], [1])  # RANGE = 1000 deg/s
    device.kick(0)
    assert len(fe.used(0)) == 1
    expected = chip.dump()
    for n in range(12):
        register = n % 8
        used, (w, r), status_w, status_r, data = register_read(fe, device, 0x68, register, 2)
        assert used == {w: 1, r: 3} and (status_w, status_r) == (0, 0)
        assert data == expected[register:register + 2]
        assert fe.avail_event(0) == 1 + 2 * (n + 1)  # kick me for the entry after these
    assert [e.kind for e in bus.log][1:] == ["read_i2c_block_data"] * 12


def test_several_transfers_on_one_kick_are_answered_in_order_with_one_call(rig):
    """Reads, a write, a NACK and a read again queued before one kick: each gets its own
    result, the log shows them in order, and the driver is called once for all."""
    fe, device, chip, bus = rig
    fe.called(0)
    heads = []
    for address, register, length in ((0x68, 0x00, 1), (0x68, 0x0F, 1)):
        heads.append(fe.add(0, [header(address, FLAG_FAIL_NEXT), bytes([register])], [1]))
        heads.append(fe.add(0, [header(address, FLAG_M_RD)], [length, 1]))
    heads.append(fe.add(0, [header(0x68, 0), bytes([0x0F, 0x02])], [1]))  # RANGE = 500
    heads.append(fe.add(0, [header(0x50, FLAG_FAIL_NEXT), b"\x00"], [1]))  # nobody there
    heads.append(fe.add(0, [header(0x50, FLAG_M_RD)], [1, 1]))
    assert len(heads) == 7 and fe.called(0) == 0
    device.kick(0)
    used = fe.used(0)
    assert [h for h, _ in used] == heads and [n for _, n in used] == [1, 2, 1, 2, 1, 1, 1]
    assert fe.called(0) == 1
    writes = [fe.read_back(0, heads[i], [1])[0] for i in (0, 2, 4, 5)]
    assert writes == [b"\x00", b"\x00", b"\x00", b"\x01"]  # the last one: NACK
    assert fe.read_back(0, heads[1], [1, 1]) == [b"\x0f", b"\x00"]  # chip ID
    assert fe.read_back(0, heads[3], [1, 1]) == [b"\x00", b"\x00"]  # RANGE at reset
    assert fe.read_back(0, heads[6], [1, 1])[1] == b"\x01"  # its group fails with it
    assert chip.peek(0x0F) == 0x02
    assert [(e.kind, e.address, e.error) for e in bus.log] == [
        ("read_i2c_block_data", 0x68, None), ("read_i2c_block_data", 0x68, None),
        ("i2c_write", 0x68, None), ("i2c_read", 0x50, "EREMOTEIO")]  # a register read
    assert device.stats.failed == 2


def test_more_entries_than_the_ring_holds_end_the_connection(rig):
    fe, device, _, _ = rig
    q = fe.queues[0]
    fe.ram[q["avail"] + 2:q["avail"] + 4] = struct.pack("<H", 9)  # ring size 8
    with pytest.raises(vu.VhostUserError, match="9 entries added to a ring of 8"):
        device.kick(0)


def test_a_new_ring_size_unmaps_the_ring_until_its_addresses_come_again(rig):
    fe, device, _, _ = rig
    fe.send(vu.SET_VRING_NUM, struct.pack("<II", 0, 8))  # the same size: nothing changes
    assert device.rings[0].ready
    fe.send(vu.SET_VRING_NUM, struct.pack("<II", 0, 16))
    assert not device.rings[0].ready and device.queues[0] is None
    device.kick(0)  # a kick now serves nothing (and does not fail)
    fe.send(vu.SET_VRING_NUM, struct.pack("<II", 0, 8))
    q = fe.queues[0]
    fe.send(vu.SET_VRING_ADDR, struct.pack("<IIQQQQ", 0, 0, USER_BASE + q["desc"],
                                           USER_BASE + q["used"], USER_BASE + q["avail"], 0))
    assert device.rings[0].ready
    *_, status_w, status_r, data = register_read(fe, device, 0x68, 0x00, 1)
    assert (status_w, status_r, data) == (0, 0, b"\x0f")


def test_a_request_added_while_the_device_works_is_served_in_the_same_kick(rig):
    """The driver may add a request after the device took the ring's entries and before
    it wrote avail_event (so it did not kick): the device looks again before it stops."""
    fe, device, _, bus = rig
    added = []

    def driver_adds_one_more(_entry):
        if not added:
            added.append(fe.add(0, [header(0x68, 0), bytes([0x0F, 0x03])], [1]))

    bus.log.sinks.append(driver_adds_one_more)
    used, (w, r), *_ = register_read(fe, device, 0x68, 0x00, 1)
    assert used == {w: 1, r: 2, added[0]: 1}
    assert [e.kind for e in bus.log] == ["read_i2c_block_data", "i2c_write"]
    assert fe.avail_event(0) == 3
