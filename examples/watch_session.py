"""A session long enough to watch: a driver polls an emulated BMG160 for two minutes.

    python3 examples/watch_session.py              # then, in another terminal: bmg160-emu watch
    python3 examples/watch_session.py --seconds 30

The chip runs in real time (its clock is the wall clock). A plain smbus2 driver brings it
up and reads the three rates ten times a second while the true rate swings slowly about z
(a 20 s sine of 30 deg/s) and the range changes halfway, so the view has something to
show: sparklines, the FIFO, a changed register. Inside tmux the view opens by itself in a
pane beside this one, as ``--watch`` does. Needs only the core install; the view needs the
[watch] extra (pip install 'bmg160-emu[watch]'). Ctrl-C ends it.
"""

from __future__ import annotations

import argparse
import math
import time

import smbus2

from bmg160_emu import BMG160
from bmg160_emu.bus.patching import patch_smbus
from bmg160_emu.clock import RealTimeClock
from bmg160_emu.watch.session import watched

ADDRESS = 0x68
POLL_S = 0.1  # ten readings a second: what a slow housekeeping loop does
SWING_PERIOD_S = 20.0
SWING_DPS = 30.0


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=120.0, help="how long (default 120)")
    args = parser.parse_args()

    chip = BMG160(seed=1, clock=RealTimeClock())
    with patch_smbus({1: {ADDRESS: chip}}) as buses, \
            watched({ADDRESS: chip}, [buses[1].log], "examples/watch_session.py"):
        bus = smbus2.SMBus(1)
        bus.write_byte_data(ADDRESS, 0x14, 0xB6)  # soft reset
        time.sleep(0.03)
        bus.write_byte_data(ADDRESS, 0x0F, 0x02)  # RANGE: +-500 deg/s
        bus.write_byte_data(ADDRESS, 0x10, 0x04)  # BW: 200 Hz, 23 Hz filter
        bus.write_byte_data(ADDRESS, 0x3E, 0x40)  # FIFO_CONFIG_1: FIFO mode, to watch it fill
        start = time.monotonic()
        switched = False
        try:
            while (elapsed := time.monotonic() - start) < args.seconds:
                swing = SWING_DPS * math.sin(2 * math.pi * elapsed / SWING_PERIOD_S)
                chip.set_true_rate((5.0, 0.0, swing))
                raw = bus.read_i2c_block_data(ADDRESS, 0x02, 6)
                z = int.from_bytes(bytes(raw[4:6]), "little", signed=True)
                if not switched and elapsed > args.seconds / 2:
                    bus.write_byte_data(ADDRESS, 0x0F, 0x03)  # RANGE: +-250 deg/s
                    switched = True
                print(f"\rt = {elapsed:6.1f} s  z = {z:6d} counts", end="", flush=True)
                time.sleep(POLL_S)
        except KeyboardInterrupt:
            pass
        print()
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
