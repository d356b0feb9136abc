"""A traced session with injected faults decodes them as fault lines and replays them."""

from __future__ import annotations

import json
from types import SimpleNamespace

import pytest

from bmg160_emu.adcs.faults import FaultSchedule
from bmg160_emu.bus.i2c import I2CBus
from bmg160_emu.cli import main
from bmg160_emu.clock import VirtualClock
from bmg160_emu.device.chip import BMG160
from bmg160_emu.io.trace import TraceHeader, TraceWriter, read_trace
from bmg160_emu.session.decode import describe_transaction
from bmg160_emu.session.trace_replay import replay_trace

SEED = 5
TRUE_RATE = (3.0, -1.0, 0.5)
FAULTS = [
    {"kind": "nack", "on_transaction": 5},
    {"kind": "stuck_axis", "axis": "x", "at_s": 0.05, "duration_s": 0.1},
    {"kind": "spike", "axis": "z", "amplitude_dps": 80.0, "samples": 20, "on_transaction": 30},
    {"kind": "seu", "register": 0x0F, "bit": 0, "on_transaction": 45},
]


def _faulty_session(path) -> list[tuple[float, bytes]]:
    """A driver polling the rate registers every 5 ms while the schedule injects faults;
    returns (time, rate bytes) of the reads that succeeded."""
    chip = BMG160(SEED, clock=VirtualClock(), address=0x68)
    chip.set_true_rate(TRUE_RATE)
    bus = I2CBus(1, {0x68: chip})
    header = TraceHeader(SEED)
    header.add_chip({"address": 0x68}, TRUE_RATE)
    schedule = FaultSchedule(FAULTS, seed=1)
    schedule.install([SimpleNamespace(index=0, chip=chip, bus=bus, address=0x68)])
    reads = []
    with TraceWriter(path, header) as writer:
        bus.log.sinks.append(writer)
        for _ in range(60):
            chip.advance(0.005)
            try:
                reads.append((chip.time, bytes(bus.read_i2c_block_data(0x68, 0x02, 6))))
            except OSError:
                pass
    return reads


@pytest.fixture
def faulty_trace(tmp_path):
    path = tmp_path / "faults.jsonl"
    reads = _faulty_session(path)
    return path, reads


def test_the_trace_holds_the_nack_and_an_entry_per_other_fault(faulty_trace):
    path, reads = faulty_trace
    _, records = read_trace(path)
    kinds = [r["kind"] for r in records if r["kind"].startswith("fault:")]
    assert kinds == ["fault:stuck_axis", "fault:spike", "fault:seu"]
    assert [r["error"] for r in records if r["error"]] == ["EREMOTEIO"]
    # the stuck x axis really repeated one value during its 0.1 s window
    stuck = {data[0:2] for t, data in reads if 0.055 <= t < 0.15}
    assert len(stuck) == 1


def test_fault_entries_decode_as_fault_lines(faulty_trace):
    path, _ = faulty_trace
    _, records = read_trace(path)
    lines = [describe_transaction(r) for r in records if r["kind"].startswith("fault:")]
    assert "FAULT injected: stuck_axis axis x for 0.1 s" in lines[0]
    assert "FAULT injected: spike axis z +80 deg/s x20" in lines[1]
    assert "FAULT injected: SEU register 0x0f bit 0: 0x00 -> 0x01" in lines[2]
    assert all("{" not in line for line in lines)  # the replay parameters stay out of sight


def test_a_session_with_faults_replays_without_divergence(faulty_trace):
    path, _ = faulty_trace
    header, records = read_trace(path)
    result = replay_trace(header, records)
    assert result.ok, str(result.divergence)
    assert result.faults_reapplied == 3 and result.faults_skipped == []
    assert result.transactions == len([r for r in records if not r["kind"].startswith("fault:")])


@pytest.mark.parametrize("kind", ["fault:stuck_axis", "fault:spike", "fault:seu"])
def test_without_a_fault_entry_the_replay_diverges(faulty_trace, kind):
    """The control: each re-applied fault is what keeps the replay on the recorded reads."""
    path, _ = faulty_trace
    header, records = read_trace(path)
    result = replay_trace(header, [r for r in records if r["kind"] != kind])
    assert not result.ok


def _strip_parameters(path, kinds) -> None:
    """Keep only the description in these entries, as older versions wrote them."""
    lines = path.read_text().splitlines()
    for i, line in enumerate(lines):
        record = json.loads(line)
        if record.get("kind") in kinds:
            text = bytes(record["written"]).decode().split("\n")[0]
            record["written"] = list(text.encode())
            lines[i] = json.dumps(record)
    path.write_text("\n".join(lines) + "\n")


def test_sample_fault_entries_without_parameters_are_listed_as_not_replayed(faulty_trace, capsys):
    path, _ = faulty_trace
    _strip_parameters(path, {"fault:stuck_axis", "fault:spike", "fault:seu"})
    result = replay_trace(*read_trace(path))
    assert [s.split(":", 1)[1].strip() for s in result.faults_skipped] == [
        "stuck_axis axis x for 0.1 s", "spike axis z +80 deg/s x20",
    ]
    assert not result.ok
    assert main(["trace", str(path), "--replay"]) == 1
    err = capsys.readouterr().err
    assert "2 injected fault(s) that the replay cannot act again" in err
    assert "stuck_axis axis x for 0.1 s" in err and "divergence at" in err


def test_a_chip_fault_is_acted_again_from_its_description_alone(faulty_trace):
    path, _ = faulty_trace
    _strip_parameters(path, {"fault:seu"})
    result = replay_trace(*read_trace(path))
    assert result.ok, str(result.divergence)
    assert result.faults_reapplied == 3 and result.faults_skipped == []


def test_the_trace_command_decodes_and_replays_a_faulty_session(faulty_trace, capsys):
    path, _ = faulty_trace
    assert main(["trace", str(path)]) == 0
    out = capsys.readouterr().out
    assert "FAULT injected: stuck_axis" in out and "failed: EREMOTEIO" in out
    assert main(["trace", str(path), "--replay"]) == 0
    out = capsys.readouterr().out
    assert "(3 injected fault(s) re-applied)" in out


def test_a_script_session_with_faults_replays(tmp_path, capsys):
    script = tmp_path / "faults.script"
    script.write_text(
        "write RANGE 0x02\nadvance 20ms\nfault stuck_axis axis=y duration_s=0.03\n"
        "fault bias_step axis=z step_dps=25\n"
        + "advance 5ms\nburst RATE_X_LSB 6\n" * 10
        + "fault seu register=BW bit=1\nburst RATE_X_LSB 6\nread BW\n"
    )
    trace = tmp_path / "faults.jsonl"
    assert main(["script", str(script), "--seed", "3", "--true-rate", "1", "2", "3",
                 "--trace", str(trace), "-q"]) == 0
    header, records = read_trace(trace)
    assert len([r for r in records if r["kind"].startswith("fault:")]) == 3
    result = replay_trace(header, records)
    assert result.ok, str(result.divergence)
    assert result.faults_reapplied == 3


@pytest.mark.parametrize(
    "fault",
    [
        {"kind": "lost_samples", "samples": 15, "on_transaction": 8},
        {"kind": "saturation", "axis": "y", "amplitude_dps": -1.0, "duration_s": 0.02,
         "on_transaction": 8},
        {"kind": "bias_step", "step_dps": 4.0, "at_s": 0.031},
        {"kind": "temperature_ramp", "rate_c_per_s": 50.0, "tc_bias_dps_per_c": [0.2, 0.0, -0.1],
         "duration_s": 0.05, "at_s": 0.02},
        {"kind": "stuck_axis", "axis": "z", "duration_s": 0.008, "probability": 0.1},
        {"kind": "brownout", "on_transaction": 12},
        {"kind": "corrupt_byte", "byte": 1, "bit": 3, "on_transaction": 9},  # a read's byte
        {"kind": "corrupt_byte", "bit": 0, "on_transaction": 11},  # the written RANGE
    ],
    ids=lambda f: f"{f['kind']}-{f['on_transaction']}" if f["kind"] == "corrupt_byte" else f["kind"],
)
def test_every_fault_kind_replays_and_is_needed_for_it(tmp_path, fault):
    chip = BMG160(SEED, clock=VirtualClock(), address=0x68)
    chip.set_true_rate(TRUE_RATE)
    bus = I2CBus(1, {0x68: chip})
    header = TraceHeader(SEED)
    header.add_chip({"address": 0x68}, TRUE_RATE)
    FaultSchedule([fault], seed=2).install([SimpleNamespace(index=0, chip=chip, bus=bus, address=0x68)])
    path = tmp_path / "one.jsonl"
    with TraceWriter(path, header) as writer:
        bus.log.sinks.append(writer)
        for _ in range(20):
            chip.advance(0.005)
            bus.read_i2c_block_data(0x68, 0x02, 6)
            bus.read_byte_data(0x68, 0x0F)
            bus.write_byte_data(0x68, 0x0F, 0x00)  # RANGE: a corrupted write shows in the read
    header_dict, records = read_trace(path)
    assert any(r["kind"] == f"fault:{fault['kind']}" for r in records)
    result = replay_trace(header_dict, records)
    assert result.ok, str(result.divergence)
    assert not replay_trace(header_dict, [r for r in records if not r["kind"].startswith("fault:")]).ok


def test_a_timeout_that_stalled_the_bus_replays(tmp_path):
    """No entry for bus faults: the failed transaction carries ETIMEDOUT, and the stall is in
    the recorded times of the transactions after it."""
    chip = BMG160(SEED, clock=VirtualClock(), address=0x68)
    bus = I2CBus(1, {0x68: chip})
    header = TraceHeader(SEED)
    header.add_chip({"address": 0x68})
    FaultSchedule([{"kind": "timeout", "on_transaction": 3, "stall_s": 0.0123}]).install(
        [SimpleNamespace(index=0, chip=chip, bus=bus, address=0x68)])
    path = tmp_path / "timeout.jsonl"
    with TraceWriter(path, header) as writer:
        bus.log.sinks.append(writer)
        for _ in range(8):
            chip.advance(0.002)
            try:
                bus.read_i2c_block_data(0x68, 0x02, 6)
            except OSError:
                pass
    header_dict, records = read_trace(path)
    assert [r["error"] for r in records].count("ETIMEDOUT") == 1
    assert replay_trace(header_dict, records).ok


def test_a_fault_entry_for_a_chip_the_header_lacks_is_a_clear_error(faulty_trace, capsys):
    path, _ = faulty_trace
    lines = path.read_text().splitlines()
    for i, line in enumerate(lines):
        record = json.loads(line)
        if record.get("kind") == "fault:stuck_axis":
            record["address"] = 0x69
            lines[i] = json.dumps(record)
    path.write_text("\n".join(lines) + "\n")
    assert main(["trace", str(path), "--replay"]) == 2
    assert "fault entry for a chip at 0x69 that the header does not describe" in capsys.readouterr().err
