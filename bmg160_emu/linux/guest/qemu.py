"""The QEMU engine: Debian's kernel under TCG with the host's root over 9p.

Why QEMU: it boots the distribution kernel as it is, so the driver under test runs in the
kernel users have; it needs no kernel build. Its cost: about 6 s per boot under TCG on our
2-core machine and about 100 us of CPU per register read (linux-kernel-notes.md). Guest RAM
is a shared memfd so the vhost-user back ends can map it (without share=on QEMU boots and
every transfer hangs).
"""

from __future__ import annotations

import shlex
import shutil
import subprocess
from pathlib import Path

from bmg160_emu.linux.guest import agent
from bmg160_emu.linux.guest.cache import cache_dir
from bmg160_emu.linux.guest.debian import find_kernel, prepare_kernel
from bmg160_emu.linux.guest.debian_modules import (
    build_bundled,
    bundled_dir,
    tools_missing,
    user_module,
)
from bmg160_emu.linux.guest.engine import Boot, EngineError, Progress
from bmg160_emu.linux.guest.initramfs import build_initramfs, busybox_missing

BINARY = "qemu-system-x86_64"


def vhost_user_args(i2c_socket: Path | None, gpio_socket: Path | None = None,
                    memory_mb: int = 512) -> list[str]:
    """QEMU options for the vhost-user virtio-i2c (and virtio-gpio) devices."""
    if i2c_socket is None and gpio_socket is None:
        return []
    args = ["-object", f"memory-backend-memfd,id=mem,size={memory_mb}M,share=on",
            "-machine", "memory-backend=mem"]
    if i2c_socket is not None:
        args += ["-chardev", f"socket,id=vi2c,path={i2c_socket}",
                 "-device", "vhost-user-i2c-pci,chardev=vi2c"]
    if gpio_socket is not None:
        args += ["-chardev", f"socket,id=vgpio,path={gpio_socket}",
                 "-device", "vhost-user-gpio-pci,chardev=vgpio"]
    return args


class QemuEngine:
    """Debian's kernel under QEMU (TCG), the busybox initramfs, 9p for the host's root."""

    name = "qemu"

    def __init__(self, cache: Path | None = None, extra_args: tuple[str, ...] = ()) -> None:
        self.cache = cache
        self.extra_args = extra_args  # more QEMU options (e.g. -name for thread names)

    def missing(self) -> list[str]:
        lines = []
        if shutil.which(BINARY) is None:
            lines.append(f"{BINARY} is missing (Debian package qemu-system-x86)")
        reason = busybox_missing()
        if reason:
            lines.append(reason)
        lines += tools_missing()
        lines += [line for line in agent.missing() if line not in lines]
        if shutil.which("depmod") is None:
            lines.append("depmod is missing (Debian package kmod)")
        if not lines and (find_kernel(self.cache) is None or bundled_dir(self.cache) is None):
            lines.append(f"no kernel and modules in {self.cache or cache_dir()} yet "
                         "(run: bmg160-emu kernel prepare --engine qemu)")
        return lines

    def prepare(self, progress: Progress) -> None:
        kernel = prepare_kernel(self.cache, progress)
        progress(f"kernel {kernel.version}: {kernel.vmlinuz}")
        progress(f"initramfs: {build_initramfs(kernel, self.cache)}")
        progress(f"modules: {build_bundled(self.cache, progress)}")

    def build_module(self, path: Path, progress: Progress) -> list[Path]:
        """A user's .ko as it is, or its Kbuild folder built against Debian's headers."""
        return user_module(path, self.cache, progress)

    def board_module(self) -> Path | None:
        folder = bundled_dir(self.cache)
        return folder / "bmg160-board.ko" if folder is not None else None

    def command(self, boot: Boot) -> list[str]:
        """QEMU's command line for ``boot`` (the kernel and initramfs must be prepared)."""
        kernel = find_kernel(self.cache)
        if kernel is None:
            raise EngineError("no guest kernel in the cache (run: bmg160-emu kernel prepare)")
        initrd = build_initramfs(kernel, self.cache)
        results = boot.results.resolve()
        if boot.time_travel is not None:
            raise EngineError("the qemu engine cannot run in virtual time (UML's time "
                              "travel only): run it in real time")
        script = boot.script if boot.agent is None else agent_script(boot)
        if script is None:
            raise EngineError("a boot needs a script or the agent")
        words = [
            # no_timer_check: on a loaded host the slow TCG boot fails the kernel's check of
            # the timer interrupt ("IO-APIC + timer doesn't work!", a panic; seen here)
            "console=ttyS0", "quiet", "panic=-1", "no_timer_check",
            f"guest_script={script.resolve()}", f"guest_out={results}",
            f"guest_root={kernel.root}",
        ]
        if boot.i2c_socket is not None or boot.gpio_socket is not None:
            vio = bundled_dir(self.cache)
            if vio is None:
                raise EngineError("the virtio modules are not built "
                                  "(run: bmg160-emu kernel prepare --engine qemu)")
            words.append(f"guest_vio={vio}")
        if boot.modules:
            words.append("guest_modules=" + ",".join(
                str(m.resolve()) if isinstance(m, Path) else m for m in boot.modules))
        if not boot.host_root_readonly:
            words.append("guest_rw=1")
        for key, value in boot.environment.items():
            if not key[:1].isupper() or any(c.isspace() for c in f"{key}{value}"):
                raise EngineError(f"environment word {key}={value!r}: the name must start "
                                  "with an upper-case letter and neither may hold spaces")
            words.append(f"{key}={value}")
        readonly = "on" if boot.host_root_readonly else "off"
        return [
            shutil.which(BINARY) or BINARY,
            "-cpu", "max",  # numpy needs modern instructions under TCG
            "-m", str(boot.memory_mb), "-smp", str(boot.cpus),
            "-nographic", "-no-reboot", "-nodefaults", "-serial", "stdio",
            "-kernel", str(kernel.vmlinuz), "-initrd", str(initrd),
            "-append", " ".join(words),
            "-virtfs",
            (f"local,path=/,mount_tag=host,security_model=none,readonly={readonly},"
             "multidevs=remap"),
            "-virtfs", f"local,path={results},mount_tag=out,security_model=none,multidevs=remap",
            *vhost_user_args(boot.i2c_socket, boot.gpio_socket, boot.memory_mb),
            *self.extra_args,
        ]

    def start(self, boot: Boot) -> subprocess.Popen[bytes]:
        boot.results.mkdir(parents=True, exist_ok=True)
        return subprocess.Popen(agent.guarded(self.command(boot)), stdin=subprocess.DEVNULL,
                                stdout=subprocess.PIPE, stderr=subprocess.STDOUT)


def agent_script(boot: Boot) -> Path:
    """The boot script that makes the agent serve ``boot.agent`` (QEMU's /init is busybox:
    the agent runs chrooted in the host's root, from the cache, as any host program)."""
    assert boot.agent is not None
    words = " ".join(shlex.quote(w) for w in (str(agent.binary()), "serve", *boot.agent.words))
    script = boot.agent.folder / "boot.sh"
    script.parent.mkdir(parents=True, exist_ok=True)
    script.write_text(f"cd /\nexec {words}\n")
    return script


def engine() -> QemuEngine:
    return QemuEngine()
