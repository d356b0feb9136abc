#!/usr/bin/env bash
# Linux front ends (issue 4): what the umockdev tests and the QEMU kernel tests need.
# Idempotent: installs only missing Debian packages, builds PyGObject into the active
# environment only if gi is not importable, and downloads/unpacks the kernel package into
# the cache (~/.cache/bmg160-emu, never the repository) only once.
set -euo pipefail
cd "$(dirname "$0")/../.."
export DEBIAN_FRONTEND=noninteractive

packages=(
    i2c-tools gcc                                   # both routes: clients, the C test program
    umockdev gir1.2-umockdev-1.0 libumockdev0       # A: virtual /dev/i2c-N
    libgirepository1.0-dev libcairo2-dev pkg-config # A: building PyGObject in a venv
    qemu-system-x86 busybox-static cpio kmod        # B: the guest
    util-linux                                      # B: setpriv for the permission check
    make patch xz-utils                             # C: out-of-tree guest modules (virtio)
)
. .ci/apt-missing.sh
apt_install_missing "${packages[@]}"

# Debian's python3-gi serves Debian's /usr/bin/python3 only; a venv builds its own.
if ! python3 -c "import gi" 2>/dev/null; then
    python3 -m pip install --quiet 'PyGObject<3.50'   # 3.50+ needs GLib >= 2.80 (Debian 12 has 2.74)
fi
python3 -c "import gi; gi.require_version('UMockdev', '1.0'); from gi.repository import UMockdev"

# The guest (bmg160_emu.linux.guest): Debian's kernel package unpacked into the cache, the
# busybox initramfs, and the modules Debian's configuration leaves out (i2c-virtio,
# gpio-virtio (patched), the IIO software triggers, bmg160-board), built against the guest
# kernel's linux-headers with sources from linux-source-6.1 of the same version (apt-get
# download + dpkg -x into the cache; rebuilt only when their sources change).
PYTHONPATH=$PWD${PYTHONPATH:+:$PYTHONPATH} python3 -m bmg160_emu kernel prepare --engine qemu
