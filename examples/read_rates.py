"""An unmodified smbus2 program: check the chip ID, set +-500 deg/s at 200 Hz, print one
reading of the three rates. Run it against the emulator with
``bmg160-emu run -- python3 examples/read_rates.py`` (docs/commands/run.md)."""

import time

import smbus2

ADDRESS = 0x68
CHIP_ID, RATE_X_LSB, RANGE, BW = 0x00, 0x02, 0x0F, 0x10  # BMG160 data sheet, section 7
LSB_PER_DPS = 65.536  # at +-500 deg/s (data sheet, table 3)

with smbus2.SMBus(1) as bus:
    chip_id = bus.read_byte_data(ADDRESS, CHIP_ID)
    if chip_id != 0x0F:
        raise SystemExit(f"no BMG160 at 0x{ADDRESS:02x}: chip ID 0x{chip_id:02x}")
    bus.write_byte_data(ADDRESS, RANGE, 0x02)  # +-500 deg/s
    bus.write_byte_data(ADDRESS, BW, 0x04)  # 200 Hz ODR, 23 Hz filter
    time.sleep(0.02)  # a few samples at the new settings
    raw = bytes(bus.read_i2c_block_data(ADDRESS, RATE_X_LSB, 6))
    counts = [int.from_bytes(raw[i : i + 2], "little", signed=True) for i in (0, 2, 4)]
    print("rate (deg/s):", " ".join(f"{c / LSB_PER_DPS:+.2f}" for c in counts))
