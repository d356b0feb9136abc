"""Runs INSIDE the guest (stdlib only): read an IIO device's buffer for some seconds into a
file, ending by itself.

Why not ``cat`` and ``kill``: i2c-virtio (6.1) waits for its requests interruptibly, and a
process killed while the driver talks I2C on its behalf abandons a transfer the device still
completes into freed memory (slab corruption). This reader ends on its own and drains what
the watermark held back before it does.

Usage: ``python iio_capture.py SECONDS /dev/iio:deviceN OUT``.
"""

from __future__ import annotations

import os
import select
import sys
import time

CHUNK = 16 * 512  # bytes per read: 512 records of a 3-axis gyro with its timestamp


def capture(seconds: float, device: str, out: str) -> int:
    fd = os.open(device, os.O_RDONLY | os.O_NONBLOCK)
    data: list[bytes] = []
    end = time.monotonic() + seconds
    while (left := end - time.monotonic()) > 0:
        ready, _, _ = select.select([fd], [], [], left)
        if ready:
            try:
                data.append(os.read(fd, CHUNK))
            except BlockingIOError:
                pass
    while True:
        try:
            chunk = os.read(fd, CHUNK)
        except BlockingIOError:
            break
        if not chunk:
            break
        data.append(chunk)
    os.close(fd)
    with open(out, "wb") as handle:
        handle.write(b"".join(data))
    return 0


if __name__ == "__main__":
    raise SystemExit(capture(float(sys.argv[1]), sys.argv[2], sys.argv[3]))
