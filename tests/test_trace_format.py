"""Transaction traces: JSON Lines writing from a TransactionLog, reading back, and decoding."""

from __future__ import annotations

import json

import pytest

from bmg160_emu.io.trace import TraceFormatError, TraceHeader, TraceWriter, read_trace
from bmg160_emu.session.decode import describe_read, describe_transaction, describe_write
from bmg160_emu.session.trace_replay import replay_trace
from bmg160_emu.traffic.transaction import Transaction, TransactionLog


def _session() -> list[Transaction]:
    return [
        Transaction(0.0, 1, 0x68, "write_byte_data", 0x0F, written=b"\x02"),
        Transaction(0.001, 1, 0x68, "read_i2c_block_data", 0x02, read=bytes([0xF4, 0xFF, 3, 0, 40, 0])),
        Transaction(0.002, 1, 0x68, "read_byte_data", 0x00, error="EREMOTEIO"),
    ]


def test_a_log_sink_writes_one_json_line_per_transaction_after_a_header(tmp_path):
    path = tmp_path / "session.jsonl"
    header = TraceHeader(seed=7)
    header.add_chip({"profile": "paper", "address": 0x68}, (1.0, 0.0, 0.0), [(0x0F, b"\x02")])
    with TraceWriter(path, header) as writer:
        log = TransactionLog(sinks=[writer])
        for transaction in _session():
            log.append(transaction)
    lines = path.read_text().splitlines()
    assert len(lines) == 5  # header, three transactions, the end line of a complete session
    assert json.loads(lines[-1]) == {"end": "bmg160-emu trace", "transactions": 3}
    assert json.loads(lines[0]) == {
        "format": "bmg160-emu trace", "version": 1, "seed": 7,
        "chips": [{"settings": {"profile": "paper", "address": 0x68},
                   "true_rate_dps": [1.0, 0.0, 0.0], "setup_writes": [[0x0F, [2]]]}],
    }
    header, records = read_trace(path)
    assert header["seed"] == 7
    back = [Transaction.from_dict(r) for r in records]
    assert back == _session()
    assert [r["_line"] for r in records] == [2, 3, 4]
    assert header["_partial"] is None


def test_a_session_cut_short_leaves_a_trace_without_its_end_line_that_reads_as_partial(tmp_path):
    path = tmp_path / "cut.jsonl"
    with pytest.raises(KeyboardInterrupt), TraceWriter(path, TraceHeader(seed=7)) as writer:
        for transaction in _session()[:2]:
            writer(transaction)
        raise KeyboardInterrupt
    header, records = read_trace(path)
    assert len(records) == 2 and "cut short" in header["_partial"]
    # a cut session with no transaction leaves no file (a header alone looked like a result)
    empty = tmp_path / "empty.jsonl"
    with pytest.raises(KeyboardInterrupt), TraceWriter(empty, TraceHeader(seed=7)):
        raise KeyboardInterrupt
    assert not empty.exists() and list(tmp_path.glob(".empty*")) == []


def test_an_end_line_that_miscounts_or_is_followed_by_more_is_refused(tmp_path):
    path = tmp_path / "s.jsonl"
    with TraceWriter(path, TraceHeader(seed=7)) as writer:
        writer.write_all(_session())
    lines = path.read_text().splitlines()
    path.write_text("\n".join(lines[:2] + lines[-1:]) + "\n")  # two lines lost before the end
    with pytest.raises(TraceFormatError, match="end line says 3 transactions, the trace holds 1"):
        read_trace(path)
    path.write_text("\n".join(lines + lines[1:2]) + "\n")
    with pytest.raises(TraceFormatError, match="after the end line"):
        read_trace(path)


def test_reading_reports_the_line_of_a_broken_record(tmp_path):
    path = tmp_path / "broken.jsonl"
    path.write_text(
        json.dumps(TraceHeader().to_dict()) + "\n"
        + json.dumps(_session()[0].to_dict()) + "\n"
        + '{"time": 0.1, "kind": \n'
    )
    with pytest.raises(TraceFormatError, match=r"broken.jsonl:3:\d+: invalid JSON"):
        read_trace(path)


def test_a_bare_log_without_header_decodes_but_does_not_replay(tmp_path):
    path = tmp_path / "bare.jsonl"
    path.write_text("".join(json.dumps(t.to_dict()) + "\n" for t in _session()))
    header, records = read_trace(path)
    assert header == {} and len(records) == 3
    assert "write 0x0F RANGE <- 0x02" in describe_transaction(records[0])
    with pytest.raises(TraceFormatError, match="no header line: replay needs the seed"):
        replay_trace(header, records)


def test_a_json_file_that_is_not_a_trace_is_refused(tmp_path):
    path = tmp_path / "other.jsonl"
    path.write_text('{"format": "something else"}\n')
    with pytest.raises(TraceFormatError, match=r"other.jsonl:1: not a bmg160-emu trace"):
        read_trace(path)


def test_a_record_without_time_is_refused(tmp_path):
    path = tmp_path / "notime.jsonl"
    path.write_text(json.dumps(TraceHeader().to_dict()) + '\n{"kind": "read_byte_data"}\n')
    with pytest.raises(TraceFormatError, match=r"notime.jsonl:2: .*'time'"):
        read_trace(path)


def test_writes_and_bursts_are_decoded_for_a_person():
    assert describe_write(0x0F, b"\x02") == "write 0x0F RANGE <- 0x02 (+-500 deg/s)"
    assert describe_read(0x02, bytes([0xF4, 0xFF, 3, 0, 40, 0])) == "burst read 0x02..0x07 -> x=-12 y=3 z=40"
    assert describe_read(0x00, b"\x0f").startswith("read 0x00 CHIP_ID -> 0x0f")
    assert describe_write(0x10, b"\x04") == "write 0x10 BW <- 0x04 (ODR 200 Hz, 23 Hz)"


def test_a_burst_into_fifo_data_stops_the_register_span_there():
    text = describe_read(0x3E, bytes([0x40, 1, 2, 3]))
    assert text.startswith("burst read 0x3E..0x3F ->")
    assert "FIFO_DATA=0x03" in text


def test_failed_transactions_show_the_errno_name():
    line = describe_transaction(_session()[2].to_dict())
    assert "read_byte_data 0x00 CHIP_ID failed: EREMOTEIO" in line
    assert "0.002000s" in line


def test_a_process_call_shows_the_write_then_the_read_from_where_the_pointer_went():
    record = Transaction(0.0, 1, 0x68, "process_call", 0x0F, written=b"\x02\x84",
                         read=b"\x00\x00").to_dict()
    line = describe_transaction(record)
    assert "write 0x0F..0x10: 0x0F RANGE <- 0x02 (+-500 deg/s)" in line
    assert "then burst read 0x11..0x12 -> LPM1=0x00 LPM2=0x00" in line
