"""Runs INSIDE the QEMU guest: read IIO buffers for some seconds, then exit by itself.

Usage: python guest_iio_capture.py SECONDS /dev/iio:deviceA OUT_A [/dev/iio:deviceB OUT_B ...]

Why not ``cat`` and ``kill``: i2c-virtio (6.1) waits for its requests interruptibly, and a
process that dies by a signal while the driver talks I2C on its behalf (closing the
device) abandons a transfer the device still completes into freed memory. This reader
ends on its own, so the shell can disable the buffers afterwards with no signal about.
It wakes when a buffer holds its watermark (set by the caller), and drains what is left
before it ends.
"""

from __future__ import annotations

import os
import select
import sys
import time


def main() -> int:
    seconds = float(sys.argv[1])
    pairs = list(zip(sys.argv[2::2], sys.argv[3::2]))
    fds = {os.open(device, os.O_RDONLY | os.O_NONBLOCK): out for device, out in pairs}
    data: dict[int, list[bytes]] = {fd: [] for fd in fds}
    end = time.monotonic() + seconds
    while (left := end - time.monotonic()) > 0:
        ready, _, _ = select.select(list(fds), [], [], left)
        for fd in ready:
            try:
                data[fd].append(os.read(fd, 16 * 512))
            except BlockingIOError:
                pass
    for fd in fds:  # what the watermark held back: a non-blocking read returns it
        while True:
            try:
                chunk = os.read(fd, 16 * 512)
            except BlockingIOError:
                break
            if not chunk:
                break
            data[fd].append(chunk)
    for fd, out in fds.items():
        with open(out, "wb") as handle:
            handle.write(b"".join(data[fd]))
        os.close(fd)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
