"""The QEMU guest's first user space: a busybox initramfs whose /init mounts the host's root
over 9p, brings up the virtio adapters and modules, and runs the boot script chrooted in it.

Why chroot into the host: the project's own Python, i2c-tools and the user's programs run
unchanged inside the guest, with nothing copied (linux-kernel-notes.md). /init keeps the
engine contract of :mod:`bmg160_emu.linux.guest.engine`; it reads its settings from the
kernel command line (``guest_*`` words, and upper-case ``KEY=VAL`` words for the script).
"""

from __future__ import annotations

import gzip
import shutil
import stat
import subprocess
import tempfile
from pathlib import Path

from bmg160_emu.linux.guest.cache import cache_dir, content_hash
from bmg160_emu.linux.guest.debian import GuestKernel
from bmg160_emu.linux.guest.engine import EngineError

# Module load order that boots the 9p host file system (linux-kernel-notes.md).
NINEP_MODULES = [
    "virtio_ring", "virtio", "virtio_pci_legacy_dev", "virtio_pci_modern_dev", "virtio_pci",
    "netfs", "fscache", "9pnet", "9pnet_virtio", "9p",
]

INIT_SCRIPT = r"""#!/bin/sh
# initramfs /init (bmg160_emu.linux.guest.initramfs): the engine contract under QEMU.
export PATH=/bin:/sbin
mount -t proc proc /proc
mount -t sysfs sys /sys
mount -t devtmpfs dev /dev
for m in $(cat /modules.list); do insmod /modules/$m.ko || echo "init: insmod $m failed"; done
script=; out=; modroot=; vio=; mods=; rw=; envs=
for arg in $(cat /proc/cmdline); do
    case "$arg" in
        guest_script=*) script=${arg#guest_script=} ;;
        guest_out=*) out=${arg#guest_out=} ;;
        guest_root=*) modroot=${arg#guest_root=} ;;
        guest_vio=*) vio=${arg#guest_vio=} ;;
        guest_modules=*) mods=${arg#guest_modules=} ;;
        guest_rw=1) rw=1 ;;
        [A-Z]*=*) envs="$envs $arg" ;;
    esac
done
HOSTPATH=/usr/local/sbin:/usr/local/bin:/usr/sbin:/usr/bin:/sbin:/bin
host() { chroot /host /usr/bin/env -i PATH=$HOSTPATH "$@"; }
mkdir -p /host
opts=trans=virtio,version=9p2000.L,msize=262144,cache=loose
[ -n "$rw" ] && opts=trans=virtio,version=9p2000.L,msize=262144
if ! mount -t 9p -o $opts host /host; then
    echo "init: cannot mount the host file system"; poweroff -f
fi
mount -t proc proc /host/proc
mount -t sysfs sys /host/sys
mount -o bind /dev /host/dev
mount -t tmpfs run /host/run
mkdir -p /host/run/home /host/run/tmp
if [ -n "$out" ]; then
    mkdir -p "/host$out" 2>/dev/null
    mount -t 9p -o trans=virtio,version=9p2000.L,msize=262144 out "/host$out" \
        || echo "init: cannot mount the results folder $out"
fi
bus=; gpiobase=
if [ -n "$vio" ]; then
    host modprobe -d "$modroot" i2c-dev
    [ -e "/host$vio/i2c-virtio.ko" ] && host insmod "$vio/i2c-virtio.ko"
    [ -e "/host$vio/gpio-virtio.ko" ] && host insmod "$vio/gpio-virtio.ko" force_irq=1
    i=0
    while [ -z "$bus" ] && [ $i -lt 100 ]; do
        for d in /sys/bus/i2c/devices/i2c-*; do
            grep -q virtio "$d/name" 2>/dev/null && bus=${d##*/i2c-}
        done
        [ -z "$bus" ] && sleep 0.05; i=$((i + 1))
    done
    for c in /sys/class/gpio/gpiochip*; do
        case "$(cat "$c/label" 2>/dev/null)" in virtio*) gpiobase=$(cat "$c/base") ;; esac
    done
fi
for m in $(echo "$mods" | tr ',' ' '); do
    case "$m" in
        /*) host insmod "$m" || echo "init: insmod $m failed" ;;
        *) host modprobe -d "$modroot" "$m" || echo "init: modprobe $m failed" ;;
    esac
done
echo "init: running $script"
chroot /host /usr/bin/env -i PATH=$HOSTPATH HOME=/run/home TMPDIR=/run/tmp \
    BMG160_RESULTS="$out" GUEST_OUT="$out" GUEST_ENGINE=qemu GUEST_ROOT="$modroot" \
    GUEST_MODULES="$modroot/lib/modules/$(uname -r)" GUEST_I2C_BUS="$bus" \
    GUEST_GPIO_BASE="$gpiobase" $envs /bin/sh "$script"
status=$?
echo "init: script exited with status $status"
[ -n "$out" ] && { echo $status > "/host$out/exit-status"; sync; }
poweroff -f
"""


def _is_static(binary: Path) -> bool:
    """An ELF with no program interpreter (the initramfs has no dynamic loader)."""
    return b"ld-linux" not in binary.read_bytes()[:8192]


def busybox_missing() -> str | None:
    """Why the initramfs cannot be built here, or None."""
    busybox = shutil.which("busybox")
    if busybox is None or not _is_static(Path(busybox)):
        return "a static busybox is missing (Debian package busybox-static)"
    if shutil.which("cpio") is None:
        return "cpio is missing (Debian package cpio)"
    return None


def build_initramfs(kernel: GuestKernel, cache: Path | None = None) -> Path:
    """A gzip'd newc cpio with the static busybox, /init and the 9p modules (once per
    kernel and /init text)."""
    key = content_hash([], INIT_SCRIPT, *NINEP_MODULES, length=8)
    target = (cache or cache_dir()) / f"initramfs-{kernel.version}-{key}.cpio.gz"
    if target.exists():
        return target
    reason = busybox_missing()
    if reason:
        raise EngineError(reason)
    busybox = shutil.which("busybox") or "busybox"
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
        files = subprocess.run(["find", "."], cwd=root, capture_output=True, check=True).stdout
        cpio = subprocess.run(["cpio", "-o", "-H", "newc", "--quiet"], cwd=root, input=files,
                              capture_output=True, check=True).stdout
    target.parent.mkdir(parents=True, exist_ok=True)
    partial = target.with_suffix(".tmp")
    partial.write_bytes(gzip.compress(cpio, compresslevel=6))
    partial.replace(target)
    return target
