"""The in-process /dev/i2c-N answers as the kernel's i2c-dev does, check by check.

tests/kernel_guest/guest_i2c_dev_parity.py makes every ioctl argument shape (bad pointers
included: an argument of 8 or 16, a message buffer at 0x10, a data pointer of 8, one at
TASK_SIZE_MAX or in the vsyscall page, a read into a read-only page), the descriptor calls
(read, write, pread, lseek, dup, dup2, select, F_GETFL, io.FileIO, open, os.fdopen) and the
node's (stat, lstat, access, exists, glob, listdir, scandir, pathlib), through fcntl and
through smbus2, smbus3, Adafruit_PureIO and periphery. The kernel test runs it inside a
guest on the real kernel's /dev/i2c-N (i2c-dev over the virtio adapter, the chips served by
this package) on every guest engine that is ready, Debian's own x86-64 kernel under QEMU and
our user-mode Linux build, and in this process under patch_i2c_dev, and compares the answers
one by one. The in-process node answers as the x86-64 kernel users run; where an engine's
kernel answers otherwise for a known reason (KNOWN_DIFFERENCES) the test says so and checks
that exactly that is what differs. The quick test compares this process with the x86-64
kernel's answers recorded in tests/data/i2c_dev_parity_kernel.json (written by the kernel
test on the qemu engine with BMG160_RECORD_PARITY=1, so the record is that kernel's).
"""

from __future__ import annotations

import ctypes
import errno
import fcntl
import json
import os
import re
import sys
import warnings
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pytest

from bmg160_emu.bus.i2c import DEFAULT_FUNCS, I2CBus
from bmg160_emu.bus.i2c_dev_node import patch_i2c_dev
from bmg160_emu.bus.kernel_abi import I2C_RDWR, I2C_SLAVE, I2C_SMBUS
from bmg160_emu.clock import VirtualClock
from bmg160_emu.device.chip import BMG160
from bmg160_emu.linux.guest.engine import ENGINE_MODULES
from bmg160_emu.traffic.kinds import I2C_FUNC_I2C

GUEST_FILES = Path(__file__).resolve().parent / "kernel_guest"
SCRIPT = GUEST_FILES / "guest_i2c_dev_parity.py"
RECORD = Path(__file__).resolve().parent / "data" / "i2c_dev_parity_kernel.json"
RECORD_ENGINE = "qemu"  # the record is the x86-64 kernel's (Debian's own, under QEMU)
EINVAL = {"error": "OSError", "errno": "EINVAL"}


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


# ---------------------------------------------------------------------- kernel versions


def upstream_version(release: str, version: str) -> tuple[int, ...] | None:
    """The upstream version of a guest kernel from ``uname -r`` and ``uname -v``: Debian's
    kernels name it in ``-v`` ("... Debian 6.1.192-3 ...", their ``-r`` is the ABI name
    6.1.0-57-amd64), our user-mode Linux build in ``-r`` (6.1.176)."""
    found = (re.search(r"Debian (\d+)\.(\d+)\.(\d+)", version)
             or re.match(r"(\d+)\.(\d+)\.(\d+)", release))
    return tuple(int(part) for part in found.groups()) if found else None


@dataclass(frozen=True)
class KnownDifference:
    """Checks a kernel of one stable series older than ``since`` answers otherwise than the
    in-process node (which answers as the newer kernel), and why."""

    since: tuple[int, int, int]
    checks: frozenset[str]
    ours: dict[str, Any]  # the in-process answer to each of them
    reason: str

    def applies(self, version: tuple[int, ...] | None) -> bool:
        return version is not None and version[:2] == self.since[:2] and version < self.since


ZERO_BLOCK_CHECKS = frozenset(
    f"{via} I2C_SMBUS {kind} of 0" for via in ("fcntl", "smbus3")
    for kind in ("i2c block read", "i2c block write", "block write"))

KNOWN_DIFFERENCES = (
    KnownDifference(
        since=(6, 1, 190), checks=ZERO_BLOCK_CHECKS, ours=EINVAL,
        reason="Linux 6.1.190 (\"i2c: smbus: reject oversized block transfers in the common "
               "path\", Debian 12's kernel since then) refuses an I2C block, block write or "
               "block process call count of 0 in __i2c_smbus_xfer, before any transfer; an "
               "older 6.1 kernel passes a count of 0 on to the adapter (our user-mode Linux "
               "build is made from the host's linux-source-6.1, which may be older than the "
               "kernel Debian ships)"),
)


def test_the_upstream_version_of_each_engine_s_kernel_is_read():
    assert upstream_version("6.1.0-57-amd64", "#1 SMP PREEMPT_DYNAMIC Debian 6.1.192-3 "
                            "(2026-11-02)") == (6, 1, 192)
    assert upstream_version("6.1.176", "#1 Thu Dec 3 10:00:00 UTC 2026") == (6, 1, 176)
    assert upstream_version("weird", "") is None
    zero = KNOWN_DIFFERENCES[0]
    assert zero.applies((6, 1, 176)) and not zero.applies((6, 1, 190))
    assert not zero.applies((6, 12, 3)) and not zero.applies(None)  # another series: unknown


# ---------------------------------------------------------------------- the record


def test_the_in_process_node_answers_as_the_recorded_kernel():
    if not RECORD.exists():
        pytest.skip("no recorded answers of the kernel (run the kernel test with "
                    "BMG160_RECORD_PARITY=1)")
    recorded = json.loads(RECORD.read_text(encoding="utf-8"))
    assert recorded["machine"] == "x86_64"  # the kernel users run, not user-mode Linux's
    ours = in_process(recorded["bus"], recorded["funcs"])
    assert differences(recorded["checks"], ours) == []
    assert len(recorded["checks"]) > 150  # the whole list ran


def test_a_pointer_the_kernel_refuses_is_efault_in_process():
    # what the record shows, from the kernel's source (drivers/i2c/i2c-dev.c: put_user and
    # copy_from_user/copy_to_user fail; access_ok above TASK_SIZE_MAX), in case the record
    # is missing
    ours = in_process(7)
    efault = {"error": "OSError", "errno": "EFAULT"}
    for name in ("I2C_FUNCS arg 8", "I2C_FUNCS arg 1", "fcntl I2C_RDWR arg 16",
                 "fcntl I2C_RDWR write buffer at 0x10", "fcntl I2C_SMBUS read byte, data at 8",
                 "fcntl I2C_SMBUS read byte, data at TASK_SIZE_MAX",
                 "fcntl I2C_SMBUS read byte, data in the vsyscall page",
                 "fcntl I2C_SMBUS read i2c block into a read-only page",
                 "smbus2 i2c_rdwr buffer at 0x10", "periphery ioctl I2C_FUNCS arg 8"):
        assert ours[name] == efault, name
    for name in ZERO_BLOCK_CHECKS:
        assert ours[name] == EINVAL, name


def _smbus_request(read_write: int, command: int, size: int, union: Any) -> Any:
    checks = _checks_module()
    return checks.i2c_smbus_ioctl_data(read_write, command, size, ctypes.addressof(union))


def test_a_zero_block_count_is_refused_before_the_chip_sees_anything():
    # __i2c_smbus_xfer (Linux 6.1.190): the count is checked before any transfer, so a
    # refused write leaves no transaction, and a count of 1..32 goes through
    bus = I2CBus(3, {0x68: BMG160(seed=1)})
    with patch_i2c_dev({3: bus}):
        fd = os.open("/dev/i2c-3", os.O_RDWR)
        try:
            fcntl.ioctl(fd, I2C_SLAVE, 0x68)
            union = (ctypes.c_uint8 * 34)()
            for read_write, size in ((1, 8), (0, 8), (0, 5), (0, 7)):  # i2c block r/w, block
                with pytest.raises(OSError) as refused:  # write, block process call
                    fcntl.ioctl(fd, I2C_SMBUS, _smbus_request(read_write, 0x10, size, union))
                assert refused.value.errno == errno.EINVAL, (read_write, size)
            union[0] = 33
            with pytest.raises(OSError, match="Invalid argument"):
                fcntl.ioctl(fd, I2C_SMBUS, _smbus_request(1, 0x00, 8, union))
            assert len(bus.log) == 0
            union[0] = 1
            assert fcntl.ioctl(fd, I2C_SMBUS, _smbus_request(1, 0x00, 8, union)) == 0
            assert union[1] == 0x0F  # CHIP_ID
        finally:
            os.close(fd)


def test_rdwr_on_an_adapter_without_i2c_copies_the_buffers_before_refusing():
    # i2cdev_ioctl_rdwr copies every buffer (memdup_user: EFAULT) before i2c_transfer finds
    # no master_xfer (EOPNOTSUPP)
    checks = _checks_module()
    bus = I2CBus(4, {0x68: BMG160(seed=1)}, funcs=DEFAULT_FUNCS & ~I2C_FUNC_I2C)
    with patch_i2c_dev({4: bus}):
        fd = os.open("/dev/i2c-4", os.O_RDWR)
        try:
            table = (checks.i2c_msg * 1)()
            table[0].addr, table[0].flags, table[0].len, table[0].buf = 0x68, 0, 1, 0x10
            request = checks.i2c_rdwr_ioctl_data(ctypes.addressof(table), 1)
            with pytest.raises(OSError) as bad:
                fcntl.ioctl(fd, I2C_RDWR, request)
            assert bad.value.errno == errno.EFAULT
            good = (ctypes.c_uint8 * 1)()
            table[0].buf = ctypes.addressof(good)
            with pytest.raises(OSError) as refused:
                fcntl.ioctl(fd, I2C_RDWR, request)
            assert refused.value.errno == errno.EOPNOTSUPP
        finally:
            os.close(fd)


# ---------------------------------------------------------------------- the kernels


@pytest.fixture(scope="module", params=ENGINE_MODULES)
def engine_guest(request: pytest.FixtureRequest,
                 tmp_path_factory: pytest.TempPathFactory) -> Iterator[Any]:
    """A guest of one engine for this module's checks (skipped, with what that engine
    lacks, when it is not prepared); its time as the kernel fixture's ini says."""
    from bmg160_emu.pytest_kernel import KernelSession

    time_mode = (os.environ.get("BMG160_KERNEL_TIME")
                 or request.config.getini("bmg160_kernel_time") or None)
    session = KernelSession(request.param, tmp_path_factory.mktemp(f"parity-{request.param}"),
                            time_mode)
    try:
        yield session.ensure()  # pytest.skip("no kernel guest here: engine ... not ready: ...")
    finally:
        session.close()


@pytest.mark.kernel
def test_the_kernel_s_i2c_dev_and_the_in_process_node_answer_alike(engine_guest):
    guest = engine_guest
    out = guest.run(f'echo $GUEST_I2C_BUS; uname -r; uname -v; uname -m; "$BMG160_PY" {SCRIPT} '
                    '$GUEST_I2C_BUS', timeout_s=600)
    number, release, version, machine, text = out.stdout.split("\n", 4)
    kernel = json.loads(text)
    funcs = int(guest.run(
        '"$BMG160_PY" -c "import fcntl,os,struct; fd=os.open(\'/dev/i2c-$GUEST_I2C_BUS\', '
        'os.O_RDWR); print(struct.unpack(\'Q\', fcntl.ioctl(fd, 0x0705, bytes(8)))[0])"'
    ).stdout)
    ours = in_process(int(number), funcs)
    upstream = upstream_version(release, version)
    known = [k for k in KNOWN_DIFFERENCES if k.applies(upstream)]
    stated = set().union(*(k.checks for k in known))
    assert differences({n: v for n, v in kernel.items() if n not in stated},
                       {n: v for n, v in ours.items() if n not in stated}) == []
    for difference in known:  # exactly what the reason says differs, no more
        for name in sorted(difference.checks):
            assert ours[name] == difference.ours, name
            assert kernel[name] != difference.ours, (name, kernel[name])
        warnings.warn(f"{engine_guest.engine.name} engine, kernel {release} "
                      f"({'.'.join(map(str, upstream or ()))}): {len(difference.checks)} checks "
                      f"answered as that kernel does, not as the in-process node: "
                      f"{difference.reason}", stacklevel=1)
    record = {"kernel": release, "version": version, "machine": machine,
              "engine": guest.engine.name, "bus": int(number), "funcs": funcs,
              "checks": kernel}
    if os.environ.get("BMG160_RECORD_PARITY") and guest.engine.name == RECORD_ENGINE:
        RECORD.write_text(_record_text(record), encoding="utf-8")
    elif RECORD.exists():  # the record the quick test uses is still that kernel's answer
        recorded = json.loads(RECORD.read_text(encoding="utf-8"))
        if (recorded.get("kernel"), recorded.get("version")) == (release, version):
            assert recorded["checks"] == kernel
