"""The in-process /dev/i2c-N answers as the kernel's i2c-dev does, check by check.

tests/kernel_guest/guest_i2c_dev_parity.py makes every ioctl argument shape (bad pointers
included: an argument of 8 or 16, a message buffer at 0x10, a data pointer of 8, a read
into a read-only page), the descriptor calls (read, write, pread, lseek, dup, dup2, select,
F_GETFL, io.FileIO, open, os.fdopen) and the node's (stat, lstat, access, exists, glob,
listdir, scandir, pathlib), through fcntl and through smbus2, smbus3, Adafruit_PureIO and
periphery. The kernel test runs it inside a Linux 6.1 guest on the real kernel's
/dev/i2c-N (i2c-dev over the virtio adapter, the chips served by this package) and in this
process under patch_i2c_dev, and compares the answers one by one; the quick test compares
this process with the guest's answers recorded in tests/data/i2c_dev_parity_kernel.json
(written by the kernel test with BMG160_RECORD_PARITY=1, so the record is the kernel's).
"""

from __future__ import annotations

import json
import os
import sys
from pathlib import Path
from typing import Any

import pytest

from bmg160_emu.bus.i2c import I2CBus
from bmg160_emu.bus.i2c_dev_node import patch_i2c_dev
from bmg160_emu.clock import VirtualClock
from bmg160_emu.device.chip import BMG160

GUEST_FILES = Path(__file__).resolve().parent / "kernel_guest"
SCRIPT = GUEST_FILES / "guest_i2c_dev_parity.py"
RECORD = Path(__file__).resolve().parent / "data" / "i2c_dev_parity_kernel.json"


def _checks_module() -> Any:
    sys.path.insert(0, str(GUEST_FILES))
    try:
        import guest_i2c_dev_parity
    finally:
        sys.path.remove(str(GUEST_FILES))
    return guest_i2c_dev_parity


def in_process(bus_number: int, funcs: int | None = None) -> dict[str, Any]:
    """The checks against the in-process node: two chips at 0x68 and 0x69, as the guest's."""
    clock = VirtualClock()
    chips = {0x68: BMG160(seed=1, clock=clock), 0x69: BMG160(seed=2, clock=clock, address=0x69)}
    bus = I2CBus(bus_number, chips)
    if funcs is not None:
        bus.funcs = funcs
    with patch_i2c_dev({bus_number: bus}):
        results = _checks_module().run_checks(bus_number)
    return json.loads(json.dumps(results))  # as the guest's JSON gives them


def _record_text(record: dict[str, Any]) -> str:
    """The record as JSON with one check per line (a difference reads as one line)."""
    checks = record["checks"]
    head = {key: value for key, value in record.items() if key != "checks"}
    lines = [f" {json.dumps(key)}: {json.dumps(value)}," for key, value in head.items()]
    body = [f"  {json.dumps(name)}: {json.dumps(checks[name])}" for name in checks]
    return "{\n" + "\n".join(lines) + '\n "checks": {\n' + ",\n".join(body) + "\n }\n}\n"


def differences(kernel: dict[str, Any], ours: dict[str, Any]) -> list[str]:
    lines = [f"{name}: kernel {kernel.get(name)!r}, in process {ours.get(name)!r}"
             for name in sorted(set(kernel) | set(ours)) if kernel.get(name) != ours.get(name)]
    return lines


def test_the_in_process_node_answers_as_the_recorded_kernel():
    if not RECORD.exists():
        pytest.skip("no recorded answers of the kernel (run the kernel test with "
                    "BMG160_RECORD_PARITY=1)")
    recorded = json.loads(RECORD.read_text(encoding="utf-8"))
    ours = in_process(recorded["bus"], recorded["funcs"])
    assert differences(recorded["checks"], ours) == []
    assert len(recorded["checks"]) > 150  # the whole list ran


def test_a_pointer_the_kernel_refuses_is_efault_in_process():
    # what the record shows, from the kernel's source (drivers/i2c/i2c-dev.c: put_user and
    # copy_from_user/copy_to_user fail), in case the record is missing
    ours = in_process(7)
    efault = {"error": "OSError", "errno": "EFAULT"}
    for name in ("I2C_FUNCS arg 8", "I2C_FUNCS arg 1", "fcntl I2C_RDWR arg 16",
                 "fcntl I2C_RDWR write buffer at 0x10", "fcntl I2C_SMBUS read byte, data at 8",
                 "smbus2 i2c_rdwr buffer at 0x10", "periphery ioctl I2C_FUNCS arg 8"):
        assert ours[name] == efault, name


@pytest.mark.kernel
@pytest.mark.bmg160_kernel(driver=None)
def test_the_kernel_s_i2c_dev_and_the_in_process_node_answer_alike(bmg160_kernel):
    guest = bmg160_kernel.run(f'echo $GUEST_I2C_BUS; "$BMG160_PY" {SCRIPT} $GUEST_I2C_BUS',
                              timeout_s=300)
    number, _, text = guest.stdout.partition("\n")
    kernel = json.loads(text)
    funcs = int(bmg160_kernel.run(
        '"$BMG160_PY" -c "import fcntl,os,struct; fd=os.open(\'/dev/i2c-$GUEST_I2C_BUS\', '
        'os.O_RDWR); print(struct.unpack(\'Q\', fcntl.ioctl(fd, 0x0705, bytes(8)))[0])"'
    ).stdout)
    ours = in_process(int(number), funcs)
    assert differences(kernel, ours) == []
    record = {"kernel": bmg160_kernel.run("uname -r").stdout.strip(), "bus": int(number),
              "funcs": funcs, "checks": kernel}
    if os.environ.get("BMG160_RECORD_PARITY"):
        RECORD.write_text(_record_text(record), encoding="utf-8")
    elif RECORD.exists():  # the record the quick test uses is still the kernel's answer
        assert json.loads(RECORD.read_text(encoding="utf-8"))["checks"] == kernel
