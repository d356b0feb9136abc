"""Boot Debian's own kernel under QEMU with a busybox initramfs and run one host script in it.

Why: kernel modules (i2c-stub, i2c-dev, the kernel's bmg160 driver) cannot be loaded on our
machines, but QEMU under software emulation boots the distribution kernel in seconds. The
guest mounts the host's root file system read-only over 9p and chroots into it, so the
project's own Python and the host's i2c-tools run unchanged inside the guest.

Artefacts (kernel package, unpacked modules, initramfs) live in a cache folder outside the
repository (``$BMG160_EMU_CACHE`` or ``~/.cache/bmg160-emu``).

Usage::

    python tools/qemu/guest.py prepare            # download + unpack kernel, build initramfs
    python tools/qemu/guest.py run SCRIPT OUTDIR  # boot, run SCRIPT with /bin/sh, power off

Inside the guest, SCRIPT runs chrooted in the host's root with ``GUEST_MODULES`` (folder of
the kernel's ``.ko`` files) and ``GUEST_OUT`` (= OUTDIR, the only writable host folder)
set; the host's ``/tmp`` stays visible read-only, and ``/run`` is a guest tmpfs (``HOME``
and ``TMPDIR`` point into it). ``modprobe -d "$GUEST_ROOT" NAME`` loads a module with its
dependencies.
"""

from __future__ import annotations

import argparse
import gzip
import os
import shutil
import stat
import subprocess
import sys
import tempfile
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

# Module load order that boots the 9p host file system (linux-kernel-notes.md).
NINEP_MODULES = [
    "virtio_ring", "virtio", "virtio_pci_legacy_dev", "virtio_pci_modern_dev", "virtio_pci",
    "netfs", "fscache", "9pnet", "9pnet_virtio", "9p",
]

INIT_SCRIPT = r"""#!/bin/sh
# initramfs /init: load 9p, mount the host root read-only, run the requested script chrooted.
export PATH=/bin:/sbin
mount -t proc proc /proc
mount -t sysfs sys /sys
mount -t devtmpfs dev /dev
for m in $(cat /modules.list); do insmod /modules/$m.ko || echo "init: insmod $m failed"; done
script=; out=; modroot=; py=
for arg in $(cat /proc/cmdline); do
    case "$arg" in
        guest_script=*) script=${arg#guest_script=} ;;
        guest_out=*) out=${arg#guest_out=} ;;
        guest_root=*) modroot=${arg#guest_root=} ;;
    esac
done
mkdir -p /host
if mount -t 9p -o trans=virtio,version=9p2000.L,msize=262144,cache=loose host /host; then
    mount -t proc proc /host/proc
    mount -t sysfs sys /host/sys
    mount -o bind /dev /host/dev
    mount -t tmpfs run /host/run
    mkdir -p /host/run/home /host/run/tmp
    if [ -n "$out" ]; then
        mkdir -p "/host$out" 2>/dev/null
        mount -t 9p -o trans=virtio,version=9p2000.L,msize=262144 out "/host$out" \
            || echo "init: cannot mount the output folder $out"
    fi
    echo "init: running $script"
    chroot /host /usr/bin/env -i PATH=/usr/local/sbin:/usr/local/bin:/usr/sbin:/usr/bin:/sbin:/bin \
        HOME=/run/home TMPDIR=/run/tmp GUEST_OUT="$out" GUEST_ROOT="$modroot" \
        GUEST_MODULES="$modroot/lib/modules/$(uname -r)" /bin/sh "$script"
    echo "init: script exited with status $?"
    [ -n "$out" ] && sync
else
    echo "init: cannot mount the host file system"
fi
poweroff -f
"""


def cache_dir() -> Path:
    return Path(os.environ.get("BMG160_EMU_CACHE", Path.home() / ".cache" / "bmg160-emu"))


@dataclass(frozen=True)
class GuestKernel:
    """An unpacked Debian kernel package: the image and its module tree."""

    root: Path  # the dpkg -x folder
    version: str

    @property
    def vmlinuz(self) -> Path:
        return self.root / "boot" / f"vmlinuz-{self.version}"

    @property
    def modules(self) -> Path:
        return self.root / "lib" / "modules" / self.version

    def module_path(self, name: str) -> Path:
        for candidate in (name, name.replace("-", "_"), name.replace("_", "-")):
            hits = list(self.modules.rglob(f"{candidate}.ko"))
            if hits:
                return hits[0]
        raise FileNotFoundError(f"module {name} not in {self.modules}")


def find_kernel(cache: Path | None = None) -> GuestKernel | None:
    """The unpacked kernel in the cache, or None if `prepare` has not run."""
    root = (cache or cache_dir()) / "kernel" / "root"
    versions = sorted((root / "lib" / "modules").glob("*")) if root.exists() else []
    for moddir in reversed(versions):
        kernel = GuestKernel(root, moddir.name)
        if kernel.vmlinuz.exists() and (kernel.modules / "modules.dep").exists():
            return kernel
    return None


def prepare_kernel(cache: Path | None = None) -> GuestKernel:
    """Download Debian's current amd64 kernel package and unpack it (no system install)."""
    kernel = find_kernel(cache)
    if kernel:
        return kernel
    work = (cache or cache_dir()) / "kernel"
    work.mkdir(parents=True, exist_ok=True)
    deps = subprocess.run(
        ["apt-cache", "depends", "linux-image-amd64"], capture_output=True, text=True, check=True
    ).stdout
    names = [ln.split()[-1] for ln in deps.splitlines() if "Depends: linux-image-" in ln]
    if not names:
        raise RuntimeError("apt-cache names no linux-image package (run apt-get update)")
    debs = list(work.glob(f"{names[0]}_*.deb"))
    if not debs:
        subprocess.run(["apt-get", "download", names[0]], cwd=work, check=True)
        debs = list(work.glob(f"{names[0]}_*.deb"))
    subprocess.run(["dpkg", "-x", str(debs[0]), str(work / "root")], check=True)
    version = names[0].removeprefix("linux-image-")
    subprocess.run(["depmod", "-b", str(work / "root"), version], check=True)
    kernel = find_kernel(cache)
    if kernel is None:
        raise RuntimeError(f"unpacking {debs[0]} gave no usable kernel")
    return kernel


def build_initramfs(kernel: GuestKernel, cache: Path | None = None) -> Path:
    """A gzip'd newc cpio with the static busybox, /init and the 9p modules."""
    target = (cache or cache_dir()) / f"initramfs-{kernel.version}.cpio.gz"
    if target.exists() and target.stat().st_mtime >= Path(__file__).stat().st_mtime:
        return target
    busybox = shutil.which("busybox")
    if busybox is None or not _is_static(Path(busybox)):
        raise RuntimeError("a static busybox is needed (Debian package busybox-static)")
    with tempfile.TemporaryDirectory() as tmp:
        root = Path(tmp)
        for sub in ("bin", "sbin", "proc", "sys", "dev", "modules", "host"):
            (root / sub).mkdir()
        shutil.copy2(busybox, root / "bin" / "busybox")
        applets = subprocess.run(
            [busybox, "--list"], capture_output=True, text=True, check=True
        ).stdout.split()
        for applet in applets:
            if applet != "busybox":
                (root / "bin" / applet).symlink_to("busybox")
        for name in NINEP_MODULES:
            shutil.copy2(kernel.module_path(name), root / "modules" / f"{name}.ko")
        (root / "modules.list").write_text("\n".join(NINEP_MODULES) + "\n")
        init = root / "init"
        init.write_text(INIT_SCRIPT)
        init.chmod(init.stat().st_mode | stat.S_IXUSR | stat.S_IXGRP | stat.S_IXOTH)
        files = subprocess.run(
            ["find", "."], cwd=root, capture_output=True, check=True
        ).stdout
        cpio = subprocess.run(
            ["cpio", "-o", "-H", "newc", "--quiet"], cwd=root, input=files,
            capture_output=True, check=True,
        ).stdout
    tmp_target = target.with_suffix(".tmp")
    tmp_target.write_bytes(gzip.compress(cpio, compresslevel=6))
    tmp_target.replace(target)
    return target


def _is_static(binary: Path) -> bool:
    """An ELF with no program interpreter (the initramfs has no dynamic loader)."""
    return b"ld-linux" not in binary.read_bytes()[:8192]


def qemu_binary() -> str | None:
    return shutil.which("qemu-system-x86_64")


def missing_requirements(cache: Path | None = None) -> str | None:
    """Why a guest cannot boot here, or None when it can."""
    if qemu_binary() is None:
        return "qemu-system-x86_64 is missing (Debian package qemu-system-x86)"
    if shutil.which("busybox") is None:
        return "busybox is missing (Debian package busybox-static)"
    if find_kernel(cache) is None:
        return (
            f"no unpacked Debian kernel in {cache or cache_dir()}/kernel "
            "(run: python tools/qemu/guest.py prepare, or .ci/setup.d/linux.sh)"
        )
    return None


@dataclass
class GuestRun:
    returncode: int
    console: str
    timed_out: bool


def run_guest(
    script: Path,
    out_dir: Path,
    console_log: Path | None = None,
    timeout_s: float = 150.0,
    memory_mb: int = 1024,
    cpus: int = 2,
    cache: Path | None = None,
    qemu_args: Sequence[str] = (),
) -> GuestRun:
    """Boot the guest, run `script` in it, always end QEMU; return its console text.
    ``qemu_args`` are added to QEMU's command line (e.g. :func:`vhost_user_args`)."""
    kernel = prepare_kernel(cache)
    initrd = build_initramfs(kernel, cache)
    out_dir = out_dir.resolve()
    out_dir.mkdir(parents=True, exist_ok=True)
    script = script.resolve()
    cmd = [
        qemu_binary() or "qemu-system-x86_64",
        "-cpu", "max",  # numpy needs modern instructions under TCG
        # Two vCPUs: QEMU runs them on two host threads, so the adapter and the kernel
        # driver's reader (or the adapter's start-up and other checks) overlap.
        "-m", str(memory_mb), "-smp", str(cpus),
        "-nographic", "-no-reboot", "-nodefaults", "-serial", "stdio",
        "-kernel", str(kernel.vmlinuz), "-initrd", str(initrd),
        "-append",
        (
            # no_timer_check: on a loaded host the slow TCG boot fails the kernel's check of
            # the timer interrupt ("IO-APIC + timer doesn't work!", a panic; seen here)
            f"console=ttyS0 quiet panic=-1 no_timer_check guest_script={script} "
            f"guest_out={out_dir} "
            f"guest_root={kernel.root}"
        ),
        "-virtfs",
        "local,path=/,mount_tag=host,security_model=none,readonly=on,multidevs=remap",
        "-virtfs", f"local,path={out_dir},mount_tag=out,security_model=none,multidevs=remap",
        *qemu_args,
    ]
    proc = subprocess.Popen(
        cmd, stdin=subprocess.DEVNULL, stdout=subprocess.PIPE, stderr=subprocess.STDOUT
    )
    timed_out = False
    try:
        output, _ = proc.communicate(timeout=timeout_s)
    except subprocess.TimeoutExpired:
        timed_out = True
        proc.kill()
        output, _ = proc.communicate()
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    console = output.decode("utf-8", "replace").replace("\r\n", "\n")
    if console_log is not None:
        console_log.write_text(console)
    return GuestRun(proc.returncode, console, timed_out)


def vhost_user_args(
    i2c_socket: Path, gpio_socket: Path | None = None, memory_mb: int = 1024
) -> list[str]:
    """QEMU options for the vhost-user virtio-i2c (and virtio-gpio) devices of
    ``bmg160-emu vhost-user-i2c``: guest RAM must be a shared memfd so the back end can map
    it (without share=on QEMU boots but every transfer hangs; linux-kernel-notes.md)."""
    args = [
        "-object", f"memory-backend-memfd,id=mem,size={memory_mb}M,share=on",
        "-machine", "memory-backend=mem",
        "-chardev", f"socket,id=vi2c,path={i2c_socket}",
        "-device", "vhost-user-i2c-pci,chardev=vi2c",
    ]
    if gpio_socket is not None:
        args += [
            "-chardev", f"socket,id=vgpio,path={gpio_socket}",
            "-device", "vhost-user-gpio-pci,chardev=vgpio",
        ]
    return args


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    sub = parser.add_subparsers(dest="action", required=True)
    sub.add_parser("prepare", help="download and unpack the kernel, build the initramfs")
    run = sub.add_parser("run", help="boot the guest and run SCRIPT in it")
    run.add_argument("script", type=Path)
    run.add_argument("out_dir", type=Path)
    run.add_argument("--timeout", type=float, default=150.0)
    args = parser.parse_args(argv)
    if args.action == "prepare":
        kernel = prepare_kernel()
        print(f"kernel {kernel.version}: {kernel.vmlinuz}")
        print(f"initramfs: {build_initramfs(kernel)}")
        return 0
    result = run_guest(args.script, args.out_dir, timeout_s=args.timeout)
    sys.stdout.write(result.console)
    return 124 if result.timed_out else 0


if __name__ == "__main__":
    raise SystemExit(main())
