"""The user-mode Linux engine: our own UML build of Debian's linux-source-6.1 runs as an
ordinary host process, with the host's root as its root (hostfs) and the vhost-user back
ends on ``virtio_uml.device`` sockets.

Why UML: no emulated machine to boot, so a guest is up in about 1 s (QEMU under TCG: about
6 s) and a register read costs about half the CPU of QEMU's (linux-kernel-notes.md,
"User-mode Linux"). Its costs: a 3.5-minute kernel build once (:mod:`uml_build`), ptrace
(every guest system call is traced), and a host FPU state that must fit the kernel's
buffers (patch 0001; checked here before a boot rather than hanging in it).
"""

from __future__ import annotations

import os
import secrets
import shutil
import subprocess
from pathlib import Path

from bmg160_emu.linux.guest import agent, uml_build
from bmg160_emu.linux.guest.cache import cache_dir, content_hash
from bmg160_emu.linux.guest.engine import Boot, EngineError, Progress

XSAVE_PROBE = uml_build.DATA / "xsave_size.c"
VIRTIO_ID_I2C = 34  # virtio 1.2 specification, 5 "Device Types"
VIRTIO_ID_GPIO = 41
# The guest's memory is a file UML maps; tmpfs keeps it out of the disk's page cache.
MEMORY_DIR = Path("/dev/shm")


def host_xsave_bytes() -> int | None:
    """The host CPU's XSAVE area in bytes (CPUID 0xD), from a small C probe compiled into
    the cache once; None where it cannot be told (no gcc, not x86)."""
    probe = cache_dir() / f"xsave-size-{content_hash([XSAVE_PROBE], length=8)}"
    if not probe.exists():
        if shutil.which("gcc") is None:
            return None
        probe.parent.mkdir(parents=True, exist_ok=True)
        partial = probe.with_suffix(".tmp")
        built = subprocess.run(["gcc", "-O", "-o", str(partial), str(XSAVE_PROBE)],
                               capture_output=True, check=False)
        if built.returncode != 0:
            return None
        partial.replace(probe)
    out = subprocess.run([str(probe)], capture_output=True, text=True, check=False)
    return int(out.stdout) if out.returncode == 0 and out.stdout.strip().isdigit() else None


def xsave_problem(host_bytes: int | None, kernel_bytes: int) -> str | None:
    """The one line a host with a too-large FPU state gets, instead of a guest that hangs."""
    if host_bytes is None or host_bytes <= kernel_bytes:
        return None
    return (f"the host CPU's XSAVE area is {host_bytes} bytes (CPUID 0xD) but the UML kernel "
            f"has room for {kernel_bytes}: raise FP_AREA_BYTES in uml_build.py and patch 0001")


def ptrace_problem() -> str | None:
    """UML traces its processes; Yama's mode 3 forbids ptrace outright."""
    scope = Path("/proc/sys/kernel/yama/ptrace_scope")
    if scope.exists() and scope.read_text().strip() == "3":
        return "ptrace is disabled (kernel.yama.ptrace_scope = 3); UML needs it"
    return None


class UmlEngine:
    """Our UML kernel as a host process; hostfs for the host's root and the results."""

    name = "uml"
    time_travel = True  # time-travel=ext: the guest's clock can be the back end's calendar

    def missing(self) -> list[str]:
        lines = [f"{package} is missing (Debian package {package})"
                 for package in uml_build.missing_packages()]
        lines += [line for line in agent.missing() if line not in lines]
        for problem in (ptrace_problem(),
                        xsave_problem(host_xsave_bytes(), uml_build.FP_AREA_BYTES)):
            if problem:
                lines.append(problem)
        if not lines and (uml_build.find_kernel() is None or not self._vio_ready()):
            lines.append(f"no UML kernel in {cache_dir()} yet "
                         "(run: bmg160-emu kernel prepare --engine uml)")
        return lines

    def _vio_ready(self) -> bool:
        kernel = uml_build.find_kernel()
        return kernel is not None and (kernel.vio / "ready").exists()

    def prepare(self, progress: Progress) -> None:
        problem = xsave_problem(host_xsave_bytes(), uml_build.FP_AREA_BYTES)
        if problem:
            raise EngineError(problem)
        kernel = uml_build.build(progress)
        progress(f"uml: {kernel.binary}")
        progress(f"uml: the guest's agent: {agent.binary()}")

    def kernel(self) -> uml_build.UmlKernel:
        """The built kernel, or an :class:`EngineError` saying how to build it."""
        kernel = uml_build.find_kernel()
        if kernel is None or not (kernel.vio / "ready").exists():
            raise EngineError("no UML kernel in the cache "
                              "(run: bmg160-emu kernel prepare --engine uml)")
        return kernel

    def build_module(self, path: Path, progress: Progress) -> list[Path]:
        """A user's .ko as it is, or its Kbuild folder built for this kernel (ARCH=um)."""
        return uml_build.user_module(self.kernel(), path, progress)

    def board_module(self) -> Path:
        """bmg160-board.ko built for this kernel (the chips' IRQs from virtio-gpio lines)."""
        return self.kernel().board

    def command(self, boot: Boot) -> list[str]:
        """The UML command line for ``boot``: the agent (agent.c) is its init."""
        kernel = self.kernel()
        results = boot.results.resolve()
        words = [
            f"mem={boot.memory_mb}M", "root=/dev/root", "rootfstype=hostfs", "rootflags=/",
            "ro" if boot.host_root_readonly else "rw", f"init={agent.binary()}",
            # the console on stdout, nothing read; no other consoles or serial lines
            "con=null", "ssl=null", "con0=null,fd:1", "quiet", "panic=-1",
            f"guest_out={results}", f"guest_modroot={kernel.modules_root}",
            # a reboot re-execs UML with this command line: the agent ends it by this token
            f"guest_boot={secrets.token_hex(4)}",
        ]
        if boot.agent is not None:
            words.append("guest_agent=" + ",".join(boot.agent.words))
        elif boot.script is not None:
            words.append(f"guest_script={boot.script.resolve()}")
        else:
            raise EngineError("a boot needs a script or the agent")
        if boot.time_travel is not None:
            # UML's external time travel: the calendar on this socket is the guest's clock
            # (arch/um/kernel/time.c); the back ends then notify in band (virtio_uml.c)
            words.append(f"time-travel=ext:{boot.time_travel.resolve()}")
        if boot.cpus != 1:
            raise EngineError(f"the uml engine runs one CPU (asked for {boot.cpus})")
        if boot.i2c_socket is not None:
            words.append(f"virtio_uml.device={boot.i2c_socket.resolve()}:{VIRTIO_ID_I2C}")
        if boot.gpio_socket is not None:
            words.append(f"virtio_uml.device={boot.gpio_socket.resolve()}:{VIRTIO_ID_GPIO}")
        if boot.i2c_socket is not None or boot.gpio_socket is not None:
            words.append(f"guest_vio={kernel.vio}")
        if boot.modules:
            words.append("guest_modules=" + ",".join(
                str(m.resolve()) if isinstance(m, Path) else m for m in boot.modules))
        for key, value in boot.environment.items():
            if not key[:1].isupper() or any(c.isspace() for c in f"{key}{value}"):
                raise EngineError(f"environment word {key}={value!r}: the name must start "
                                  "with an upper-case letter and neither may hold spaces")
            words.append(f"{key}={value}")
        return [str(kernel.binary), *words]

    def start(self, boot: Boot) -> subprocess.Popen[bytes]:
        boot.results.mkdir(parents=True, exist_ok=True)
        env = dict(os.environ)
        if os.access(MEMORY_DIR, os.W_OK):
            env["TMPDIR"] = str(MEMORY_DIR)
        return subprocess.Popen(agent.guarded(self.command(boot)), stdin=subprocess.DEVNULL,
                                env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT)


def engine() -> UmlEngine:
    return UmlEngine()
