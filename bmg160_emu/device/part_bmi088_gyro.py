"""The BMI088 gyroscope as differences from the BMG160 table (docs/parts.md has the sources).

BMI088 data sheet (BST-BMI088-DS001) section 5.4, the gyroscope register map, lists
CHIP_ID, the rate registers, GYRO_INT_STAT_1, FIFO_STATUS, GYRO_RANGE, GYRO_BANDWIDTH,
GYRO_LPM1, GYRO_SOFTRESET, GYRO_INT_CTRL, INT3_INT4_IO_CONF, INT3_INT4_IO_MAP, FIFO_WM_EN,
FIFO_EXT_INT_S, GYRO_SELF_TEST and the three FIFO registers; every other address is
reserved. The drivers read to check it (PX4 ``Bosch_BMI088_Gyroscope_Registers.hpp``, Bosch
BMI08x Sensor API ``bmi08_defs.h``) name the same registers at the same addresses.
"""

from __future__ import annotations

from bmg160_emu.device.part_spec import Differences, derive, frozen
from bmg160_emu.device.registers import BMI088_FIFO_EXT_INT_S, REGISTERS

# BMG160 registers the BMI088 gyroscope map (DS 5.4) marks reserved: no temperature
# (0x08), no any-motion/high-rate/offset interrupts (0x09, 0x0B, 0x0C, 0x17, 0x19-0x1C,
# 0x21-0x27), no LPM2 and RATE_HBW (0x12-0x13), no offset compensation or NVM (0x31-0x33,
# 0x36-0x3B).
STREAM_DEPTH_FRAMES = 99  # DS 4.9.4.4, 5.5.16

ABSENT = (
    "TEMP", "INT_STATUS_0", "INT_STATUS_2", "INT_STATUS_3", "LPM2", "RATE_HBW", "INT_MAP_0",
    "INT_MAP_2", "INT_DATA_SRC", "ANY_TH", "ANY_EN", "INT_RST_LATCH",
    "HIGH_TH_X", "HIGH_DUR_X", "HIGH_TH_Y", "HIGH_DUR_Y", "HIGH_TH_Z", "HIGH_DUR_Z",
    "SOC", "A_FOC", "TRIM_NVM_CTRL", "OFC1", "OFC2", "OFC3", "OFC4", "TRIM_GP0", "TRIM_GP1",
    # and every register the BMG160 reserves is reserved here too (0x01, 0x0D, 0x1D, ...)
    *(reg.name for reg in REGISTERS if reg.reserved),
)

# Registers kept with only the bits DS 5.5 describes (the other bits are '-': read 0).
FIELDS = frozen({
    "INT_STATUS_1": ("data_int", "fifo_int"),                   # 5.5.3: bits 7 and 4
    "LPM1": ("suspend", "deep_suspend"),                        # 5.5.7: 0x00, 0x80, 0x20
    "INT_EN_0": ("data_en", "fifo_en"),                         # 5.5.9: bits 7 and 6
    "INT_MAP_1": ("int2_data", "int2_fifo", "int1_fifo", "int1_data"),  # 5.5.11: 7, 5, 2, 0
    "FIFO_CONFIG_0": ("fifo_water_mark_level_trigger_retain",),  # 5.5.15: bit 7 reserved
    "FIFO_CONFIG_1": ("fifo_mode",),                            # 5.5.16, map 5.4: 7:6 only
})

RENAMED = frozen({
    "CHIP_ID": "GYRO_CHIP_ID", "INT_STATUS_1": "GYRO_INT_STAT_1", "RANGE": "GYRO_RANGE",
    "BW": "GYRO_BANDWIDTH", "LPM1": "GYRO_LPM1", "BGW_SOFTRESET": "GYRO_SOFTRESET",
    "INT_EN_0": "GYRO_INT_CTRL", "INT_EN_1": "INT3_INT4_IO_CONF",
    "INT_MAP_1": "INT3_INT4_IO_MAP", "BIST": "GYRO_SELF_TEST",
})

# 5.5.13: the FIFO synchronisation register, in place of the BMG160's SPI3/watchdog
# register. Stored only: no pin is an input in the model, so no frame is ever tagged.
FIFO_EXT_INT_S = BMI088_FIFO_EXT_INT_S

# DS 5.5.10, 5.5.11 name the pin fields after INT3 and INT4 (int3_od, int4_data ...)
DIFFERENCES = Differences(absent=ABSENT, fields=FIELDS, renamed=RENAMED,
                          replaced=frozen({"BGW_SPI3_WDT": FIFO_EXT_INT_S}),
                          pin_fields=("INT3", "INT4"))

BMI088_GYRO = derive(
    "bmi088_gyro", "BMI088 gyroscope", DIFFERENCES, pins=("INT3", "INT4"),
    noise_profile="bmi088_datasheet",
    # DS 4.9.4.4 and 5.5.16: stream mode holds 99 frames (FIFO mode 100), and the FIFO
    # interrupt without a watermark comes at 99 frames in stream mode
    stream_depth=STREAM_DEPTH_FRAMES)
