"""The BMI088 gyroscope's pin registers decode in the part's own words: INT3 and INT4.

BMI088 data sheet 5.5.10 and 5.5.11: INT3_INT4_IO_CONF holds int4_od, int4_lvl, int3_od,
int3_lvl, and INT3_INT4_IO_MAP int4_data, int4_fifo, int3_fifo, int3_data, where the
BMG160's INT_EN_1 and INT_MAP_1 name the same bits after INT1 and INT2. The BMI055 and
BMX055 gyroscopes keep the BMG160's names (their table is the BMG160's, bit for bit).
"""

from __future__ import annotations

from bmg160_emu.bus.i2c import I2CBus
from bmg160_emu.device.config import ChipConfig
from bmg160_emu.device.parts import part_table
from bmg160_emu.io.trace import TraceHeader, TraceWriter, read_trace
from bmg160_emu.session.decode import describe_transaction


def test_the_bmi088_pin_registers_name_int3_and_int4():
    table = part_table("bmi088_gyro")
    assert [f.name for f in table.register(0x16).fields] == [
        "int4_od", "int4_lvl", "int3_od", "int3_lvl"]
    assert [f.name for f in table.register(0x18).fields] == [
        "int4_data", "int4_fifo", "int3_fifo", "int3_data"]
    assert "INT3 active level" in {f.meaning for f in table.register(0x16).fields}
    assert [f.name for f in part_table("bmi055_gyro").register(0x16).fields] == [
        "int2_od", "int2_lvl", "int1_od", "int1_lvl"]


def test_a_trace_decodes_them_so(tmp_path):
    gyro = ChipConfig(address=0x68, part="bmi088_gyro", noise=False)
    header = TraceHeader(1)
    header.add_config(gyro)
    bus = I2CBus(1, {0x68: gyro.build(seed=1)})
    path = tmp_path / "pins.jsonl"
    with TraceWriter(path, header) as trace:
        bus.log.sinks.append(trace)
        bus.write_byte_data(0x68, 0x16, 0x05)  # INT3 and INT4 active high
        bus.write_byte_data(0x68, 0x18, 0x81)  # data-ready to INT3 and INT4
    _, records = read_trace(path)
    parts = {0x68: part_table("bmi088_gyro").registers}
    conf, io_map = (describe_transaction(r, parts=parts) for r in records)
    assert "int3_lvl high" in conf and "int4_lvl high" in conf and "int1" not in conf
    assert "int3_data" in io_map and "int4_data" in io_map and "int2" not in io_map
