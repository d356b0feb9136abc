"""Benchmark: transactions per second through the umockdev /dev/i2c-N front end.

The transaction is the driver's 6-byte rate read (an I2C block read of RATE_X_LSB..RATE_Z_MSB,
``I2C_SMBUS`` size 8). Three clients do it N times in a row:

- a C program calling ioctl(I2C_SMBUS) on the virtual /dev/i2c-1 (compiled here with cc),
- smbus2's ``read_i2c_block_data`` in a child Python process on the virtual /dev/i2c-1,
- the same smbus2 call on the in-process FakeSMBus (the reference, measured in this run).

Each client times its own loop (process start-up excluded). Prints transactions per second
and each umockdev client's ratio to the reference.

    python tools/bench_umockdev.py [--count 3000]
"""

from __future__ import annotations

import argparse
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

C_CLIENT = r"""
#include <fcntl.h>
#include <linux/i2c.h>
#include <linux/i2c-dev.h>
#include <stdio.h>
#include <stdlib.h>
#include <sys/ioctl.h>
#include <time.h>

int main(int argc, char **argv)
{
    int fd = open("/dev/i2c-1", O_RDWR), n = atoi(argv[1]), i;
    union i2c_smbus_data d;
    struct i2c_smbus_ioctl_data a = { I2C_SMBUS_READ, 0x02, I2C_SMBUS_I2C_BLOCK_DATA, &d };
    struct timespec t0, t1;
    if (fd < 0 || ioctl(fd, I2C_SLAVE, 0x68) < 0) { perror("open"); return 1; }
    clock_gettime(CLOCK_MONOTONIC, &t0);
    for (i = 0; i < n; i++) {
        d.block[0] = 6;
        if (ioctl(fd, I2C_SMBUS, &a) < 0) { perror("I2C_SMBUS"); return 1; }
    }
    clock_gettime(CLOCK_MONOTONIC, &t1);
    printf("%.6f\n", (t1.tv_sec - t0.tv_sec) + (t1.tv_nsec - t0.tv_nsec) / 1e9);
    return 0;
}
"""

SMBUS2_CLIENT = """
import sys, time
from smbus2 import SMBus
n = int(sys.argv[1])
with SMBus(1) as bus:
    t0 = time.perf_counter()
    for _ in range(n):
        bus.read_i2c_block_data(0x68, 0x02, 6)
    print(f"{time.perf_counter() - t0:.6f}")
"""


def new_chip():
    from bmg160_emu.clock import RealTimeClock
    from bmg160_emu.device.chip import BMG160

    return BMG160(seed=1, clock=RealTimeClock(), true_rate=(20.0, -10.0, 5.0))


def reference_fake_smbus(count: int) -> float:
    from bmg160_emu.bus.smbus import FakeSMBus

    with FakeSMBus(1, devices={0x68: new_chip()}) as bus:
        bus.log.enabled = False  # as for the umockdev bus: measure the route, not the log
        t0 = time.perf_counter()
        for _ in range(count):
            bus.read_i2c_block_data(0x68, 0x02, 6)
        return time.perf_counter() - t0


def through_umockdev(command: list[str]) -> float:
    from bmg160_emu.bus.i2c import I2CBus
    from bmg160_emu.linux.umockdev import VirtualI2CDevices

    bus = I2CBus(1, {0x68: new_chip()})
    bus.log.enabled = False  # as the reference: measure the route, not the log
    with VirtualI2CDevices([bus]) as devices:
        result = devices.run(command, capture_output=True, text=True, timeout=600)
    if result.returncode != 0:
        raise SystemExit(f"client failed: {result.stderr}")
    return float(result.stdout.split()[-1])


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--count", type=int, default=3000, help="transactions per client")
    args = parser.parse_args()
    n = args.count
    cc = shutil.which("cc") or shutil.which("gcc")
    if cc is None:
        raise SystemExit("no C compiler")
    with tempfile.TemporaryDirectory() as tmp:
        source, binary = Path(tmp, "bench.c"), Path(tmp, "bench")
        source.write_text(C_CLIENT)
        subprocess.run([cc, "-O2", "-o", str(binary), str(source)], check=True)
        script = Path(tmp, "bench_smbus2.py")
        script.write_text(SMBUS2_CLIENT)
        reference = reference_fake_smbus(n)
        c_time = through_umockdev([str(binary), str(n)])
        py_time = through_umockdev([sys.executable, str(script), str(n)])
    ref_rate = n / reference
    print(f"6-byte rate reads, {n} per client")
    print(f"  reference  smbus2 API on FakeSMBus (in-process): {ref_rate:10.0f} tx/s")
    for name, seconds in (("C ioctl on umockdev /dev/i2c-1", c_time),
                          ("smbus2 on umockdev /dev/i2c-1", py_time)):
        rate = n / seconds
        print(f"  {name:<39}: {rate:10.0f} tx/s  ratio to reference {rate / ref_rate:.4f}"
              f"  ({1e6 * seconds / n:.0f} us per transaction)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
