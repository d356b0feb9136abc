"""Replaying a trace against a fresh chip reproduces the session, or names the first divergence."""

from __future__ import annotations

import errno
import json

import pytest
from smbus2 import i2c_msg

from bmg160_emu.bus.i2c import I2CBus
from bmg160_emu.bus.smbus import FakeSMBus
from bmg160_emu.bus.spi import FakeSpiDev
from bmg160_emu.clock import VirtualClock
from bmg160_emu.device.chip import BMG160
from bmg160_emu.io.trace import TraceHeader, TraceWriter, read_trace
from bmg160_emu.session.trace_replay import replay_trace

SEED = 11
TRUE_RATE = (12.5, -3.0, 0.25)


def _driver_session(path, seed: int = SEED) -> None:
    """A noisy chip driven the way drivers do (spec section 7), traced to ``path``."""
    settings = {"address": 0x68, "profile": "paper"}
    chip = BMG160(seed, clock=VirtualClock(), **settings)
    chip.set_true_rate(TRUE_RATE)
    header = TraceHeader(seed)
    header.add_chip(settings, TRUE_RATE)
    with TraceWriter(path, header) as writer, FakeSMBus(1, devices={0x68: chip}) as bus:
        bus.i2c_bus.log.sinks.append(writer)
        assert bus.read_byte_data(0x68, 0x00) == 0x0F
        bus.write_byte_data(0x68, 0x14, 0xB6)  # soft reset
        chip.advance(0.030)
        bus.write_byte_data(0x68, 0x0F, 0x02)  # +-500 deg/s
        bus.write_byte_data(0x68, 0x10, 0x04)  # 200 Hz
        bus.write_byte_data(0x68, 0x3E, 0x40)  # FIFO mode
        for k in range(40):
            chip.advance(0.005 if k % 3 else 0.0123)
            bus.read_i2c_block_data(0x68, 0x02, 6)
            bus.read_byte_data(0x68, 0x0A)
            bus.read_word_data(0x68, 0x04)
        bus.read_byte_data(0x68, 0x0E)
        bus.read_i2c_block_data(0x68, 0x3F, 30)  # five FIFO frames
        write, read = i2c_msg.write(0x68, [0x06]), i2c_msg.read(0x68, 2)
        bus.i2c_rdwr(write, read)
        with pytest.raises(OSError):
            bus.read_byte_data(0x69, 0x00)  # nobody at 0x69: EREMOTEIO, recorded
        spi = FakeSpiDev(chip)
        spi.log.sinks.append(writer)
        chip.advance(0.05)
        spi.xfer2([0x82, 0, 0, 0, 0, 0, 0])
        spi.xfer2([0x0F, 0x01, 0x10, 0x05])  # RANGE, then an (address, data) pair: BW
        chip.advance(0.05)
        spi.xfer2([0xBF] + [0] * 12)  # two FIFO frames


def test_a_driver_session_replays_without_divergence(tmp_path):
    path = tmp_path / "session.jsonl"
    _driver_session(path)
    header, records = read_trace(path)
    assert len(records) > 120
    result = replay_trace(header, records)
    assert result.ok, str(result.divergence)
    assert result.transactions == len(records)


def test_a_changed_byte_is_reported_at_its_line(tmp_path):
    path = tmp_path / "session.jsonl"
    _driver_session(path)
    lines = path.read_text().splitlines()
    target = next(
        i for i, line in enumerate(lines[1:], 1)
        if json.loads(line)["kind"] == "read_i2c_block_data" and json.loads(line)["time"] > 0.1
    )
    record = json.loads(lines[target])
    record["read"][0] ^= 0x01
    lines[target] = json.dumps(record)
    path.write_text("\n".join(lines) + "\n")
    result = replay_trace(*read_trace(path))
    assert not result.ok
    assert result.divergence.line == target + 1
    assert "burst read 0x02..0x07" in result.divergence.expected
    assert result.divergence.expected != result.divergence.actual


def test_another_seed_diverges_at_the_first_noisy_read(tmp_path):
    path = tmp_path / "session.jsonl"
    _driver_session(path)
    header, records = read_trace(path)
    header["seed"] = SEED + 1
    result = replay_trace(header, records)
    first_rate_read = next(r["_line"] for r in records if r["kind"] == "read_i2c_block_data")
    assert result.divergence is not None and result.divergence.line == first_rate_read


def test_recorded_bus_errors_are_replayed_as_errors(tmp_path):
    chip = BMG160(SEED)
    bus = I2CBus(2, {0x68: chip})
    path = tmp_path / "nack.jsonl"
    header = TraceHeader(SEED)
    header.add_chip({"address": 0x68})

    def nack_third(bus, index, address, kind):
        if index == 2:
            raise OSError(errno.EREMOTEIO, "NACK")

    bus.transaction_hooks.append(nack_third)
    with TraceWriter(path, header) as writer:
        bus.log.sinks.append(writer)
        for _ in range(4):
            try:
                bus.read_byte_data(0x68, 0x00)
            except OSError:
                pass
    _, records = read_trace(path)
    assert [r["error"] for r in records] == [None, None, "EREMOTEIO", None]
    assert replay_trace(*read_trace(path)).ok
