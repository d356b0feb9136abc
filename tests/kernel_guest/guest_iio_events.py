"""Runs INSIDE the QEMU guest: print the IIO events of a device for some seconds.

Usage: python guest_iio_events.py /dev/iio:deviceN SECONDS [READY_FILE]. READY_FILE is
created once the event file descriptor is open (step the rate after it). One line per event:
``id=0x... timestamp_ns=... type=... dir=...`` (struct iio_event_data, linux/iio/events.h).
"""

from __future__ import annotations

import array
import fcntl
import os
import select
import struct
import sys
import time

IIO_GET_EVENT_FD_IOCTL = 0x80046990  # _IOR('i', 0x90, int)


def main() -> int:
    device, seconds = sys.argv[1], float(sys.argv[2])
    fd = os.open(device, os.O_RDONLY)
    holder = array.array("i", [0])
    fcntl.ioctl(fd, IIO_GET_EVENT_FD_IOCTL, holder, True)
    events = holder[0]
    if len(sys.argv) > 3:
        with open(sys.argv[3], "w") as ready:
            ready.write("ready\n")
    end = time.monotonic() + seconds
    while (left := end - time.monotonic()) > 0:
        ready, _, _ = select.select([events], [], [], left)
        if not ready:
            break
        data = os.read(events, 16)
        event_id, timestamp = struct.unpack("<Qq", data)
        # IIO_EVENT_CODE_EXTRACT_TYPE: bits 56..63, _DIR: 48..54, channel type 32..39
        print(f"id=0x{event_id:016x} timestamp_ns={timestamp} type={event_id >> 56 & 0xFF} "
              f"dir={event_id >> 48 & 0x7F} chan_type={event_id >> 32 & 0xFF}", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
