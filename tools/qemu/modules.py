"""Build the guest kernel modules Debian's 6.1 kernel does not ship, from Debian's packages.

Why: Debian's configuration leaves CONFIG_I2C_VIRTIO, CONFIG_GPIO_VIRTIO and the IIO
software triggers unset (linux-kernel-notes.md), so they are built out of tree against
the guest kernel's own ``linux-headers`` package, with the source files taken from
``linux-source-6.1`` of the same version. Nothing is installed on the system: the
packages are fetched with ``apt-get download`` and unpacked with ``dpkg -x`` into the cache.

Built (into ``$CACHE/kmod-<kernel version>/``):

- ``i2c-virtio`` (drivers/i2c/busses) with ``kmod/i2c-virtio-wait.patch``: the 6.1 driver
  waits for its requests interruptibly, and a signal then frees requests the device still
  owns (the device writes into freed memory: slab corruption);
- ``gpio-virtio`` (drivers/gpio) with ``kmod/gpio-virtio-force-irq.patch`` applied: QEMU
  7.2's vhost-user-gpio-pci never offers VIRTIO_GPIO_F_IRQ, and the stock driver then sets
  up no interrupts; the patch adds a ``force_irq`` parameter (docs/virtio-i2c.md);
- ``industrialio-sw-trigger``, ``industrialio-configfs``, ``iio-trig-hrtimer`` (drivers/iio):
  the hrtimer trigger for buffered capture without an interrupt line (the i2c-stub route);
- ``bmg160-board`` (``kmod/bmg160-board.c``, ours): the bmg160 client with its IRQ.

Usage: ``python tools/qemu/modules.py build`` (prints the folder); the kernel tests call
:func:`build_modules`, which does nothing when the folder is up to date.
"""

from __future__ import annotations

import hashlib
import importlib.util
import shutil
import subprocess
import sys
import tarfile
import tempfile
from pathlib import Path

HERE = Path(__file__).resolve().parent
KMOD = HERE / "kmod"
PATCHES = (KMOD / "gpio-virtio-force-irq.patch", KMOD / "i2c-virtio-wait.patch")
BOARD = KMOD / "bmg160-board.c"

# source file in linux-source-6.1 -> module name
SOURCES = {
    "drivers/i2c/busses/i2c-virtio.c": "i2c-virtio",
    "drivers/gpio/gpio-virtio.c": "gpio-virtio",
    "drivers/iio/industrialio-sw-trigger.c": "industrialio-sw-trigger",
    "drivers/iio/industrialio-configfs.c": "industrialio-configfs",
    "drivers/iio/trigger/iio-trig-hrtimer.c": "iio-trig-hrtimer",
}
MODULES = [*SOURCES.values(), "bmg160-board"]


def _guest():
    spec = importlib.util.spec_from_file_location("bmg160_guest_for_modules", HERE / "guest.py")
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module
    spec.loader.exec_module(module)
    return module


def _package_version(cache: Path, kernel_version: str) -> str:
    """The Debian version of the unpacked kernel package (6.1.176-1), from its file name."""
    debs = sorted((cache / "kernel").glob(f"linux-image-{kernel_version}_*.deb"))
    if not debs:
        raise RuntimeError(f"no linux-image-{kernel_version} package in {cache / 'kernel'}")
    return debs[-1].name.split("_")[1]


def _unpacked_sources(cache: Path, kernel_version: str) -> Path:
    """linux-source, linux-headers (arch + common) and linux-kbuild, unpacked once."""
    version = _package_version(cache, kernel_version)
    work = cache / "kbuild" / version
    root = work / "root"
    stamp = work / "unpacked"
    if stamp.exists():
        return root
    work.mkdir(parents=True, exist_ok=True)
    common = kernel_version.rsplit("-", 1)[0] + "-common"
    major = ".".join(kernel_version.split(".")[:2])
    packages = [f"linux-source-{major}", f"linux-headers-{kernel_version}",
                f"linux-headers-{common}", f"linux-kbuild-{major}"]
    for package in packages:
        if not list(work.glob(f"{package}_{version}_*.deb")):
            subprocess.run(["apt-get", "download", "-q", f"{package}={version}"], cwd=work,
                           check=True, stdout=subprocess.DEVNULL)
        deb = next(work.glob(f"{package}_{version}_*.deb"))
        subprocess.run(["dpkg", "-x", str(deb), str(root)], check=True)
    # the headers' top Makefile includes the common tree by its installed path: point it
    # at the unpacked one (linux-kernel-notes.md)
    makefile = root / "usr/src" / f"linux-headers-{kernel_version}" / "Makefile"
    makefile.write_text(f"include {root}/usr/src/linux-headers-{common}/Makefile\n")
    stamp.write_text(version + "\n")
    return root


def _extract(root: Path, major: str, target: Path) -> None:
    tarball = root / "usr/src" / f"linux-source-{major}.tar.xz"
    wanted = {f"linux-source-{major}/{path}": path for path in SOURCES}
    with tarfile.open(tarball) as archive:
        for member in archive:
            if member.name in wanted:
                out = target / Path(wanted[member.name]).name
                extracted = archive.extractfile(member)
                assert extracted is not None
                out.write_bytes(extracted.read())
                if len(list(target.glob("*.c"))) == len(wanted):
                    return
    missing = [p for p in SOURCES if not (target / Path(p).name).exists()]
    raise RuntimeError(f"{tarball} lacks {', '.join(missing)}")


def _fingerprint(kernel_version: str) -> str:
    digest = hashlib.sha256(kernel_version.encode())
    for path in (*PATCHES, BOARD, Path(__file__)):
        digest.update(path.read_bytes())
    return digest.hexdigest()[:12]


def module_dir(cache: Path | None = None) -> Path | None:
    """The folder of built modules for the cached kernel, or None if not built (or stale)."""
    guest = _guest()
    cache = cache or guest.cache_dir()
    kernel = guest.find_kernel(cache)
    if kernel is None:
        return None
    out = cache / f"kmod-{kernel.version}"
    stamp = out / "fingerprint"
    if stamp.exists() and stamp.read_text().strip() == _fingerprint(kernel.version) and all(
            (out / f"{m}.ko").exists() for m in MODULES):
        return out
    return None


def build_modules(cache: Path | None = None) -> Path:
    """Build (once) and return the folder holding every module of :data:`MODULES`."""
    guest = _guest()
    cache = cache or guest.cache_dir()
    ready = module_dir(cache)
    if ready is not None:
        return ready
    kernel = guest.prepare_kernel(cache)
    for tool in ("make", "gcc", "patch"):
        if shutil.which(tool) is None:
            raise RuntimeError(f"{tool} is missing (Debian packages make, gcc, patch)")
    root = _unpacked_sources(cache, kernel.version)
    major = ".".join(kernel.version.split(".")[:2])
    headers = root / "usr/src" / f"linux-headers-{kernel.version}"
    out = cache / f"kmod-{kernel.version}"
    with tempfile.TemporaryDirectory() as tmp:
        build = Path(tmp)
        _extract(root, major, build)
        for patch in PATCHES:  # a/drivers/<dir>/<file>: the sources sit flat in build/
            strip = len(Path(patch.read_text().split("\n--- ", 1)[1].split()[0]).parts) - 1
            subprocess.run(["patch", "-s", f"-p{strip}", "-i", str(patch)], cwd=build,
                           check=True)
        shutil.copy2(BOARD, build / BOARD.name)
        (build / "Kbuild").write_text(
            "".join(f"obj-m += {name}.o\n" for name in MODULES))
        result = subprocess.run(
            ["make", "-s", "-C", str(headers), f"M={build}", "modules"],
            check=False, capture_output=True, text=True)
        if result.returncode:
            raise RuntimeError(f"module build failed:\n{result.stdout}\n{result.stderr}")
        out.mkdir(parents=True, exist_ok=True)
        for name in MODULES:
            shutil.copy2(build / f"{name}.ko", out / f"{name}.ko")
    (out / "fingerprint").write_text(_fingerprint(kernel.version) + "\n")
    return out


def main(argv: list[str] | None = None) -> int:
    args = sys.argv[1:] if argv is None else argv
    if args != ["build"]:
        print("usage: python tools/qemu/modules.py build", file=sys.stderr)
        return 2
    print(build_modules())
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
