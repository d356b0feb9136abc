"""The transaction log: what a test asserts on and a person prints; JSON-ready records."""

from __future__ import annotations

import json

import pytest
from _standin_chip import RegisterFileChip

from bmg160_emu.bus.i2c import I2CBus
from bmg160_emu.traffic.transaction import Transaction, TransactionLog


def test_each_transaction_is_recorded_with_time_address_kind_register_and_bytes():
    chip = RegisterFileChip()
    bus = I2CBus(3, {0x68: chip})
    chip.advance(0.25)
    bus.write_byte_data(0x68, 0x0F, 0x02)
    bus.read_i2c_block_data(0x68, 0x02, 2)
    first, second = bus.log
    assert (first.time, first.bus, first.address, first.kind) == (0.25, 3, 0x68, "write_byte_data")
    assert (first.register, first.written, first.read, first.error) == (0x0F, b"\x02", b"", None)
    assert (second.kind, second.register, second.read) == ("read_i2c_block_data", 0x02, b"\x02\x03")


def test_to_dict_survives_json_and_from_dict_gives_the_same_transaction():
    t = Transaction(1.5, 1, 0x68, "read_i2c_block_data", 2, b"", b"\x01\xff", None)
    again = Transaction.from_dict(json.loads(json.dumps(t.to_dict())))
    assert again == t


def test_from_dict_accepts_hex_strings_and_names_a_missing_field():
    t = Transaction.from_dict({"time": 0, "kind": "i2c_write", "written": "02 03"})
    assert t.written == b"\x02\x03"
    with pytest.raises(ValueError, match="kind"):
        Transaction.from_dict({"time": 0})


def test_printing_the_log_shows_one_line_per_transaction_with_bytes_in_hex():
    log = TransactionLog()
    log.record(0.0, 1, 0x68, "read_byte_data", 0x00, b"", b"\x0f")
    log.record(0.0, 1, 0x50, "read_byte_data", 0x00, error="EREMOTEIO")
    lines = str(log).splitlines()
    assert len(lines) == 2
    assert "0x68" in lines[0] and "-> 0f" in lines[0]
    assert "FAILED EREMOTEIO" in lines[1]


def test_filter_selects_by_kind_address_register_and_failure():
    log = TransactionLog()
    log.record(0.0, 1, 0x68, "read_byte_data", 0x00)
    log.record(0.0, 1, 0x69, "write_byte_data", 0x0F, b"\x01")
    log.record(0.0, 1, 0x50, "read_byte_data", 0x00, error="EREMOTEIO")
    assert [t.address for t in log.filter(kind="read_byte_data")] == [0x68, 0x50]
    assert [t.address for t in log.filter(register=0x0F)] == [0x69]
    assert [t.address for t in log.filter(failed=True)] == [0x50]


def test_maxlen_keeps_the_newest_and_total_keeps_counting():
    log = TransactionLog(maxlen=2)
    for i in range(5):
        log.record(float(i), 1, 0x68, "read_byte", None)
    assert [t.time for t in log] == [3.0, 4.0]
    assert log.total == 5


def test_sinks_receive_each_new_transaction():
    got = []
    log = TransactionLog(sinks=[got.append])
    log.record(0.0, 1, 0x68, "write_quick")
    assert got == [Transaction(0.0, 1, 0x68, "write_quick")]


def test_disabled_log_records_nothing():
    chip = RegisterFileChip()
    bus = I2CBus(1, {0x68: chip})
    bus.log.enabled = False
    bus.read_byte_data(0x68, 0)
    assert len(bus.log) == 0


def test_a_trace_writer_sink_gets_every_transaction_as_a_json_line(tmp_path):
    from bmg160_emu.io.trace import TraceWriter, read_trace

    chip = RegisterFileChip()
    bus = I2CBus(1, {0x68: chip})
    path = tmp_path / "session.jsonl"
    with TraceWriter(path) as writer:
        bus.log.sinks.append(writer)
        bus.write_byte_data(0x68, 0x0F, 0x02)
        bus.read_i2c_block_data(0x68, 0x02, 6)
        with pytest.raises(OSError):
            bus.read_byte_data(0x69, 0x00)
    _, records = read_trace(path)
    again = [Transaction.from_dict(r) for r in records]
    assert again == list(bus.log)


def test_printed_log_shows_session_events_by_their_description():
    from bmg160_emu.traffic.transaction import Transaction

    fault = Transaction(0.5, 1, 0x68, "fault:stuck_axis", written=b"stuck axis x\n{\"axis\": 0}")
    assert str(fault).endswith("fault:stuck_axis: stuck axis x")
    assert str(Transaction(0.5, 1, 0x68, "fault:brownout")).endswith("fault:brownout")
    read = Transaction(0.5, 1, 0x68, "read_byte_data", register=2, read=b"\x01")
    assert str(read).endswith("read_byte_data reg 0x02 -> 01")


def test_fake_smbus_fast_lane_logs_what_the_bus_logs():
    # FakeSMBus.read_i2c_block_data takes a polling driver's repeat reads itself (I2CBus's
    # lane inlined): the log, a sink, a hook's transaction index and the total must be what
    # I2CBus.read_i2c_block_data gives for the same reads
    from bmg160_emu.bus.smbus import FakeSMBus

    def session(through_fake: bool):
        chip = RegisterFileChip()
        bus = I2CBus(2, {0x68: chip})
        fake = FakeSMBus(bus)
        sunk: list[Transaction] = []
        indices: list[int] = []
        out = []
        for step in range(6):
            chip.advance(0.01)
            if step == 2:
                bus.log.sinks.append(sunk.append)
            if step == 4:
                bus.transaction_hooks.append(lambda b, i, a, k: indices.append(i))
            if through_fake:
                out.append(fake.read_i2c_block_data(0x68, 0x02, 6))
            else:
                out.append(list(bus.read_i2c_block_data(0x68, 0x02, 6)))
        return out, [t.to_dict() for t in bus.log], [t.to_dict() for t in sunk], indices, bus.log.total

    assert session(True) == session(False)


def test_fake_smbus_fast_lane_logs_the_bmg160_time_from_its_clock_ns():
    # on a BMG160 the lane logs its virtual clock's ns (no float made) and the log turns it
    # into seconds when read: the same Transaction, time included, as I2CBus's own path
    from bmg160_emu.bus.smbus import FakeSMBus
    from bmg160_emu.device.chip import BMG160

    def session(through_fake: bool):
        chip = BMG160(seed=3)
        bus = I2CBus(2, {0x68: chip})
        fake = FakeSMBus(bus)
        times = []
        for _ in range(5):
            chip.advance(0.0125)  # not a whole number of ns per float second: 12.5 ms steps
            if through_fake:
                fake.read_i2c_block_data(0x68, 0x02, 6)
            else:
                bus.read_i2c_block_data(0x68, 0x02, 6)
            times.append(chip.time)
        return [t.to_dict() for t in bus.log], times, bus.log.entries

    fast, slow = session(True), session(False)
    assert fast == slow
    assert [t["time"] for t in fast[0]] == fast[1]  # exactly chip.time, float for float
    assert all(type(entry[0]) is float for entry in fast[2])


def test_maxlen_drops_in_bulk_and_indexes_the_kept_entries_from_either_end():
    log = TransactionLog(maxlen=3)
    for i in range(10):
        log.record(float(i), 1, 0x68, "read_byte", None)
    assert [t.time for t in log] == [7.0, 8.0, 9.0]
    assert (len(log), log.total) == (3, 10)
    assert (log[0].time, log[-1].time, log[-3].time) == (7.0, 9.0, 7.0)
    for index in (3, -4):
        with pytest.raises(IndexError):
            log[index]
    assert len(log.fields) <= log.limit  # bounded: trimmed back to maxlen past twice it
    assert log.kinds() == ["read_byte"] * 3
    log.clear()
    assert (len(log), log.total, bool(log), str(log)) == (0, 10, False, "(no transactions)")


def test_an_entry_of_the_wrong_width_is_refused_whole():
    log = TransactionLog()
    with pytest.raises(ValueError, match="8 fields"):
        log.add((0.0, 1, 0x68, "read_byte"))
    assert (len(log), log.total) == (0, 0)


def test_fake_smbus_fast_lane_keeps_the_log_bounded_by_maxlen():
    # the lane has the log trimmed at every 1024th transaction index (not at each read):
    # the kept entries are the newest maxlen at any time, memory at most 1024 entries more
    # than the log's own limit, and total counts every read
    from bmg160_emu.bus.smbus import FakeSMBus
    from bmg160_emu.device.chip import BMG160

    log = TransactionLog(maxlen=5)
    chip = BMG160(seed=3)
    fake = FakeSMBus(I2CBus(1, {0x68: chip}, log=log))
    longest, times = 0, []
    for _ in range(5000):
        chip.advance(0.01)
        fake.read_i2c_block_data(0x68, 0x02, 6)
        times.append(chip.time)
        longest = max(longest, len(log.fields))
    assert (len(log), log.total) == (5, 5000)
    assert [t.time for t in log] == times[-5:]
    assert longest <= log.limit + 1024 * log.WIDTH
