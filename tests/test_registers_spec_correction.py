"""A spec correction is one edit of the register table: the model, the decoder, the SPI
framing, the dump formats, the docs table and the firmware's generated register header all
follow.

The corrected table is a copy, installed in a fresh interpreter before anything else is
imported (the model evaluates addresses and masks once, at import), so this process's table
stays the spec's."""

from __future__ import annotations

import json
import subprocess
import sys
import textwrap

import pytest

PROBE = textwrap.dedent('''
    import dataclasses, json, sys
    from bmg160_emu.device import registers as R

    if sys.argv[1] == "corrected":
        table = list(R.REGISTERS)
        rng = R.BY_NAME["RANGE"]
        # a reset value correction: RANGE powers up in code 3 (+-250 deg/s)
        table[rng.address] = dataclasses.replace(rng, reset=0x03)
        hbw = R.BY_NAME["RATE_HBW"]
        # a field correction: shadow_dis is bit 5, not bit 6
        fields = tuple(dataclasses.replace(f, msb=5, lsb=5) if f.name == "shadow_dis" else f
                       for f in hbw.fields)
        table[hbw.address] = dataclasses.replace(hbw, fields=fields)
        R._install(tuple(table))

    from bmg160_emu.device.chip import BMG160
    from bmg160_emu.firmware.register_table import firmware_registers, render_registers_header
    from bmg160_emu.io import dump as dump_io

    def msb_after_lsb(shadow_dis_value):
        # X ramps by 2000 deg/s per s: its MSB changes every few ms; LSB read, 20 ms, MSB read
        chip = BMG160(noise=False, true_rate=lambda t: (2000.0 * t, 0.0, 0.0))
        chip.write(0x13, bytes([shadow_dis_value]))
        chip.advance(0.05)
        lsb_time_msb = chip.peek(0x03)
        chip.read(0x02, 1)
        chip.advance(0.02)
        return chip.read(0x03, 1)[0] == lsb_time_msb, chip.peek(0x13)

    def spi_reads():
        # the SPI framing over the corrected chip: a burst from RANGE and a write of RATE_HBW
        from bmg160_emu.bus.spi import FakeSpiDev

        spi = FakeSpiDev(BMG160(noise=False))
        burst = spi.xfer2([0x80 | 0x0F, 0, 0])[1:]
        spi.xfer2([0x13, 0x60])
        return burst + spi.xfer2([0x80 | 0x13, 0])[1:]

    chip = BMG160(seed=1)
    snapshot = dump_io.RegisterDump.from_chip(chip)
    header = render_registers_header()
    out = {
        "reset_range": chip.dump()[0x0F],
        "sensitivity": chip.sensitivity,
        "latched_0x20": msb_after_lsb(0x20),
        "latched_0x40": msb_after_lsb(0x40),
        "describe_0x20": R.BY_NAME["RATE_HBW"].describe(0x20),
        "decode_dump_range": R.decode_dump(chip.dump())[0x0F],
        "table_format": dump_io.format_dump(snapshot, "table"),
        "json_format": dump_io.format_dump(snapshot, "json"),
        "docs": R.markdown_table(),
        "header": header,
        "firmware_reset": firmware_registers()[0x0F].reset,
        "firmware_mask": firmware_registers()[0x13].write_mask,
        "spi": spi_reads(),
    }
    print(json.dumps(out))
''')


def _probe(which: str) -> dict:
    proc = subprocess.run([sys.executable, "-c", PROBE, which], capture_output=True, text=True,
                          check=False, timeout=120)
    assert proc.returncode == 0, proc.stderr
    return json.loads(proc.stdout)


@pytest.fixture(scope="module")
def spec():
    return _probe("spec")


@pytest.fixture(scope="module")
def corrected():
    return _probe("corrected")


def test_the_model_powers_up_with_the_corrected_reset_value(spec, corrected):
    assert (spec["reset_range"], spec["sensitivity"]) == (0x00, 16.384)
    assert (corrected["reset_range"], corrected["sensitivity"]) == (0x03, 131.072)


def test_the_model_takes_shadow_dis_from_the_corrected_bit(spec, corrected):
    # (MSB latched by the LSB read, RATE_HBW content after the write)
    assert spec["latched_0x40"] == [False, 0x40] and spec["latched_0x20"] == [True, 0x00]
    assert corrected["latched_0x20"] == [False, 0x20]
    assert corrected["latched_0x40"] == [True, 0x00]  # bit 6 is now reserved


def test_the_spi_framing_follows(spec, corrected):
    # RANGE, BW read in one SPI burst, then RATE_HBW after writing 0x60 (bits 6 and 5)
    assert spec["spi"] == [0x00, 0x80, 0x40]
    assert corrected["spi"] == [0x03, 0x80, 0x20]  # only the corrected bit 5 is stored


def test_the_decoder_and_the_dump_formats_follow(spec, corrected):
    assert "shadow_dis=1" in corrected["describe_0x20"]
    assert "shadow_dis=0" in spec["describe_0x20"]
    assert "range=3" in corrected["decode_dump_range"]
    assert "range=0" in spec["decode_dump_range"]
    assert spec["table_format"] != corrected["table_format"]
    assert "range=3" in corrected["table_format"] and "range=3" not in spec["table_format"]
    assert json.loads(corrected["json_format"]) != json.loads(spec["json_format"])


def test_the_docs_table_follows(spec, corrected):
    assert "| 0x0F | RANGE | rw | 0x03 |" in corrected["docs"]
    assert "| 0x0F | RANGE | rw | 0x00 |" in spec["docs"]
    assert "`shadow_dis` [5] rw" in corrected["docs"]
    assert "`shadow_dis` [6] rw" in spec["docs"]


def _reset_values(header: str) -> list[int]:
    body = header.split("bmg_reset_values[64] PROGMEM = {")[1].split("};")[0]
    return [int(v, 16) for v in body.replace(",", " ").split()]


def test_the_firmware_header_follows(spec, corrected):
    assert "#define BMG_RATE_HBW_SHADOW_DIS_MASK 0x20" in corrected["header"]
    assert "#define BMG_RATE_HBW_SHADOW_DIS_MASK 0x40" in spec["header"]
    assert _reset_values(corrected["header"])[0x0F] == 0x03
    assert _reset_values(spec["header"])[0x0F] == 0x00
    assert (corrected["firmware_reset"], corrected["firmware_mask"]) == (0x03, 0xA0)
    assert (spec["firmware_reset"], spec["firmware_mask"]) == (0x00, 0xC0)


def test_the_firmware_sources_keep_no_copy_of_the_register_table():
    from bmg160_emu.firmware.build import FIRMWARE_DIR

    sources = {p.name: p.read_text(encoding="utf-8") for p in (FIRMWARE_DIR / "src").iterdir()}
    assert '#include "bmg160_registers.h"' in sources["regmap.c"]
    for name, text in sources.items():
        assert "#define REG_" not in text, name
        assert "bmg_regs[0x" not in text, name
