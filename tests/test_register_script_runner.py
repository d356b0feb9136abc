"""Register scripts run against the chip model: readable log, first failed expectation stops it."""

from __future__ import annotations

import pytest

from bmg160_emu.device import spec_choices
from bmg160_emu.device.chip import BMG160
from bmg160_emu.session.script import run_script
from bmg160_emu.session.script_language import ScriptFailure, parse_script

BRING_UP = """\
read CHIP_ID == 0x0F
write BGW_SOFTRESET 0xB6
advance 30ms
write RANGE 0x02
read RANGE == 0x02 mask 0x07
write BW 0x04                      # 200 Hz
write INT_EN_0 0x80                # data_en
poll INT_STATUS_1 bit 7 timeout 10ms every 100us
dump table
"""


def _run(text: str, chip: BMG160 | None = None) -> tuple[list[str], BMG160]:
    chip = chip or BMG160(seed=5, noise=False)
    lines: list[str] = []
    run_script(text, chip, lines.append, source="t.script")
    return lines, chip


def test_a_bring_up_script_runs_and_logs_every_statement():
    lines, chip = _run(BRING_UP)
    assert lines[0].startswith("   1  t=0.000000s  read 0x00 CHIP_ID -> 0x0f")
    assert any("write 0x0F RANGE <- 0x02 (+-500 deg/s)" in line for line in lines)
    poll = next(line for line in lines if "poll 0x0A INT_STATUS_1 bit 7 == 1" in line)
    assert int(poll.rsplit("last ", 1)[1].rstrip(")"), 16) & 0x80  # the bit it waited for
    assert any(line.strip().startswith("0x0F RANGE") for line in lines)  # the dump
    assert chip.peek(0x0F) == 0x02


def test_a_failed_expectation_names_the_line_and_the_decoded_fields():
    script = "write RANGE 0x02\nadvance 1ms\nread RANGE == 0x03 mask 0x07\nread CHIP_ID\n"
    with pytest.raises(ScriptFailure) as info:
        _run(script)
    assert info.value.line == 3
    message = str(info.value)
    assert message.startswith("t.script:3: 0x0F RANGE: expected 0x03, read 0x02 (mask 0x07)")
    assert "range expected 3 (+-250 deg/s), got 2 (+-500 deg/s)" in message


def test_nothing_runs_when_the_script_has_a_syntax_error():
    chip = BMG160(seed=5, noise=False)
    with pytest.raises(ValueError, match=r"t.script:2:7"):
        run_script("write RANGE 0x02\nwrite NOPE 1\n", chip, print, source="t.script")
    assert chip.peek(0x0F) == 0x00


def test_poll_times_out_in_simulated_time():
    # data_en off: data_int never rises
    with pytest.raises(ScriptFailure, match=r":1: 0x0A INT_STATUS_1 bit 7 still 0 after 5 ms"):
        _run("poll INT_STATUS_1 bit 7 timeout 5ms\n")


def test_rate_statement_sets_the_true_rate_seen_in_the_rate_registers():
    counts = round(100.0 * spec_choices.SENSITIVITY_BINARY[0])  # +-2000 deg/s range, spec 5.1
    lsb, msb = counts & 0xFF, counts >> 8
    script = f"rate 100 0 0\nadvance 100ms\nburst RATE_X_LSB 2 == {lsb:#x} {msb:#x}\n"
    lines, _ = _run(script)
    assert f"burst read 0x02..0x03 -> x={counts}" in lines[-1]


def test_a_burst_over_32_bytes_reads_the_fifo_in_one_transfer():
    script = "write BW 0x04\nwrite FIFO_CONFIG_1 0x40\nadvance 50ms\nburst FIFO_DATA 60\n"
    lines, chip = _run(script)
    assert "0x3F x60" in lines[-1]
    assert chip.peek(0x0E) & 0x7F == 0  # ten frames read, FIFO empty again


def test_an_injected_nack_fails_the_next_access_with_its_errno():
    script = "read CHIP_ID\nfault nack max_count=1\nread CHIP_ID == 0x0F\n"
    with pytest.raises(ScriptFailure, match=r":3: bus error during read: EREMOTEIO"):
        _run(script)


def test_fault_statements_are_checked_before_running():
    with pytest.raises(ValueError, match=r":1:7: unknown fault kind 'gremlin'"):
        parse_script("fault gremlin\n", source="f")
    with pytest.raises(ValueError, match=r":1:18: unknown fault parameter 'colour'"):
        parse_script("fault stuck_axis colour=red\n", source="f")
    with pytest.raises(ValueError, match=r":1:7: stuck_axis: needs an axis"):
        parse_script("fault stuck_axis\n", source="f")


def test_chip_statement_switches_to_the_other_address_on_the_bus():
    from bmg160_emu.bus.i2c import I2CBus
    from bmg160_emu.clock import VirtualClock

    clock = VirtualClock()
    chips = {a: BMG160(seed=5, address=a, clock=clock, noise=False) for a in (0x68, 0x69)}
    lines: list[str] = []
    script = "write RANGE 0x01\nchip 0x69\nwrite RANGE 0x03\nread RANGE == 0x03\nchip 0x6a\n"
    with pytest.raises(ScriptFailure, match=r":5: no chip at 0x6a on this bus"):
        run_script(script, chips[0x68], lines.append, "t.script", bus=I2CBus(1, chips))
    assert (chips[0x68].peek(0x0F), chips[0x69].peek(0x0F)) == (0x01, 0x03)


def test_the_same_script_over_spi_reads_what_it_reads_over_i2c():
    """Whichever front end carries the accesses, a seeded chip gives the same session: the
    SPI port sends read frames (0x80 | reg, auto-increment) and (address, data) pairs."""
    from bmg160_emu.bus.spi import FakeSpiDev
    from bmg160_emu.session.script import ScriptRunner, SpiRegisterPort

    text = BRING_UP.replace("dump table\n", "") + (
        "write RANGE 0x03 0x04\n"          # two registers in one write: RANGE and BW
        "read BW == 0x84\n"
        "rate 12 -4 7\nadvance 20ms\nburst RATE_X_LSB 6\nburst FIFO_STATUS 3\n"
    )
    statements = parse_script(text, "t.script")
    i2c_lines: list[str] = []
    run_script(text, BMG160(seed=5), i2c_lines.append, source="t.script")
    chip = BMG160(seed=5)
    spi = FakeSpiDev(chip)
    spi_lines: list[str] = []
    ScriptRunner(chip, spi_lines.append, "t.script", port=SpiRegisterPort(spi)).run(statements)
    assert spi_lines == i2c_lines
    assert {t.kind for t in spi.log} == {"spi_read", "spi_write", "true_rate"}
